"""One bag reader and one writer for every verb: corrupt and cut-off bags, third-party readers.

``tcomp estimate`` (through :func:`tcomp_core.io.read_bag`) and ``tcomp process`` (through
:class:`tcomp_core.io.BagStream`) must refuse the same corrupt files and accept the same cut-off
ones with the same one-line messages; the bags ``process`` and ``reconstruct`` write must open
with rosbags, the ``mcap`` package and pybag-sdk.
"""

from __future__ import annotations

import struct
import warnings
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from rosbags.rosbag2 import Reader

from tcomp_core.cli import main
from tcomp_core.errors import DataError, TruncatedInputWarning
from tcomp_core.io import (
    DEFAULT_TOPICS,
    GAS_TOPIC,
    read_bag,
    write_bag,
    write_bag_copy,
    write_series,
)
from tcomp_core.process import ProcessConfig, process
from tcomp_core.simulate import simulate_pair

BAGS = Path(__file__).resolve().parent.parent / "bags"
START_NS = 1_700_000_000 * 10**9
TC1, TC2, TREF = DEFAULT_TOPICS


def _record_bag(path: Path, *, ours: bool = False) -> Path:
    """20 s at 500 Hz with a reference in several chunks, by write_bag or copied (``ours``)."""
    data = simulate_pair(
        "sinusoid",
        tau1=0.0238,
        tau2=0.1168,
        dt=2e-3,
        duration=20.0,
        noise_percent=1.0,
        phi=1.0,
        seed=5,
    )
    series = {TC1: data.tc1, TC2: data.tc2, TREF: data.gas}
    if not ours:
        return write_bag(path, data.time, series, start_ns=START_NS)
    plain = write_bag(path.with_name(f"{path.name}_rosbags"), data.time, series, start_ns=START_NS)
    origin = read_bag(plain).origin
    assert origin is not None
    return write_bag_copy(path, origin, np.empty(0, np.int64), np.empty(0), compress=False)


def _chunks(mcap: Path) -> list[tuple[int, int]]:
    """(offset, length) of every top-level chunk record of an MCAP file."""
    data = mcap.read_bytes()
    at, found = 8, []
    while at + 9 <= len(data):
        opcode, length = struct.unpack_from("<BQ", data, at)
        if opcode == 0x06:
            found.append((at, length))
        if opcode == 0x0F:
            break
        at += 9 + length
    return found


def _records_start(data: bytes, chunk: int) -> int:
    """File offset of the first record inside the (uncompressed) chunk at ``chunk``."""
    (name_length,) = struct.unpack_from("<I", data, chunk + 9 + 28)
    return chunk + 9 + 28 + 4 + name_length + 8


def _message_record(data: bytes, chunk: int, skip: int) -> int:
    """File offset of the ``skip``-th message record (opcode 0x05) inside a plain chunk."""
    at = _records_start(data, chunk)
    seen = 0
    while True:
        opcode, length = struct.unpack_from("<BQ", data, at)
        if opcode == 0x05:
            if seen == skip:
                return at
            seen += 1
        at += 9 + length


def _run(capsys, *argv: str) -> tuple[int, list[str], list[str]]:
    """Run the CLI: status, its error lines and its warning lines (text after the prefix)."""
    status = main(list(argv))
    err = capsys.readouterr().err.splitlines()
    errors = [line.split(": error: ", 1)[1] for line in err if ": error: " in line]
    warned = [line.split(": warning: ", 1)[1] for line in err if ": warning: " in line]
    return status, errors, warned


def _estimate_and_process(capsys, bag: Path, out: Path):
    estimate = _run(capsys, "estimate", str(bag))
    processed = _run(capsys, "process", str(bag), "-o", str(out), "--no-diagnose")
    return estimate, processed


def _assert_same_refusal(capsys, bag: Path, out: Path, expected: str) -> str:
    (status_e, errors_e, _), (status_p, errors_p, _) = _estimate_and_process(capsys, bag, out)
    assert status_e == status_p == 1
    assert len(errors_e) == 1 and errors_e == errors_p, (errors_e, errors_p)
    assert expected in errors_e[0], errors_e[0]
    assert not (out / "metadata.yaml").exists()  # no finished output from a refused input
    return errors_e[0]


def test_crc_mismatch_is_refused_alike(tmp_path, capsys):
    bag = _record_bag(tmp_path / "crc", ours=True)
    mcap = next(bag.glob("*.mcap"))
    data = bytearray(mcap.read_bytes())
    chunk, _ = _chunks(mcap)[0]
    assert struct.unpack_from("<I", data, chunk + 9 + 24)[0] != 0  # our writer sets the CRC
    data[_message_record(data, chunk, 4000) + 60] ^= 0x40  # one bit of a temperature
    mcap.write_bytes(bytes(data))
    message = _assert_same_refusal(capsys, bag, tmp_path / "out", f"chunk at byte {chunk} (")
    assert str(mcap) in message and "CRC mismatch" in message
    assert TC1 in message and TC2 in message


def test_corrupt_inner_record_length_is_refused_alike(tmp_path, capsys):
    bag = _record_bag(tmp_path / "inner")
    mcap = next(bag.glob("*.mcap"))
    data = bytearray(mcap.read_bytes())
    chunk, _ = _chunks(mcap)[0]
    struct.pack_into("<I", data, chunk + 9 + 24, 0)  # CRC 0, "not computed", as rosbags writes
    record = _message_record(data, chunk, 600)
    struct.pack_into("<Q", data, record + 1, 10**7)
    mcap.write_bytes(bytes(data))
    inner = record - _records_start(data, chunk)
    message = _assert_same_refusal(capsys, bag, tmp_path / "out", f"chunk at byte {chunk} (")
    assert str(mcap) in message
    assert f"record at byte {inner} has length 10000000, past the chunk's end" in message


def test_corrupt_outer_record_length_is_refused_alike(tmp_path, capsys):
    bag = _record_bag(tmp_path / "outer")
    mcap = next(bag.glob("*.mcap"))
    data = bytearray(mcap.read_bytes())
    chunk, length = _chunks(mcap)[-1]
    struct.pack_into("<Q", data, chunk + 1, length + 1000)
    mcap.write_bytes(bytes(data))
    message = _assert_same_refusal(capsys, bag, tmp_path / "out", f"chunk at byte {chunk}: ")
    assert str(mcap) in message
    assert f"its record length is {length + 1000} bytes" in message


@pytest.mark.slow
def test_cut_off_bag_is_read_alike_up_to_its_last_complete_record(tmp_path, capsys):
    bag = _record_bag(tmp_path / "cut")
    mcap = next(bag.glob("*.mcap"))
    chunk, length = _chunks(mcap)[-1]
    mcap.write_bytes(mcap.read_bytes()[: chunk + length // 2])
    (status_e, errors_e, warned_e), (status_p, errors_p, warned_p) = _estimate_and_process(
        capsys, bag, tmp_path / "out"
    )
    assert status_e == status_p == 0 and errors_e == errors_p == []
    assert len(warned_e) == 1 and warned_e[0] in warned_p
    assert warned_e[0].startswith(f"{mcap}: input truncated: record (opcode 0x06)")
    assert f"(record at byte {chunk} of {chunk + length // 2})" in warned_e[0]
    full = read_bag(_record_bag(tmp_path / "full"))
    with pytest.warns(UserWarning, match="input truncated"):
        cut = read_bag(bag)
    assert full.tc1.size // 4 < cut.tc1.size < full.tc1.size
    np.testing.assert_array_equal(cut.tc1, full.tc1[: cut.tc1.size])
    copied = read_bag(tmp_path / "out", topics=(TC1, TC1, None))  # every tc1 message read
    # read_bag ends where every topic (the reference too) got; process copies every record read
    assert cut.tc1.size <= copied.tc1.size < full.tc1.size
    np.testing.assert_array_equal(copied.tc1, full.tc1[: copied.tc1.size])


# --------------------------------------------------------------------------------------------
# What we write opens with third-party readers


@pytest.fixture(scope="module")
def processed(tmp_path_factory) -> tuple[Path, dict[str, int]]:
    out = tmp_path_factory.mktemp("processed") / "out"
    result = process(BAGS / "ramp_500hz", out, ProcessConfig(diagnose=False))
    counts = {TC1: 5000, TC2: 5000, TREF: 5000, GAS_TOPIC: result.gas}
    return out, counts


@pytest.mark.slow
def test_process_output_opens_with_rosbags(processed):
    out, counts = processed
    with Reader(out) as reader:
        seen: dict[str, int] = {}
        for connection, _, _ in reader.messages():
            seen[connection.topic] = seen.get(connection.topic, 0) + 1
    assert {topic: seen[topic] for topic in counts} == counts


def test_process_output_opens_with_the_mcap_reader(processed):
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    out, counts = processed
    with next(out.glob("*.mcap")).open("rb") as handle:
        reader = make_reader(handle)
        assert {c.compression for c in reader.get_summary().chunk_indexes} == {"zstd"}
        seen: dict[str, int] = {}
        first = None
        for schema, channel, message in reader.iter_messages(topics=list(counts)):
            seen[channel.topic] = seen.get(channel.topic, 0) + 1
            first = first or store.deserialize_cdr(message.data, schema.name)
    assert seen == counts
    assert first is not None and first.header.frame_id == "probe"


def test_process_output_opens_with_pybag(processed):
    from pybag.mcap_reader import McapFileReader

    out, counts = processed
    reader = McapFileReader.from_file(next(out.glob("*.mcap")))
    try:
        assert set(counts) <= set(reader.get_topics())
        gas = list(reader.messages(GAS_TOPIC))
        assert len(gas) == counts[GAS_TOPIC]
        assert len(list(reader.messages(TC1))) == counts[TC1]
    finally:
        reader.close()
    assert gas[0].data.header.frame_id == "probe"
    assert np.all(np.isfinite([message.data.temperature for message in gas]))


def _raw(bag: Path) -> dict[str, list[tuple[int, bytes]]]:
    found: dict[str, list[tuple[int, bytes]]] = {}
    with Reader(bag) as reader:
        for connection, log_time, raw in reader.messages():
            found.setdefault(connection.topic, []).append((log_time, bytes(raw)))
    return found


@pytest.mark.slow
def test_reconstruct_to_a_bag_keeps_every_input_message(tmp_path, capsys):
    out = tmp_path / "gas_bag"
    assert main(["reconstruct", str(BAGS / "ramp_500hz"), "-o", str(out)]) == 0
    capsys.readouterr()
    before, after = _raw(BAGS / "ramp_500hz"), _raw(out)
    for topic in (TC1, TC2, TREF):
        assert after[topic] == before[topic]  # every message, byte for byte, log times too
    gas = read_bag(out, topics=(GAS_TOPIC, GAS_TOPIC, None))
    assert gas.frame_id == "probe" and gas.tc1.size >= 4999
    assert np.isin(gas.stamps_ns, read_bag(BAGS / "ramp_500hz").stamps_ns).all()
    with next(out.glob("*.mcap")).open("rb") as handle:
        chunks = make_reader(handle).get_summary().chunk_indexes
    assert chunks and {chunk.compression for chunk in chunks} == {"zstd"}


@pytest.mark.slow
@pytest.mark.parametrize("compress", [False, True], ids=["plain", "zstd"])
def test_random_damage_gives_a_record_or_a_data_error_never_another_exception(tmp_path, compress):
    """Seeded fuzzing: flipped bits, overwritten words and cut-off ends anywhere in the file."""
    time = np.arange(3000) * 1e-3
    series = {TC1: np.sin(time), TC2: np.cos(time)}
    theirs = write_bag(tmp_path / "theirs", time, series, compress=compress)
    origin = read_bag(theirs).origin
    assert origin is not None
    ours = write_bag_copy(tmp_path / "ours", origin, [], [], compress=compress)
    rng = np.random.default_rng(2026)
    outcomes = {"record": 0, "refused": 0}
    for bag in (theirs, ours):
        mcap = next(bag.glob("*.mcap"))
        intact = mcap.read_bytes()
        for _ in range(80):
            data = bytearray(intact)
            kind = rng.integers(3)
            if kind == 0:
                data[rng.integers(len(data))] ^= 1 << int(rng.integers(8))
            elif kind == 1:
                at = int(rng.integers(len(data) - 8))
                data[at : at + 8] = rng.bytes(8)
            else:
                data = data[: int(rng.integers(8, len(data)))]
            mcap.write_bytes(bytes(data))
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", TruncatedInputWarning)
                    read_bag(bag)
                outcomes["record"] += 1
            except DataError as exc:
                assert "\n" not in str(exc)  # one line
                outcomes["refused"] += 1
        mcap.write_bytes(intact)
    assert min(outcomes.values()) > 10, outcomes


def test_write_series_copies_a_bag_record_and_stamps_gas_at_its_samples(tmp_path):
    record = read_bag(BAGS / "ramp_500hz")
    gas = record.tc1[10:20] + 1.0
    out = write_series(
        tmp_path / "copy",
        record.time[10:20],
        record.tc1[10:20],
        record.tc2[10:20],
        gas=gas,
        inputs=record,
    )
    copied = read_bag(out, topics=(GAS_TOPIC, GAS_TOPIC, None))
    assert copied.stamps_ns.tolist() == record.stamps_ns[10:20].tolist()
    np.testing.assert_array_equal(copied.tc1, gas)
    assert read_bag(out).stamps_ns.size == record.stamps_ns.size  # every input message
    with pytest.raises(DataError, match=r"time\[0\] = .* is not a sample time of .*ramp_500hz"):
        write_series(
            tmp_path / "off",
            record.time[:3] + 1e-4,
            record.tc1[:3],
            record.tc2[:3],
            gas=record.tc1[:3],
            inputs=record,
        )
