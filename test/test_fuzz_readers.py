"""Property-based fuzzing of the readers (issue 13, design.md convention 11).

Any bytes given as a CSV file, an MCAP bag or a bag's ``metadata.yaml`` give either a valid record
or one :class:`~tcomp_core.errors.TcompError` whose message names the file: never another
exception, never a non-finite value, never a hang (hypothesis's deadline bounds each example).
Seeded (``derandomize``) so a failure reproduces.
"""

import shutil
import struct
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tcomp_core.errors import TcompError
from tcomp_core.io import open_stream, read_record, write_bag

# A bag cut short is read up to its last record with a warning: expected here.
pytestmark = pytest.mark.filterwarnings("ignore::tcomp_core.errors.TruncatedInputWarning")

SETTINGS = settings(
    derandomize=True,
    max_examples=150,
    deadline=5000,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)


@pytest.fixture(scope="module")
def small_bag(tmp_path_factory):
    rng = np.random.default_rng(13)
    time = np.arange(400) * 0.002
    series = {
        "/tc1/temperature": 300 + 20 * np.sin(2 * np.pi * 3 * time) + rng.normal(0, 0.2, 400),
        "/tc2/temperature": 300 + 15 * np.sin(2 * np.pi * 3 * time - 0.5),
    }
    path = tmp_path_factory.mktemp("fuzz") / "small"
    write_bag(path, time, series, compress=False)
    return path


def check_record(record):
    assert record.tc1.size == record.tc2.size == record.time.size
    for values in (record.tc1, record.tc2):
        assert ((values >= -273.15) & (values <= 2000.0)).all()
    assert np.isfinite(record.time).all()


def read_all_ways(path: Path, names: str):
    """read_record and the streaming reader of tcomp process; the outcome of each."""
    try:
        check_record(read_record(path))
    except TcompError as exc:
        assert names in str(exc), str(exc)
    try:
        stream = open_stream(path)
        for block in stream:
            for batch in block.series.values():
                assert batch.stamps_ns.size == batch.temperature.size
        stream.check_topics()
    except TcompError as exc:
        assert names in str(exc), str(exc)


mutations = st.lists(
    st.one_of(
        st.tuples(st.just("flip"), st.integers(0, 10**7), st.integers(0, 7)),
        st.tuples(st.just("cut"), st.integers(0, 10**7), st.just(0)),
        st.tuples(st.just("delete"), st.integers(0, 10**7), st.integers(1, 64)),
        st.tuples(st.just("insert"), st.integers(0, 10**7), st.integers(1, 64)),
        st.tuples(
            st.just("length"),
            st.integers(0, 10**7),
            st.sampled_from([0, 1, 2**31, 2**32 - 1, 2**40, 2**63, 2**64 - 1]),
        ),
    ),
    min_size=1,
    max_size=4,
)


@pytest.mark.slow
@SETTINGS
@given(mutations)
def test_mutated_mcap_reads_or_fails_with_one_error_naming_the_file(small_bag, tmp_path, edits):
    data = bytearray((small_bag / "small.mcap").read_bytes())
    for kind, position, value in edits:
        at = position % max(len(data), 1)
        if kind == "flip" and data:
            data[at] ^= 1 << value
        elif kind == "cut":
            del data[at:]
        elif kind == "delete":
            del data[at : at + value]
        elif kind == "insert":
            data[at:at] = bytes(range(value))
        elif kind == "length" and len(data) >= at + 8:
            struct.pack_into("<Q", data, at, value)
    bag = tmp_path / "bag"
    shutil.rmtree(bag, ignore_errors=True)
    shutil.copytree(small_bag, bag)
    (bag / "small.mcap").write_bytes(bytes(data))
    read_all_ways(bag, str(bag))
    read_all_ways(bag / "small.mcap", str(bag))


yaml_values = st.one_of(
    st.none(),
    st.integers(),
    st.text(max_size=20),
    st.lists(st.text(max_size=12), max_size=3),
    st.dictionaries(st.text(max_size=5), st.integers(), max_size=2),
    st.sampled_from(["/etc/passwd", "../small/small.mcap", "small.mcap", ".", "", "x/../../y"]),
)


@pytest.mark.slow
@SETTINGS
@given(yaml_values, st.sampled_from(["mcap", "sqlite3", 7]))
def test_metadata_yaml_is_validated(small_bag, tmp_path, files, storage):
    from ruamel.yaml import YAML

    bag = tmp_path / "bag"
    shutil.rmtree(bag, ignore_errors=True)
    shutil.copytree(small_bag, bag)
    yaml = YAML(typ="safe")
    info = yaml.load((bag / "metadata.yaml").read_text())
    body = info["rosbag2_bagfile_information"]
    body["relative_file_paths"] = files
    body["storage_identifier"] = storage
    with (bag / "metadata.yaml").open("w") as stream:
        yaml.dump(info, stream)
    read_all_ways(bag, str(bag))


def test_metadata_cannot_point_outside_the_bag(small_bag, tmp_path):
    from ruamel.yaml import YAML

    bag = tmp_path / "bag"
    shutil.copytree(small_bag, bag)
    yaml = YAML(typ="safe")
    info = yaml.load((bag / "metadata.yaml").read_text())
    for name in ("/etc/passwd", "../other/small.mcap"):
        info["rosbag2_bagfile_information"]["relative_file_paths"] = [name]
        with (bag / "metadata.yaml").open("w") as stream:
            yaml.dump(info, stream)
        with pytest.raises(TcompError, match="outside the bag directory"):
            read_record(bag)


cells = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.integers(-(10**30), 10**30).map(str),
    st.sampled_from(
        ["", " ", "nan", "inf", "-inf", "1e308", "1e309", "abc", "0x10", "1,5", '"2"']
    ),
)
rows = st.lists(st.lists(cells, min_size=0, max_size=5), max_size=40)


@pytest.mark.slow
@SETTINGS
@given(
    st.sampled_from(["time,tc1,tc2", "time,tc1,tc2,ref", "tc1,tc2", "", "time;tc1;tc2"]),
    rows,
    st.sampled_from(["\n", "\r\n"]),
    st.booleans(),
)
def test_csv_reads_or_fails_with_one_error_naming_the_file(tmp_path, header, body, newline, bom):
    text = newline.join([header, *(",".join(row) for row in body)])
    path = tmp_path / "fuzz.csv"
    path.write_bytes(("\ufeff" if bom else "").encode() + text.encode("utf-8"))
    read_all_ways(path, str(path))


@pytest.mark.slow
@SETTINGS
@given(st.binary(max_size=300))
def test_any_bytes_as_csv_or_mcap(tmp_path, payload):
    for name in ("junk.csv", "junk.mcap"):
        path = tmp_path / name
        path.write_bytes(payload)
        read_all_ways(path, str(path))


def test_good_csv_still_reads(tmp_path):
    # The property above must not be met by refusing everything.
    path = tmp_path / "good.csv"
    time = np.arange(100) * 0.01
    lines = ["time,tc1,tc2", *(f"{t},{20 + np.sin(t)},{21 + np.cos(t)}" for t in time.tolist())]
    path.write_text("\n".join(lines))
    read_all_ways(path, str(path))
    assert read_record(path).tc1.size == 100


@pytest.mark.parametrize("kind", ["fifo", "device", "symlink loop"])
def test_non_regular_inputs_are_refused_without_blocking(tmp_path, kind):
    import os

    path = tmp_path / "x.csv"
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "device":
        path.symlink_to("/dev/zero")
    else:
        (tmp_path / "y.csv").symlink_to(path)
        path.symlink_to(tmp_path / "y.csv")
    with pytest.raises(TcompError, match=r"x\.csv"):
        read_record(path)
    with pytest.raises(TcompError, match=r"x\.csv"):
        open_stream(path)
