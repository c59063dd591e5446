"""``make demo``'s core job runs, and runs again over its own outputs (every output is --force)."""

import pytest

from tcomp_core.demo import main


@pytest.mark.slow
def test_demo_runs_twice_into_the_same_directory(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["--out", str(out)]) == 0
    first = sorted(p.name for p in out.iterdir())
    assert main(["--out", str(out)]) == 0  # raises SystemExit on a failing step
    assert sorted(p.name for p in out.iterdir()) == first
    assert (out / "diagnosis" / "index.html").is_file()
    assert not [p for p in out.rglob(".*partial*")]
