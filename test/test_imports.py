"""Import structure: no import cycle in the project, and a command line that starts fast.

The cycle check reads the source with :mod:`ast` instead of importing it, so it sees every
import, at module level and inside functions, whether or not it would run.
"""

from __future__ import annotations

import ast
import subprocess
import sys
import textwrap
from collections.abc import Iterator, Mapping
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("tcomp_core", "tcomp_ros")
#: Libraries that take most of a second to import; ``tcomp --help`` must not need them.
HEAVY = ("numpy", "scipy", "matplotlib", "rosbags", "mcap")

Graph = dict[str, set[str]]


def project_modules(root: Path, packages: tuple[str, ...]) -> dict[str, Path]:
    """Every module of ``packages`` under ``root`` by dotted name (a package by its own name)."""
    modules: dict[str, Path] = {}
    for package in packages:
        for path in sorted((root / package).rglob("*.py")):
            parts = path.relative_to(root).with_suffix("").parts
            if parts[-1] == "__init__":
                parts = parts[:-1]
            modules[".".join(parts)] = path
    return modules


def _imported(node: ast.AST, module: str, is_package: bool) -> Iterator[str]:
    """The dotted names one ``import`` / ``from ... import`` statement can load."""
    if isinstance(node, ast.Import):
        for alias in node.names:
            yield alias.name
    elif isinstance(node, ast.ImportFrom):
        if node.level:
            package = module if is_package else module.rpartition(".")[0]
            for _ in range(node.level - 1):
                package = package.rpartition(".")[0]
            base = ".".join(part for part in (package, node.module) if part)
        else:
            base = node.module or ""
        for alias in node.names:
            yield f"{base}.{alias.name}"
            yield base


def import_graph(root: Path, packages: tuple[str, ...]) -> Graph:
    """Edges from each project module to the project modules it imports.

    ``import a.b`` is an edge to ``a.b``; ``from a import b`` an edge to ``a.b`` when that is a
    module, else to ``a``. Imports anywhere in the file count (module level, functions,
    ``if TYPE_CHECKING:`` blocks); a package is the node of its ``__init__``.
    """
    modules = project_modules(root, packages)
    graph: Graph = {name: set() for name in modules}
    for name, path in modules.items():
        tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
        is_package = path.name == "__init__.py"
        for node in ast.walk(tree):
            if not isinstance(node, ast.Import | ast.ImportFrom):
                continue
            candidates = list(_imported(node, name, is_package))
            if isinstance(node, ast.ImportFrom):
                # Pairs (base.name, base): the first that is a project module wins.
                pairs = zip(candidates[::2], candidates[1::2], strict=True)
                targets = [full if full in modules else base for full, base in pairs]
            else:
                targets = candidates
            for target in targets:
                # ``import a.b.c`` where only ``a.b`` is ours: the edge goes to ``a.b``.
                while target and target not in modules:
                    target = target.rpartition(".")[0]
                if target and target != name:
                    graph[name].add(target)
    return graph


def find_cycles(graph: Mapping[str, set[str]]) -> list[list[str]]:
    """One shortest cycle through each strongly connected group of modules that has one.

    Returns
    -------
    list of list of str
        Each cycle as the modules on it, the first repeated at the end, sorted.
    """
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    groups: list[set[str]] = []

    def connect(node: str) -> None:  # Tarjan's algorithm
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for successor in sorted(graph.get(node, ())):
            if successor not in index:
                connect(successor)
                low[node] = min(low[node], low[successor])
            elif successor in on_stack:
                low[node] = min(low[node], index[successor])
        if low[node] == index[node]:
            group = set()
            while True:
                member = stack.pop()
                on_stack.discard(member)
                group.add(member)
                if member == node:
                    break
            if len(group) > 1 or node in graph.get(node, ()):
                groups.append(group)

    for node in sorted(graph):
        if node not in index:
            connect(node)
    return sorted(_shortest_cycle(graph, group) for group in groups)


def _shortest_cycle(graph: Mapping[str, set[str]], group: set[str]) -> list[str]:
    """Breadth-first from the group's first member back to itself, inside the group."""
    start = min(group)
    previous: dict[str, str] = {}
    frontier = [start]
    while frontier:
        following = []
        for node in frontier:
            for successor in sorted(graph.get(node, set()) & group):
                if successor == start:
                    path = [node]
                    while path[-1] != start:
                        path.append(previous[path[-1]])
                    return [*reversed(path), start]
                if successor not in previous:
                    previous[successor] = node
                    following.append(successor)
        frontier = following
    raise AssertionError(f"{sorted(group)} is strongly connected but has no cycle")


@pytest.mark.slow
def test_the_project_has_no_import_cycle():
    graph = import_graph(ROOT, PACKAGES)
    assert "tcomp_core.errors" in graph and "tcomp_ros" in graph
    cycles = find_cycles(graph)
    assert not cycles, "import cycles:\n" + "\n".join(" -> ".join(c) for c in cycles)


def _write_package(root: Path, files: dict[str, str]) -> None:
    for relative, text in files.items():
        path = root / relative
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(textwrap.dedent(text))


def test_cycles_through_relative_function_level_and_from_imports_are_found(tmp_path):
    _write_package(
        tmp_path,
        {
            "pkg/__init__.py": "from .sub import thing\n",
            # from-import of a package attribute that is a module: edge to pkg.sub.leaf
            "pkg/sub/__init__.py": "from . import leaf\nthing = 1\n",
            "pkg/sub/leaf.py": """
                def late():
                    from ..other import value  # inside a function, two levels up
                    return value
            """,
            "pkg/other.py": "import pkg.sub.leaf\nvalue = 2\n",
            # from-import of a name that is not a module: edge to the package itself
            "pkg/user.py": "from pkg import thing\n",
            "free/__init__.py": "",
            "free/a.py": "from free import b\n",
            "free/b.py": "import os\n",
        },
    )
    graph = import_graph(tmp_path, ("pkg", "free"))
    assert graph["pkg.sub"] == {"pkg.sub.leaf"}
    assert graph["pkg.sub.leaf"] == {"pkg.other"}
    assert graph["pkg.user"] == {"pkg"}
    assert graph["free.a"] == {"free.b"}
    assert find_cycles(graph) == [["pkg.other", "pkg.sub.leaf", "pkg.other"]]


def test_find_cycles_lists_each_cycle_once():
    graph = {"a": {"b"}, "b": {"a", "c"}, "c": set(), "x": {"y"}, "y": {"z"}, "z": {"x"}}
    assert find_cycles(graph) == [["a", "b", "a"], ["x", "y", "z", "x"]]
    assert find_cycles({"a": {"b"}, "b": {"c"}, "c": set()}) == []


def test_every_option_string_is_defined_once_in_choices():
    """The numerical modules import the option tuples and their Literal types, never redefine."""
    from tcomp_core import choices

    names = set(choices.__all__)
    redefined = []
    for module, path in project_modules(ROOT, PACKAGES).items():
        if module == "tcomp_core.choices":
            continue
        for node in ast.parse(path.read_text(encoding="utf-8")).body:
            targets = (
                node.targets if isinstance(node, ast.Assign) else [getattr(node, "target", None)]
            )
            for target in targets:
                if isinstance(target, ast.Name) and target.id in names:
                    redefined.append(f"{path.relative_to(ROOT)}:{node.lineno} {target.id}")
    assert not redefined, "defined outside tcomp_core/choices.py: " + ", ".join(redefined)


def _loaded_after(code: str) -> set[str]:
    """Top-level modules loaded by a fresh interpreter after running ``code``."""
    probe = f"{code}\nimport sys\nprint('MODULES', *{{mod.split('.')[0] for mod in sys.modules}})"
    completed = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, check=True, cwd=ROOT
    )
    last = completed.stdout.splitlines()[-1].split()
    assert last[0] == "MODULES", f"{code!r} did not run to its end: {completed.stdout[-300:]}"
    return set(last[1:])


@pytest.mark.slow
def test_lazy_names_load_on_first_use_and_shadow_their_submodule():
    assert not {"numpy", "scipy"} & _loaded_after("import tcomp_core\ntcomp_core.METHODS")
    # The submodule tcomp_core.reconstruct loaded first must not hide the function.
    code = """
import sys
import tcomp_core.reconstruct
import tcomp_core
from tcomp_core import reconstruct
module = sys.modules["tcomp_core.reconstruct"]
assert reconstruct is tcomp_core.reconstruct is module.reconstruct, reconstruct
assert tcomp_core.Reconstruction is module.Reconstruction
assert tcomp_core.estimate is sys.modules["tcomp_core.estimators"].estimate
assert set(tcomp_core.__all__) <= set(dir(tcomp_core))
"""
    assert "numpy" in _loaded_after(code)
    import tcomp_core

    with pytest.raises(AttributeError, match="has no attribute 'nothing'"):
        tcomp_core.nothing  # noqa: B018


@pytest.mark.parametrize(
    "code",
    [
        "import tcomp_core.cli",
        "from tcomp_core.cli import build_parser\nbuild_parser().format_help()",
        "import contextlib, io\n"
        "from tcomp_core.cli import VERBS, main\n"
        "for verb in VERBS:\n"
        "    with contextlib.suppress(SystemExit), contextlib.redirect_stdout(io.StringIO()):\n"
        "        main([verb.__name__.rpartition('.')[2], '--help'])",
        "import contextlib, io\n"
        "from tcomp_core.cli import main\n"
        "with contextlib.suppress(SystemExit), contextlib.redirect_stdout(io.StringIO()):\n"
        "    main(['--version'])",
    ],
    ids=["import", "help", "every-verb-help", "version"],
)
def test_building_the_parser_loads_no_heavy_library(code):
    heavy = _loaded_after(code) & set(HEAVY)
    assert not heavy, f"{code!r} loaded {sorted(heavy)}"


def test_the_replay_node_loads_no_scipy_until_it_simulates():
    # A bag replay (or a refused parameter) needs no signal processing: scipy is most of a
    # second of the node's start-up; the simulated source imports it when it runs.
    assert "scipy" not in _loaded_after("import tcomp_ros.replay")
    assert "scipy" in _loaded_after(
        "import tcomp_ros.replay\nfrom tcomp_core.simulate import simulate_pair"
    )
