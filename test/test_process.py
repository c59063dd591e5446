"""tcomp process: bulk codec, chunk reader, bag writer, schedule, outputs, bad input, --jobs."""

from __future__ import annotations

import argparse
import csv
import shutil
import threading
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore
from sim_records import make_pair

from tcomp_core.cli.process import add_parser as add_process_command
from tcomp_core.effects import EFFECT_NAMES
from tcomp_core.errors import DataError, TcompError
from tcomp_core.io import (
    DEFAULT_COLUMNS,
    DEFAULT_TOPICS,
    McapScan,
    decode_payloads,
    decode_rows,
    encode,
    log_times,
    payloads,
    read_bag,
    read_csv,
    write_bag,
    write_csv,
)
from tcomp_core.online import OnlineCompensator, OnlineConfig
from tcomp_core.process import (
    Outcome,
    ProcessConfig,
    format_summary,
    process,
    process_many,
)
from tcomp_core.process.output import DIAGNOSIS_TOPIC, HISTORY_TOPIC, STATUS_NAME
from tcomp_core.simulate import simulate_pair

BAGS = Path(__file__).resolve().parent.parent / "bags"
TEMPERATURE = "sensor_msgs/msg/Temperature"
TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
START_NS = 1_700_000_000 * 10**9
FAST = ProcessConfig(diagnose=False)


def _raw_messages(bag: Path) -> dict[str, list[bytes]]:
    found: dict[str, list[bytes]] = {}
    with Reader(bag) as reader:
        for connection, _, raw in reader.messages():
            found.setdefault(connection.topic, []).append(bytes(raw))
    return found


def _sim_bag(path: Path, seconds: float = 4.0, rate: float = 500.0, seed: int = 3) -> Path:
    data = simulate_pair(
        "sinusoid",
        tau1=0.0238,
        tau2=0.1168,
        dt=1 / rate,
        duration=seconds,
        noise_percent=1.0,
        phi=1.0,
        seed=seed,
    )
    series = {DEFAULT_TOPICS[0]: data.tc1, DEFAULT_TOPICS[1]: data.tc2}
    return write_bag(path, data.time, series, start_ns=START_NS, frame_id="probe")


# -- codec ------------------------------------------------------------------------------------
def test_bulk_decode_equals_rosbags_on_every_message_of_a_bundled_bag():
    bag = BAGS / "ramp_500hz"
    raw = _raw_messages(bag)
    for topic, messages in raw.items():
        batch = decode_payloads(messages)
        assert batch.fallback == 0
        for k, data in enumerate(messages):
            message = TYPESTORE.deserialize_cdr(data, TEMPERATURE)
            stamp = message.header.stamp
            assert batch.stamps_ns[k] == stamp.sec * 10**9 + stamp.nanosec, topic
            assert batch.temperature[k] == message.temperature
            assert batch.variance[k] == message.variance
        assert (
            batch.frame_id == TYPESTORE.deserialize_cdr(messages[0], TEMPERATURE).header.frame_id
        )


def test_encode_is_byte_identical_to_rosbags(rng):
    stamps = START_NS + np.sort(rng.integers(0, 10**12, 50))
    values, variances = rng.normal(300, 50, 50), rng.uniform(0, 1, 50)
    for frame in ("", "a", "tc", "probe_frame_1234"):
        rows = encode(stamps, values, variances, frame)
        for k in range(50):
            sec, nanosec = divmod(int(stamps[k]), 10**9)
            types = TYPESTORE.types
            message = types[TEMPERATURE](
                header=types["std_msgs/msg/Header"](
                    stamp=types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec),
                    frame_id=frame,
                ),
                temperature=values[k],
                variance=variances[k],
            )
            assert rows[k].tobytes() == bytes(TYPESTORE.serialize_cdr(message, TEMPERATURE))
        back = decode_rows(rows)
        assert np.array_equal(back.stamps_ns, stamps) and back.frame_id == frame


def test_fallback_decodes_big_endian_and_odd_frames(rng):
    stamps = START_NS + np.arange(6) * 1000
    values = rng.normal(size=6)
    messages = [bytes(r) for r in encode(stamps, values, 0.5, "tc")]
    types = TYPESTORE.types
    odd = types[TEMPERATURE](
        header=types["std_msgs/msg/Header"](
            stamp=types["builtin_interfaces/msg/Time"](
                sec=int(stamps[2] // 10**9), nanosec=int(stamps[2] % 10**9)
            ),
            frame_id="x",
        ),
        temperature=float(values[2]),
        variance=0.5,
    )
    messages[2] = bytes(TYPESTORE.serialize_cdr(odd, TEMPERATURE, little_endian=False))
    messages[4] = bytes(encode(stamps[4:5], values[4:5], 0.5, "tc" * 9)[0])  # other length
    batch = decode_payloads(messages)
    assert batch.fallback == 1  # big endian; the longer frame is its own fixed-layout group
    assert np.array_equal(batch.stamps_ns, stamps)
    assert np.array_equal(batch.temperature, values)
    assert messages[2][:4] == b"\x00\x00\x00\x00"


def test_rows_that_break_the_layout_inside_a_block_fall_back(rng):
    rows = encode(START_NS + np.arange(4), rng.normal(size=4), 0.0, "tc").copy()
    big = TYPESTORE.serialize_cdr(
        TYPESTORE.deserialize_cdr(rows[1].tobytes(), TEMPERATURE), TEMPERATURE, little_endian=False
    )
    assert len(big) == rows.shape[1]
    rows[1] = np.frombuffer(bytes(big), np.uint8)
    batch = decode_rows(rows)
    assert batch.fallback == 1
    assert np.array_equal(batch.stamps_ns, START_NS + np.arange(4))


# -- reader and writer ------------------------------------------------------------------------
def test_scan_reads_every_message_like_rosbags():
    bag = BAGS / "rig_sine_5khz"
    scan = McapScan(sorted(bag.glob("*.mcap")), list(DEFAULT_TOPICS[:3]), TEMPERATURE)
    got: dict[str, list[bytes]] = {}
    for chunk in scan:
        for topic, blocks in chunk.topics.items():
            for block in blocks:
                got.setdefault(topic, []).extend(bytes(r) for r in payloads(block))
                assert np.all(np.diff(log_times(block)) >= 0)
    assert scan.truncation is None
    assert got == _raw_messages(bag)


def _check_outputs_open(bag: Path, expected: dict[str, int]) -> None:
    with (bag / f"{bag.name}.mcap").open("rb") as handle:
        reader = make_reader(handle)
        counts: dict[str, int] = {}
        for _, channel, _ in reader.iter_messages(log_time_order=True):
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
        assert reader.get_summary().statistics.message_count == sum(expected.values())
    assert counts == expected
    with Reader(bag) as reader:
        assert {c.topic: c.msgcount for c in reader.connections} == expected
        for connection, _, raw in reader.messages():
            TYPESTORE.deserialize_cdr(raw, connection.msgtype)
        for connection in reader.connections:
            assert connection.ext.offered_qos_profiles[0].depth == 10


# -- the pipeline -----------------------------------------------------------------------------
@pytest.mark.slow
def test_bag_output_opens_with_mcap_and_rosbags(tmp_path):
    result = process(BAGS / "ramp_500hz", tmp_path / "out", FAST)
    assert result.pairs == 5000 and result.warnings == []
    _check_outputs_open(
        tmp_path / "out",
        {
            "/tc1/temperature": 5000,
            "/tc2/temperature": 5000,
            "/tref/temperature": 5000,
            "/gas_temperature": result.gas,
            HISTORY_TOPIC: result.reports,
        },
    )
    assert result.estimates == 19  # every 0.5 s of a 10 s record, the last batch at 9.998 s
    assert result.reports == 9  # every second of stamp time, as the node publishes
    with Reader(tmp_path / "out") as reader:
        history = [
            TYPESTORE.deserialize_cdr(raw, c.msgtype)
            for c, _, raw in reader.messages(
                [c for c in reader.connections if c.topic == HISTORY_TOPIC]
            )
        ]
    status = history[-1].status[0]
    values = {kv.key: kv.value for kv in status.values}
    assert status.name == STATUS_NAME
    assert abs(float(values["tau1_s"]) - 0.0238) < 0.003
    assert abs(float(values["tau2_s"]) - 0.1168) < 0.01
    assert values["method"] == "ml-eiv" and int(values["window_samples"]) == 1000


def _history(bag: Path) -> list[tuple[int, int, dict[str, str]]]:
    """(header stamp ns, level, key-values) of each /diagnostics status of a bag."""
    found = []
    with Reader(bag) as reader:
        wanted = [c for c in reader.connections if c.topic == HISTORY_TOPIC]
        for connection, _, raw in reader.messages(wanted):
            array = TYPESTORE.deserialize_cdr(raw, connection.msgtype)
            status = array.status[0]
            stamp = array.header.stamp.sec * 10**9 + array.header.stamp.nanosec
            found.append((stamp, int(status.level), {kv.key: kv.value for kv in status.values}))
    return found


@pytest.mark.slow
def test_the_tau_history_is_what_the_engine_said_at_each_stamp(tmp_path):
    process(BAGS / "ramp_500hz", tmp_path / "out", FAST)
    record = read_bag(BAGS / "ramp_500hz")
    history = _history(tmp_path / "out")
    assert len(history) == 9
    window = round(FAST.online.window_s / record.dt)
    for stamp, _, values in history:
        by_then = int(np.searchsorted(record.stamps_ns, stamp, side="right"))
        assert int(values["matched"]) == by_then  # every pair stamped up to then, no later one
        assert int(values["received_tc1"]) == int(values["received_tc2"]) == by_then
        assert int(values["window_samples"]) == min(by_then, window)
        assert int(values["published"]) <= by_then
    taus = [values["first_order_tau1_s"] for _, _, values in history]
    assert len(set(taus)) >= len(taus) - 1  # τ moves with the window, report after report
    # The published gas's τ is its Kalman filter's, built for an estimate accepted before (a
    # retune follows a move of 1 %, taken over with the pairs after it).
    for _, _, values in history:
        published, estimate = float(values["tau1_s"]), float(values["first_order_tau1_s"])
        assert published == pytest.approx(estimate, rel=0.05)
    windows = [int(values["window_samples"]) for _, _, values in history]
    assert windows[0] < windows[-1] == window  # the window fills


def _drive_directly(stamps, tc1, tc2, config: OnlineConfig, update_s: float, batch_s: float):
    """The documented schedule, written out independently of ScheduledEngine.

    Batches of ``batch_s``; each alone until τ is known, then together up to the next one that
    calls for an update or a report (every second); every stamp has both samples here, so the
    pairs are the samples and no queue overflows.
    """
    compensator = OnlineCompensator(config)
    t0, batch_ns, update_ns = int(stamps[0]), round(batch_s * 1e9), round(update_s * 1e9)
    report_ns = 10**9
    ids = (stamps - t0) // batch_ns
    next_update, next_report = t0 + update_ns, t0 + report_ns
    out_stamps, out_gas = [], []
    pending = [ids == batch for batch in np.unique(ids)]
    while pending:
        end = 0
        if compensator.tau is not None:
            for k, part in enumerate(pending):
                end, last = k, int(stamps[part][-1])
                if last >= next_update or last >= next_report:
                    break
        part = np.logical_or.reduce(pending[: end + 1])
        del pending[: end + 1]
        s, g, _ = compensator.add_pairs(stamps[part], tc1[part], tc2[part])
        out_stamps.append(s)
        out_gas.append(g)
        last = int(stamps[part][-1])
        if last >= next_update:
            compensator.update_estimate()
            next_update = t0 + ((last - t0) // update_ns + 1) * update_ns
        if last >= next_report:
            next_report = t0 + ((last - t0) // report_ns + 1) * report_ns
    return np.concatenate(out_stamps), np.concatenate(out_gas)


@pytest.mark.slow
@pytest.mark.parametrize("batch_s", [0.1, 0.02])
def test_gas_equals_the_compensator_driven_on_the_documented_schedule(tmp_path, batch_s):
    bag = BAGS / "ramp_500hz"
    config = ProcessConfig(
        diagnose=False, batch_s=batch_s, online=OnlineConfig(update_period_s=0.5)
    )
    process(bag, tmp_path / "out", config)
    record = read_bag(bag)
    stamps, gas = _drive_directly(
        record.stamps_ns, record.tc1, record.tc2, config.online, 0.5, batch_s
    )
    with Reader(tmp_path / "out") as reader:
        connection = [c for c in reader.connections if c.topic == "/gas_temperature"]
        messages = [
            TYPESTORE.deserialize_cdr(raw, TEMPERATURE)
            for _, _, raw in reader.messages(connection)
        ]
    written = np.array([m.temperature for m in messages])
    written_stamps = np.array(
        [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in messages]
    )
    assert np.array_equal(written, gas)  # bit for bit
    assert np.array_equal(written_stamps, stamps)


@pytest.mark.slow
def test_csv_in_and_out(tmp_path):
    record = read_bag(BAGS / "ramp_500hz")
    source = write_csv(
        tmp_path / "in.csv", record.time - record.time[0], record.tc1, record.tc2, record.ref
    )
    result = process(source, tmp_path / "out.csv", FAST)
    with (tmp_path / "out.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert list(rows[0]) == ["time", "tc1", "tc2", "ref", "gas", "gas_variance", "tau1", "tau2"]
    assert len(rows) == record.time.size == result.pairs
    filled = [r for r in rows if r["gas"]]
    assert len(filled) == result.gas
    assert rows[-1]["gas"] == ""  # the last pair has no successor
    assert float(rows[10]["tc1"]) == record.tc1[10]
    gas = np.array([float(r["gas"]) for r in filled])
    ref = np.array([float(r["ref"]) for r in filled])
    assert np.sqrt(np.mean((gas - ref)[len(gas) // 2 :] ** 2)) < 0.2 * np.std(ref)
    # Each gas value comes with its variance; the start-up's wide errors are marked by it.
    std = np.sqrt([float(r["gas_variance"]) for r in filled])
    assert np.all(std > 0)
    assert std[:5].min() > np.median(std)
    assert np.mean(np.abs(gas - ref) > 4 * std) < 0.01
    # CSV in, bag out: the inputs are encoded on the default topics.
    process(source, tmp_path / "bag", FAST)
    back = read_bag(tmp_path / "bag")
    assert np.array_equal(back.tc1, record.tc1)


@pytest.mark.slow
def test_existing_output_needs_force(tmp_path):
    process(BAGS / "ramp_500hz", tmp_path / "out", FAST)
    with pytest.raises(DataError, match="exists; pass --force"):
        process(BAGS / "ramp_500hz", tmp_path / "out", FAST)
    (tmp_path / "plain").mkdir()
    (tmp_path / "plain" / "keep.txt").write_text("x")
    with pytest.raises(DataError, match="not a rosbag2 bag"):
        process(
            BAGS / "ramp_500hz", tmp_path / "plain", ProcessConfig(diagnose=False, overwrite=True)
        )
    again = process(
        BAGS / "ramp_500hz", tmp_path / "out", ProcessConfig(diagnose=False, overwrite=True)
    )
    assert again.pairs == 5000


@pytest.mark.slow
def test_truncated_bag_is_processed_up_to_the_last_good_message(tmp_path):
    bag = tmp_path / "cut"
    shutil.copytree(BAGS / "rig_sine_5khz", bag)
    mcap = bag / "rig_sine_5khz.mcap"
    data = mcap.read_bytes()
    # Cut inside the third chunk (of four), at 55 % of the file.
    mcap.write_bytes(data[: int(0.55 * len(data))])
    result = process(bag, tmp_path / "out", FAST)
    assert 0 < result.pairs < 15000
    truncated, where = result.warnings[:2]
    assert "input truncated" in truncated and "cut off" in truncated
    assert "/tc1/temperature" in where and "the last good stamped 1700000001." in where
    full = read_bag(BAGS / "rig_sine_5khz")
    # Every pair processed is a true pair of the full record, from its start.
    assert result.pairs > 9000  # two whole chunks and part of the cut one
    out = read_bag(tmp_path / "out", topics=("/tc1/temperature", "/tc2/temperature", None))
    count = min(out.tc1.size, result.pairs)
    assert np.array_equal(out.tc1[:count], full.tc1[:count])


def test_missing_topic_and_no_pairs_are_errors(tmp_path):
    with pytest.raises(DataError, match="no topic /nope"):
        process(
            BAGS / "ramp_500hz",
            tmp_path / "a",
            ProcessConfig(diagnose=False, topics=("/tc1/temperature", "/nope", None)),
        )
    with pytest.raises(DataError, match="no such bag"):
        process(tmp_path / "missing", tmp_path / "b", FAST)


@pytest.mark.slow
def test_diagnosis_verdict_topic(tmp_path):
    bag = _sim_bag(tmp_path / "sim", seconds=6.0, rate=500.0)
    result = process(bag, tmp_path / "out", ProcessConfig(diagnose_samples=3000))
    assert result.verdict in ("none", *EFFECT_NAMES)
    assert result.diagnosis["samples"] == "3000"
    with Reader(tmp_path / "out") as reader:
        connection = [c for c in reader.connections if c.topic == DIAGNOSIS_TOPIC]
        (message,) = [
            TYPESTORE.deserialize_cdr(raw, c.msgtype) for c, _, raw in reader.messages(connection)
        ]
    values = {kv.key: kv.value for kv in message.status[0].values}
    assert values["verdict"] == result.verdict
    # The closing diagnosis is timed apart from the streaming, and the table says so.
    assert 0.0 < result.diagnosis_seconds < result.seconds
    assert result.pairs_per_s > result.pairs / result.seconds
    table = format_summary([Outcome(bag, tmp_path / "out", result)])
    assert f"{result.diagnosis_seconds:.2f} s" in table.splitlines()[1]


@pytest.mark.slow
def test_jobs_two_on_a_directory_and_the_cli(tmp_path, capsys):
    inputs = tmp_path / "in"
    inputs.mkdir()
    _sim_bag(inputs / "a", seed=1)
    _sim_bag(inputs / "b", seed=2)
    parser = argparse.ArgumentParser(prog="tcomp")
    verbs = parser.add_subparsers(dest="verb", required=True)
    add_process_command(verbs)
    args = parser.parse_args(
        ["process", str(inputs), "-o", str(tmp_path / "out"), "--jobs", "2", "--no-diagnose"]
    )
    assert args.handler(args) == 0
    table = capsys.readouterr().out
    lines = table.splitlines()
    assert "pairs/s" in table
    header = next(k for k, line in enumerate(lines) if line.startswith("input "))
    assert "diagnosis" in lines[header]
    assert all("skipped" in line for line in lines[header + 1 : header + 3])
    assert any(line.startswith("a ") for line in lines)
    assert any(line.startswith("b ") for line in lines)
    for name in ("a", "b"):
        assert read_bag(tmp_path / "out" / name).tc1.size == 2000
    outcomes = process_many(
        [inputs / "a", inputs / "b"], tmp_path / "out2", FAST, jobs=2, suffix=".csv"
    )
    serial = process(inputs / "b", tmp_path / "b.csv", FAST)
    assert [o.result.pairs for o in outcomes] == [2000, 2000]
    assert (tmp_path / "out2" / "b.csv").read_text() == (tmp_path / "b.csv").read_text()
    assert outcomes[1].result.gas == serial.gas


@pytest.mark.slow
def test_cli_refuses_existing_output_without_force(tmp_path, capsys):
    parser = argparse.ArgumentParser(prog="tcomp")
    add_process_command(parser.add_subparsers(dest="verb"))
    argv = ["process", str(BAGS / "ramp_500hz"), "-o", str(tmp_path / "o.csv"), "--no-diagnose"]
    args = parser.parse_args(argv)
    assert args.handler(args) == 0
    with pytest.raises(TcompError, match="exists; pass --force"):
        args.handler(parser.parse_args(argv))
    assert args.handler(parser.parse_args([*argv, "--force"])) == 0


@pytest.mark.slow
def test_unmatched_samples_are_dropped_and_reported(tmp_path):
    data = make_pair("sinusoid", duration=3.0, noise_percent=1.0, seed=5)
    bag = write_bag(
        tmp_path / "in",
        data.time,
        {DEFAULT_TOPICS[0]: data.tc1, DEFAULT_TOPICS[1]: data.tc2},
        start_ns=START_NS,
    )
    mcap = next(bag.glob("*.mcap"))
    # Drop one tc2 message by re-writing the bag without it through rosbags.
    raw = _raw_messages(bag)
    raw["/tc2/temperature"].pop(100)
    from rosbags.rosbag2 import StoragePlugin, Writer

    shutil.rmtree(tmp_path / "holes", ignore_errors=True)
    with Writer(tmp_path / "holes", version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        for topic, messages in raw.items():
            connection = writer.add_connection(topic, TEMPERATURE, typestore=TYPESTORE)
            for message in messages:
                stamp = TYPESTORE.deserialize_cdr(message, TEMPERATURE).header.stamp
                writer.write(connection, stamp.sec * 10**9 + stamp.nanosec, message)
    assert mcap.exists()
    result = process(tmp_path / "holes", tmp_path / "out", FAST)
    assert result.pairs == 1499 and result.counters["unmatched_tc1"] == 1
    assert any("dropped 1 tc1 samples" in w for w in result.warnings)


# -- copying the inputs -----------------------------------------------------------------------
BEST_EFFORT_QOS = """- history: 1
  depth: 5
  reliability: 2
  durability: 2
  deadline:
    sec: 0
    nsec: 0
  lifespan:
    sec: 0
    nsec: 0
  liveliness: 1
  liveliness_lease_duration:
    sec: 0
    nsec: 0
  avoid_ros_namespace_conventions: false"""


def _mcap_file(path: Path, topics: list[str], stamps, values: dict[str, np.ndarray]) -> None:
    """One lz4-chunked MCAP file written by the ``mcap`` package, channels in ``topics`` order."""
    from mcap.writer import CompressionType, Writer

    definition, _ = TYPESTORE.generate_msgdef(TEMPERATURE, ros_version=2)
    with path.open("wb") as handle:
        writer = Writer(handle, compression=CompressionType.LZ4, chunk_size=20_000)
        writer.start(profile="ros2", library="test")
        schema = writer.register_schema(TEMPERATURE, "ros2msg", definition.encode())
        channels = {
            topic: writer.register_channel(
                topic, "cdr", schema, metadata={"offered_qos_profiles": BEST_EFFORT_QOS}
            )
            for topic in topics
        }
        rows = {topic: encode(stamps, values[topic], 0.0, "probe") for topic in topics}
        for index, stamp in enumerate(stamps.tolist()):
            for topic in topics:
                writer.add_message(
                    channels[topic], stamp, rows[topic][index].tobytes(), stamp, sequence=index
                )
        writer.finish()


@pytest.mark.slow
def test_multi_file_lz4_bag_with_other_channel_ids_and_qos_is_copied_whole(tmp_path):
    data = make_pair("multisine", duration=8.0, noise_percent=1.0, seed=5)
    stamps = START_NS + np.arange(data.time.size, dtype=np.int64) * 2_000_000
    tc1, tc2 = DEFAULT_TOPICS[:2]
    values = {tc1: data.tc1, tc2: data.tc2}
    bag = tmp_path / "two_files"
    bag.mkdir()
    half = stamps.size // 2
    # The second file registers the topics the other way round: channel ids swap.
    _mcap_file(bag / "a.mcap", [tc1, tc2], stamps[:half], {k: v[:half] for k, v in values.items()})
    _mcap_file(bag / "b.mcap", [tc2, tc1], stamps[half:], {k: v[half:] for k, v in values.items()})
    (bag / "metadata.yaml").write_text(
        "rosbag2_bagfile_information:\n  relative_file_paths:\n  - a.mcap\n  - b.mcap\n"
    )
    result = process(bag, tmp_path / "out", FAST)
    assert result.pairs == stamps.size and result.warnings == []
    # The same samples as one ordinary single-file bag give the same results, bit for bit.
    single = write_bag(tmp_path / "single", data.time, values, start_ns=START_NS, frame_id="probe")
    reference = process(single, tmp_path / "out_single", FAST)
    assert result.tau == reference.tau and result.gas == reference.gas
    gas_of = {
        bag: read_bag(bag, topics=("/gas_temperature", "/gas_temperature", None)).tc1
        for bag in (tmp_path / "out", tmp_path / "out_single")
    }
    assert np.array_equal(gas_of[tmp_path / "out"], gas_of[tmp_path / "out_single"])
    _check_outputs_open_any_qos(tmp_path / "out")
    with Reader(tmp_path / "out") as reader:
        connections = {c.topic: c for c in reader.connections}
        for topic in (tc1, tc2):
            qos = connections[topic].ext.offered_qos_profiles[0]
            assert (qos.depth, qos.reliability.name) == (5, "BEST_EFFORT")  # as recorded
        assert connections["/gas_temperature"].ext.offered_qos_profiles[0].depth == 10
        copied = {
            topic: [
                TYPESTORE.deserialize_cdr(raw, TEMPERATURE).temperature
                for _, _, raw in reader.messages([connections[topic]])
            ]
            for topic in (tc1, tc2)
        }
    for topic in (tc1, tc2):
        assert np.array_equal(copied[topic], values[topic])  # every message, on its own topic


def _check_outputs_open_any_qos(bag: Path) -> None:
    with (bag / f"{bag.name}.mcap").open("rb") as handle:
        reader = make_reader(handle)
        times = [message.log_time for _, _, message in reader.iter_messages(log_time_order=True)]
    assert times == sorted(times)
    with Reader(bag) as reader:
        for connection, _, raw in reader.messages():
            TYPESTORE.deserialize_cdr(raw, connection.msgtype)


@pytest.mark.slow
def test_copied_records_are_byte_identical_and_keep_the_input_channel_ids(tmp_path):
    source = BAGS / "ramp_500hz"
    process(source, tmp_path / "out", FAST)

    def records(bag: Path) -> dict[str, list[tuple[int, int, bytes]]]:
        with next(bag.glob("*.mcap")).open("rb") as handle:
            reader = make_reader(handle)
            found: dict[str, list[tuple[int, int, bytes]]] = {}
            for _, channel, message in reader.iter_messages():
                found.setdefault(channel.topic, []).append(
                    (channel.id, message.log_time, message.data)
                )
        return found

    before, after = records(source), records(tmp_path / "out")
    for topic in DEFAULT_TOPICS:
        assert after[topic] == before[topic]


@pytest.mark.slow
def test_a_failing_write_ends_the_run_with_its_error_and_no_thread_left(tmp_path, monkeypatch):
    from tcomp_core.io import mcap_write

    threads = {thread.name for thread in threading.enumerate()}

    def disk_full(*_):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(mcap_write.McapBagWriter, "_write_chunk", disk_full)
    with pytest.raises(DataError, match=r"out: cannot write: No space left"):  # names it
        process(BAGS / "rig_sine_5khz", tmp_path / "out", FAST)
    assert list(tmp_path.iterdir()) == []  # nothing half written is left, under any name
    assert {thread.name for thread in threading.enumerate()} == threads


@pytest.mark.slow
@pytest.mark.parametrize("flag", [[], ["--no-compress"]])
def test_the_bag_reads_back_the_same_compressed_or_not(tmp_path, flag, capsys):
    compress = not flag  # zstd unless --no-compress
    parser = argparse.ArgumentParser(prog="tcomp")
    add_process_command(parser.add_subparsers(dest="verb"))
    argv = ["process", str(BAGS / "rig_sine_5khz"), "-o", str(tmp_path / "out"), *flag]
    args = parser.parse_args([*argv, "--no-diagnose"])
    assert args.handler(args) == 0
    result = process(BAGS / "rig_sine_5khz", tmp_path / "again", ProcessConfig(diagnose=False))
    gas_topics = ("/gas_temperature", "/gas_temperature", None)
    gas = read_bag(tmp_path / "out", topics=gas_topics)
    assert gas.tc1.size == result.gas > 0
    assert np.array_equal(gas.tc1, read_bag(tmp_path / "again", topics=gas_topics).tc1)
    with next((tmp_path / "out").glob("*.mcap")).open("rb") as handle:
        chunks = make_reader(handle).get_summary().chunk_indexes
    assert {chunk.compression for chunk in chunks} == {"zstd" if compress else ""}
    assert len(chunks) > 1


@pytest.mark.parametrize("samples", [15_000, 25_000])
def test_the_output_model_is_fitted_on_as_many_pairs_as_asked(tmp_path, samples):
    """``--diagnose-samples`` was ignored: a CSV block handed one input after the other
    overflowed the matcher's queue (2 000), and 2 000 pairs were fitted whatever it said."""
    from tcomp_core.process.output_model import fit_stream_output_model

    pair = simulate_pair("multisine", dt=5e-5, duration=1.5, noise_percent=1.0, seed=5)
    path = write_csv(tmp_path / "fast.csv", pair.time, pair.tc1, pair.tc2)
    fitted = fit_stream_output_model(
        path,
        (),
        topics=DEFAULT_TOPICS,
        columns=DEFAULT_COLUMNS,
        samples=samples,
        slop_ns=0,
        queue_size=2000,
        valid_range=(-273.15, 2000.0),
        gap_factor=1.5,
    )
    assert fitted.record[0].size == samples
    np.testing.assert_array_equal(fitted.record[1], pair.tc1[:samples])


def _rate_change_record():
    """2 s at 500 Hz, then 2 s at 2 kHz of one multisine through both sensors."""
    slow = simulate_pair("multisine", dt=2e-3, duration=2.0, noise_percent=1.0, seed=8)
    fast = simulate_pair("multisine", dt=5e-4, duration=2.0, noise_percent=1.0, seed=9)
    time = np.concatenate((slow.time, slow.time[-1] + 2e-3 + fast.time))
    return time, np.concatenate((slow.tc1, fast.tc1)), np.concatenate((slow.tc2, fast.tc2))


@pytest.mark.slow
def test_a_rate_change_gets_one_verdict_from_a_csv_and_a_bag(tmp_path):
    """The same stamps in a CSV and a bag: process follows the change in both (the CSV used
    to be refused as "not uniformly sampled"); the verbs that need one rate say where it
    changed."""
    time, tc1, tc2 = _rate_change_record()
    source = write_csv(tmp_path / "in.csv", time, tc1, tc2)
    write_bag(tmp_path / "in_bag", time, dict(zip(DEFAULT_TOPICS[:2], (tc1, tc2), strict=True)))
    outcomes = [
        process(source, tmp_path / "out.csv", FAST),
        process(tmp_path / "in_bag", tmp_path / "out_bag.csv", FAST),
    ]
    for outcome in outcomes:
        assert outcome.pairs == time.size
        assert any("the sample rate changed 1 time(s)" in text for text in outcome.warnings)
    assert outcomes[0].gas == outcomes[1].gas > 0.8 * time.size
    with pytest.raises(DataError, match=r"changes from 0.002 s to 0.0005 s at sample 1001"):
        read_csv(source)
