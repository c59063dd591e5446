"""CSV and rosbag2 MCAP round trips, and every malformed input named precisely."""

from __future__ import annotations

import re
import shutil
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
import yaml
from rosbags.rosbag2 import Reader, StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from tcomp_core.errors import DataError, InvalidReadingsWarning, TruncatedInputWarning
from tcomp_core.io import (
    DEFAULT_TOPICS,
    GAS_TOPIC,
    TEMPERATURE_TYPE,
    DiagnosticStatusFields,
    Record,
    encode_diagnostic_array,
    read_bag,
    read_csv,
    read_record,
    write_bag,
    write_csv,
    write_series,
)

RNG_SEED = 31
TC1, TC2, TREF = DEFAULT_TOPICS
EPOCH_NS = 1_700_000_000_000_000_007
STORE = get_typestore(Stores.ROS2_JAZZY)


@pytest.fixture
def arrays():
    """time (s, 2 ms steps from 3 s), tc1, tc2, ref (deg C), full-precision random values."""
    rng = np.random.default_rng(RNG_SEED)
    count = 200
    return (
        np.arange(count) * 0.002 + 3.0,
        300 + rng.standard_normal(count),
        310 + rng.standard_normal(count),
        rng.random(count) * 1e-3 + 1e-300,
    )


def _temperature(stamp_ns: int, value: float, frame_id: str = "f"):
    header = STORE.types["std_msgs/msg/Header"](
        stamp=STORE.types["builtin_interfaces/msg/Time"](
            sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9
        ),
        frame_id=frame_id,
    )
    return STORE.types[TEMPERATURE_TYPE](header=header, temperature=value, variance=0.0)


def _write_messages(path, messages, *, log_times=None):
    """A bag with arbitrary Temperature messages: {topic: [(stamp_ns, value), ...]}."""
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        for topic, items in messages.items():
            connection = writer.add_connection(topic, TEMPERATURE_TYPE, typestore=STORE)
            for position, (stamp, value) in enumerate(items):
                log_time = stamp if log_times is None else log_times[position]
                raw = STORE.serialize_cdr(_temperature(stamp, value), TEMPERATURE_TYPE)
                writer.write(connection, log_time, raw)
    return path


def _paired(count=50, start=10**9, step=10**6):
    stamps = [start + index * step for index in range(count)]
    return stamps, [(stamp, 20.0 + index) for index, stamp in enumerate(stamps)]


# --------------------------------------------------------------------------------------------
# CSV round trips


@pytest.mark.parametrize("with_ref", [True, False])
def test_csv_round_trip_is_exact(tmp_path, arrays, with_ref):
    time, tc1, tc2, ref = arrays
    path = write_csv(tmp_path / "r.csv", time, tc1, tc2, ref if with_ref else None)
    header = path.read_text().splitlines()[0]
    assert header == ("time,tc1,tc2,ref" if with_ref else "time,tc1,tc2")
    record = read_csv(path)
    np.testing.assert_array_equal(record.time, time)
    np.testing.assert_array_equal(record.tc1, tc1)
    np.testing.assert_array_equal(record.tc2, tc2)
    if with_ref:
        np.testing.assert_array_equal(record.ref, ref)
    else:
        assert record.ref is None
    assert record.dt == pytest.approx(0.002, rel=1e-12)
    assert "r.csv" in record.source
    assert record.frame_id == ""
    assert record.stamps_ns is None


def test_csv_keeps_awkward_floats_bit_exact(tmp_path):
    time = np.arange(6) * 0.1
    values = np.array([0.1 + 0.2, 1e-300, 5e-324, -0.0, 1.7976931348623157e308, -1 / 3])
    # Unscreened: 1.8e308 °C is a value to round-trip here, not a temperature.
    record = read_csv(write_csv(tmp_path / "f.csv", time, values, values[::-1]), screen=False)
    assert record.tc1.tobytes() == values.tobytes()
    assert record.tc2.tobytes() == values[::-1].tobytes()


def test_csv_custom_columns_extra_and_bom(tmp_path):
    path = tmp_path / "custom.csv"
    path.write_text("\ufefftime, a ,b,note,fast\n0,1,2,x,5\n0.5,3,4,y,6\n1.0,5,6,z,7\n\n")
    record = read_record(path, columns=("a", "b", "fast"))
    np.testing.assert_array_equal(record.tc1, [1, 3, 5])
    np.testing.assert_array_equal(record.tc2, [2, 4, 6])
    np.testing.assert_array_equal(record.ref, [5, 6, 7])
    assert record.dt == 0.5
    assert "columns time, a, b, fast" in record.source
    assert read_csv(path, columns=("a", "b")).ref is None


def test_write_csv_extra_columns_and_checks(tmp_path, arrays):
    time, tc1, tc2, ref = arrays
    path = write_csv(tmp_path / "g.csv", time, tc1, tc2, extra={"gas": ref, "z": tc1})
    assert path.read_text().splitlines()[0] == "time,tc1,tc2,gas,z"
    np.testing.assert_array_equal(read_csv(path, columns=("tc1", "tc2", "gas")).ref, ref)
    with pytest.raises(DataError, match=r"extra column name 'tc1' is empty or already used"):
        write_csv(tmp_path / "h.csv", time, tc1, tc2, extra={"tc1": tc1})
    with pytest.raises(DataError, match=r"column 'tc2' has shape \(199,\), time \(200,\)"):
        write_csv(tmp_path / "h.csv", time, tc1, tc2[:-1])
    bad_time = time.copy()
    bad_time[7] = np.inf
    with pytest.raises(DataError, match=r"h\.csv: column 'time': sample 7 is inf"):
        write_csv(tmp_path / "h.csv", bad_time, tc1, tc2)
    assert not (tmp_path / "h.csv").exists()


def test_existing_csv_is_not_overwritten(tmp_path, arrays):
    time, tc1, tc2, _ = arrays
    target = tmp_path / "x.csv"
    target.write_text("precious")
    with pytest.raises(DataError, match=r"x\.csv exists; pass --force"):
        write_csv(target, time, tc1, tc2)
    assert target.read_text() == "precious"
    write_csv(target, time, tc1, tc2, overwrite=True)
    np.testing.assert_array_equal(read_csv(target).tc1, tc1)


# --------------------------------------------------------------------------------------------
# Bad CSV


def _csv(tmp_path, text, name="bad.csv"):
    path = tmp_path / name
    path.write_text(text)
    return path


GOOD_HEAD = "time,tc1,tc2\n0,1,2\n"


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("", "empty file"),
        ("\n\n", "empty file"),
        ("time,tc1,tc2\n", "header only, no samples"),
        ("time,tc1,tc2\n\n\n", "header only, no samples"),
        ("0,1,2\n0.1,1,2\n", r"no header: row 1 holds numbers \(0,1,2\)"),
        ("time,tc1\n0,1\n", r"no column 'tc2'; the header has columns 'time', 'tc1'"),
        ("t,tc1,tc2\n0,1,2\n", r"no column 'time'; the header has columns 't', 'tc1', 'tc2'"),
        ("time,tc1,tc2,tc1\n0,1,2,3\n", "column 'tc1' appears 2 times in the header"),
        (GOOD_HEAD + "0.1,1,x2\n", r"row 3, column 'tc2': 'x2' is not a number"),
        (GOOD_HEAD + "0.1,,2\n", r"row 3, column 'tc1': '' is not a number"),
        (GOOD_HEAD + "0.1,1,2\nzero,1,2\n", r"row 4, column 'time': 'zero' is not a number"),
        (GOOD_HEAD + "inf,1,2\n", r"row 3, column 'time': 'inf' is not finite"),
        (GOOD_HEAD + "0.1,1\n", "row 3 has 2 fields, the header 3"),
        (GOOD_HEAD + "0.1,1,2,4\n", "row 3 has 4 fields, the header 3"),
        (GOOD_HEAD + "\n0.1,1,2\n", "row 3 is blank but data follow on row 4"),
        (
            GOOD_HEAD + "0.2,1,2\n0.1,1,2\n",
            r"column 'time' is not strictly increasing at sample 2: 0\.2 s is followed by "
            r"0\.1 s \(sample k is on row k \+ 2",
        ),
        (
            GOOD_HEAD + "0.1,1,2\n0.2,1,2\n0.35,1,2\n",
            r"not uniformly sampled: the step before sample 3 is 0\.15 s .* \(50 % off",
        ),
    ],
)
def test_bad_csv_named_precisely(tmp_path, text, expected):
    path = _csv(tmp_path, text)
    with pytest.raises(DataError, match=expected) as info:
        read_csv(path)
    assert str(path) in str(info.value)


@pytest.mark.parametrize(
    ("cell", "column", "shown"),
    [("nan,2", "tc1", "nan"), ("1,inf", "tc2", "inf"), ("-Infinity,2", "tc1", "-inf")],
)
def test_non_finite_readings_are_left_out_and_named(tmp_path, cell, column, shown):
    path = _csv(tmp_path, GOOD_HEAD + f"0.1,{cell}\n0.2,1,2\n0.3,1,2\n")
    with pytest.warns(
        InvalidReadingsWarning,
        match=rf"left out 1 column '{column}' reading\(s\) .* \(the first at row 3: {shown}\)",
    ):
        record = read_csv(path)
    assert record.left_out is not None and record.left_out.tolist() == [0, 1, 0, 0]


def test_named_ref_column_must_exist(tmp_path):
    path = _csv(tmp_path, "time,a,b\n0,1,2\n0.1,1,2\n")
    assert read_csv(path, columns=("a", "b", None)).ref is None
    assert read_csv(path, columns=("a", "b", "ref")).ref is None  # the default ref is optional
    with pytest.raises(DataError, match=r"bad\.csv: no column 'fast'; .* 'time', 'a', 'b'"):
        read_csv(path, columns=("a", "b", "fast"))


def test_missing_csv_file(tmp_path):
    with pytest.raises(DataError, match=r"nothere\.csv: cannot open CSV file: No such file"):
        read_record(tmp_path / "nothere.csv")


def test_binary_file_named_csv(tmp_path):
    path = tmp_path / "binary.csv"
    path.write_bytes(b"time,tc1,tc2\n" + np.random.default_rng(RNG_SEED).bytes(256))
    with pytest.raises(DataError, match=r"binary\.csv: not a UTF-8 text file") as info:
        read_csv(path)
    assert isinstance(info.value.__cause__, UnicodeDecodeError)


def test_bad_column_and_topic_arguments(tmp_path):
    path = _csv(tmp_path, "time,tc1,tc2\n0,1,2\n0.1,1,2\n")
    with pytest.raises(DataError, match="columns takes 2 or 3 names"):
        read_record(path, columns=("tc1",))
    with pytest.raises(DataError, match="topics: the tc1 and tc2 names must be non-empty"):
        read_bag(tmp_path, topics=("", TC2))


# --------------------------------------------------------------------------------------------
# Bag round trips


@pytest.mark.parametrize("with_ref", [True, False])
def test_bag_round_trip_is_exact(tmp_path, arrays, with_ref):
    time, tc1, tc2, ref = arrays
    series = {TC1: tc1, TC2: tc2}
    if with_ref:
        series[TREF] = ref
    path = write_bag(tmp_path / "bag", time, series, frame_id="probe", start_ns=EPOCH_NS)
    assert (path / "metadata.yaml").is_file()
    expected = EPOCH_NS + np.rint(time * 1e9).astype(np.int64)  # exact for these times
    mcap = next(path.glob("*.mcap"))
    for target in (path, mcap, str(mcap)):  # the directory or the .mcap file
        record = read_record(target)
        np.testing.assert_array_equal(record.stamps_ns, expected)
        np.testing.assert_array_equal(record.tc1, tc1)
        np.testing.assert_array_equal(record.tc2, tc2)
        if with_ref:
            np.testing.assert_array_equal(record.ref, ref)
        else:
            assert record.ref is None
        np.testing.assert_allclose(record.time, EPOCH_NS * 1e-9 + time, rtol=0, atol=1e-6)
        assert record.dt == pytest.approx(0.002, rel=1e-12)
        assert record.frame_id == "probe"
        assert TC1 in record.source and (TREF in record.source) == with_ref


def test_bag_time_is_sec_plus_nanosec(tmp_path, arrays):
    time, tc1, tc2, _ = arrays
    record = read_bag(write_bag(tmp_path / "bag", time, {TC1: tc1, TC2: tc2}))
    sec, nanosec = np.divmod(record.stamps_ns, 10**9)
    np.testing.assert_array_equal(record.time, sec + nanosec / 1e9)
    np.testing.assert_allclose(record.time, time, rtol=0, atol=5e-10)


def test_bag_metadata_qos_log_time_and_variance(tmp_path, arrays):
    time, tc1, tc2, _ = arrays
    path = write_bag(tmp_path / "bag", time, {TC1: tc1, TC2: tc2}, variance={TC2: 0.25})
    info = yaml.safe_load((path / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["version"] == 9
    assert info["storage_identifier"] == "mcap"
    for entry in info["topics_with_message_count"]:
        assert entry["message_count"] == time.size
        meta = entry["topic_metadata"]
        assert meta["type"] == TEMPERATURE_TYPE
        (qos,) = meta["offered_qos_profiles"]
        assert (qos["reliability"], qos["history"], qos["depth"], qos["durability"]) == (
            "reliable",
            "keep_last",
            10,
            "volatile",
        )
    with Reader(path) as reader:
        for connection, log_time, raw in reader.messages():
            message = STORE.deserialize_cdr(raw, connection.msgtype)
            stamp = message.header.stamp
            assert log_time == stamp.sec * 10**9 + stamp.nanosec
            assert message.variance == (0.25 if connection.topic == TC2 else 0.0)
            assert message.header.frame_id == "tc"


def test_stamps_are_rounded_exactly_to_the_nanosecond(tmp_path):
    rng = np.random.default_rng(RNG_SEED)
    count = 200
    # Near-ties: the float nearest to k + 1/2 ns lies a hair to either side; the float product
    # t * 1e9 rounds many of them onto the tie and then to even, exact rounding does not. Exact
    # ties (m / 1024 s) go to even. Steps are 1 ms +- 1 us, inside the uniformity tolerance.
    near_tie = (np.arange(count) * 1_000_000 + rng.integers(0, 1000, count) + 0.5) / 1e9
    ties = 0.25 + np.arange(count) * (1 / 1024)
    for name, times in (("near", near_tie), ("ties", ties)):
        value = np.ones(count)
        path = write_bag(tmp_path / name, times, {TC1: value, TC2: value}, start_ns=EPOCH_NS)
        exact = [round(Fraction(float(t)) * 10**9) for t in times]
        assert read_bag(path).stamps_ns.tolist() == [EPOCH_NS + ns for ns in exact]
        if name == "near":  # the case does tell exact rounding from the naive product
            assert (np.rint(times * 1e9).astype(np.int64) != exact).sum() > count // 10


def test_write_series_dispatches_on_suffix(tmp_path, arrays):
    time, tc1, tc2, ref = arrays
    csv_path = write_series(tmp_path / "a.csv", time, tc1, tc2, ref, gas=ref * 2)
    assert csv_path.read_text().splitlines()[0] == "time,tc1,tc2,ref,gas"
    np.testing.assert_array_equal(read_csv(csv_path, columns=("tc1", "tc2", "gas")).ref, ref * 2)
    bag_path = write_series(tmp_path / "a_bag", time, tc1, tc2, gas=ref)
    record = read_record(bag_path)
    np.testing.assert_array_equal(record.tc2, tc2)
    assert record.ref is None  # no /tref/temperature was written
    np.testing.assert_array_equal(read_bag(bag_path, topics=(GAS_TOPIC, TC1, None)).tc1, ref)
    with_ref = read_record(write_series(tmp_path / "r_bag", time, tc1, tc2, ref))
    np.testing.assert_array_equal(with_ref.ref, ref)


def test_bare_mcap_without_metadata(tmp_path, arrays):
    time, tc1, tc2, ref = arrays
    path = write_bag(tmp_path / "bag", time, {TC1: tc1, TC2: tc2, TREF: ref}, compress=True)
    bare = tmp_path / "loose.mcap"
    shutil.copy(next(path.glob("*.mcap")), bare)
    record = read_record(bare)
    np.testing.assert_array_equal(record.tc1, tc1)
    np.testing.assert_array_equal(record.ref, ref)
    assert "loose.mcap" in record.source


def test_bare_mcap_from_the_mcap_library(tmp_path):
    """A non-rosbag2 writer: ros2msg schema, cdr encoding, no chunks, no summary."""
    from mcap.writer import IndexType
    from mcap.writer import Writer as McapWriter

    schema = (
        "std_msgs/Header header\nfloat64 temperature\nfloat64 variance\n"
        + "=" * 80
        + "\nMSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n"
        + "=" * 80
        + "\nMSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n"
    ).encode()
    stamps, items = _paired(count=40)
    path = tmp_path / "foreign.mcap"
    with path.open("wb") as handle:
        writer = McapWriter(handle, index_types=IndexType.NONE, use_chunking=False)
        writer.start(profile="ros2", library="test")
        schema_id = writer.register_schema(TEMPERATURE_TYPE, "ros2msg", schema)
        channels = [writer.register_channel(topic, "cdr", schema_id) for topic in (TC1, TC2)]
        for stamp, value in items:
            raw = bytes(STORE.serialize_cdr(_temperature(stamp, value), TEMPERATURE_TYPE))
            for channel in channels:
                writer.add_message(channel, log_time=stamp, data=raw, publish_time=stamp)
        writer.finish()
    record = read_record(path)
    assert record.stamps_ns.tolist() == stamps
    np.testing.assert_array_equal(record.tc2, [value for _, value in items])
    assert record.dt == pytest.approx(1e-3)


def test_messages_are_ordered_by_stamp_not_log_time(tmp_path):
    stamps, items = _paired(count=30)
    log_times = list(range(len(items), 0, -1))  # logged in reverse
    path = _write_messages(tmp_path / "rev", {TC1: items, TC2: items}, log_times=log_times)
    record = read_bag(path)
    assert record.stamps_ns.tolist() == stamps
    np.testing.assert_array_equal(record.tc1, [value for _, value in items])


def test_bag_opens_with_the_mcap_reader(tmp_path, arrays):
    from mcap.reader import make_reader

    time, tc1, tc2, _ = arrays
    path = write_bag(tmp_path / "bag", time, {TC1: tc1, TC2: tc2})
    with next(path.glob("*.mcap")).open("rb") as handle:
        reader = make_reader(handle)
        topics = {channel.topic for channel in reader.get_summary().channels.values()}
        count = sum(1 for _ in reader.iter_messages())
    assert topics == {TC1, TC2}
    assert count == 2 * time.size


def test_existing_bag_is_not_overwritten(tmp_path, arrays):
    time, tc1, tc2, _ = arrays
    path = write_bag(tmp_path / "bag", time, {TC1: tc1, TC2: tc2})
    with pytest.raises(DataError, match=r"bag exists; pass --force"):
        write_bag(path, time, {TC1: tc2, TC2: tc1})
    np.testing.assert_array_equal(read_bag(path).tc1, tc1)
    write_bag(path, time, {TC1: tc2, TC2: tc1}, overwrite=True)
    np.testing.assert_array_equal(read_bag(path).tc1, tc2)
    keep = tmp_path / "not_a_bag"
    keep.mkdir()
    (keep / "thesis.tex").write_text("precious")
    with pytest.raises(DataError, match="not_a_bag is a directory that is not a rosbag2 bag"):
        write_bag(keep, time, {TC1: tc1}, overwrite=True)
    assert (keep / "thesis.tex").read_text() == "precious"


def test_write_bag_checks_its_input(tmp_path, arrays):
    time, tc1, tc2, _ = arrays
    target = tmp_path / "w"
    with pytest.raises(DataError, match=r"w: topic /tc2/temperature has shape \(199,\)"):
        write_bag(target, time, {TC1: tc1, TC2: tc2[:-1]})
    with pytest.raises(DataError, match="no series to write"):
        write_bag(target, time, {})
    with pytest.raises(DataError, match="variance given for topics not written: /typo"):
        write_bag(target, time, {TC1: tc1}, variance={"/typo": 1.0})
    with pytest.raises(DataError, match=r"sample 0 is stamped -1000000 ns; stamps must lie"):
        write_bag(target, time - 3.001, {TC1: tc1})
    assert not target.exists()


# --------------------------------------------------------------------------------------------
# Bad bags


@pytest.fixture
def good_bag(tmp_path, arrays):
    time, tc1, tc2, _ = arrays
    return write_bag(tmp_path / "good", time, {TC1: tc1, TC2: tc2})


def test_missing_bag(tmp_path):
    with pytest.raises(DataError, match=r"nobag: no such bag"):
        read_record(tmp_path / "nobag")
    with pytest.raises(DataError, match=r"nofile\.mcap: no such bag"):
        read_bag(tmp_path / "nofile.mcap")


def test_directory_that_is_not_a_bag(tmp_path, good_bag):
    plain = tmp_path / "plain"
    plain.mkdir()
    with pytest.raises(DataError, match=r"plain: not a rosbag2 bag: the directory has no meta"):
        read_record(plain)
    (good_bag / "metadata.yaml").unlink()
    with pytest.raises(DataError, match=r"no metadata\.yaml; to read a bare MCAP file, pass it"):
        read_bag(good_bag)
    assert read_bag(next(good_bag.glob("*.mcap"))).tc1.size == 200  # as a bare file it reads


def test_file_of_unknown_format(tmp_path):
    path = tmp_path / "notes.txt"
    path.write_text("time,tc1,tc2\n")
    with pytest.raises(DataError, match=r"notes\.txt: cannot tell the format"):
        read_record(path)


@pytest.mark.parametrize("direct", [False, True], ids=["directory", "mcap-file"])
def test_truncated_mcap_is_read_up_to_its_last_complete_record(tmp_path, direct):
    time = np.arange(20_000) * 1e-3
    values = np.sin(time)
    bag = write_bag(tmp_path / "cut", time, {TC1: values, TC2: values + 1}, start_ns=EPOCH_NS)
    mcap = next(bag.glob("*.mcap"))
    data = mcap.read_bytes()
    mcap.write_bytes(data[: len(data) // 2])
    target = mcap if direct else bag
    with pytest.warns(TruncatedInputWarning, match=r"cut\.mcap: input truncated: .* cut off"):
        record = read_bag(target)
    assert 1000 < record.tc1.size < time.size
    np.testing.assert_array_equal(record.tc1, values[: record.tc1.size])
    np.testing.assert_array_equal(record.tc2, values[: record.tc1.size] + 1)


def test_garbage_mcap_in_bag(good_bag):
    mcap = next(good_bag.glob("*.mcap"))
    mcap.write_bytes(np.random.default_rng(RNG_SEED).bytes(4096))
    with pytest.raises(DataError, match=re.escape(f"{mcap}: not an MCAP file")):
        read_record(good_bag)


def test_garbage_bare_mcap(tmp_path):
    path = tmp_path / "random.mcap"
    path.write_bytes(np.random.default_rng(RNG_SEED).bytes(4096))
    with pytest.raises(DataError, match=r"random\.mcap: not an MCAP file"):
        read_record(path)


def test_corrupt_metadata(good_bag):
    (good_bag / "metadata.yaml").write_text("rosbag2_bagfile_information: [unclosed\n")
    with pytest.raises(DataError, match=r"good/metadata\.yaml: cannot read the file list") as info:
        read_bag(good_bag)
    assert info.value.__cause__ is not None


def test_metadata_reads_as_ruamel_reads_it_in_every_bundled_and_written_bag(good_bag):
    # The metadata reader (libyaml) and ruamel.yaml, which rosbags writes it with, agree on
    # every bag this project ships or writes.
    from ruamel.yaml import YAML

    from tcomp_core.io.paths import _load_yaml

    root = Path(__file__).resolve().parents[1] / "bags"
    files = [*sorted(root.glob("*/metadata.yaml")), good_bag / "metadata.yaml"]
    assert len(files) > 3
    for path in files:
        text = path.read_text()
        assert _load_yaml(text) == YAML(typ="safe").load(text), path


def test_metadata_that_is_no_mapping_is_a_data_error(good_bag):
    (good_bag / "metadata.yaml").write_text("- just\n- a list\n")
    with pytest.raises(DataError, match=r"good/metadata\.yaml: cannot read the file list"):
        read_bag(good_bag)


def test_sqlite_bag_is_refused_with_a_hint(good_bag):
    meta = good_bag / "metadata.yaml"
    meta.write_text(
        meta.read_text().replace("storage_identifier: mcap", "storage_identifier: sqlite3")
    )
    with pytest.raises(DataError, match=r"good: storage 'sqlite3'; only rosbag2 MCAP bags"):
        read_bag(good_bag)


def test_missing_topic_lists_what_is_there(good_bag):
    with pytest.raises(DataError, match=r"good: no topic /probe/t; the bag has ") as info:
        read_bag(good_bag, topics=(TC1, "/probe/t", None))
    message = str(info.value)
    assert f"{TC1} ({TEMPERATURE_TYPE})" in message
    assert f"{TC2} ({TEMPERATURE_TYPE})" in message


def test_optional_and_named_reference_topics(good_bag):
    assert read_bag(good_bag).ref is None  # the default reference topic is optional
    with pytest.raises(DataError, match="no topic /fast/temperature; the bag has /tc1"):
        read_bag(good_bag, topics=(TC1, TC2, "/fast/temperature"))


def _wrong_type_bag(path, topics):
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        for topic in topics:
            kind = TEMPERATURE_TYPE if topic != topics[-1] else "std_msgs/msg/Float64"
            connection = writer.add_connection(topic, kind, typestore=STORE)
            for index in range(20):
                stamp = 10**9 + index * 10**6
                if kind == TEMPERATURE_TYPE:
                    message = _temperature(stamp, 1.0)
                else:
                    message = STORE.types[kind](data=1.0)
                writer.write(connection, stamp, STORE.serialize_cdr(message, kind))
    return path


@pytest.mark.parametrize("topics", [(TC1, TC2), (TC1, TC2, TREF)], ids=["tc2", "default-ref"])
def test_wrong_message_type(tmp_path, topics):
    path = _wrong_type_bag(tmp_path / "typed", topics)
    expected = f"typed: topic {topics[-1]} carries std_msgs/msg/Float64, not {TEMPERATURE_TYPE}"
    with pytest.raises(DataError, match=re.escape(expected)):
        read_bag(path)


def test_topic_without_messages(tmp_path):
    _, items = _paired()
    path = _write_messages(tmp_path / "silent", {TC1: items, TC2: []})
    with pytest.raises(DataError, match=r"silent: topic /tc2/temperature has no messages"):
        read_bag(path)


def test_unequal_message_counts(tmp_path):
    _, items = _paired(count=50)
    path = _write_messages(tmp_path / "short", {TC1: items, TC2: items[:-5]})
    with pytest.raises(
        DataError,
        match=r"short: /tc1/temperature has 50 messages but /tc2/temperature has 45; the first "
        r"unpaired sample is 45: /tc1/temperature stamped 1\.045000000 s, /tc2/temperature none",
    ):
        read_bag(path)


def test_unequal_counts_name_the_first_stamp_that_differs(tmp_path):
    _, items = _paired(count=50)
    path = _write_messages(tmp_path / "gap", {TC1: items, TC2: items[:10] + items[11:]})
    with pytest.raises(
        DataError,
        match=r"the first unpaired sample is 10: /tc1/temperature stamped 1\.010000000 s, "
        r"/tc2/temperature 1\.011000000 s",
    ):
        read_bag(path)


def test_stamps_that_do_not_pair(tmp_path):
    _, items = _paired(count=50)
    shifted = [
        (stamp + 500 if index >= 17 else stamp, v) for index, (stamp, v) in enumerate(items)
    ]
    path = _write_messages(tmp_path / "skew", {TC1: items, TC2: shifted})
    with pytest.raises(
        DataError,
        match=r"skew: sample 17: /tc1/temperature is stamped 1\.017000000 s but "
        r"/tc2/temperature 1\.017000500 s",
    ):
        read_bag(path)


def test_reference_stamps_must_pair_too(tmp_path):
    _, items = _paired(count=30)
    late = [(stamp + 1, value) for stamp, value in items]
    path = _write_messages(tmp_path / "ref", {TC1: items, TC2: items, TREF: late})
    with pytest.raises(DataError, match=r"sample 0: /tc1/temperature .* but /tref/temperature"):
        read_bag(path)


@pytest.mark.parametrize(("bad_value", "text"), [(np.nan, "nan"), (-np.inf, "-inf"), (3e8, "3")])
def test_invalid_temperature_in_bag_is_left_out_and_named(tmp_path, arrays, bad_value, text):
    time, tc1, tc2, _ = arrays
    broken = tc2.copy()
    broken[42] = bad_value
    path = write_bag(tmp_path / "nan", time, {TC1: tc1, TC2: broken})
    with pytest.warns(
        InvalidReadingsWarning,
        match=rf"nan \(topics .*\): left out 1 topic /tc2/temperature reading\(s\) not finite "
        rf"or outside -273\.15\.\.2000 °C \(the first at stamp 3\.084000000 s: {text}",
    ):
        record = read_bag(path)
    # Inside the record: bridged between its neighbours, marked, the record stays whole.
    assert record.tc2.size == 200 and record.left_out is not None
    assert np.flatnonzero(record.left_out).tolist() == [42]
    assert record.tc2[42] == pytest.approx(0.5 * (tc2[41] + tc2[43]))


def test_duplicate_and_non_uniform_stamps(tmp_path):
    _, items = _paired(count=30)
    doubled = [*items[:5], items[4], *items[5:]]
    path = _write_messages(tmp_path / "dup", {TC1: doubled, TC2: doubled})
    # A repeated stamp is left out (the later one), as the node's pair matcher drops it.
    with pytest.warns(
        InvalidReadingsWarning,
        match=r"dup \(topics /tc1/temperature, /tc2/temperature\): left out 1 sample\(s\) "
        r"whose time repeats the one before \(the first at stamp 1\.004000000 s\)",
    ):
        assert read_bag(path).time.size == 30
    jumped = [*items[:10], *items[11:]]
    path = _write_messages(tmp_path / "jump", {TC1: jumped, TC2: jumped})
    with pytest.raises(
        DataError, match=r"jump \(topics .*\): header\.stamp of /tc1/.* not uniformly sampled"
    ):
        read_bag(path)


def test_record_checks_its_fields():
    time = np.arange(5.0)
    with pytest.raises(DataError, match=r"here: tc2 has shape \(4,\), time \(5,\)"):
        Record(time=time, tc1=time, tc2=time[:-1], ref=None, source="here", dt=1.0)
    with pytest.raises(DataError, match=r"here: dt=0\.0 must be a finite interval"):
        Record(time=time, tc1=time, tc2=time, ref=None, source="here", dt=0.0)


@pytest.mark.parametrize(
    "statuses",
    [
        [],
        [DiagnosticStatusFields(0, "tcomp: process", "estimating", "pair", {"tau1_s": "0.0238"})],
        [
            DiagnosticStatusFields(2, "a", "°C and ünïcode", "", {"k": "", "": "v" * 7}),
            DiagnosticStatusFields(3, "", "", "hw", {}),
        ],
    ],
)
def test_diagnostic_array_encoder_writes_what_rosbags_writes(statuses):
    store = get_typestore(Stores.ROS2_JAZZY)
    types = store.types
    stamp_ns = 1_700_000_000_123_456_789
    sec, nanosec = divmod(stamp_ns, 1_000_000_000)
    message = types["diagnostic_msgs/msg/DiagnosticArray"](
        header=types["std_msgs/msg/Header"](
            stamp=types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec), frame_id=""
        ),
        status=[
            types["diagnostic_msgs/msg/DiagnosticStatus"](
                level=s.level,
                name=s.name,
                message=s.message,
                hardware_id=s.hardware_id,
                values=[
                    types["diagnostic_msgs/msg/KeyValue"](key=k, value=v)
                    for k, v in s.values.items()
                ],
            )
            for s in statuses
        ],
    )
    expected = bytes(store.serialize_cdr(message, "diagnostic_msgs/msg/DiagnosticArray"))
    assert encode_diagnostic_array(stamp_ns, statuses) == expected


def test_diagnostic_array_encoder_refuses_what_the_message_cannot_hold():
    with pytest.raises(ValueError, match="stamp_ns"):
        encode_diagnostic_array(-1, [])
    with pytest.raises(ValueError, match="level"):
        encode_diagnostic_array(0, [DiagnosticStatusFields(256, "", "", "", {})])


def test_the_gas_variance_is_written_as_a_column_and_as_the_message_field(tmp_path, arrays):
    from rosbags.highlevel import AnyReader

    time, tc1, tc2, ref = arrays
    variance = np.linspace(0.01, 0.02, time.size)
    csv_path = write_series(tmp_path / "v.csv", time, tc1, tc2, gas=ref, gas_variance=variance)
    assert csv_path.read_text().splitlines()[0] == "time,tc1,tc2,gas,gas_variance"
    read = read_csv(csv_path, columns=("tc1", "tc2", "gas_variance"))
    np.testing.assert_array_equal(read.ref, variance)
    for name, inputs in (
        ("plain", None),
        (
            "copy",
            read_record(write_bag(tmp_path / "in", time, {TC1: tc1, TC2: tc2}, start_ns=EPOCH_NS)),
        ),
    ):
        bag = write_series(
            tmp_path / name,
            time if inputs is None else inputs.time,
            tc1,
            tc2,
            gas=ref,
            gas_variance=variance,
            inputs=inputs,
        )
        with AnyReader([bag]) as reader:
            gas = [c for c in reader.connections if c.topic == GAS_TOPIC]
            fields = [
                reader.deserialize(raw, c.msgtype).variance
                for c, _, raw in reader.messages(connections=gas)
            ]
        np.testing.assert_array_equal(fields, variance)
    with pytest.raises(DataError, match="variance without a gas"):
        write_series(tmp_path / "w.csv", time, tc1, tc2, gas_variance=variance)
