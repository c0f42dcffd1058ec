"""Start-up cost: what ``import hexapod_pin`` and ``hexapod-pin --help`` load.

Each runs in a fresh interpreter and prints ``sorted(sys.modules)``; the tests assert
modules, not times (the times are in benchmarks/README.md). The heavy modules, measured
with ``python -X importtime`` (2026-12-05): Pinocchio (0.3 s alone), numba (0.3 s), SciPy
(0.4 s through ``scipy.optimize`` / ``scipy.linalg``), ProxSuite, and the optional viewer,
plotting, MuJoCo and Dask extras.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: modules neither a bare import nor ``--help`` may load (top-level names)
HEAVY = ("pinocchio", "numba", "scipy", "proxsuite", "meshcat", "matplotlib", "mujoco",
         "dask", "pandas", "yourdfpy", "trimesh")


def _loaded(code: str) -> list[str]:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])])}
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env=env, cwd=ROOT, timeout=120, check=False)
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


def _heavy(modules: list[str]) -> list[str]:
    return sorted({m.split(".")[0] for m in modules} & set(HEAVY))


def test_a_bare_import_loads_no_heavy_module_and_no_submodule():
    modules = _loaded("import hexapod_pin, sys, json; print(json.dumps(sorted(sys.modules)))")
    assert _heavy(modules) == []
    assert [m for m in modules if m.startswith("hexapod_pin")] == ["hexapod_pin"]


def test_help_loads_only_the_command_line():
    code = ("import sys, json\n"
            "from hexapod_pin.cli import app\n"
            "try:\n    app(['--help'], prog_name='hexapod-pin')\n"
            "except SystemExit as exc:\n    assert exc.code == 0, exc.code\n"
            "print(json.dumps(sorted(sys.modules)))")
    modules = _loaded(code)
    assert _heavy(modules) == []
    ours = {m for m in modules if m.startswith("hexapod_pin")}
    assert ours <= {"hexapod_pin", "hexapod_pin.errors"} | {
        m for m in ours if m.startswith("hexapod_pin.cli")}, sorted(ours)


def test_the_check_sees_a_heavy_module():
    """The tests above can fail: a heavy import is reported."""
    assert _heavy(_loaded("import sys, json, pinocchio; print(json.dumps(sorted(sys.modules)))")
                  ) == ["pinocchio"]


@pytest.mark.parametrize("name", ["Hexapod", "simulate", "robots", "InputError", "warmup"])
def test_every_public_name_loads_on_first_use(name):
    import hexapod_pin
    assert name in dir(hexapod_pin)
    assert getattr(hexapod_pin, name) is not None


def test_all_public_names_resolve_and_unknown_names_raise():
    import hexapod_pin
    for name in hexapod_pin.__all__:
        getattr(hexapod_pin, name)
    assert set(hexapod_pin.__all__) <= set(dir(hexapod_pin))
    with pytest.raises(AttributeError, match="no_such_name"):
        hexapod_pin.no_such_name  # noqa: B018


def test_the_compiled_simulator_registers_on_first_use():
    """``simulate(hexapod, backend="compiled")`` works when only the robot module was
    imported (the package no longer imports the backend eagerly)."""
    code = ("import sys, json\n"
            "from hexapod_pin.hexapod.robot import Hexapod\n"
            "from hexapod_pin.core.simulate import simulate\n"
            "assert 'hexapod_pin.hexapod.compiled_backend' not in sys.modules\n"
            "run = simulate(Hexapod.default(), 0.002, 1e-3, backend='compiled')\n"
            "assert type(run).__name__ == 'Trajectory', type(run)\n"
            "print(json.dumps(sorted(sys.modules)))")
    assert "hexapod_pin.hexapod.compiled_backend" in _loaded(code)


def test_the_help_of_simulate_names_the_library_integrators():
    from hexapod_pin.cli.dynamics import INTEGRATOR_NAMES
    from hexapod_pin.core.simulation import INTEGRATORS
    assert tuple(INTEGRATOR_NAMES) == tuple(INTEGRATORS)


def test_the_help_of_identify_names_the_library_drive_kinds():
    from hexapod_pin.cli.identification import DRIVE_NAMES
    from hexapod_pin.identification.parameters import DRIVE_KINDS
    assert tuple(DRIVE_NAMES) == tuple(DRIVE_KINDS)


def test_every_subpackage_is_an_attribute_of_the_lazy_root():
    """Each subpackage and top-level module of the package is reachable as
    ``hexapod_pin.<name>`` in a fresh interpreter without importing it first (the lazy
    root's list is complete)."""
    code = ("import importlib, pathlib, hexapod_pin\n"
            "root = pathlib.Path(hexapod_pin.__file__).parent\n"
            "names = {p.name for p in root.iterdir() if (p / '__init__.py').is_file()}\n"
            "names |= {p.stem for p in root.glob('*.py') if not p.stem.startswith('_')}\n"
            "missing = sorted(n for n in names if not hasattr(hexapod_pin, n))\n"
            "assert not missing, missing\n"
            "for n in sorted(names):\n"
            "    assert getattr(hexapod_pin, n) is importlib.import_module('hexapod_pin.' + n)\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-2000:]
