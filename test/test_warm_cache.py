"""``python -m tcomp_core.warm_cache`` runs every compiled loop, so that it lands in numba's cache.

``make test`` runs it once before the test processes start (each would otherwise compile every
loop it needs itself on a fresh clone). A loop it does not reach is compiled again by every
process that needs it: a new ``compile_loops`` call anywhere in the package must be reached too.
"""

import ast
import json
import subprocess
import sys
from pathlib import Path

import tcomp_core

#: Run in a fresh process: the test's own may have run (or loaded) any loop already.
CHILD = """
import json
from tcomp_core.compiled import COMPILED
from tcomp_core.warm_cache import main
main()
run = sorted({loop.py_func.__name__ for loop in COMPILED if loop.signatures})
print(json.dumps(run))
"""


def _declared_loops() -> set[str]:
    """The functions every ``compile_loops(...)`` call in the package hands to numba."""
    names: set[str] = set()
    for path in Path(tcomp_core.__file__).parent.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Call) and getattr(node.func, "id", None) == "compile_loops":
                names |= {arg.id for arg in node.args if isinstance(arg, ast.Name)}
    return names


def test_the_warm_up_runs_every_loop_the_package_compiles():
    declared = _declared_loops()
    assert len(declared) >= 9, declared  # the nine loops of the recurrences, fusion and ml-eiv
    done = subprocess.run(
        [sys.executable, "-c", CHILD], capture_output=True, text=True, check=True, timeout=300
    )
    said, found = done.stdout.strip().splitlines()[-2:]
    assert said.startswith("numba loops compiled or loaded from their cache in "), said
    run = set(json.loads(found))
    assert run == declared, f"not run by warm_cache: {sorted(declared - run)}"
