"""hexapod_pin.core.simulate.simulate on every robot and on a bare closed-loop model.

Independent routes: conservation of the total energy of an unactuated run; the energy
balance ``E(t) - E(0) = work(t)`` under constant actuator forces, its error shrinking like
``dt^4`` (RK4); the work of constant forces against ``u . (q_act(t) - q_act(0))`` from the
robot's own ``actuator_positions``; the controllers against their references; the platform
error against ``pin.exp3``.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import hexapod_pin as hp
import robot_registry
from hexapod_pin.core import simulate as simulate_module
from hexapod_pin.core.controllers import ActuatorPID, ComputedTorque, SimState, platform_error
from hexapod_pin.core.pose import rotation_from_rpy
from hexapod_pin.core.simulate import MAX_STEPS, Trajectory, simulate
from hexapod_pin.errors import AssemblyError, SolverError

DATA = Path(__file__).resolve().parents[1] / "data" / "parallel"
PROFILE = settings(max_examples=40, deadline=None, database=None, derandomize=True,
                   suppress_health_check=[HealthCheck.function_scoped_fixture])


@pytest.fixture(scope="module")
def hexapod():
    return robot_registry.get("hexapod")


@pytest.fixture(scope="module")
def planar():
    return robot_registry.get("planar")


@pytest.fixture(scope="module")
def five_bar():
    """A bare ClosedLoopModel (no platform) and an assembled hanging configuration."""
    clm = hp.load_parallel_robot(DATA / "five_bar_3d")
    guess = np.zeros(clm.nq)
    for joint, value in (("mot1", 0.9), ("free1", 1.0), ("mot2", 2.0), ("free2", -1.0)):
        guess[clm.joint_q_index(joint)] = value
    return clm, clm.assemble(guess).q


def drift(traj: Trajectory) -> tuple[float, float]:
    """(max |E(t) - E(0)|, max kinetic energy reached)."""
    return float(np.abs(traj.energies - traj.energies[0]).max()), float(traj.kinetic.max())


# ------------------------------------------------------------------- energy conservation
# the planar robot falling from home reaches a type-I singularity (a link perpendicular to
# its rail: the twist map refuses it) at t = 0.42 s: 0.4 s there
@pytest.mark.parametrize("name, duration", [("hexapod", 0.5), ("planar", 0.4)])
def test_unactuated_rk4_run_keeps_its_energy(name, duration, request):
    robot = request.getfixturevalue(name)
    traj = simulate(robot, duration, 1e-3)
    assert traj.status == "completed", traj.message
    change, kinetic = drift(traj)
    assert kinetic > 0.5                              # it moved (J)
    assert change <= 1e-6 * kinetic, (change, kinetic)
    assert traj.closure_residual.max() <= 1e-10
    np.testing.assert_array_equal(traj.work, 0.0)


def test_unactuated_bare_model_keeps_its_energy(five_bar):
    clm, q0 = five_bar
    traj = simulate(clm, 0.5, 1e-3, initial=(q0, np.zeros(clm.nv)))
    assert traj.status == "completed", traj.message
    change, kinetic = drift(traj)
    assert kinetic > 0.1
    assert change <= 1e-6 * kinetic, (change, kinetic)


# --------------------------------------------------------------------- energy balance
@pytest.mark.parametrize("name, forces", [("planar", [2.0, -1.0, 0.5]),
                                          ("hexapod", [5.0, -5.0, 3.0, -3.0, 2.0, -2.0])])
def test_energy_balance_with_constant_forces_is_fourth_order(name, forces, request):
    """``E(t) - E(0) - work(t)`` is the RK4 error, O(dt^4): halving dt divides it by about
    16 (measured 15-16; accepted 11-22), and at 1 ms it is below 1e-6 J."""
    robot = request.getfixturevalue(name)
    forces = np.array(forces)
    misses = []
    for dt in (2e-3, 1e-3):
        traj = simulate(robot, 0.2, dt, actuator_forces=forces)
        assert traj.status == "completed", traj.message
        misses.append(np.abs(traj.energies - traj.energies[0] - traj.work).max())
        # the work of constant forces, from the robot's actuator positions
        moved = np.array([robot.actuator_positions(q) for q in traj.q]) - traj.actuator_positions[0]
        np.testing.assert_allclose(traj.work, moved @ forces, rtol=1e-9, atol=1e-12)
        assert abs(traj.work[-1]) > 0.1                 # the forces did work (J)
    assert 11.0 < misses[0] / misses[1] < 22.0, misses
    assert misses[1] < 1e-6


# ------------------------------------------------------------------------- controllers
def test_pid_holds_a_reference(planar):
    target = planar.home_actuators + np.array([0.01, -0.005, 0.0])
    pid = ActuatorPID(kp=2000.0, kd=50.0, ki=5000.0, reference=target)
    traj = simulate(planar, 2.0, 1e-3, controller=pid)
    assert traj.status == "completed", traj.message
    error = np.abs(traj.actuator_positions - target).max(axis=1)
    assert error[0] > 4e-3 and error[-1] < 1e-4, (error[0], error[-1])
    np.testing.assert_allclose(traj.actuator_velocities[-1], 0.0, atol=1e-3)


def test_pid_without_integral_leaves_the_gravity_offset(planar):
    """With ki = 0 the PD settles at ``e = u_gravity / kp``: the static forces of the
    pose (the robot's own statics) over kp, which the integral removes."""
    kp = 4000.0
    traj = simulate(planar, 1.5, 1e-3, controller=ActuatorPID(kp=kp, kd=60.0))
    statics = planar.static_forces(traj.poses[-1])
    np.testing.assert_allclose(kp * (planar.home_actuators - traj.actuator_positions[-1]),
                               statics, rtol=2e-3, atol=1e-3)


def circle(t):
    """A planar reference starting at home: radius 2 cm, 1 Hz, with a rotation."""
    w, r, a = 2 * math.pi, 0.02, 0.05
    s, c = math.sin(w * t), math.cos(w * t)
    return (np.array([r * s, r * (1 - c), a * s]), np.array([r * w * c, r * w * s, a * w * c]),
            np.array([-r * w * w * s, r * w * w * c, -a * w * w * s]))


def test_computed_torque_tracks_a_planar_reference(planar):
    traj = simulate(planar, 0.8, 1e-3, controller=ComputedTorque(circle, kp=400.0, kd=40.0))
    assert traj.status == "completed", traj.message
    error = np.array([np.abs(circle(t)[0] - pose).max() for t, pose in zip(traj.times,
                                                                          traj.poses)])
    assert error.max() > 1e-3                       # the start at rest is off the reference
    assert error[traj.times >= 0.5].max() < 1e-4, error[traj.times >= 0.5].max()


def test_computed_torque_holds_a_tilted_hexapod_pose(hexapod):
    """The 6-D route (log3 orientation error): from home to a tilted, shifted pose."""
    target = hexapod.home_pose + np.array([0.005, -0.004, 0.003, 0.03, -0.02, 0.05])

    def hold(t):
        return target, np.zeros(6), np.zeros(6)

    traj = simulate(hexapod, 0.6, 1e-3, controller=ComputedTorque(hold, kp=400.0, kd=40.0))
    assert traj.status in ("completed", "saturated"), traj.message
    final = platform_error(target, traj.poses[-1])
    assert np.abs(platform_error(target, traj.poses[0])).max() > 0.02
    assert np.abs(final).max() < 1e-4, final


def test_platform_error_is_the_rotation_vector_in_world_axes(rng):
    for _ in range(5):
        pose = np.concatenate([rng.uniform(-1, 1, 3), rng.uniform(-0.5, 0.5, 3)])
        ref = np.concatenate([rng.uniform(-1, 1, 3), rng.uniform(-0.5, 0.5, 3)])
        err = platform_error(ref, pose)
        np.testing.assert_allclose(err[:3], ref[:3] - pose[:3], atol=1e-15)
        np.testing.assert_allclose(pin.exp3(err[3:]) @ rotation_from_rpy(pose[3:]),
                                   rotation_from_rpy(ref[3:]), atol=1e-12)
    np.testing.assert_allclose(platform_error(np.array([1.0, 2.0, 3.0]), np.ones(3)),
                               [0.0, 1.0, 2.0])


def test_computed_torque_needs_a_platform(five_bar):
    clm, q0 = five_bar
    controller = ComputedTorque(lambda t: (np.zeros(3), np.zeros(3), np.zeros(3)))
    with pytest.raises(hp.InputError, match="platform"):
        simulate(clm, 0.01, 1e-3, controller=controller, initial=(q0, np.zeros(clm.nv)))


# ----------------------------------------------------------- saturation and failures
def test_saturated_commands_are_clipped_and_reported(hexapod):
    limit = hexapod.geometry.max_actuator_force
    forces = np.array([3.0, -3.0, 2.0, -2.0, 1.0, -1.0]) * limit
    traj = simulate(hexapod, 0.02, 1e-3, actuator_forces=forces)
    assert traj.status == "saturated"
    assert "100.00% of the 20 steps" in traj.message and f"{limit:g}" in traj.message
    np.testing.assert_array_equal(traj.actuator_forces, np.tile(np.sign(forces) * limit,
                                                                (traj.times.size, 1)))
    assert traj.saturated.all()


def test_saturation_fraction_counts_the_clipped_steps(hexapod):
    limit = hexapod.geometry.max_actuator_force

    def pulse(t):                                  # over the bound for 5 of the 20 steps
        return np.full(6, 2 * limit if t < 0.005 - 1e-9 else 0.1 * limit)

    traj = simulate(hexapod, 0.02, 1e-3, actuator_forces=pulse)
    assert traj.status == "saturated" and "25.00% of the 20 steps" in traj.message
    assert traj.saturated.sum() == 5


class Bounded:
    """The planar robot with per-actuator force bounds (a protocol-only wrapper)."""

    def __init__(self, robot, bounds):
        self._robot = robot
        self.geometry = type("Spec", (), {"max_actuator_force": bounds})()

    def __getattr__(self, name):
        return getattr(self._robot, name)


def test_per_actuator_bounds_clip_each_actuator(planar):
    bounds = np.array([1.0, 2.0, np.inf])
    traj = simulate(Bounded(planar, bounds), 0.01, 1e-3,
                    actuator_forces=np.array([-5.0, 1.5, 1e3]))
    assert traj.status == "saturated" and "100.00% of the 10 steps" in traj.message
    np.testing.assert_array_equal(traj.actuator_forces[-1], [-1.0, 1.5, 1e3])
    for bad in (np.array([1.0, -1.0, 1.0]), np.ones(2), "x", math.nan):
        with pytest.raises(hp.InputError, match="max_actuator_force"):
            simulate(Bounded(planar, bad), 0.01, 1e-3)


def test_a_failing_controller_ends_the_run_failed(planar):
    def controller(state: SimState, robot) -> np.ndarray:
        if state.t > 0.0505:
            raise SolverError("test solver", "broken", "forced failure")
        return np.zeros(3)

    traj = simulate(planar, 0.2, 1e-3, controller=controller)
    assert traj.status == "failed"
    assert "forced failure" in traj.message and "t = 0.051" in traj.message
    assert traj.times[-1] == pytest.approx(0.050) and traj.times.size == 51
    assert traj.q.shape == (51, planar.model.nq) and traj.energies.shape == (51,)


def test_a_failing_step_keeps_the_samples(planar, monkeypatch):
    real_step = simulate_module.ClosedLoopIntegrator.step
    calls = []

    def step(self, q, v, tau, dt, projection_tol=1e-10):
        calls.append(1)
        if len(calls) > 30:
            raise AssemblyError("forced projection failure", 1e-3, 8, q)
        return real_step(self, q, v, tau, dt, projection_tol)

    monkeypatch.setattr(simulate_module.ClosedLoopIntegrator, "step", step)
    traj = simulate(planar, 0.1, 1e-3, record_every=10)
    assert traj.status == "failed" and "forced projection failure" in traj.message
    assert "t = 0.03" in traj.message
    np.testing.assert_allclose(traj.times, [0.0, 0.01, 0.02, 0.03])


def test_the_tree_integrates_through_a_type_one_singularity(planar):
    """Falling from home, the planar robot reaches a type-I singularity (a link
    perpendicular to its rail) at about 0.42 s: a singularity of the platform coordinates,
    not of the tree's constrained dynamics. The run goes through it (the twist read from
    the tree state, no inverse kinematics), the closures and the energy are kept, and the
    platform-level routes refuse the singular samples."""
    traj = simulate(planar, 0.6, 1e-3)
    assert traj.status == "completed"
    assert traj.closure_residual.max() < 1e-9
    drift = np.abs(traj.energies - traj.energies[0]).max()
    assert drift < 1e-6 * traj.kinetic.max()
    refused = 0
    for k in range(380, 460, 2):               # around the singular instant
        try:
            planar.twist_from_actuator_velocities(
                traj.poses[k], traj.actuator_velocities[k],
                branch=planar.branch_of(traj.poses[k], traj.actuator_positions[k]))
        except hp.SingularityError:
            refused += 1
    assert refused >= 1


# ------------------------------------------------------------------- shapes and inputs
def test_trajectory_shapes_of_robots_and_a_bare_model(hexapod, planar, five_bar):
    clm, q0 = five_bar
    cases = [(hexapod, {}), (planar, {}), (clm, {"initial": (q0, np.zeros(clm.nv))})]
    for robot, extra in cases:
        model = robot if isinstance(robot, hp.ClosedLoopModel) else robot.model
        traj = simulate(robot, 0.011, 1e-3, record_every=3, **extra)
        n = 5                                           # steps 0, 3, 6, 9 and the last, 11
        np.testing.assert_allclose(traj.times, [0.0, 0.003, 0.006, 0.009, 0.011], atol=1e-15)
        assert traj.q.shape == (n, model.nq) and traj.v.shape == (n, model.nv)
        n_act = model.n_actuated
        for name in ("actuator_positions", "actuator_velocities", "actuator_forces"):
            assert getattr(traj, name).shape == (n, n_act), name
        for name in ("energies", "kinetic", "potential", "work", "closure_residual",
                     "saturated"):
            assert getattr(traj, name).shape == (n,), name
        np.testing.assert_allclose(traj.energies, traj.kinetic + traj.potential)
        if robot is clm:
            assert traj.poses is None and traj.twists is None
        else:
            assert traj.poses.shape == (n, robot.pose_dim) == traj.twists.shape
            np.testing.assert_allclose(traj.poses[0], robot.home_pose, atol=1e-12)
            np.testing.assert_allclose(traj.twists[0], 0.0, atol=1e-12)
        assert traj.status == "completed" and traj.dt == 1e-3


def test_progress_is_called_at_most_about_a_hundred_times(planar):
    for duration, calls in ((0.25, 84), (0.3, 100), (0.005, 5)):
        seen = []
        simulate(planar, duration, 1e-3, progress=seen.append, record_every=25)
        assert len(seen) == calls and seen[-1] == 1.0 and seen == sorted(seen)


bad_numbers = st.one_of(st.floats(max_value=0.0), st.floats(-1.0, 0.0), st.just(math.nan), st.just(math.inf),
                        st.just(-math.inf), st.booleans(), st.text(max_size=3), st.none(),
                        st.complex_numbers(min_magnitude=1e-3, allow_nan=False))


@PROFILE
@given(value=bad_numbers, which=st.sampled_from(["dt", "duration"]))
def test_bad_dt_or_duration_raise_input_errors(planar, value, which):
    args = {"dt": 1e-3, "duration": 0.01, which: value}
    with pytest.raises(hp.InputError) as info:
        simulate(planar, args["duration"], args["dt"])
    assert info.value.name == which


@PROFILE
@given(dt=st.floats(min_value=1e-12, max_value=1e-6),
       duration=st.floats(min_value=1e3, max_value=1e12))
def test_too_many_steps_raise_input_errors(planar, dt, duration):
    with pytest.raises(hp.InputError, match="MAX_STEPS"):
        simulate(planar, duration, dt)
    assert duration / dt > MAX_STEPS


def bad_calls(planar, five_bar):
    clm, q0 = five_bar
    n = planar.model.nq
    home = planar.home_configuration
    off = home.copy()
    off[0] += 1e-3
    moving = np.zeros(planar.model.nv)
    moving[0] = 1.0                                  # a platform velocity the legs refuse
    return {
        "integrator": dict(integrator="euler"),
        "method": dict(method="nullspace2"),
        "record_every 0": dict(record_every=0),
        "record_every float": dict(record_every=2.0),
        "record_every bool": dict(record_every=True),
        "forces shape": dict(actuator_forces=np.zeros(4)),
        "forces nan": dict(actuator_forces=np.array([0.0, math.nan, 0.0])),
        "forces text": dict(actuator_forces="abc"),
        "both": dict(actuator_forces=np.zeros(3), controller=lambda s, r: np.zeros(3)),
        "initial shape": dict(initial=(np.zeros(n - 1), np.zeros(n))),
        "initial nan": dict(initial=(np.full(n, math.nan), np.zeros(n))),
        "initial not a pair": dict(initial=home),
        "initial off the closures": dict(initial=(off, np.zeros(n))),
        "initial velocity off the closures": dict(initial=(home, moving)),
        "controller shape": dict(controller=lambda s, r: np.zeros(2)),
        "function shape": dict(actuator_forces=lambda t: np.zeros((3, 1))),
        "projection_tol": dict(projection_tol=-1.0),
    }


BAD_CASES = ["integrator", "method", "record_every 0", "record_every float",
             "record_every bool", "forces shape", "forces nan", "forces text", "both",
             "initial shape", "initial nan", "initial not a pair", "initial off the closures",
             "initial velocity off the closures", "controller shape", "function shape",
             "projection_tol"]


@pytest.mark.parametrize("case", BAD_CASES)
def test_bad_arguments_raise_input_errors(planar, five_bar, case):
    calls = bad_calls(planar, five_bar)
    assert sorted(calls) == sorted(BAD_CASES)
    with pytest.raises(hp.InputError):
        simulate(planar, 0.005, 1e-3, **calls[case])


def test_non_finite_commands_raise_naming_the_time(planar):
    def controller(state, robot):
        return np.full(3, math.nan) if state.t > 0.0025 else np.zeros(3)

    with pytest.raises(hp.NonFiniteResultError, match="t = 0.003"):
        simulate(planar, 0.01, 1e-3, controller=controller)


def test_bad_robots_and_callables(planar, five_bar):
    clm, _ = five_bar
    with pytest.raises(hp.ArgumentTypeError):
        simulate("planar", 0.01)
    with pytest.raises(hp.ArgumentTypeError):
        simulate(planar, 0.01, controller=3.0)
    with pytest.raises(hp.InputError, match="initial"):
        simulate(clm, 0.01)                        # a bare model needs a state


def test_controller_arguments_are_checked():
    for kwargs in (dict(kp=-1.0, kd=1.0), dict(kp=1.0, kd=math.nan), dict(kp=1.0, kd=1.0,
                                                                          ki="x"),
                   dict(kp=np.array([1.0, -1.0]), kd=1.0),
                   dict(kp=1.0, kd=1.0, reference=np.zeros((2, 2)))):
        with pytest.raises(hp.InputError):
            ActuatorPID(**kwargs)
    with pytest.raises(hp.InputError):
        ComputedTorque(np.zeros(3))
    with pytest.raises(hp.InputError):
        ComputedTorque(circle, space="joint")
    with pytest.raises(hp.InputError):
        ComputedTorque(circle, kp=-1.0)


def test_trajectory_is_frozen(planar):
    traj = simulate(planar, 0.002, 1e-3)
    with pytest.raises(AttributeError):
        traj.status = "x"


def test_a_closed_loop_robot_runs_through_the_protocol():
    """Any ParallelRobot: the five-bar as a ClosedLoopRobot (its closing point the platform,
    pose (x, z)) keeps its energy falling and is held by computed torque."""
    robot_module = pytest.importorskip("hexapod_pin.core.robot")
    clm = hp.load_parallel_robot(DATA / "five_bar_3d")
    robot = robot_module.ClosedLoopRobot(clm, platform="closure_A", pose_axes=("x", "z"))
    traj = simulate(robot, 0.3, 1e-3)
    assert traj.status == "completed", traj.message
    change, kinetic = drift(traj)
    assert kinetic > 0.5 and change <= 1e-6 * kinetic
    assert traj.poses.shape == traj.twists.shape == (traj.times.size, 2)
    target = robot.home_pose + np.array([0.01, 0.01])
    held = simulate(robot, 0.6, 1e-3, controller=ComputedTorque(
        lambda t: (target, np.zeros(2), np.zeros(2))))
    np.testing.assert_allclose(held.poses[-1], target, atol=1e-5)


def test_the_hexapod_run_agrees_with_the_hexapod_simulator(hexapod):
    """The robot-specific simulator (its own state set-up, closed-form residual and pose
    extraction from the free-flyer) gives the same motion."""
    from hexapod_pin.hexapod.simulation import simulate as hexapod_simulate

    forces = np.array([5.0, -5.0, 3.0, -3.0, 2.0, -2.0])
    ours = simulate(hexapod, 0.1, 1e-3, actuator_forces=forces)
    theirs = hexapod_simulate(hexapod, 0.1, 1e-3, actuator_forces=forces, check_limits=False)
    np.testing.assert_allclose(ours.poses, theirs.poses, atol=1e-9)
    np.testing.assert_allclose(ours.twists, theirs.twists, atol=1e-8)
    np.testing.assert_allclose(ours.actuator_positions, theirs.q, atol=1e-9)
