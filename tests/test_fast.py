"""The optional compiled fast path (hexapod_pin.fast) against the reference routes.

Independent routes: the Pinocchio tree routes of Hexapod (ID / FD / statics), the tree
integrator of simulate(), and the mechanism's energy from Pinocchio (computeKineticEnergy
/ computePotentialEnergy). Compiled tests are skipped when numba is absent; the library
without numba is checked in a subprocess.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from conftest import geometry_from_reference, load_reference, random_pose

import hexapod_pin as hp
from hexapod_pin import fast
from hexapod_pin.errors import InputError, SingularityError, StrokeLimitError
from hexapod_pin.simulate import CircleTrajectory, PIDController, simulate

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def numba():
    return pytest.importorskip("numba")


def _motion(rng):
    return rng.normal(size=6) * 0.3, rng.normal(size=6), rng.normal(size=6) * 2.0


def test_single_state_routes_match_the_tree(numba, any_robot, rng):
    """ID, FD (twist_dot and carriage accelerations) and statics == the Pinocchio routes."""
    robot = any_robot
    fd = fast.fast_dynamics(robot)
    for _ in range(20):
        pose = random_pose(robot, rng)
        twist, twist_dot, wrench = _motion(rng)
        ref = robot.inverse_dynamics(pose, twist, twist_dot, wrench, method="kkt",
                                     bounded=False, joint_wrenches=False).actuator_forces
        tau = fd.inverse_dynamics(pose, twist, twist_dot, wrench, bounded=False)
        np.testing.assert_allclose(tau, ref, rtol=0, atol=1e-10 * max(1.0, np.abs(ref).max()))
        forces = ref + rng.normal(size=6)
        fwd = robot.forward_dynamics(pose, twist, forces, wrench)
        acc, qdd = fd.forward_dynamics_full(pose, twist, forces, wrench)
        np.testing.assert_allclose(acc, fwd.twist_dot, rtol=0, atol=1e-10)
        np.testing.assert_allclose(qdd, fwd.qddot, rtol=0, atol=1e-10)
        np.testing.assert_allclose(fd.forward_dynamics(pose, twist, forces), robot.forward_dynamics(
            pose, twist, forces).twist_dot, rtol=0, atol=1e-10)
        np.testing.assert_allclose(fd.static_forces(pose, wrench, bounded=False),
                                   robot.static_forces(pose, wrench, bounded=False),
                                   rtol=0, atol=1e-10)
        np.testing.assert_allclose(fd.inverse_dynamics(pose, twist, twist_dot, bounded=False),
                                   robot.inverse_dynamics(pose, twist, twist_dot, method="kkt",
                                                          bounded=False).actuator_forces,
                                   rtol=0, atol=1e-10)


@pytest.mark.parametrize("index", [0, 1, 2])
def test_reference_states(numba, index):
    """The independent implementation's states (tests/data), 1e-9 relative."""
    entry = load_reference()["hexapod"][index]
    fd = fast.fast_dynamics(hp.Hexapod(geometry_from_reference(entry)))
    pose, twist, twist_dot, wrench = (np.array(entry[k]) for k in
                                      ("pose", "twist", "twist_dot", "wrench"))
    want, static = np.array(entry["actuator_forces"]), np.array(entry["static_forces"])
    np.testing.assert_allclose(fd.inverse_dynamics(pose, twist, twist_dot, wrench), want,
                               rtol=0, atol=1e-9 * np.abs(want).max())
    np.testing.assert_allclose(fd.static_forces(pose, wrench), static, rtol=0,
                               atol=1e-9 * np.abs(static).max())
    acc, qdd = fd.forward_dynamics_full(pose, twist, want, wrench)
    np.testing.assert_allclose(acc, twist_dot, rtol=0, atol=1e-9 * max(1, np.abs(twist_dot).max()))
    np.testing.assert_allclose(qdd, entry["qddot"], rtol=0,
                               atol=1e-9 * max(1, np.abs(entry["qddot"]).max()))


def test_errors_match_the_reference_routes(numba, robot):
    fd = fast.fast_dynamics(robot)
    home, zero = robot.home_pose, np.zeros(6)
    with pytest.raises(InputError):
        fd.inverse_dynamics(np.zeros(5), zero, zero)
    with pytest.raises(InputError):
        fd.forward_dynamics(home, zero, np.full(6, np.nan))
    with pytest.raises(InputError):
        fd.static_forces(home, wrench=[0, 0, np.inf, 0, 0, 0])
    far = home + np.array([0, 0, 1.0, 0, 0, 0])
    for call in (lambda: fd.static_forces(far), lambda: fd.inverse_dynamics(far, zero, zero),
                 lambda: fd.forward_dynamics(far, zero, zero)):
        with pytest.raises(hp.UnreachablePoseError) as exc:
            call()
        assert exc.value.carriages == list(range(6))
    g = robot.geometry
    singular = home.copy()
    singular[2] = np.sqrt(g.leg_length ** 2 - (g.rail_radius - g.platform_radius) ** 2
                          - (3e-8 * g.leg_length) ** 2)
    for call in (lambda: fd.static_forces(singular),
                 lambda: fd.inverse_dynamics(singular, zero, zero),
                 lambda: fd.forward_dynamics(singular, zero, zero)):
        with pytest.raises(SingularityError):
            call()
    # saturation: only with bounded=True, carrying the needed forces
    if np.isfinite(g.max_actuator_force):
        big = np.array([0, 0, 0, 0, 0, 1e4])
        with pytest.raises(hp.ActuatorSaturationError) as exc:
            fd.inverse_dynamics(home, zero, big)
        np.testing.assert_allclose(exc.value.needed, fd.inverse_dynamics(home, zero, big,
                                                                          bounded=False))


def test_type_two_check_of_the_leg_solve(numba, robot):
    """Every leg parallel (rank-2 leg matrix) -> TYPE_II code, as PlatformMap.solve_forces."""
    wk = np.zeros((fast._WORK_ROWS, 6))
    wk[fast._RX], wk[fast._RY] = np.cos(np.arange(6)), np.sin(np.arange(6))
    wk[fast._NX], wk[fast._NY], wk[fast._NZ] = 0.1, 0.2, 0.3
    rhs = np.array([0.0, 0.0, 1.0, 0.0, 0.0, 0.0])
    assert fast._solve_legs(wk, rhs, 1e-12, np.empty((6, 6))) == fast.TYPE_II


def test_energy_is_conserved_unactuated(numba, any_robot):
    """2 s unactuated from home under gravity: the platform falls until a stroke limit
    stops the run cleanly; total energy (Pinocchio's) constant to RK4 accuracy."""
    robot = any_robot
    tr = fast.simulate_fast(robot, 2.0, 1e-3)
    assert tr.status in ("stroke_limit", "carriage_gap") and tr.message
    assert 0.05 < tr.times[-1] < 2.0
    energies = [robot.energies(p, t) for p, t in zip(tr.poses[::10], tr.twists[::10])]
    total = np.array([e.total for e in energies])
    kinetic = max(e.kinetic for e in energies)
    assert kinetic > 0.01                                    # it did move
    assert np.abs(total - total[0]).max() <= 1e-8 * kinetic
    # the recorded carriages are the IK of the recorded poses
    np.testing.assert_allclose(tr.q[-1], robot.configuration(tr.poses[-1])[
        robot.indices.carriage_q], atol=1e-12)
    with pytest.raises(StrokeLimitError):
        fast.simulate_fast(robot, 2.0, 1e-3, on_limit="raise")
    # without the limits it falls until the legs cannot reach: a clean "failed" stop
    tr = fast.simulate_fast(robot, 2.0, 1e-3, check_limits=False)
    assert tr.status == "failed" and "unreachable" in tr.message
    assert np.all(np.isfinite(tr.poses)) and np.all(np.diff(tr.times) > 0)


def test_simulation_matches_the_tree_integrator(numba, any_robot):
    """PID on a circle for 0.2 s: platform-coordinate RK4 == tree RK4 (simulate())."""
    robot = any_robot
    reference = CircleTrajectory(robot.home_pose, 0.01, 1.0)
    gains = {"kp": 2000.0, "ki": 500.0, "kd": 50.0}
    start = reference(0.0)
    tree = simulate(robot, 0.2, 1e-3, controller=PIDController(robot, reference, **gains),
                    pose0=start.pose, twist0=start.twist)
    quick = fast.simulate_fast(robot, 0.2, 1e-3, reference=reference, **gains)
    assert tree.status == quick.status == "completed"
    np.testing.assert_allclose(quick.times, tree.times, atol=1e-15)
    assert np.abs(quick.poses - tree.poses).max() <= 1e-8
    assert np.abs(quick.twists - tree.twists).max() <= 1e-7
    np.testing.assert_allclose(quick.actuator_forces, tree.actuator_forces, atol=1e-6)
    np.testing.assert_allclose(quick.q, tree.q, atol=1e-8)
    np.testing.assert_allclose(quick.qdot, tree.qdot, atol=1e-7)
    assert np.abs(tree.poses - tree.poses[0]).max() > 5e-3        # a real motion
    # constant forces and record_every
    forces = robot.static_forces(robot.home_pose) * 1.3
    tree = simulate(robot, 0.1, 1e-3, actuator_forces=forces, record_every=5)
    quick = fast.simulate_fast(robot, 0.1, 1e-3, actuator_forces=forces, record_every=5)
    assert quick.poses.shape == tree.poses.shape == (21, 6)
    assert np.abs(quick.poses - tree.poses).max() <= 1e-10


def test_constant_wrench_is_held_in_world_axes(numba, robot):
    """simulate() holds a wrench over a step in platform axes (its free-flyer force), the
    fast loop in world axes: the difference is first order in dt (halves with dt)."""
    forces = robot.static_forces(robot.home_pose) * 1.3
    wrench = np.array([0.5, -0.3, 0.0, 0.01, 0.0, 0.02])
    diffs = []
    for dt in (1e-3, 5e-4):
        tree = simulate(robot, 0.1, dt, actuator_forces=forces, wrench=wrench)
        quick = fast.simulate_fast(robot, 0.1, dt, actuator_forces=forces, wrench=wrench)
        diffs.append(np.abs(quick.poses - tree.poses).max())
    assert diffs[0] <= 5e-8
    assert 1.8 < diffs[0] / diffs[1] < 2.2


def test_simulation_saturation_and_bad_arguments(numba, robot):
    reference = (np.tile(robot.home_pose + np.r_[0.02, 0, 0, 0, 0, 0], (3, 1)), np.zeros((3, 6)))
    if np.isfinite(robot.geometry.max_actuator_force):
        tr = fast.simulate_fast(robot, 0.01, 1e-3, pose0=robot.home_pose, twist0=np.zeros(6),
                                reference=reference, kp=1e6, ki=0.0, kd=0.0)
        assert tr.saturated[0]
        assert np.abs(tr.actuator_forces).max() <= robot.geometry.max_actuator_force
        with pytest.raises(hp.ActuatorSaturationError):
            fast.simulate_fast(robot, 0.01, 1e-3, pose0=robot.home_pose, reference=reference,
                               kp=1e6, ki=0.0, kd=0.0, saturation="raise")
    for kwargs in ({"duration": -1.0}, {"duration": 0.1, "dt": 0.0},
                   {"duration": 0.1, "saturation": "soft"}, {"duration": 0.1, "on_limit": "wait"},
                   {"duration": 0.1, "reference": (np.zeros((2, 6)), np.zeros((3, 6)))},
                   {"duration": 0.1, "reference": reference, "actuator_forces": np.zeros(6)}):
        with pytest.raises(InputError):
            fast.simulate_fast(robot, **kwargs)


NO_NUMBA = textwrap.dedent("""
    import sys

    class Block:
        def find_spec(self, name, path=None, target=None):
            if name == "numba" or name.startswith("numba."):
                raise ImportError("numba blocked for this test")

    sys.meta_path.insert(0, Block())
    import numpy as np
    import hexapod_pin as hp
    robot = hp.Hexapod.default()
    pose, zero = robot.home_pose, np.zeros(6)
    tau = robot.inverse_dynamics(pose, zero, zero, method="kkt").actuator_forces
    acc = robot.forward_dynamics(pose, zero, tau).twist_dot
    from hexapod_pin import fast
    assert not fast.available() and "numba" not in sys.modules
    fd = fast.fast_dynamics(robot)
    assert np.abs(fd.inverse_dynamics(pose, zero, zero) - tau).max() < 1e-10
    assert np.abs(fd.forward_dynamics(pose, zero, tau) - acc).max() < 1e-10
    tr = fast.simulate_fast(robot, 0.005, 1e-3, actuator_forces=tau)
    assert tr.status == "completed" and tr.poses.shape == (6, 6)
    print("ok")
""")


def test_library_works_without_numba():
    """numba made unimportable: the library, its default routes and (slowly, as plain
    Python) the fast module still work."""
    out = subprocess.run([sys.executable, "-c", NO_NUMBA], capture_output=True, text=True,
                         timeout=300, cwd=ROOT, check=False)
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stdout + out.stderr


def test_bench_fast_smoke():
    out = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_fast.py"),
                          "--smoke"], capture_output=True, text=True, timeout=600,
                         check=False)
    assert out.returncode == 0, out.stdout + out.stderr
    for row in ("| fast - reference ID, tau |", "| inverse_dynamics, fast |",
                "| fast, PID on a circle"):
        assert row in out.stdout, row
