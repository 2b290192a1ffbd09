"""The layout docs/developing.md describes, checked: no import cycles, only the
simulator (and the CLI) imports the simulator, modules stay small, kernels take
containers rather than dozens of arrays."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent.parent / "blastvox"
MAX_LINES = 700
MAX_PARAMETERS = 11  # typer commands (one parameter per option) excepted


def _modules() -> dict[str, Path]:
    out = {}
    for path in PACKAGE.rglob("*.py"):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = path
    return out


def _imports(path: Path, top_level_only: bool) -> set[str]:
    """blastvox modules ``path`` imports (module level, or anywhere)."""
    tree = ast.parse(path.read_text())
    nodes = tree.body if top_level_only else list(ast.walk(tree))
    found = set()
    for node in nodes:
        if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module \
                and node.module.startswith("blastvox"):
            found.add(node.module)
            found.update(f"{node.module}.{alias.name}" for alias in node.names)
        elif isinstance(node, ast.Import):
            found.update(a.name for a in node.names if a.name.startswith("blastvox"))
    return found


def test_no_import_cycles():
    modules = _modules()
    graph = {name: {m for m in _imports(path, True) if m in modules and m != name}
             for name, path in modules.items()}
    state: dict[str, int] = {}  # 1 on the path, 2 done

    def visit(name: str, path: list[str]) -> None:
        state[name] = 1
        for dep in sorted(graph[name]):
            if state.get(dep) == 1:
                raise AssertionError("import cycle: " + " -> ".join(
                    path[path.index(dep):] + [name, dep] if dep in path else [name, dep]))
            if dep not in state:
                visit(dep, path + [name])
        state[name] = 2

    for name in sorted(graph):
        if name not in state:
            visit(name, [])


def test_the_cli_has_no_import_cycle_even_through_lazy_imports():
    """The entry point imports the app lazily (signal handlers first), so a command that
    imported the entry point back made a cycle that only laziness hid (issue 33): the
    interrupt state lives in blastvox.cli.interrupt, which both import."""
    modules = {name: path for name, path in _modules().items()
               if name.startswith("blastvox.cli.")}
    graph = {name: {m for m in _imports(path, False) if m in modules and m != name}
             for name, path in modules.items()}

    def reaches(start: str, goal: str, seen: set[str]) -> bool:
        for dep in graph[start]:
            if dep == goal or (dep not in seen and reaches(dep, goal, seen | {dep})):
                return True
        return False

    cyclic = sorted(name for name in graph if reaches(name, name, {name}))
    assert not cyclic, cyclic


def test_only_the_simulator_and_the_cli_import_the_simulator():
    for name, path in _modules().items():
        if name.startswith(("blastvox.simulate", "blastvox.cli")) or name == "blastvox.shot":
            continue
        users = {m for m in _imports(path, False) if m.startswith("blastvox.simulate")}
        assert not users, f"{name} imports {sorted(users)}: read the SimCache contract instead"


def test_no_module_is_over_700_lines():
    long = {name: n for name, path in _modules().items()
            if (n := len(path.read_text().splitlines())) > MAX_LINES}
    assert not long


def test_no_function_takes_more_than_eleven_parameters():
    wide = []
    for name, path in _modules().items():
        if name.startswith("blastvox.cli"):
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                args = node.args
                count = len(args.posonlyargs) + len(args.args) + len(args.kwonlyargs)
                if count > MAX_PARAMETERS:
                    wide.append(f"{name}.{node.name} ({count})")
    assert not wide
