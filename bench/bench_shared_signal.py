"""Which campaign records the shared-signal check refuses: the one-bin test before, the check now.

``tcomp_core.validation.check_shared_signal`` refuses two readings that share no signal before
any estimate. Until the eleventh session it looked at the best single bin of power-of-two
segments only, and slow gases seen by slow sensors fell short in every bin though their readings
correlate at 0.9 and more. This benchmark runs the campaign's draws (``bench/campaign_draws.py``:
the detailed simulator, a class-2 sensor difference on every draw, noise added) through both,
the former re-implemented here as the baseline, and prints how many each refuses, every record
either one refuses (with the correlation of its two readings) and the records whose outcome
changed. Independent noise must stay refused: ``test/test_shared_signal.py``.

Usage: ``PYTHONPATH=. .venv/bin/python bench/bench_shared_signal.py [--start 8700] [--count 400]
[--jobs 2]``.
"""

from __future__ import annotations

import argparse
import math
import sys
from multiprocessing import Pool
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))


def one_bin_test_before(tc1: np.ndarray, tc2: np.ndarray) -> bool:
    """The check before the eleventh session: the best bin of power-of-two segments only."""
    from tcomp_core.validation import SHARED_MIN_LENGTH, SHARED_SEGMENTS, _shared_threshold

    for segments in SHARED_SEGMENTS:
        length = 2 ** math.floor(math.log2(max(tc1.size // segments, 1)))
        if length < SHARED_MIN_LENGTH:
            return True  # too short to look at: accepted, as the check accepts it
        window = np.hanning(length)
        spectra = []
        for values in (tc1, tc2):
            parts = values[: length * segments].reshape(segments, length)
            parts = parts - parts.mean(axis=1, keepdims=True)
            spectra.append(np.fft.rfft(parts * window, axis=1)[:, 1:])
        first, second = spectra
        cross = np.abs(np.mean(first * np.conj(second), axis=0)) ** 2
        powers = np.mean(np.abs(first) ** 2, axis=0) * np.mean(np.abs(second) ** 2, axis=0)
        coherence = cross / np.maximum(powers, np.finfo(float).tiny)
        if coherence.max() >= _shared_threshold(segments):
            return True
    return False


def judge(index: int) -> tuple[int, str, bool, bool, float]:
    """(draw, label, accepted before, accepted now, correlation of the two readings)."""
    from campaign_draws import draw, simulate

    from tcomp_core.errors import NoExcitationError
    from tcomp_core.validation import check_shared_signal

    item = draw(index)
    record, _ = simulate(item)
    try:
        check_shared_signal(record.tc1, record.tc2, record.dt)
        now = True
    except NoExcitationError:
        now = False
    before = one_bin_test_before(record.tc1, record.tc2)
    correlation = float(np.corrcoef(record.tc1, record.tc2)[0, 1])
    return index, item.label, before, now, correlation


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--start", type=int, default=8700, help="first campaign draw")
    parser.add_argument("--count", type=int, default=400, help="draws")
    parser.add_argument("--jobs", type=int, default=2, help="draws simulated at once")
    args = parser.parse_args()
    indices = range(args.start, args.start + args.count)
    with Pool(args.jobs) as pool:
        rows = sorted(pool.imap_unordered(judge, indices))
    refused_before = [row for row in rows if not row[2]]
    refused_now = [row for row in rows if not row[3]]
    print(f"campaign draws {args.start}-{args.start + args.count - 1}: {len(rows)}")
    print(f"  refused by the one-bin test before: {len(refused_before)}")
    print(f"  refused by the check now:           {len(refused_now)}")
    print(f"  accepted before, refused now:       {sum(r[2] and not r[3] for r in rows)}")
    print(f"  refused before, accepted now:       {sum(r[3] and not r[2] for r in rows)}")
    for index, label, before, now, correlation in rows:
        if not (before and now):
            was, became = ("accepted" if ok else "refused" for ok in (before, now))
            outcome = f"{was} -> {became}"
            print(f"  {index} {label}: {outcome}, readings correlate at {correlation:.3f}")


if __name__ == "__main__":
    main()
