"""``make demo``'s core job runs, and runs again over its own outputs (every output is --force)."""

import re

import pytest

from tcomp_core.demo import main


@pytest.mark.slow
def test_demo_runs_twice_into_the_same_directory(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["--out", str(out)]) == 0
    printed = capsys.readouterr().out
    # The bags with a hidden effect: compensated, the gas error against the reference falls.
    falls = re.findall(r"read half a sample on: ([\d.]+) % first order -> ([\d.]+) %", printed)
    assert len(falls) == 2, printed
    assert all(float(after) < 0.5 * float(before) for before, after in falls), falls
    assert "gas published with first-order+conduction" in printed
    first = sorted(p.name for p in out.iterdir())
    assert main(["--out", str(out)]) == 0  # raises SystemExit on a failing step
    assert sorted(p.name for p in out.iterdir()) == first
    assert (out / "diagnosis" / "index.html").is_file()
    assert not [p for p in out.rglob(".*partial*")]
