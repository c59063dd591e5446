"""``make demo``'s core job runs, and runs again over a previous run's outputs (every output
is --force): its output directory is filled beforehand with stale files of every name it
writes, so one run checks both (running it twice took 75 s of the suite)."""

import re

import pytest

from tcomp_core.demo import main

#: Everything the demo writes into its output directory: files, and directories (bags, report).
DEMO_FILES = (
    "compensated.csv",
    "compensated.png",
    "diagnosis.json",
    "radiation_compensated.csv",
    "ramp.csv",
    "reconstructed.csv",
    "reconstructed.png",
    "sweep.png",
)
#: Directories, each with the file that marks its kind (--force replaces no other directory).
DEMO_DIRECTORIES = {
    "compensated_bag": "metadata.yaml",
    "diagnosis": "index.html",
    "ramp_bag": "metadata.yaml",
    "reconstructed_postfiltered_bag": "metadata.yaml",
}
STALE = b"stale output of an earlier demo run\n"


@pytest.mark.slow
def test_demo_runs_over_a_previous_runs_outputs(tmp_path, capsys):
    out = tmp_path / "demo"
    out.mkdir()
    for name in DEMO_FILES:
        (out / name).write_bytes(STALE)
    for name, marker in DEMO_DIRECTORIES.items():
        (out / name).mkdir()
        (out / name / marker).write_bytes(STALE)
        (out / name / "stale_0.mcap").write_bytes(STALE)

    assert main(["--out", str(out)]) == 0  # raises SystemExit on a failing step
    captured = capsys.readouterr()
    printed = captured.out
    # The bags with a hidden effect: compensated, the gas error against the reference falls.
    falls = re.findall(r"read half a sample on: ([\d.]+) % first order -> ([\d.]+) %", printed)
    assert len(falls) == 2, printed
    assert all(float(after) < 0.5 * float(before) for before, after in falls), falls
    # The conduction bag with the effects its saved diagnosis found, not diagnosed again.
    assert printed.count("diagnosis.json: conduction (the final model of that diagnosis)") == 2
    assert "gas published with first-order+conduction" in printed
    # Its first-order windows see the wires 38 % apart in gain: no advice to do what is done.
    assert "published compensated with the output model of --effects" in captured.err
    assert "--effects auto compensates it" not in captured.err

    # Every output replaced, none left over from before, nothing written beside them.
    assert sorted(p.name for p in out.iterdir()) == sorted((*DEMO_FILES, *DEMO_DIRECTORIES))
    stale = [p for p in out.rglob("*") if p.is_file() and p.read_bytes() == STALE]
    assert not stale, stale
    assert all(any((out / name).iterdir()) for name in DEMO_DIRECTORIES)
    assert (out / "diagnosis" / "index.html").is_file()
    assert not [p for p in out.rglob(".*partial*")]
