"""The package's layout rules, read from its source with ``ast`` (no import needed).

* the import graph between the package's modules has no cycle, counting every import
  (function-local ones included: a local import must not hide a cycle);
* ``hexapod_pin/core`` imports no robot package, no viewer and no command line;
* robots do not import each other, and nothing below ``cli`` imports ``cli``;
* every import between the package's parts (subpackages and top-level modules) is allowed
  by one table, :data:`LAYOUT` (part -> parts it may import, after the README's layout),
  or is one of the few module edges of :data:`EXCEPTIONS`;
* no private name (leading underscore) is imported from another module of the package;
* the library never prints;
* a bare ``import hexapod_pin`` stays light (the one check that runs an interpreter).
"""

from __future__ import annotations

import ast
import os
import subprocess
import sys
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


#: part of the package -> the parts it may import (its own modules are always allowed).
#: A part is a subpackage, a top-level module, ``hexapod_pin`` (the package's __init__) or
#: ``__main__``. Data flow one way: core -> robots and loaders -> the rest -> cli.
_ALL = {"errors", "core", "hexapod", "planar", "loaders", "planning", "calibration", "viz",
        "files", "motion", "precompile", "identification"}
LAYOUT: dict[str, set[str]] = {
    "errors": set(),
    "core": {"errors"},
    "hexapod": {"core", "errors"},
    "planar": {"core", "errors"},
    "loaders": {"core", "errors"},
    "planning": {"core", "errors"},
    "calibration": {"core", "hexapod", "errors"},
    "identification": {"core", "errors", "motion", "planning"},  # any robot, its API;
    # motion files and the feasibility check for excitation trajectories
    "viz": {"core", "errors"},
    "files": {"core", "hexapod", "errors"},             # geometry files (HexapodGeometry)
    "motion": {"core", "hexapod", "files", "errors"},   # motion files, the hexapod's circle
    "precompile": {"core", "hexapod", "planar", "planning", "errors"},  # compiles every kernel
    "hexapod_pin": _ALL,                                # the public names, no cli
    "cli": _ALL | {"hexapod_pin"},
    "__main__": {"cli"},
}
#: module -> module edges outside LAYOUT that the code has today (issue 26, item 7: to be
#: moved or accepted into the table); a new edge of the same kind fails the test.
EXCEPTIONS: set[tuple[str, str]] = {
    ("hexapod_pin.planning.feasibility", "hexapod_pin.motion"),          # reads motion files
    ("hexapod_pin.calibration.measurements", "hexapod_pin.files"),       # write_text_atomic
    ("hexapod_pin.calibration.plots", "hexapod_pin.viz.plotting"),       # figure helpers
    ("hexapod_pin.viz.meshcat_scene", "hexapod_pin.files"),              # write_text_atomic
    ("hexapod_pin.viz.workspace_plots", "hexapod_pin.hexapod.workspace"),  # WorkspaceMaps
    ("hexapod_pin.viz.planning_plots", "hexapod_pin.planning.trajectory"),  # TimedTrajectory
}


def part(module: str) -> str:
    """The part of the package a module belongs to (``hexapod_pin.core.pose`` -> ``core``)."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else parts[0]


def layout_violations(graph: dict[str, set[str]], layout: dict[str, set[str]],
                      exceptions: set[tuple[str, str]]) -> list[tuple[str, str]]:
    """The edges of the module import ``graph`` that ``layout`` forbids and ``exceptions``
    does not list; a module of a part missing from ``layout`` may import no other part."""
    return sorted((src, dst) for src, targets in graph.items() for dst in targets
                  if part(dst) != part(src) and part(dst) not in layout.get(part(src), set())
                  and (src, dst) not in exceptions)


def test_the_layout_table_names_every_part():
    assert {part(m) for m in MODULES} == set(LAYOUT)
    assert set().union(*LAYOUT.values()) <= set(LAYOUT)


@pytest.mark.parametrize("name", sorted(LAYOUT))
def test_imports_follow_the_layout_table(name):
    graph = {m: _edges(m) for m in MODULES if part(m) == name}
    bad = layout_violations(graph, LAYOUT, EXCEPTIONS)
    assert not bad, f"{name} may import only {sorted(LAYOUT[name])}: {bad}"


def test_every_exception_is_still_an_import():
    """An exception that the code no longer has is removed from the list, not kept."""
    stale = [(src, dst) for src, dst in sorted(EXCEPTIONS) if dst not in _edges(src)]
    assert not stale, f"no longer imported: {stale}"


def test_the_layout_check_finds_a_forbidden_edge():
    """A test that cannot fail is a defect: planted edges against a small table."""
    layout = {"core": {"errors"}, "errors": set(), "viz": {"core"}}
    graph = {"hexapod_pin.core.a": {"hexapod_pin.core.b", "hexapod_pin.errors"},
             "hexapod_pin.viz.v": {"hexapod_pin.core.a", "hexapod_pin.hexapod.h"},
             "hexapod_pin.errors": set()}
    assert layout_violations(graph, layout, set()) == [("hexapod_pin.viz.v",
                                                        "hexapod_pin.hexapod.h")]
    assert layout_violations(graph, layout, {("hexapod_pin.viz.v", "hexapod_pin.hexapod.h")}) == []
    graph["hexapod_pin.core.a"].add("hexapod_pin.viz.v")             # core reaching up
    graph["hexapod_pin.newpkg.m"] = {"hexapod_pin.core.a"}           # a part not in the table
    assert layout_violations(graph, layout, set()) == [
        ("hexapod_pin.core.a", "hexapod_pin.viz.v"),
        ("hexapod_pin.newpkg.m", "hexapod_pin.core.a"),
        ("hexapod_pin.viz.v", "hexapod_pin.hexapod.h")]


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


def test_a_bare_import_stays_light():
    """``import hexapod_pin`` and the hexapod's own routes load neither the optional parts
    (identification, calibration, planning, the command line, views) nor scipy.signal,
    matplotlib, meshcat or typer (a fresh interpreter; the bare import alone loads no
    module of the package: tests/test_startup.py)."""
    code = ("import sys, numpy as np, hexapod_pin; r = hexapod_pin.Hexapod.default(); "
            "r.inverse_dynamics(r.home_pose, np.zeros(6), np.zeros(6)); "
            "print(' '.join(sorted(m for m in sys.modules if "
            "m.split('.')[0] in ('hexapod_pin', 'scipy', 'matplotlib', 'meshcat', "
            "'typer'))))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True, cwd=PACKAGE.parent,
                          env={**os.environ, "PYTHONPATH": str(PACKAGE.parent)})
    loaded = set(done.stdout.split())
    assert "hexapod_pin.core" in loaded                 # the check can see modules
    for heavy in ("hexapod_pin.identification", "hexapod_pin.calibration",
                  "hexapod_pin.planning", "hexapod_pin.cli", "hexapod_pin.viz",
                  "scipy.signal", "matplotlib", "meshcat", "typer"):
        assert heavy not in loaded


def _type_checking_only(tree: ast.Module) -> set[str]:
    """Names a module imports only under ``if TYPE_CHECKING:``."""
    guarded, plain = set(), set()
    for node in tree.body:
        target = guarded if (isinstance(node, ast.If)
                             and "TYPE_CHECKING" in ast.unparse(node.test)) else plain
        for sub in ast.walk(node) if target is guarded else [node]:
            if isinstance(sub, (ast.Import, ast.ImportFrom)):
                target.update((a.asname or a.name).split(".")[0] for a in sub.names)
    return guarded - plain


@pytest.mark.parametrize("module", sorted(MODULES))
def test_names_imported_for_type_checkers_are_not_used_at_run_time(module):
    """The lazy imports (the package root, the command line) keep some names under
    ``TYPE_CHECKING``: a function body that uses one without importing it itself raises
    NameError at run time (annotations are strings here and may name them)."""
    tree = ast.parse(MODULES[module].read_text(encoding="utf-8"))
    only = _type_checking_only(tree)
    bad = []
    for fn in (n for n in ast.walk(tree) if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))):
        local = {(a.asname or a.name).split(".")[0] for stmt in fn.body for sub in ast.walk(stmt)
                 if isinstance(sub, (ast.Import, ast.ImportFrom)) for a in sub.names}
        bad += [f"{fn.name}:{sub.lineno} {sub.id}" for stmt in fn.body for sub in ast.walk(stmt)
                if isinstance(sub, ast.Name) and isinstance(sub.ctx, ast.Load)
                and sub.id in only and sub.id not in local]
    assert not bad, f"{module}: {bad}"
