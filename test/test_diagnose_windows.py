"""``tcomp diagnose`` on long records: windows streamed from the file, one row each, one verdict.

The reader (:class:`tcomp_core.io.windows.WindowReader`) is checked for what bounds its memory,
counted rather than timed: it never holds more of a series than a window, a chunk and (in a bag)
the late margin, and it hands every sample over exactly once. The windows' diagnosis is checked
on records of :mod:`tcomp_core.simulate_effects` with a known effect, and bad stretches (a run
of invalid samples, a gap) are reported in their own rows while the others carry on.
"""

from __future__ import annotations

import functools
import json
import math
import os
import signal
import warnings
from pathlib import Path

import numpy as np
import pytest

from tcomp_core.cli import main
from tcomp_core.diagnose.saved import read_diagnosis_effects
from tcomp_core.diagnose.window_pool import diagnose_in_processes
from tcomp_core.diagnose.windowed import (
    WindowResult,
    diagnose_window,
    diagnose_windows,
    whole_verdict,
)
from tcomp_core.io import (
    DEFAULT_TOPICS,
    TEMPERATURE_TYPE,
    BagStream,
    McapBagWriter,
    encode,
    read_record,
    write_bag,
    write_csv,
)
from tcomp_core.io.windows import LATE_S, Window, WindowReader
from tcomp_core.simulate_effects import simulate_effect

PAPER = (0.0238, 0.1168)


def _sine_series(count: int, dt: float, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Times and two noisy readings of a 2 Hz sine (cheap: the reader is not diagnosing)."""
    rng = np.random.default_rng(seed)
    time = np.arange(count) * dt
    gas = 300.0 + 40.0 * np.sin(2 * np.pi * 2.0 * time)
    return time, gas + rng.normal(0, 0.2, count), gas + rng.normal(0, 0.2, count)


@pytest.mark.slow
def test_a_bag_is_handed_over_in_windows_holding_a_window_and_a_chunk_at_most(tmp_path):
    dt, count, window_s = 0.001, 400_000, 5.0  # 400 s at 1 kHz: 80 windows
    time, tc1, tc2 = _sine_series(count, dt, seed=1)
    bag = write_bag(tmp_path / "long", time, {"/tc1/temperature": tc1, "/tc2/temperature": tc2})
    stream = BagStream(bag, {"tc1": "/tc1/temperature", "tc2": "/tc2/temperature"})
    chunk = max(len(block.series.get("tc1", [])) for block in stream)
    reader = WindowReader(bag, window_s)
    windows = list(reader)
    assert [w.index for w in windows] == list(range(80))
    assert [w.start_s for w in windows] == pytest.approx(np.arange(80) * window_s)
    assert all(w.problem == "" and w.record is not None for w in windows)
    # Every sample exactly once, in order, as the whole-file reader reads it.
    whole = read_record(bag)
    stamps = np.concatenate([w.record.stamps_ns for w in windows if w.record is not None])
    values = np.concatenate([w.record.tc2 for w in windows if w.record is not None])
    np.testing.assert_array_equal(stamps, whole.stamps_ns)
    np.testing.assert_array_equal(values, whole.tc2)
    # The memory bound, counted: a window, the late margin and one chunk; far below the record.
    bound = round(window_s / dt) + round(LATE_S / dt) + chunk
    assert reader.peak_held <= bound, (reader.peak_held, bound)
    assert reader.peak_held < count / 5


def test_a_topic_logged_late_still_fills_its_windows(tmp_path):
    # tc2 is logged half a second after its stamps (log order is not stamp order): each window
    # waits for it, so no sample is lost and every window pairs.
    dt, count, lag = 0.001, 30_000, 500
    _, tc1, tc2 = _sine_series(count, dt, seed=6)
    stamps = 1_000_000_000 + np.arange(count, dtype=np.int64) * 1_000_000
    writer = McapBagWriter(tmp_path / "late", compress=True, chunk_bytes=20_000)
    one, two = (writer.add_channel(t, TEMPERATURE_TYPE) for t in DEFAULT_TOPICS[:2])
    for start in range(0, count + lag, 100):
        now = slice(min(start, count), min(start + 100, count))
        late = slice(max(start - lag, 0), max(min(start + 100 - lag, count), 0))
        writer.write_rows(one, stamps[now], encode(stamps[now], tc1[now], 0.0, "tc"))
        logged = stamps[late] + lag * 1_000_000
        writer.write_rows(two, logged, encode(stamps[late], tc2[late], 0.0, "tc"))
    bag = writer.close()
    reader = WindowReader(bag, 5.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        windows = list(reader)
    assert len(windows) == 6 and reader.late == 0
    assert all(w.record is not None and w.record.time.size == 5_000 for w in windows)


def test_a_csv_file_is_parsed_in_row_chunks_and_handed_over_in_windows(tmp_path):
    dt, count = 0.002, 30_000  # 60 s at 500 Hz
    time, tc1, tc2 = _sine_series(count, dt, seed=2)
    data = tmp_path / "long.csv"
    write_csv(data, time, tc1, tc2)
    reader = WindowReader(data, 10.0, csv_rows=1_000)
    windows = list(reader)
    assert len(windows) == 6 and all(w.samples == 5_000 for w in windows)
    assert reader.peak_held <= 5_000 + 1_000
    whole = read_record(data)
    np.testing.assert_array_equal(
        np.concatenate([w.record.time for w in windows if w.record is not None]), whole.time
    )


def test_the_automatic_choice_keeps_a_short_record_whole_and_cuts_a_long_one(tmp_path):
    dt, count = 0.001, 20_000
    time, tc1, tc2 = _sine_series(count, dt, seed=3)
    bag = write_bag(tmp_path / "b", time, {"/tc1/temperature": tc1, "/tc2/temperature": tc2})
    short = WindowReader(bag)
    (only,) = list(short)
    assert short.whole and only.record is not None
    whole = read_record(bag)
    np.testing.assert_array_equal(only.record.stamps_ns, whole.stamps_ns)
    np.testing.assert_array_equal(only.record.tc1, whole.tc1)
    long = WindowReader(bag, whole_samples=5_000, window_samples=4_000)
    windows = list(long)
    assert long.automatic and not long.whole and long.window_s == 4.0  # 4 000 samples, 4 s
    assert len(windows) == 5
    assert WindowReader(bag, math.inf).__iter__().__next__().record is not None


def _effect_csv(tmp_path, effect, duration, seed):
    sim = simulate_effect(
        effect, "multisine", tau1=PAPER[0], tau2=PAPER[1], duration=duration, seed=seed
    )
    data = tmp_path / f"{effect}.csv"
    write_csv(data, sim.time, sim.tc1, sim.tc2)
    return data, sim


@pytest.mark.slow
def test_windows_of_a_record_with_a_delay_each_find_it_and_so_does_the_whole(tmp_path):
    data, sim = _effect_csv(tmp_path, "delay", 30.0, seed=41)
    reader = WindowReader(data, 10.0)
    result = diagnose_windows(
        reader, source=str(data), window_s=10.0, candidates=("delay", "calibration")
    )
    assert len(result.windows) == 3
    assert [row.verdict for row in result.windows] == ["delay"] * 3
    assert result.whole.verdict == "delay" and result.whole.agree == 3
    assert result.whole.tau1 == pytest.approx(sim.tau1, rel=0.1)
    assert result.whole.tau2 == pytest.approx(sim.tau2, rel=0.1)
    lo, hi = result.windows[0].tau2_95 or (math.nan, math.nan)
    assert lo < result.windows[0].tau2 < hi


@pytest.mark.slow
def test_a_window_with_a_broken_run_or_a_gap_says_so_and_the_others_carry_on(tmp_path):
    sim = simulate_effect(None, "multisine", tau1=PAPER[0], tau2=PAPER[1], duration=50.0, seed=5)
    tc1 = sim.tc1.copy()
    rate = round(1 / sim.dt)
    tc1[12 * rate : 12 * rate + 20] = np.nan  # window 2: 20 samples in a row, not bridged
    tc1[25 * rate : 25 * rate + 3] = 3e8  # window 3: 3 samples, bridged
    keep = np.ones(tc1.size, bool)
    keep[round(35.5 * rate) : 37 * rate] = False  # window 4: a gap of 1.5 s (rate not uniform)
    data = tmp_path / "broken.csv"
    write_csv(data, sim.time[keep], tc1[keep], sim.tc2[keep])
    result = diagnose_windows(
        WindowReader(data, 10.0), source=str(data), window_s=10.0, candidates=("delay",)
    )
    rows = result.windows
    assert len(rows) == 5
    assert rows[1].verdict is None and "20 samples in a row" in rows[1].problem
    assert rows[3].verdict is None and "uniform" in rows[3].problem
    assert rows[2].verdict == "none" and any(
        "bridged" in note or "left out" in note for note in rows[2].notes
    )
    assert [rows[k].verdict for k in (0, 2, 4)] == ["none"] * 3
    assert result.whole.verdict == "none" and result.whole.voting == 3


@pytest.mark.slow
def test_windows_diagnosed_in_worker_processes_give_the_rows_diagnosed_here(tmp_path):
    data, _ = _effect_csv(tmp_path, "delay", 30.0, seed=43)
    here = diagnose_windows(
        WindowReader(data, 10.0), source=str(data), window_s=10.0, candidates=("delay",)
    )
    there = diagnose_windows(
        WindowReader(data, 10.0),
        source=str(data),
        window_s=10.0,
        diagnose_all=lambda windows: diagnose_in_processes(windows, 2, ("delay",)),
    )
    assert [row.verdict for row in there.windows] == ["delay"] * 3
    assert there == here  # every figure of every row, and the whole verdict


def _die_on(marker: Path, index: int, always: bool, window, candidates, max_effects):
    """diagnose_window, but window ``index`` kills its worker (once, or every time)."""
    if window.index == index and (always or not marker.exists()):
        marker.touch()
        os.kill(os.getpid(), signal.SIGKILL)
    return diagnose_window(window, candidates, max_effects)


def _problem_windows(count):
    """Windows without a record: their rows (the reader's problem) cost nothing to make."""
    return [
        Window(index=i, start_s=10.0 * i, length_s=10.0, samples=0, record=None, problem=f"p{i}")
        for i in range(count)
    ]


def test_a_worker_that_dies_loses_no_window_and_one_that_always_dies_is_reported(tmp_path):
    once = functools.partial(_die_on, tmp_path / "died", 1, False)
    rows = list(diagnose_in_processes(_problem_windows(6), 2, diagnose=once))
    assert (tmp_path / "died").exists()  # a worker did die
    assert [row.index for row in rows] == list(range(6))
    assert [row.problem for row in rows] == [f"p{i}" for i in range(6)]
    always = functools.partial(_die_on, tmp_path / "died_again", 2, True)
    rows = list(diagnose_in_processes(_problem_windows(5), 2, diagnose=always))
    assert [row.index for row in rows] == list(range(5))
    assert "died, also when it was diagnosed alone" in rows[2].problem
    assert rows[2].verdict is None
    # The windows in flight beside it each time are not blamed: diagnosed alone, they pass.
    assert [rows[i].problem for i in (0, 1, 3, 4)] == ["p0", "p1", "p3", "p4"]
    with pytest.raises(ValueError, match="jobs=0"):
        next(diagnose_in_processes(_problem_windows(1), 0))


def _row(index, verdict, tau=(0.02, 0.1), length=10.0):
    return WindowResult(
        index=index,
        start_s=10.0 * index,
        length_s=length,
        samples=100,
        verdict=verdict,
        tau1=tau[0],
        tau2=tau[1],
        problem="" if verdict else "broken",
        votes=verdict is not None and length >= 5.0,
    )


def test_the_whole_verdict_is_the_one_most_windows_give():
    rows = [
        _row(0, "conduction", (0.02, 0.10)),
        _row(1, "none", (0.05, 0.50)),
        _row(2, "conduction", (0.03, 0.12)),
        _row(3, None),
        _row(4, "conduction", (0.025, 0.11)),
    ]
    whole = whole_verdict(rows)
    assert (whole.verdict, whole.agree, whole.voting) == ("conduction", 3, 4)
    assert whole.disagreeing == [1]
    assert whole.tau1 == pytest.approx(0.025) and whole.tau2_range == (0.10, 0.12)
    # A tie: a found effect goes before none; a short last window does not vote.
    tie = [_row(0, "none"), _row(1, "delay"), _row(2, "none", length=2.0)]
    assert whole_verdict(tie).verdict == "delay"
    assert whole_verdict([_row(0, "none"), _row(1, "none")]).verdict == "none"
    with pytest.raises(ValueError, match="no window could be diagnosed; window 1: broken"):
        whole_verdict([_row(0, None)])


@pytest.mark.slow
def test_cli_prints_the_window_table_and_writes_the_json(tmp_path, capsys):
    data, _ = _effect_csv(tmp_path, "delay", 20.0, seed=42)
    out, report = tmp_path / "w.json", tmp_path / "report"
    status = main(
        [
            "diagnose",
            str(data),
            "--window-s",
            "10",
            "--candidates",
            "delay",
            "--max-effects",
            "1",
            "--jobs",
            "2",
            "--json",
            str(out),
            "--report",
            str(report),
        ]
    )
    assert status == 0
    printed = capsys.readouterr().out
    assert "2 windows of 10 s (as asked)" in printed
    table = [line for line in printed.splitlines() if line.strip().startswith(("1 ", "2 "))]
    assert len(table) == 2 and all("delay" in line for line in table)
    assert "whole record: verdict delay (the verdict of 2 of 2 windows)" in printed
    document = json.loads(out.read_text())
    assert document["verdict"] == "delay" and document["voting"] == 2
    assert [row["start_s"] for row in document["windows"]] == [0.0, 10.0]
    assert document["tau1"]["min"] <= document["tau1"]["median"] <= document["tau1"]["max"]
    assert read_diagnosis_effects(out) == ("delay",)  # what --effects FILE.json takes
    html = (report / "index.html").read_text()
    assert "verdict: delay (the verdict of 2 of 2 windows)" in html
    assert html.count("<tr>") == 3 and "data:image/png;base64," in html


def test_cli_refuses_a_window_that_is_not_positive(tmp_path):
    time, tc1, tc2 = _sine_series(2_000, 0.002, seed=4)
    data = tmp_path / "d.csv"
    write_csv(data, time, tc1, tc2)
    with pytest.raises(SystemExit):
        main(["diagnose", str(data), "--window-s", "0"])
    assert main(["diagnose", str(data), "--window-s", "1", "--jobs", "0"]) == 1


@pytest.mark.slow
def test_the_progress_is_each_diagnosed_windows_not_the_readers_ahead(tmp_path, monkeypatch):
    """With --jobs the reader runs ahead of the rows: the bar follows the rows."""
    import tcomp_core.process.progress as progress

    shown: list[float] = []

    class Bar:
        def update(self, fraction, pairs):
            shown.append(fraction)

        def close(self):
            pass

    monkeypatch.setattr(progress, "progress_bar", lambda label: Bar())
    # 24 s: 4 windows of 6 s, in chunks of the file the reader's fraction follows.
    sim = simulate_effect(None, "multisine", tau1=PAPER[0], tau2=PAPER[1], duration=24.0, seed=7)
    tc1, tc2, count = sim.tc1, sim.tc2, sim.tc1.size
    stamps = 1_000_000_000 + np.round(sim.time * 1e9).astype(np.int64)
    writer = McapBagWriter(tmp_path / "chunked", compress=True, chunk_bytes=20_000)
    one, two = (writer.add_channel(t, TEMPERATURE_TYPE) for t in DEFAULT_TOPICS[:2])
    for start in range(0, count, 500):
        part = slice(start, start + 500)
        writer.write_rows(one, stamps[part], encode(stamps[part], tc1[part], 0.0, "tc"))
        writer.write_rows(two, stamps[part], encode(stamps[part], tc2[part], 0.0, "tc"))
    bag = writer.close()
    argv = ["diagnose", str(bag), "--window-s", "6", "--candidates", "delay", "--jobs", "2"]
    assert main(argv) == 0
    # Four rows, each at its window's place in the file (the reader had read it all by the
    # first row: four windows are handed to two workers before a row is waited for).
    assert len(shown) == 4 and shown == sorted(shown)
    assert shown[0] < 0.5 and shown[-1] > 0.9
