"""Shared fixtures: the robots of ``tests/robot_registry.py`` (the default hexapod, a second
geometry, each robot of the shared suites), the reference states."""

import json
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import hexapod_pin as hp
from hexapod_pin.core.dynamics import forward_dynamics_tree
import robot_registry
from robot_registry import SECOND_GEOMETRY  # noqa: F401 (imported from here by the tests)

# copy of shared/reference/reference_states.json (states computed by an independent implementation)
REFERENCE = Path(__file__).resolve().parent / "data" / "reference_states.json"


@pytest.fixture(scope="session")
def robot():
    return robot_registry.get("hexapod")


@pytest.fixture(scope="session")
def robot2():
    return robot_registry.get("hexapod-second")


@pytest.fixture(scope="session", params=["default", "second"])
def any_robot(request, robot, robot2):
    return robot if request.param == "default" else robot2


@pytest.fixture(scope="module", params=robot_registry.names("shared"))
def shared_robot(request):
    """Each robot of the shared suites in turn (``robot_registry.names("shared")``)."""
    return robot_registry.get(request.param)


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


def random_pose(robot, rng, scale=1.0):
    """A random reachable pose near home, inside the strokes (rejection sampling)."""
    for _ in range(1000):
        delta = np.concatenate([rng.uniform(-0.03, 0.03, 3), rng.uniform(-0.12, 0.12, 3)])
        pose = robot.home_pose + scale * delta
        try:
            robot.inverse_kinematics(pose)
        except hp.HexapodPinError:
            continue
        return pose
    raise RuntimeError("no reachable random pose found")


def random_configuration(model, rng, around=None, scale=1.0):
    """A random configuration of a ``pin.Model`` drawn from ``rng``: ``around`` (default:
    neutral) moved by a uniform tangent vector in ``[-scale, scale]^nv``. (Not
    ``pin.randomConfiguration``: Pinocchio's own generator has a state that depends on the
    tests run before, so its draws change with the test order.)"""
    start = pin.neutral(model) if around is None else around
    return pin.integrate(model, start, rng.uniform(-scale, scale, model.nv))


def import_benchmarks(*names):
    """Modules of benchmarks/ (not a package), imported with it briefly on sys.path."""
    import importlib
    import sys

    bench = str(Path(__file__).resolve().parent.parent / "benchmarks")
    sys.path.insert(0, bench)
    try:
        return tuple(importlib.import_module(name) for name in names)
    finally:
        sys.path.remove(bench)


def load_reference():
    return json.loads(REFERENCE.read_text())


def geometry_from_reference(entry):
    fields = {k: tuple(v) if isinstance(v, list) else v for k, v in entry["geometry"].items()}
    return hp.HexapodGeometry(**fields)


def fd_constraint_jacobian(model, q, h=1e-6):
    """Central finite differences of ``model.residual`` along ``pin.integrate``, one
    column per velocity coordinate: the independent route for ``constraint_jacobian``."""
    cols = []
    for j in range(model.nv):
        dv = np.zeros(model.nv)
        dv[j] = h
        cols.append((model.residual(pin.integrate(model.model, q, dv))
                     - model.residual(pin.integrate(model.model, q, -dv))) / (2 * h))
    return np.array(cols).T


def forward_dynamics_full_tau(clm, q, v, tau, method="pinocchio"):
    """``forward_dynamics_tree`` for a full generalised force ``tau`` (nv,): its actuated
    entries as the actuator forces, the rest as the external force."""
    tau = np.asarray(tau, dtype=float)
    tau_ext = tau.copy()
    tau_ext[clm.actuated_v] = 0.0
    return forward_dynamics_tree(clm, q, v, tau[clm.actuated_v], tau_ext, method=method)


#: a two-link URDF template (format fields mass, ixx, x, axis) for the description checks
TWO_LINKS = """<robot name="t">
  <link name="base"/>
  <link name="arm"><inertial><origin xyz="0 0 0.1"/><mass value="{mass}"/>
    <inertia ixx="{ixx}" iyy="0.02" izz="0.03" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="j" type="revolute"><parent link="base"/><child link="arm"/>
    <origin xyz="{x} 0 0"/><axis xyz="{axis}"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
</robot>"""


def one_line_error(result, code: int, *words: str) -> str:
    """The one ``error:`` line a CLI run printed on stderr, after checking its exit
    ``code``, that nothing else (no traceback) was printed, and that it names ``words``."""
    assert result.exit_code == code, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:"), result.stderr
    assert "Traceback" not in result.output
    for word in words:
        assert word in lines[0], (word, lines[0])
    return lines[0]


def null_space_kkt(mass, force, jac, rhs):
    """The unique ``a`` with ``mass a = force + jac^T lambda``, ``jac a = rhs`` (jac may
    have dependent rows): least-norm particular solution plus the null-space part (a numpy
    reference written for the tests, independent of the library's solves)."""
    u, s, vt = np.linalg.svd(jac)
    rank = int(np.sum(s > 1e-10 * s[0]))
    basis = vt[rank:].T
    particular = vt[:rank].T @ ((u[:, :rank].T @ rhs) / s[:rank])
    z = np.linalg.solve(basis.T @ mass @ basis, basis.T @ (force - mass @ particular))
    return particular + basis @ z
