"""``tcomp campaign`` on 1 and 2 Dask workers against ``tcomp process --jobs 1``, same files.

The files are a generated campaign (``bench/campaign_data.py``: probes over simulated days,
multisines at 500 Hz). The baseline is ``tcomp process`` on every recording one after the other
(its engine with its closing diagnosis of the whole recording: the same work as a campaign with
one diagnosis window per recording); the campaign runs on an embedded local cluster of 1, then
2 worker processes, each from a fresh output directory (cluster start-up included), then once
more on the 2-worker output (a rerun: nothing to do). Prints recordings/s and pairs/s of each
and the ratios.

    .venv/bin/python bench/bench_campaign.py [--days 4] [--duration-s 10]
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import campaign_data

from tcomp_core.campaign import CampaignOptions, ClusterSpec, find_recordings, run_campaign
from tcomp_core.process import ProcessConfig, process_one


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--days", type=int, default=4, help="recordings per probe (2 probes)")
    parser.add_argument("--duration-s", type=float, default=10.0, help="each recording, s")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as scratch:
        root = Path(scratch)
        campaign_data.write_campaign(root / "in", days=args.days, duration_s=args.duration_s)
        recordings = [r.path for r in find_recordings([root / "in"])]
        started = time.perf_counter()
        outcomes = [
            process_one(path, root / "process" / f"recording{i}", ProcessConfig(), False)
            for i, path in enumerate(recordings)
        ]
        baseline = time.perf_counter() - started
        pairs = sum(o.result.pairs for o in outcomes if o.result is not None)
        print(f"{len(recordings)} recordings, {pairs} pairs in all")
        print(f"{'run':<28}{'seconds':>9}{'recordings/s':>14}{'pairs/s':>10}{'vs process':>12}")
        _line("tcomp process --jobs 1", baseline, len(recordings), pairs, baseline)
        options = CampaignOptions(window_s=math.inf)
        quiet = lambda line: None  # noqa: E731
        seconds = {}
        for workers in (1, 2):
            started = time.perf_counter()
            result = run_campaign(
                [root / "in"],
                root / f"campaign{workers}",
                options,
                ClusterSpec(workers=workers),
                log=quiet,
            )
            seconds[workers] = time.perf_counter() - started
            assert result.failed == 0 and result.processed == len(recordings)
            _line(
                f"campaign, {workers} worker(s)",
                seconds[workers],
                len(recordings),
                pairs,
                baseline,
            )
        started = time.perf_counter()
        again = run_campaign([root / "in"], root / "campaign2", options, log=quiet)
        rerun = time.perf_counter() - started
        assert again.processed == 0
        print(f"{'rerun (nothing to do)':<28}{rerun:>9.2f}")
        print(f"scaling 1 -> 2 workers: {seconds[1] / seconds[2]:.2f}x")


def _line(name: str, seconds: float, recordings: int, pairs: int, baseline: float) -> None:
    print(
        f"{name:<28}{seconds:>9.2f}{recordings / seconds:>14.3f}{pairs / seconds:>10.4g}"
        f"{baseline / seconds:>11.2f}x"
    )


if __name__ == "__main__":
    main()
