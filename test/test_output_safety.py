"""Every output option of every verb (issue 13, design.md convention 12).

For each: an existing output is refused without ``--force`` and replaced with it; an output that
is, contains or sits inside the input is refused even with ``--force`` and the input is left as
it was; a run that fails half way leaves nothing behind, under any name.
"""

import csv
import shutil

import numpy as np
import pytest

from tcomp_core.cli import main
from tcomp_core.io import write_bag, write_csv
from tcomp_core.simulate import simulate_pair

SLOW_VERBS = {"diagnose", "fit", "study"}

# (verb, arguments before the output, output option, output name, arguments after)
CASES = [
    ("simulate", ["--signal", "ramp", "--duration", "2"], "-o", "sim.csv", []),
    ("simulate", ["--signal", "ramp", "--duration", "2"], "-o", "sim_bag", []),
    ("reconstruct", ["{data}"], "-o", "gas.csv", []),
    ("reconstruct", ["{data}"], "-o", "gas_bag", []),
    ("reconstruct", ["{data}", "-o", "{tmp}/plain.csv"], "--png", "gas.png", []),
    ("process", ["{data}", "--no-diagnose"], "-o", "processed.csv", []),
    ("process", ["{data}", "--no-diagnose"], "-o", "processed_bag", []),
    ("track", ["{data}", "--memory-s", "0.5"], "-o", "tau.csv", []),
    ("sweep", ["{data}", "--bandwidths", "20", "50"], "--png", "sweep.png", []),
    ("diagnose", ["{data}"], "--json", "diag.json", []),
    ("diagnose", ["{data}"], "--report", "report_dir", []),
    ("fit", ["{data}", "--effects", "delay"], "--json", "fit.json", []),
    (
        "study",
        ["--runs", "2", "--noise-levels", "1", "--signals", "ramp", "--png", "{tmp}/s.png"],
        "--json",
        "study.json",
        [],
    ),
]


def case_id(case):
    return f"{case[0]}{case[2]}:{case[3]}"


def params():
    for case in CASES:
        marks = [pytest.mark.slow] if case[0] in SLOW_VERBS else []
        yield pytest.param(case, id=case_id(case), marks=marks)


@pytest.fixture
def data(tmp_path):
    pair = simulate_pair("ramp", noise_percent=1.0, duration=6.0, dt=0.002, seed=2)
    path = tmp_path / "in.csv"
    write_csv(path, pair.time, pair.tc1, pair.tc2)
    return path


def argv(case, data, tmp_path, output, force=False):
    verb, before, option, _, after = case
    fill = {"data": str(data), "tmp": str(tmp_path)}
    return [
        verb,
        *(item.format(**fill) for item in before),
        option,
        str(output),
        *after,
        *(["--force"] if force else []),
    ]


def snapshot(path):
    if path.is_dir():
        return {
            p.relative_to(path): p.read_bytes() for p in sorted(path.rglob("*")) if p.is_file()
        }
    return path.read_bytes()


def hidden_leftovers(directory):
    return [p.name for p in directory.rglob(".*partial*")]


@pytest.mark.slow
@pytest.mark.parametrize("case", list(params()))
def test_existing_output_needs_force_then_is_replaced(case, data, tmp_path, capsys):
    output = tmp_path / case[3]
    if output.suffix:
        output.write_text("precious")
    else:
        output.mkdir()
        (output / "metadata.yaml").write_text("precious")  # an output tcomp may replace
    before = snapshot(output)
    assert main(argv(case, data, tmp_path, output)) == 1
    error = capsys.readouterr().err
    assert f"{output} exists" in error and "--force" in error and "Traceback" not in error
    assert snapshot(output) == before
    assert main(argv(case, data, tmp_path, output, force=True)) == 0, capsys.readouterr().err
    assert snapshot(output) != before
    assert hidden_leftovers(tmp_path) == []


@pytest.mark.parametrize("case", [c for c in params() if "{data}" in c.values[0][1]])
@pytest.mark.parametrize("where", ["same", "inside"])
def test_output_overlapping_the_input_is_refused_even_with_force(
    case, data, tmp_path, capsys, where
):
    pair = simulate_pair("ramp", noise_percent=1.0, duration=6.0, dt=0.002, seed=2)
    bag = tmp_path / "recording"
    write_bag(bag, pair.time, {"/tc1/temperature": pair.tc1, "/tc2/temperature": pair.tc2})
    source = bag if where == "inside" else data
    output = bag / "recording.mcap" if where == "inside" else data
    before = {"bag": snapshot(bag), "csv": snapshot(data)}
    code = main(argv(case, source, tmp_path, output, force=True))
    error = capsys.readouterr().err
    assert code == 1 and "the output would overwrite or sit inside the input" in error, error
    assert {"bag": snapshot(bag), "csv": snapshot(data)} == before


def test_bag_file_as_input_and_its_directory_as_output_is_refused(tmp_path, capsys):
    pair = simulate_pair("ramp", noise_percent=1.0, duration=2.0, dt=0.002, seed=2)
    bag = tmp_path / "v2"
    write_bag(bag, pair.time, {"/tc1/temperature": pair.tc1, "/tc2/temperature": pair.tc2})
    before = snapshot(bag)
    assert main(["process", str(bag / "v2.mcap"), "-o", str(bag), "--force"]) == 1
    assert "sit inside the input" in capsys.readouterr().err
    assert snapshot(bag) == before


def test_two_outputs_on_one_path_are_refused(data, tmp_path, capsys):
    same = tmp_path / "same.csv"
    assert main(["simulate", "--signal", "ramp", "-o", str(same), "-o", str(same)]) == 1
    assert "named twice" in capsys.readouterr().err
    assert not same.exists()


@pytest.mark.slow
def test_a_run_failing_half_way_leaves_nothing_and_the_rerun_is_not_blocked(
    data, tmp_path, capsys, monkeypatch
):
    output = tmp_path / "gas.csv"
    real_writer = csv.writer

    class FailingWriter:
        def __init__(self, handle, **kwargs):
            self._writer = real_writer(handle, **kwargs)

        def writerow(self, row):
            self._writer.writerow(row)

        def writerows(self, rows):
            for index, row in enumerate(rows):
                if index == 100:
                    raise OSError(28, "No space left on device")
                self._writer.writerow(row)

    monkeypatch.setattr(csv, "writer", FailingWriter)
    assert main(["reconstruct", str(data), "-o", str(output)]) == 1
    error = capsys.readouterr().err
    assert f"{output}: cannot write: No space left on device" in error
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.csv"]  # nothing, under any name
    monkeypatch.setattr(csv, "writer", real_writer)
    assert main(["reconstruct", str(data), "-o", str(output)]) == 0
    rows = np.genfromtxt(output, delimiter=",", names=True)
    assert rows.size > 2000


def test_a_directory_tcomp_did_not_write_is_never_replaced(data, tmp_path, capsys):
    mine = tmp_path / "photos"
    mine.mkdir()
    (mine / "cat.jpg").write_bytes(b"\xff\xd8")
    assert main(["reconstruct", str(data), "-o", str(mine), "--force"]) == 1
    assert "not a rosbag2 bag" in capsys.readouterr().err
    assert (mine / "cat.jpg").read_bytes() == b"\xff\xd8"
    shutil.rmtree(mine)
