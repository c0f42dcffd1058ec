"""The compiled fast path (hexapod_pin.hexapod.fast) against the reference routes.

Independent routes: the Pinocchio tree routes of Hexapod (ID / FD / statics), the tree
integrator of simulate(), the mechanism's energy from Pinocchio (computeKineticEnergy
/ computePotentialEnergy), one integrator step written out with Pinocchio's forward
dynamics and SO(3) exponential, and the convergence orders of the integrators (numba is a
dependency of the library).
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from conftest import geometry_from_reference, load_reference, random_pose

import hexapod_pin as hp
from hexapod_pin.hexapod import fast
from hexapod_pin.errors import InputError, SingularityError, StrokeLimitError, UnreachablePoseError
from hexapod_pin.hexapod.simulation import CircleTrajectory, PIDController, simulate

ROOT = Path(__file__).resolve().parents[2]


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
        np.testing.assert_allclose(qdd, fwd.actuator_accelerations, rtol=0, atol=1e-10)
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
    assert quick.real_time_factor == pytest.approx(0.2 / quick.wall_time, rel=1e-12)
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
                   {"duration": 0.1, "reference": reference, "actuator_forces": np.zeros(6)},
                   {"duration": 0.1, "integrator": "euler"}, {"duration": 0.1, "integrator": 1}):
        with pytest.raises(InputError):
            fast.simulate_fast(robot, **kwargs)
    with pytest.raises(InputError) as exc:
        fast.simulate_fast(robot, 0.1, integrator="RK4")
    assert exc.value.value == "RK4" and "semi_implicit_euler" in str(exc.value)


# -- integrators ------------------------------------------------------------------------
def _final_state(tr):
    return np.concatenate([tr.poses[-1], tr.twists[-1]])


@pytest.mark.parametrize("spin", [1.0, 0.05])
def test_semi_implicit_euler_step_written_out(numba, robot, rng, spin):
    """Three steps of the scheme by hand: Pinocchio's forward dynamics for the
    acceleration, ``v += dt a``, ``p += dt v``, ``R = exp3(dt w) R`` (pin.exp3); a fast
    and a slow spin (the kernel's exponential switches to a series below 0.1 mrad)."""
    pose = robot.home_pose + np.r_[0.004, -0.003, 0.002, 0.03, -0.02, 0.05]
    twist = np.r_[0.02, -0.01, 0.03, np.r_[0.3, -0.2, 0.5] * spin]
    forces = robot.static_forces(pose) + rng.normal(size=6)
    wrench = np.r_[0.4, -0.2, 0.1, 0.01, 0.02, -0.01]
    dt = 2e-3
    tr = fast.simulate_fast(robot, 3 * dt, dt, pose0=pose, twist0=twist, actuator_forces=forces,
                            wrench=wrench, integrator="semi_implicit_euler")
    assert tr.status == "completed" and tr.integrator == "semi_implicit_euler"
    p, rot, tw = pose[:3].copy(), pin.rpy.rpyToMatrix(*pose[3:]), twist.copy()
    for k in range(1, 4):
        acc = robot.forward_dynamics(np.r_[p, pin.rpy.matrixToRpy(rot)], tw, forces,
                                     wrench).twist_dot
        tw = tw + dt * acc
        p = p + dt * tw[:3]
        rot = pin.exp3(dt * tw[3:]) @ rot
        np.testing.assert_allclose(tr.twists[k], tw, rtol=0, atol=1e-12)
        np.testing.assert_allclose(tr.poses[k, :3], p, rtol=0, atol=1e-14)
        qx, qy, qz, qw = tr.quaternions[k]
        np.testing.assert_allclose(pin.Quaternion(qw, qx, qy, qz).toRotationMatrix(), rot,
                                   rtol=0, atol=1e-13)
        np.testing.assert_allclose(tr.poses[k, 3:], pin.rpy.matrixToRpy(rot), rtol=0,
                                   atol=1e-13)
    assert np.abs(tr.twists[-1] - twist).max() > 1e-3          # a real motion


def test_integrators_converge_at_their_order(numba, robot):
    """0.1 s under constant forces and a wrench from a moving start: the error against
    RK4 at dt = 0.1 ms halves (semi-implicit Euler), quarters (rk2), falls 16x (rk4)
    when dt halves."""
    kwargs = {"actuator_forces": robot.static_forces(robot.home_pose) * 1.3,
              "wrench": np.r_[0.5, -0.3, 0.0, 0.01, 0.0, 0.02],
              "twist0": np.r_[0.01, -0.02, 0.01, 0.1, -0.2, 0.3]}
    exact = _final_state(fast.simulate_fast(robot, 0.1, 1e-4, **kwargs))
    for integrator, order in (("semi_implicit_euler", 1), ("rk2", 2), ("rk4", 4)):
        errors = [np.abs(_final_state(fast.simulate_fast(robot, 0.1, dt, integrator=integrator,
                                                         **kwargs)) - exact).max()
                  for dt in (1e-3, 5e-4)]
        assert 0.9 * 2 ** order < errors[0] / errors[1] < 1.1 * 2 ** order, (integrator, errors)
    assert errors[0] < 1e-11                                       # rk4 at 1 ms
    assert np.abs(exact[6:]).max() > 1e-2                          # a real motion


def _energy_error(robot, tr, kp=0.0, feedforward=None, q_ref=None):
    """Total energy minus its start, over the largest kinetic energy reached (both from
    Pinocchio), with the potential of a spring ``kp`` and of constant forces if any."""
    parts = [robot.energies(p, t) for p, t in zip(tr.poses, tr.twists)]
    total = np.array([e.total for e in parts])
    if feedforward is not None:
        total += 0.5 * kp * ((q_ref - tr.q) ** 2).sum(axis=1) - tr.q @ feedforward
    kinetic = np.array([e.kinetic for e in parts])
    return (total - total[0]) / kinetic.max(), kinetic


def test_semi_implicit_euler_energy_unactuated(numba, robot):
    """Unactuated fall under gravity from home (until a stroke limit, ~0.34 s): the
    energy error is first order in dt, bounded by 2 % of the kinetic energy at 1 ms
    (measured 1.4 %, a loss), against ~1e-11 for RK4."""
    drift = []
    for dt in (1e-3, 5e-4):
        tr = fast.simulate_fast(robot, 2.0, dt, integrator="semi_implicit_euler",
                                record_every=round(2e-3 / dt))
        assert tr.status == "stroke_limit" and tr.times[-1] > 0.3
        error, kinetic = _energy_error(robot, tr)
        assert kinetic.max() > 0.01
        drift.append(np.abs(error).max())
    assert drift[0] < 0.02
    assert 1.8 < drift[0] / drift[1] < 2.2
    tr = fast.simulate_fast(robot, 2.0, 1e-3, record_every=2)
    assert np.abs(_energy_error(robot, tr)[0]).max() < 1e-9


def test_semi_implicit_euler_energy_of_an_oscillation(numba, robot):
    """A swing about home under a spring (P-law, kp = 2000 N/m, no ki / kd) plus the
    static forces, commands held over each step: the energy (mechanism + spring + the
    constant forces' potential) stays within 10 % of the kinetic energy over 2 s with the
    semi-implicit Euler step, and the swing does not grow; RK4 with the same held
    commands gains energy (the hold lags half a step)."""
    home = robot.home_pose
    hold = robot.static_forces(home)
    q_ref = robot.configuration(home)[robot.indices.carriage_q]
    kwargs = {"reference": (home[None], np.zeros((1, 6))), "kp": 2000.0, "ki": 0.0, "kd": 0.0,
              "feedforward": True, "pose0": home + np.r_[0.003, 0, 0.002, 0, 0.01, 0],
              "record_every": 5}
    peaks = {}
    for integrator in ("semi_implicit_euler", "rk4"):
        tr = fast.simulate_fast(robot, 2.0, 1e-3, integrator=integrator, **kwargs)
        # RK4's growing swing reaches the force bound near the end, and its status says so
        assert tr.status == ("completed" if integrator == "semi_implicit_euler"
                             else "saturated")
        error, kinetic = _energy_error(robot, tr, 2000.0, hold, q_ref)
        peaks[integrator] = kinetic[:100].max(), kinetic[-100:].max()
        if integrator == "semi_implicit_euler":
            assert np.abs(error).max() < 0.1
    first, last = peaks["semi_implicit_euler"]
    assert 0.01 < last < 1.05 * first
    first, last = peaks["rk4"]
    assert last > 2.0 * first


def test_bench_fast_smoke():
    out = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_fast.py"),
                          "--smoke"], capture_output=True, text=True, timeout=600,
                         check=False)
    assert out.returncode == 0, out.stdout + out.stderr
    for row in ("| fast - reference ID, tau |", "| inverse_dynamics, fast |",
                "| fast, PID on a circle (completed) | semi_implicit_euler |",
                "| fast, constant static forces from home (completed) | rk4 |",
                "| rk2 |"):
        assert row in out.stdout, row


def test_stepper_continues_the_compiled_loop(numba, robot):
    """FastStepper.step, called N times, lands where one simulate_fast run of N steps does
    (same kernel, bit for bit), for each integrator; reset() restarts the clock."""
    pose = robot.home_pose + np.r_[0.003, -0.002, 0.001, 0.01, -0.02, 0.03]
    twist = np.r_[0.01, 0.0, 0.02, 0.1, -0.1, 0.05]
    forces = robot.static_forces(pose) * 1.05
    wrench = np.r_[0.5, -0.2, 0.1, 0.01, 0.02, -0.01]
    for integrator in fast.INTEGRATORS:
        stepper = fast.FastStepper(robot, 1e-3, pose0=pose, twist0=twist, integrator=integrator)
        for _ in range(40):
            stepper.step(forces, wrench)
        run = fast.simulate_fast(robot, 0.04, 1e-3, pose0=pose, twist0=twist,
                                 actuator_forces=forces, wrench=wrench, integrator=integrator,
                                 saturation="ignore")
        np.testing.assert_array_equal(stepper.pose, run.poses[-1])
        np.testing.assert_array_equal(stepper.twist, run.twists[-1])
        assert stepper.time == pytest.approx(0.04)
        assert np.abs(stepper.twist - twist).max() > 1e-3           # a real motion
    stepper.reset(pose, twist)
    assert stepper.time == 0.0
    np.testing.assert_allclose(stepper.pose, pose, atol=1e-15)


def test_stepper_limits_and_errors(numba, robot):
    stepper = fast.FastStepper(robot, 1e-3)
    push = robot.static_forces(robot.home_pose) + np.r_[30.0, -30.0, 0, 0, 0, 0]
    with pytest.raises(StrokeLimitError):
        for _ in range(2000):
            stepper.step(push)
    with pytest.raises(InputError, match="actuator_forces"):
        stepper.step([0.0, np.nan, 0.0, 0.0, 0.0, 0.0])
    with pytest.raises(InputError, match="integrator"):
        fast.FastStepper(robot, integrator="euler")
    with pytest.raises(InputError, match="dt"):
        fast.FastStepper(robot, dt=0.0)
    far = robot.home_pose.copy()
    far[2] += 1.0
    with pytest.raises(UnreachablePoseError):
        fast.FastStepper(robot, pose0=far)
