"""The host package's shape: no import cycle, no hand-written file over 600 lines.

The import graph is read from the source with `ast` (nothing is imported): every `import` and
`from ... import` anywhere in a module counts, at the top, inside a function (a lazy import still
ties the two modules together) or under `if TYPE_CHECKING:`. Relative imports are resolved against
the importing module's package. `from pkg import name` is an edge to the module pkg.name where that
module exists, else to pkg. (An import by name at run time, importlib.import_module as
planning/__init__.py's lazy names do, is not seen: those stay inside their package.)

Two graphs are checked for cycles:
  modules   rovernav.sim.runner -> rovernav.runlog.writer, ...
  units     each module folded into its unit below rovernav: a subpackage (rovernav.sim) or a
            top-level module (rovernav.config); an edge between two units is an import from one
            into the other. A cycle here (sim -> runlog -> sim) is two parts of the program that
            each need the other, though no single module imports itself round the loop.
            A package's cli.py (rovernav.sim.cli) is a unit of its own: a command's front end,
            above every package as rovernav/cli.py is.

A generated file (its first line a comment saying "GENERATED", as link/messages_gen.py's) may be
longer than 600 lines.

There is no allowlist: an import that closes a cycle, or a hand-written file over 600 lines,
fails the test until it is moved below what it serves, or split.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

HOST = Path(__file__).resolve().parents[1] / "host"
ROOT = "rovernav"
MAX_LINES = 600


def module_name(path: Path) -> str:
    parts = list(path.relative_to(HOST).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def modules() -> dict[str, Path]:
    return {module_name(p): p for p in sorted((HOST / ROOT).rglob("*.py"))}


def _package_of(name: str, path: Path) -> str:
    """The package a relative import in this module is resolved against."""
    return name if path.name == "__init__.py" else name.rpartition(".")[0]


def _known(name: str, known: dict[str, Path]) -> str | None:
    """The module `name` names, or its nearest enclosing module that exists (None outside the package)."""
    while name:
        if name in known:
            return name
        name = name.rpartition(".")[0]
    return None


def imports_of(name: str, path: Path, known: dict[str, Path]) -> set[str]:
    """The package's modules this module imports."""
    tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                target = _known(alias.name, known)
                if target:
                    found.add(target)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = _package_of(name, path)
                for _ in range(node.level - 1):
                    base = base.rpartition(".")[0]
                stem = f"{base}.{node.module}" if node.module else base
            else:
                stem = node.module or ""
            if not (stem == ROOT or stem.startswith(ROOT + ".")):
                continue
            for alias in node.names:
                full = f"{stem}.{alias.name}"
                target = full if full in known else _known(stem, known)
                if target:
                    found.add(target)
    found.discard(name)
    return found


def module_graph() -> dict[str, set[str]]:
    known = modules()
    return {name: imports_of(name, path, known) for name, path in known.items()}


def unit_of(module: str) -> str:
    """rovernav.sim.runner -> rovernav.sim; rovernav.config -> rovernav.config; rovernav -> rovernav.
    A package's cli.py (rovernav.sim.cli) is a unit of its own: a command's front end, which the
    `rovernav` command (rovernav.cli) dispatches to, sits above every package as rovernav.cli does."""
    parts = module.split(".")
    if len(parts) == 3 and parts[-1] == "cli":
        return module
    return ".".join(parts[:2])


def unit_graph(graph: dict[str, set[str]]) -> dict[str, set[str]]:
    units: dict[str, set[str]] = {}
    for src, targets in graph.items():
        edges = units.setdefault(unit_of(src), set())
        edges.update(unit_of(t) for t in targets if unit_of(t) != unit_of(src))
    return units


def cycles(graph: dict[str, set[str]]) -> list[frozenset[str]]:
    """The strongly connected components with more than one node (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[frozenset[str]] = []
    counter = 0
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph.get(root, ()))))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph.get(child, ())))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = set()
                while True:
                    top = stack.pop()
                    on_stack.discard(top)
                    component.add(top)
                    if top == node:
                        break
                if len(component) > 1:
                    found.append(frozenset(component))
    return found


def a_loop(graph: dict[str, set[str]], component: frozenset[str]) -> list[str]:
    """One closed path through a component, for the message: a -> b -> ... -> a."""
    start = min(component)
    paths = {start: [start]}
    queue = [start]
    while queue:  # breadth first: the shortest way back to start
        node = queue.pop(0)
        for child in sorted(graph.get(node, ())):
            if child == start:
                return paths[node] + [start]
            if child in component and child not in paths:
                paths[child] = paths[node] + [child]
                queue.append(child)
    raise AssertionError(f"no loop through {sorted(component)}")


def explain(graph: dict[str, set[str]], components: list[frozenset[str]]) -> str:
    return "\n".join(" -> ".join(a_loop(graph, c)) for c in components)


def check_cycles(graph: dict[str, set[str]]) -> None:
    found = cycles(graph)
    assert not found, "import cycle(s):\n" + explain(graph, found)


def test_no_module_cycle():
    check_cycles(module_graph())


def test_no_cycle_between_packages():
    check_cycles(unit_graph(module_graph()))


def generated(path: Path) -> bool:
    """A generated file says so in its first comment line ("# GENERATED by ...")."""
    with path.open(encoding="utf-8") as f:
        first = f.readline()
    return first.startswith("#") and "generated" in first.lower()


def long_files() -> dict[str, int]:
    out = {}
    for path in sorted((HOST / ROOT).rglob("*.py")):
        if generated(path):
            continue
        n = len(path.read_text(encoding="utf-8").splitlines())
        if n > MAX_LINES:
            out[path.relative_to(HOST).as_posix()] = n
    return out


def test_no_long_file():
    found = long_files()
    assert not found, f"files over {MAX_LINES} lines (split them): {found}"


# ---------------------------------------------------------------- the checks can fail


def test_cycle_finder_sees_a_cycle():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a", "d"}, "d": set(), "e": {"e"}}
    assert cycles(graph) == [frozenset({"a", "b", "c"})]
    assert a_loop(graph, frozenset({"a", "b", "c"})) == ["a", "b", "c", "a"]
    with pytest.raises(AssertionError, match="a -> b -> c -> a"):
        check_cycles(graph)
    check_cycles({**graph, "c": {"d"}})  # the loop broken: no cycle left


def test_units_fold_modules():
    # what the issue found: the simulator writes run logs, and the replay drew with the simulator's report
    graph = {
        "rovernav.sim.runner": {"rovernav.runlog.writer"},
        "rovernav.runlog.writer": set(),
        "rovernav.runlog.replay": {"rovernav.sim.report"},
        "rovernav.sim.report": set(),
    }
    assert cycles(graph) == []  # no module imports itself round a loop ...
    assert cycles(unit_graph(graph)) == [frozenset({"rovernav.sim", "rovernav.runlog"})]  # ... but the packages do
    assert [unit_of(m) for m in ("rovernav.sim.cli", "rovernav.evaluation.arenas.cli", "rovernav.cli", "rovernav")] == [
        "rovernav.sim.cli",
        "rovernav.evaluation",
        "rovernav.cli",
        "rovernav",
    ]


def test_relative_imports_resolve(tmp_path):
    known = {
        "rovernav": HOST / ROOT / "__init__.py",
        "rovernav.sim": HOST / ROOT / "sim" / "__init__.py",
        "rovernav.sim.a": tmp_path / "a.py",
        "rovernav.sim.b": tmp_path / "b.py",
        "rovernav.files": tmp_path / "files.py",
        "rovernav.runlog": tmp_path / "runlog.py",
    }
    (tmp_path / "a.py").write_text(
        "from . import b\nfrom ..files import write_atomic\nimport os\n"
        "def f():\n    from .. import runlog\n    from rovernav.sim.b import x\n"
    )
    assert imports_of("rovernav.sim.a", tmp_path / "a.py", known) == {
        "rovernav.sim.b",
        "rovernav.files",
        "rovernav.runlog",
    }
