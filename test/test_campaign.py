"""``tcomp campaign``: recordings found, processed and diagnosed on Dask, tabulated, reported."""

from __future__ import annotations

import json
import math
import os
import signal
import sys
from pathlib import Path

import numpy as np
import pytest

from tcomp_core.campaign import (
    CampaignOptions,
    ClusterSpec,
    ProbeRule,
    Recording,
    find_recordings,
    run_campaign,
    run_recording,
)
from tcomp_core.campaign.ledger import Ledger
from tcomp_core.campaign.report import (
    RecordingPoint,
    error_jumps,
    fouling_alarms,
    verdict_changes,
)
from tcomp_core.campaign.table import campaign_rows, read_table, write_table
from tcomp_core.cli import main
from tcomp_core.errors import DataError
from tcomp_core.io import write_bag

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))

import campaign_data


def _bag(path: Path, topics=("/tc1/temperature", "/tc2/temperature"), n=200, start_ns=0):
    time = np.arange(n) * 0.002
    rng = np.random.default_rng(5)
    series = {topic: 20.0 + rng.standard_normal(n) for topic in topics}
    return write_bag(path, time, series, frame_id="probe7", start_ns=start_ns)


def _csv(path: Path, n=200) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    rows = [f"{k * 0.002:.3f},{20 + k % 7},{20 + k % 5}" for k in range(n)]
    path.write_text("time,tc1,tc2\n" + "\n".join(rows) + "\n")
    return path


# -- finding the recordings ---------------------------------------------------------------------


def test_a_directory_is_walked_for_bags_mcap_and_csv_files_and_bags_are_not_entered(tmp_path):
    _bag(tmp_path / "cellA" / "probe1" / "day1")
    _csv(tmp_path / "cellA" / "probe2" / "day1.csv")
    (tmp_path / "cellA" / "probe2" / "notes.txt").write_text("not a recording")
    found = find_recordings([tmp_path])
    assert [r.name for r in found] == ["cellA__probe1__day1", "cellA__probe2__day1.csv"]
    # The bag's own .mcap file is part of the bag, not a second recording.
    assert all(not r.name.endswith(".mcap") for r in found)


def test_a_glob_finds_the_recordings_it_matches_and_a_glob_matching_nothing_is_an_error(tmp_path):
    _csv(tmp_path / "a" / "day1.csv")
    _csv(tmp_path / "b" / "day1.csv")
    _csv(tmp_path / "b" / "other.csv")
    found = find_recordings([str(tmp_path / "*" / "day1.csv")])
    assert [r.name for r in found] == ["a__day1.csv", "b__day1.csv"]
    with pytest.raises(DataError, match=r"matches no bag"):
        find_recordings([str(tmp_path / "*" / "nothing*.csv")])


def test_a_recording_reached_from_two_inputs_is_one_recording(tmp_path, monkeypatch):
    _csv(tmp_path / "cellA" / "probe2" / "day1.csv")
    _csv(tmp_path / "cellA" / "probe2" / "day2.csv")
    monkeypatch.chdir(tmp_path)
    found = find_recordings(
        [
            tmp_path / "cellA",
            "cellA/probe2/day1.csv",  # relative: the same file as the walk's
            str(tmp_path / "cellA" / "*" / "day*.csv"),
        ]
    )
    assert [r.name for r in found] == ["probe2__day1.csv", "probe2__day2.csv"]


def test_the_campaign_output_inside_an_input_is_not_walked(tmp_path, monkeypatch):
    _csv(tmp_path / "p" / "day1.csv")
    _csv(tmp_path / "out" / "recordings" / "p__day1.csv")
    found = find_recordings([tmp_path], exclude=tmp_path / "out")
    assert [r.name for r in found] == ["p__day1.csv"]
    monkeypatch.chdir(tmp_path)  # relative paths, as typed: `tcomp campaign . -o out`
    found = find_recordings(["."], exclude=Path("out").resolve())
    assert [r.name for r in found] == ["p__day1.csv"]


def test_the_probe_comes_from_a_directory_level_a_map_file_or_the_frame(tmp_path):
    recording = Recording(tmp_path / "cellA" / "probe3" / "day07.csv", "x")
    assert ProbeRule.parse("dir").probe(recording, None, "") == "probe3"
    assert ProbeRule.parse("dir:2").probe(recording, None, "") == "cellA"
    mapping = tmp_path / "probes.csv"
    mapping.write_text("# pattern,probe\n*/cellB/*,wrong\n*/probe3/*,P-0003\n")
    assert ProbeRule.parse(f"map:{mapping}").probe(recording, None, "") == "P-0003"
    assert ProbeRule.parse("frame").probe(recording, None, "probe7") == "probe7"
    with pytest.raises(DataError, match=r"day07\.csv: no frame_id"):
        ProbeRule.parse("frame").probe(recording, None, "")
    with pytest.raises(DataError, match=r"no pattern of the --probe map"):
        ProbeRule.parse(f"map:{mapping}").probe(
            Recording(tmp_path / "elsewhere.csv", "y"), None, ""
        )
    for bad in ("dir:0", "dir:x", "topics", "map:"):
        with pytest.raises(DataError, match="--probe"):
            ProbeRule.parse(bad)


def test_a_bag_holding_several_probes_is_one_recording_per_namespace(tmp_path):
    topics = [f"/probe{i}/tc{j}/temperature" for i in (1, 2) for j in (1, 2)]
    _bag(tmp_path / "cell" / "run1", topics=[*topics, "/probe3/tc1/temperature"])
    found = find_recordings([tmp_path], rule=ProbeRule.parse("topic"))
    # probe3 has no tc2: not a probe of this bag.
    assert [(r.name, r.probe) for r in found] == [
        ("cell__run1__probe1", "/probe1"),
        ("cell__run1__probe2", "/probe2"),
    ]
    assert found[0].topics == ("/probe1/tc1/temperature", "/probe1/tc2/temperature", None)
    rule = ProbeRule.parse("topic")
    assert (
        rule.probe(Recording(tmp_path / "x.mcap", "x"), "/cell9/tc1/temperature", "") == "/cell9"
    )
    with pytest.raises(DataError, match="no namespace"):
        rule.probe(Recording(tmp_path / "x.mcap", "x"), "/tc1/temperature", "")


# -- the ledger, the table, the report's rules --------------------------------------------------


def test_a_key_changes_with_the_bytes_and_the_options_and_the_digest_is_reused(tmp_path):
    recording = Recording(_csv(tmp_path / "in" / "a.csv"), "a.csv")
    ledger = Ledger(tmp_path / "out")
    first = ledger.key(recording, {"window_s": 60})
    assert ledger.key(recording, {"window_s": 60}) == first
    assert ledger.key(recording, {"window_s": 30}) != first
    ledger.save_digests()
    again = Ledger(tmp_path / "out")
    assert again.key(recording, {"window_s": 60}) == first
    text = recording.path.read_text().replace("20,", "21,", 1)
    recording.path.write_text(text)
    os.utime(recording.path, ns=(1, 1))  # a new modification time: hashed again
    assert again.key(recording, {"window_s": 60}) != first


def test_a_result_counts_as_finished_only_with_its_output(tmp_path):
    ledger = Ledger(tmp_path)
    output = tmp_path / "recordings" / "a.csv"
    ledger.entry_path("k1").write_text(json.dumps({"output": str(output)}))
    assert ledger.finished("k1") is None
    output.parent.mkdir()
    output.write_text("time\n")
    assert ledger.finished("k1") == {"output": str(output)}
    assert ledger.finished("missing") is None


def test_the_table_keeps_every_window_and_a_failed_recording_as_one_row(tmp_path):
    entries = [
        {
            "recording": "p__day1",
            "file": "in/p/day1",
            "probe": "p",
            "pairs": 10,
            "invalid": 1,
            "dropped": 2,
            "tau": [0.02, 0.1],
            "verdict": "none",
            "output": "out/p__day1",
            "windows": [
                {
                    "window": i,
                    "window_start_s": 1.7e9 + 60 * i,
                    "verdict": "none",
                    "tau1": 0.02,
                    "tau1_low": 0.019,
                    "tau1_high": 0.021,
                    "params": "{}",
                    "votes": True,
                }
                for i in range(2)
            ],
        },
        {"recording": "q__bad", "file": "in/q/bad", "error": "in/q/bad: not an MCAP file"},
    ]
    rows = campaign_rows(entries)
    parquet, csv = write_table(rows, tmp_path)
    table = read_table(parquet)
    # By probe (a failed recording's is not known: first), then start.
    assert [(r["recording"], r["window"]) for r in table] == [
        ("q__bad", -1),
        ("p__day1", 0),
        ("p__day1", 1),
    ]
    assert table[2]["window_start"].timestamp() == pytest.approx(1.7e9 + 60)
    assert table[1]["invalid"] == 1 and table[1]["dropped"] == 2
    assert table[0]["error"] == "in/q/bad: not an MCAP file"
    assert math.isnan(table[0]["tau1"])
    lines = csv.read_text().splitlines()
    assert len(lines) == 4 and lines[0].startswith('"probe","recording"')


def _point(name, start, tau1, tau2=0.1, base=0.3, verdict="none"):
    return RecordingPoint(name, start, tau1, tau2, base, base, verdict)


def test_fouling_jumps_and_verdict_changes_are_found_per_probe():
    series = {
        "A": [_point("a0", 0, 0.020), _point("a1", 1, 0.022), _point("a2", 2, 0.026)],
        "B": [
            _point("b0", 0, 0.020),
            _point("b1", 1, 0.021, base=0.4),
            _point("b2", 2, 0.020, base=5.0, verdict="conduction"),
        ],
    }
    alarms = fouling_alarms(series, threshold=0.2)
    assert [(a["probe"], a["tau"]) for a in alarms] == [("A", "tau1")]
    assert alarms[0]["change"] == pytest.approx(0.3)
    assert [(j["probe"], j["recording"]) for j in error_jumps(series)] == [("B", "b2")]
    assert verdict_changes(series) == [
        {"probe": "B", "recording": "b2", "before": "none", "after": "conduction"}
    ]


# -- one recording, and the whole campaign on a cluster -----------------------------------------


def test_a_recording_that_cannot_be_read_is_an_error_entry_and_is_not_kept(tmp_path):
    bad = tmp_path / "in" / "bad.csv"
    bad.parent.mkdir()
    bad.write_text("time,tc1,tc2\n0,1,x\n")
    entry_path = tmp_path / "ledger" / "k.json"
    entry = run_recording(
        Recording(bad, "bad.csv"),
        str(tmp_path / "out.csv"),
        str(entry_path),
        "k",
        CampaignOptions(),
    )
    assert "bad.csv" in entry["error"]
    assert not entry_path.exists()


@pytest.mark.slow
@pytest.mark.realtime  # a Dask cluster: tasks spread over workers as they free
def test_a_generated_campaign_on_two_workers_follows_the_truth_and_survives_a_killed_worker(
    tmp_path,
):
    from distributed import Client, LocalCluster

    # Three days: the fouling probe grows over them, the steady one conducts from day 1 on.
    truths = campaign_data.write_campaign(tmp_path / "in", days=3)
    options = CampaignOptions(window_s=math.inf)
    killed: list[str] = []
    with (
        LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
        ) as cluster,
        Client(cluster) as client,
    ):

        def kill_a_busy_worker(line: str) -> None:
            if killed or not line.startswith("[1/"):
                return
            busy = [worker for worker, keys in client.processing().items() if keys]
            if busy:
                pid = client.run(os.getpid, workers=busy[:1])[busy[0]]
                os.kill(pid, signal.SIGKILL)
                killed.append(busy[0])

        spec = ClusterSpec(scheduler=cluster.scheduler_address)
        result = run_campaign(
            [tmp_path / "in"], tmp_path / "out", options, spec, log=kill_a_busy_worker
        )
    assert killed, "no worker was busy to be killed"
    assert (result.recordings, result.processed, result.failed) == (6, 6, 0)
    rows = read_table(result.table)
    assert len(rows) == 6 and not any(r["error"] for r in rows)
    by_name = {(r["probe"], r["recording"].split("__")[-1]): r for r in rows}
    for truth in truths:
        row = by_name[(truth.probe, f"day{truth.day:02d}")]
        assert row["tau1"] == pytest.approx(truth.tau1, rel=0.05), (truth, row["tau1"])
        assert row["tau2"] == pytest.approx(truth.tau2, rel=0.05), (truth, row["tau2"])
        assert row["verdict"] == truth.effect, (truth, row["verdict"])
        assert Path(row["output"]).is_dir()
        assert row["window_length_s"] == pytest.approx(10.0)  # diagnosed whole: its length
    report = result.report.read_text()
    assert "fouling</td><td>tau1" in report and "steady</td><td>tau1" not in report
    assert "steady: steady__day01: none → conduction" in report
    # A rerun finds every result and does no work.
    again = run_campaign([tmp_path / "in"], tmp_path / "out", options, ClusterSpec(workers=1))
    assert (again.processed, again.reused) == (0, 6)
    assert json.dumps(read_table(again.table), default=str) == json.dumps(rows, default=str)


def test_the_cli_names_a_bad_probe_rule_and_inputs_without_recordings(tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    assert main(["campaign", str(tmp_path / "empty"), "-o", str(tmp_path / "out")]) == 1
    assert "holds no bag directory, .mcap or .csv file" in capsys.readouterr().err
    _csv(tmp_path / "in" / "a.csv")
    argv = ["campaign", str(tmp_path / "in"), "-o", str(tmp_path / "out"), "--probe", "dir:0"]
    assert main(argv) == 1
    assert "--probe dir:0" in capsys.readouterr().err


@pytest.mark.slow
@pytest.mark.realtime  # a Dask cluster: tasks spread over workers as they free
def test_the_windows_of_one_recording_are_diagnosed_across_the_workers_as_here(tmp_path):
    from distributed import Client, LocalCluster, get_task_stream

    bag = Path(__file__).resolve().parents[1] / "bags" / "ramp_500hz"
    recording = Recording(bag, "ramp_500hz")
    options = CampaignOptions(window_s=2.5)
    here = run_recording(
        recording, str(tmp_path / "here"), str(tmp_path / "here.json"), "k", options
    )
    with (
        LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
        ) as cluster,
        Client(cluster) as client,
        get_task_stream(client) as stream,
    ):
        future = client.submit(
            run_recording,
            recording,
            str(tmp_path / "there"),
            str(tmp_path / "there.json"),
            "k",
            options,
            pure=False,
        )
        there = future.result()
    windows = [t for t in stream.data if str(t["key"]).startswith("diagnose_window")]
    assert len(windows) == 4
    assert len({t["worker"] for t in windows}) == 2
    assert [w["verdict"] for w in there["windows"]] == [w["verdict"] for w in here["windows"]]
    for mine, theirs in zip(here["windows"], there["windows"], strict=True):
        assert theirs["tau1"] == pytest.approx(mine["tau1"], rel=1e-9)
    assert json.loads((tmp_path / "there.json").read_text())["verdict"] == here["verdict"]
