"""End-to-end rate of ``tcomp process`` against the plain rosbags per-message loop.

Generates (once, cached in ``out/bench_process/``) a two-sensor 5 kHz bag of ``--minutes``
minutes (10 by default: 3 M pairs, 6 M messages; a seeded sinusoid plus noise through the two
first-order lags), written with the bulk encoder. Then, in the same run:

- ``tcomp process`` end to end (read, pair, estimate, reconstruct, write a bag with the inputs,
  gas_temperature and the tau history; no diagnosis), pairs per second and peak memory;
- the plain loop ``for c, t, raw in reader.messages(): typestore.deserialize_cdr(raw, ...)``
  over the first ``--loop-messages`` messages (200 k by default, it is slow), messages per
  second converted to pairs per second (two messages per pair).

Imports happen before any clock starts. Both output modes run: uncompressed (``--no-compress``,
rosbag2's default) then zstd chunks (``tcomp process``'s default).

Usage: ``python bench/bench_process.py [--minutes 10] [--rate-hz 5000]`` (another rate, e.g.
2000, generates and caches its own bag).
"""

from __future__ import annotations

import argparse
import resource
import shutil
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
from scipy import signal

from tcomp_core.io import DEFAULT_TOPICS, TEMPERATURE_TYPE, McapBagWriter, encode, offered_qos
from tcomp_core.process import ProcessConfig, process

RATE_HZ = 5000
TAU = (0.0238, 0.1168)
START_NS = 1_700_000_000 * 1_000_000_000
BLOCK = 5_000


def sensor_blocks(
    minutes: float, rate_hz: int = RATE_HZ, seed: int = 7
) -> Iterator[tuple[np.ndarray, list[np.ndarray]]]:
    """The benchmark signal, block by block: stamps (ns) and the tc1, tc2 readings (degrees C).

    A seeded sum of a 10 Hz and a 1 Hz sinusoid about 300 °C through the paper's two
    first-order lags (:data:`TAU`), white noise of σ = 0.3 °C on each reading; blocks of
    :data:`BLOCK` samples, ``rate_hz`` samples/s, ``minutes * 60 * rate_hz`` in all.
    """
    rng = np.random.default_rng(seed)
    count = round(minutes * 60 * rate_hz)
    dt = 1.0 / rate_hz
    poles = [np.exp(-dt / tau) for tau in TAU]
    states = [None, None]
    for start in range(0, count, BLOCK):
        index = np.arange(start, min(start + BLOCK, count))
        time_s = index * dt
        gas = 300.0 + 50.0 * np.sin(2 * np.pi * 10.0 * time_s) + 20.0 * np.sin(2 * np.pi * time_s)
        stamps = START_NS + index * (1_000_000_000 // rate_hz)
        readings = []
        for k, pole in enumerate(poles):
            zi = states[k] if states[k] is not None else np.array([pole * gas[0]])
            measured, states[k] = signal.lfilter([1 - pole], [1, -pole], gas, zi=zi)
            readings.append(measured + rng.normal(0.0, 0.3, measured.size))
        yield stamps, readings


def make_bag(path: Path, minutes: float, seed: int = 7, rate_hz: int = RATE_HZ) -> Path:
    """Write the benchmark bag block by block (bounded memory), ``rate_hz`` samples/s."""
    writer = McapBagWriter(path, compress=True)
    qos = offered_qos()
    channels = [writer.add_channel(topic, TEMPERATURE_TYPE, qos) for topic in DEFAULT_TOPICS[:2]]
    for stamps, readings in sensor_blocks(minutes, rate_hz, seed):
        for measured, channel in zip(readings, channels, strict=True):
            writer.write_rows(channel, stamps, encode(stamps, measured, 0.0, "probe"))
    return writer.close()


def plain_loop_rate(bag: Path, limit: int) -> tuple[float, int]:
    """Messages per second of rosbags' per-message deserialization, first ``limit`` messages."""
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    typestore = get_typestore(Stores.ROS2_JAZZY)
    count = 0
    started = time.perf_counter()
    with Reader(bag) as reader:
        for connection, _, raw in reader.messages():
            message = typestore.deserialize_cdr(raw, connection.msgtype)
            _ = (message.header.stamp.sec, message.header.stamp.nanosec, message.temperature)
            count += 1
            if count >= limit:
                break
    return count / (time.perf_counter() - started), count


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=10.0)
    parser.add_argument("--rate-hz", type=int, default=RATE_HZ, help="sample rate of the bag")
    parser.add_argument("--loop-messages", type=int, default=200_000)
    parser.add_argument("--cache", type=Path, default=Path("out/bench_process"))
    parser.add_argument(
        "--repeat", type=int, default=3, help="runs per output mode; the best and median shown"
    )
    args = parser.parse_args(argv)
    suffix = "" if args.rate_hz == RATE_HZ else f"_{args.rate_hz}hz"
    bag = args.cache / f"sine_5khz_{args.minutes:g}min{suffix}"
    if not (bag / "metadata.yaml").is_file():
        shutil.rmtree(bag, ignore_errors=True)
        bag.parent.mkdir(parents=True, exist_ok=True)
        started = time.perf_counter()
        make_bag(bag, args.minutes, rate_hz=args.rate_hz)
        print(f"generated {bag} in {time.perf_counter() - started:.1f} s")
    size_mb = sum(f.stat().st_size for f in bag.iterdir()) / 1e6
    # Load rosbags' message store before any clock starts, as plain_loop_rate does: a one-off
    # import (about 0.1 s) that would otherwise be charged to whichever run comes first.
    from rosbags.typesys import Stores, get_typestore

    get_typestore(Stores.ROS2_JAZZY)
    runs = []
    for compress in (False, True):
        results = []
        for _ in range(args.repeat):
            with tempfile.TemporaryDirectory() as tmp:
                output = Path(tmp) / "processed"
                result = process(bag, output, ProcessConfig(diagnose=False, compress=compress))
                out_mb = sum(f.stat().st_size for f in output.iterdir()) / 1e6
            results.append(result)
        results.sort(key=lambda r: r.pairs_per_s)
        runs.append((compress, results[-1], results[len(results) // 2], out_mb))
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    loop_rate, looped = plain_loop_rate(bag, args.loop_messages)
    pairs = runs[0][1].pairs
    print(f"bag: {bag} ({size_mb:.0f} MB), {pairs} pairs, {2 * pairs} messages")
    print(f"best and median of {args.repeat} runs (a loaded 2-core machine varies by ~15 %)")
    print(
        f"{'what':<44} {'pairs/s':>12} {'median':>10} {'seconds':>9} {'output MB':>10} "
        f"{'vs loop':>8}"
    )
    for compress, best, median, out_mb in runs:
        what = f"tcomp process, {'zstd' if compress else 'uncompressed'} output"
        rate = best.pairs_per_s
        print(
            f"{what:<44} {rate:>12.4g} {median.pairs_per_s:>10.4g} {best.seconds:>9.2f} "
            f"{out_mb:>10.0f} {rate / (loop_rate / 2):>7.1f}x"
        )
    print(
        f"{f'plain rosbags loop (first {looped} messages)':<44} {loop_rate / 2:>12.4g} "
        f"{looped / loop_rate:>9.2f}"
    )
    result = runs[0][1]
    print(f"{result.estimates} estimates, tau = {result.tau}; peak RSS {peak_mb:.0f} MB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
