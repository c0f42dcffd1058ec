"""The package's layout rules, read from its source with ``ast`` (no import needed).

* the import graph between the package's modules has no cycle, counting every import
  (function-local ones included: a local import must not hide a cycle);
* ``hexapod_pin/core`` imports no robot package, no viewer and no command line;
* robots do not import each other, and nothing below ``cli`` imports ``cli``;
* no private name (leading underscore) is imported from another module of the package;
* the library never prints.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "hexapod_pin"
ROBOTS = ("hexapod_pin.hexapod", "hexapod_pin.planar")
ABOVE_CORE = ROBOTS + ("hexapod_pin.loaders", "hexapod_pin.viz", "hexapod_pin.cli")


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


MODULES = _modules()


def _resolve(module: str, is_package: bool, level: int, target: str | None) -> str:
    base = module.split(".")
    if not is_package:
        base = base[:-1]
    if level > 1:
        base = base[:len(base) - (level - 1)]
    return ".".join(base + ([target] if target else []))


def _imports(module: str) -> list[tuple[str, list[str], int]]:
    """(imported module, imported names, line) of every import in ``module``."""
    path = MODULES[module]
    tree = ast.parse(path.read_text(encoding="utf-8"))
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(alias.name, [], node.lineno) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            target = node.module
            if node.level:
                target = _resolve(module, path.name == "__init__.py", node.level, node.module)
            out.append((target, [a.name for a in node.names], node.lineno))
    return out


def _edges(module: str) -> set[str]:
    """Modules of the package that ``module`` imports (``from pkg import sub`` -> pkg.sub)."""
    out = set()
    for target, names, _ in _imports(module):
        if not target.startswith("hexapod_pin"):
            continue
        subs = [f"{target}.{n}" for n in names if f"{target}.{n}" in MODULES]
        out.update(subs or [target])
        if subs and len(subs) < len(names):
            out.add(target)
    out.discard(module)
    return {m for m in out if m in MODULES}


def test_the_layout_exists():
    for package in ("core", "loaders", "hexapod", "planar", "viz", "cli"):
        assert (PACKAGE / package / "__init__.py").is_file(), package
    assert (PACKAGE / "errors.py").is_file()


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """A cycle of the directed graph (as a path whose last node repeats one), or None."""
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return stack[stack.index(nxt):] + [nxt]
            if nxt not in state and (found := visit(nxt)):
                return found
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state and (found := visit(node)):
            return found
    return None


def test_no_import_cycle():
    graph = {m: _edges(m) for m in MODULES}
    # a package's __init__ re-exporting its submodules is not a cycle of the code:
    # drop the edges from a submodule to its own parent package's __init__
    for m, targets in graph.items():
        graph[m] = {t for t in targets if not m.startswith(t + ".")}
    cycle = find_cycle(graph)
    assert cycle is None, "import cycle: " + " -> ".join(cycle or [])


def test_the_cycle_finder_finds_cycles():
    """A test that cannot fail is a defect: the finder sees a planted cycle."""
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": set()}) is None


@pytest.mark.parametrize("module", sorted(m for m in MODULES if m.startswith("hexapod_pin.core")))
def test_core_imports_no_robot_viewer_or_cli(module):
    bad = [(t, line) for t, _, line in _imports(module)
           if any(t == p or t.startswith(p + ".") for p in ABOVE_CORE)]
    assert not bad, f"{module} imports {bad}"


@pytest.mark.parametrize("module", sorted(m for m in MODULES if m.startswith(ROBOTS)))
def test_robots_do_not_import_each_other_or_the_cli(module):
    own = next(p for p in ROBOTS if module.startswith(p))
    others = [p for p in ROBOTS if p != own] + ["hexapod_pin.cli", "hexapod_pin.viz"]
    bad = [(t, line) for t, _, line in _imports(module)
           if any(t == p or t.startswith(p + ".") for p in others)]
    assert not bad, f"{module} imports {bad}"


@pytest.mark.parametrize("module", sorted(MODULES))
def test_no_private_name_crosses_a_module(module):
    bad = [(t, n, line) for t, names, line in _imports(module) if t.startswith("hexapod_pin")
           for n in names if n.startswith("_") and not n.startswith("__")]
    assert not bad, f"{module} imports private names {bad}"


@pytest.mark.parametrize("module", sorted(MODULES))
def test_no_private_attribute_of_another_module(module):
    """``workspace._estimate`` through ``from . import workspace`` is as private as importing
    ``_estimate`` itself."""
    modules = {}
    for target, names, _ in _imports(module):
        for name in names:
            if f"{target}.{name}" in MODULES:
                modules[name] = f"{target}.{name}"
    tree = ast.parse(MODULES[module].read_text(encoding="utf-8"))
    aliases = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            for alias in node.names:
                if alias.name in modules:
                    aliases[alias.asname or alias.name] = modules[alias.name]
    bad = [(aliases[node.value.id], node.attr, node.lineno) for node in ast.walk(tree)
           if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
           and node.value.id in aliases and node.attr.startswith("_")
           and not node.attr.startswith("__")]
    assert not bad, f"{module} uses private names of other modules {bad}"


@pytest.mark.parametrize("module", sorted(m for m in MODULES if not m.startswith("hexapod_pin.cli")))
def test_the_library_never_prints(module):
    tree = ast.parse(MODULES[module].read_text(encoding="utf-8"))
    calls = [node.lineno for node in ast.walk(tree) if isinstance(node, ast.Call)
             and isinstance(node.func, ast.Name) and node.func.id == "print"]
    assert not calls, f"{module} calls print at lines {calls}"
