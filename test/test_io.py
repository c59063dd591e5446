"""CSV and rosbag2 MCAP round trips, and every malformed input named precisely."""

import numpy as np
import pytest

from tcomp_core.errors import DataError
from tcomp_core.io import read_bag, read_csv, read_record, write_bag, write_csv, write_series

RNG_SEED = 31


@pytest.fixture
def record_arrays():
    rng = np.random.default_rng(RNG_SEED)
    count = 500
    time = np.arange(count) * 0.002 + 3.0
    return (
        time,
        300 + rng.standard_normal(count),
        310 + rng.standard_normal(count),
        rng.random(count),
    )


@pytest.mark.parametrize("with_ref", [True, False])
def test_csv_round_trip_is_exact(tmp_path, record_arrays, with_ref):
    time, tc1, tc2, ref = record_arrays
    path = write_csv(tmp_path / "r.csv", time, tc1, tc2, ref if with_ref else None)
    record = read_csv(path)
    np.testing.assert_array_equal(record.time, time)
    np.testing.assert_array_equal(record.tc1, tc1)
    np.testing.assert_array_equal(record.tc2, tc2)
    if with_ref:
        np.testing.assert_array_equal(record.ref, ref)
    else:
        assert record.ref is None
    assert record.dt == pytest.approx(0.002, rel=1e-12)


@pytest.mark.parametrize("with_ref", [True, False])
def test_bag_round_trip_is_exact(tmp_path, record_arrays, with_ref):
    time, tc1, tc2, ref = record_arrays
    series = {"/tc1/temperature": tc1, "/tc2/temperature": tc2}
    if with_ref:
        series["/tref/temperature"] = ref
    path = write_bag(tmp_path / "bag", time, series, start_ns=1_700_000_000_000_000_007)
    assert (path / "metadata.yaml").is_file()
    assert "offered_qos_profiles" in (path / "metadata.yaml").read_text()
    for target in (path, next(path.glob("*.mcap"))):  # the directory or the .mcap file
        record = read_bag(target)
        np.testing.assert_array_equal(record.tc1, tc1)
        np.testing.assert_array_equal(record.tc2, tc2)
        expected = 1_700_000_000_000_000_007 + np.rint(time * 1e9).astype(np.int64)
        np.testing.assert_array_equal(record.stamps_ns, expected)
        assert (record.ref is not None) == with_ref
        assert record.dt == pytest.approx(0.002, rel=1e-9)


def test_compressed_bag_reads_back(tmp_path, record_arrays):
    time, tc1, tc2, _ = record_arrays
    series = {"/tc1/temperature": tc1, "/tc2/temperature": tc2}
    path = write_bag(tmp_path / "bag", time, series, compress=True)
    np.testing.assert_array_equal(read_bag(path).tc1, tc1)


def test_bag_opens_with_the_mcap_reader(tmp_path, record_arrays):
    from mcap.reader import make_reader

    time, tc1, tc2, _ = record_arrays
    path = write_bag(tmp_path / "bag", time, {"/tc1/temperature": tc1, "/tc2/temperature": tc2})
    with next(path.glob("*.mcap")).open("rb") as handle:
        reader = make_reader(handle)
        topics = {channel.topic for channel in reader.get_summary().channels.values()}
        count = sum(1 for _ in reader.iter_messages())
    assert topics == {"/tc1/temperature", "/tc2/temperature"}
    assert count == 2 * time.size


def test_write_series_dispatches_on_suffix(tmp_path, record_arrays):
    time, tc1, tc2, ref = record_arrays
    csv_path = write_series(tmp_path / "a.csv", time, tc1, tc2, ref, gas=ref)
    assert csv_path.read_text().splitlines()[0] == "time,tc1,tc2,ref,gas"
    bag_path = write_series(tmp_path / "a_bag", time, tc1, tc2, gas=ref)
    np.testing.assert_array_equal(read_record(bag_path).tc2, tc2)
    np.testing.assert_array_equal(
        read_bag(bag_path, topics=("/gas_temperature", "/tc1/temperature", None)).tc1, ref
    )


def test_existing_output_is_not_overwritten(tmp_path, record_arrays):
    time, tc1, tc2, _ = record_arrays
    target = tmp_path / "x.csv"
    target.write_text("precious")
    with pytest.raises(DataError, match=r"x\.csv exists"):
        write_csv(target, time, tc1, tc2)
    assert target.read_text() == "precious"
    write_csv(target, time, tc1, tc2, overwrite=True)
    assert read_csv(target).tc1.size == time.size


def _csv(tmp_path, text, name="bad.csv"):
    path = tmp_path / name
    path.write_text(text)
    return path


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("", "empty file"),
        ("time,tc1,tc2\n", "header only"),
        ("time,tc1\n0,1\n", "no column 'tc2'; the header has time, tc1"),
        ("time,tc1,tc2\n0,1,2\n0.1,1,x2\n", r"row 3, column 'tc2': 'x2' is not a number"),
        ("time,tc1,tc2\n0,1,2\n0.1,nan,2\n", r"row 3, column 'tc1': 'nan' is not finite"),
        ("time,tc1,tc2\n0,1,2\n0.1,inf,2\n", r"row 3, column 'tc1': 'inf' is not finite"),
        ("time,tc1,tc2\n0,1,2\n0.1,1\n", "row 3 has 2 fields, the header 3"),
        ("time,tc1,tc2\n0,1,2\n0.2,1,2\n0.1,1,2\n", "not strictly increasing at sample 2"),
        (
            "time,tc1,tc2\n0,1,2\n0.1,1,2\n0.2,1,2\n0.35,1,2\n",
            r"not uniformly sampled: the step before sample 3 is 0.15 s .* \(50 % off",
        ),
    ],
)
def test_bad_csv_named_precisely(tmp_path, text, expected):
    path = _csv(tmp_path, text)
    with pytest.raises(DataError, match=expected) as info:
        read_csv(path)
    assert "bad.csv" in str(info.value)


def test_missing_csv_file(tmp_path):
    with pytest.raises(DataError, match=r"nothere\.csv: cannot open"):
        read_record(tmp_path / "nothere.csv")


def test_named_ref_column_must_exist(tmp_path):
    path = _csv(tmp_path, "time,a,b\n0,1,2\n0.1,1,2\n")
    assert read_csv(path, columns=("a", "b", None)).ref is None
    with pytest.raises(DataError, match="no column 'fast'"):
        read_csv(path, columns=("a", "b", "fast"))


def test_missing_bag(tmp_path):
    with pytest.raises(DataError, match="nobag: no such bag"):
        read_bag(tmp_path / "nobag")


@pytest.fixture
def good_bag(tmp_path, record_arrays):
    time, tc1, tc2, _ = record_arrays
    return write_bag(tmp_path / "good", time, {"/tc1/temperature": tc1, "/tc2/temperature": tc2})


def test_truncated_mcap(tmp_path, good_bag):
    mcap = next(good_bag.glob("*.mcap"))
    data = mcap.read_bytes()
    mcap.write_bytes(data[: len(data) // 2])
    with pytest.raises(DataError, match="truncated, corrupt") as info:
        read_bag(good_bag)
    assert "good" in str(info.value)
    assert info.value.__cause__ is not None


def test_garbage_mcap(tmp_path, good_bag):
    mcap = next(good_bag.glob("*.mcap"))
    mcap.write_bytes(np.random.default_rng(RNG_SEED).bytes(4096))
    with pytest.raises(DataError, match="cannot read the bag"):
        read_bag(good_bag)


def test_missing_topic_lists_what_is_there(good_bag):
    with pytest.raises(
        DataError, match=r"no topic /probe/t; the bag has /tc1/temperature"
    ) as info:
        read_bag(good_bag, topics=("/tc1/temperature", "/probe/t", None))
    assert "sensor_msgs/msg/Temperature" in str(info.value)


def test_wrong_message_type(tmp_path):
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    path = tmp_path / "typed"
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        for topic in ("/tc1/temperature", "/tc2/temperature"):
            connection = writer.add_connection(topic, "std_msgs/msg/Float64", typestore=store)
            message = store.types["std_msgs/msg/Float64"](data=1.0)
            writer.write(connection, 1, store.serialize_cdr(message, "std_msgs/msg/Float64"))
    with pytest.raises(DataError, match="carries std_msgs/msg/Float64, not sensor_msgs"):
        read_bag(path)


def test_stamps_that_do_not_pair(tmp_path, record_arrays):
    time, tc1, tc2, _ = record_arrays
    path = write_bag(tmp_path / "a", time, {"/tc1/temperature": tc1})
    other = write_bag(tmp_path / "b", time + 0.0005, {"/tc2/temperature": tc2})
    # Merge: copy tc2 of the shifted bag into a bag with tc1 at the original stamps.
    from tcomp_core.io import read_bag as read

    merged = tmp_path / "merged"
    shifted = read(other, topics=("/tc2/temperature", "/tc2/temperature", None))
    base = read(path, topics=("/tc1/temperature", "/tc1/temperature", None))
    _write_two_clocks(merged, base, shifted)
    with pytest.raises(DataError, match=r"sample 0: /tc1/temperature is stamped 3.000000000 s"):
        read_bag(merged)


def _write_two_clocks(path, first, second):
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    kind = "sensor_msgs/msg/Temperature"
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        for topic, record in (("/tc1/temperature", first), ("/tc2/temperature", second)):
            connection = writer.add_connection(topic, kind, typestore=store)
            for stamp, value in zip(record.stamps_ns.tolist(), record.tc1.tolist(), strict=True):
                header = store.types["std_msgs/msg/Header"](
                    stamp=store.types["builtin_interfaces/msg/Time"](
                        sec=stamp // 10**9, nanosec=stamp % 10**9
                    ),
                    frame_id="",
                )
                message = store.types[kind](header=header, temperature=value, variance=0.0)
                writer.write(connection, stamp, store.serialize_cdr(message, kind))


def test_unequal_message_counts(tmp_path, record_arrays):
    time, tc1, tc2, _ = record_arrays
    first = read_bag(
        write_bag(tmp_path / "a", time, {"/tc1/temperature": tc1, "/tc2/temperature": tc2})
    )
    shorter = read_bag(
        write_bag(
            tmp_path / "b", time[:-5], {"/tc1/temperature": tc2[:-5], "/tc2/temperature": tc2[:-5]}
        )
    )
    _write_two_clocks(tmp_path / "c", first, shorter)
    with pytest.raises(
        DataError, match="/tc1/temperature has 500 messages but /tc2/temperature has 495"
    ):
        read_bag(tmp_path / "c")


def test_non_finite_temperature_in_bag(tmp_path, record_arrays):
    time, tc1, tc2, _ = record_arrays
    broken = tc2.copy()
    broken[42] = np.nan
    path = write_bag(tmp_path / "nan", time, {"/tc1/temperature": tc1, "/tc2/temperature": broken})
    with pytest.raises(
        DataError,
        match=r"topic /tc2/temperature, message 42 \(stamp 3.084000000 s\) has temperature nan",
    ):
        read_bag(path)
