"""Time-optimal planning (hexapod_pin.planning) checked against independent routes.

Every limit is re-evaluated with the robots' single-state routes (``inverse_dynamics``:
one Pinocchio ``rnea`` per state; ``jacobian`` and ``jacobian_derivative`` for the actuator
rates), never with the coefficients the planner used; the payload mass is re-evaluated
with a robot whose platform is heavier by that mass (the payload sits at the platform
origin, its centre of mass). Rates are checked against finite differences of the poses,
optimality against a bisection over uniform time-scalings, and the forces by integrating
the forward dynamics open loop.
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import hexapod_pin as hp
import robot_registry
from hexapod_pin.core.pose import euler_rates_matrix, rotation_from_rpy
from hexapod_pin.errors import InfeasiblePathError, InputError
from hexapod_pin.planning import GeometricPath, Limits, Payload, time_optimal
from hexapod_pin.planning.feasibility import check_feasibility

ROOT = Path(__file__).resolve().parents[2]
GRID = 200


@pytest.fixture(scope="module")
def robots():
    return {name: robot_registry.get(name) for name in robot_registry.names("closed_form")}


def _heavier(robot, mass):
    """The same robot with ``mass`` (kg) added to the platform at its origin."""
    if mass == 0:
        return robot
    geometry = dataclasses.replace(robot.geometry,
                                   platform_mass=robot.geometry.platform_mass + mass)
    return type(robot)(geometry)


def _hex_path(robot):
    h = robot.home_pose
    return np.array([h, h + [0.02, 0.0, 0.01, 0.03, 0.0, 0.05],
                     h + [0.0, 0.02, -0.01, 0.0, 0.04, -0.05]])


def _planar_path(robot):
    return np.array([[0.0, 0.0, 0.0], [0.03, 0.02, 0.2], [-0.02, 0.04, -0.1]])


def _hex_rotation_path(robot):
    h = robot.home_pose
    return np.array([h, h + [0, 0, 0, 0.08, 0, 0.25], h + [0.005, 0, 0, -0.05, 0.08, 0.4],
                     h + [0, 0, 0.005, 0, 0, -0.2]])


def _planar_rotation_path(robot):
    return np.array([[0, 0, 0], [0.0, 0.0, 0.3], [0.04, -0.02, 0.25], [0.0, 0.03, -0.2]])


CASES = {
    "hexapod": ("hexapod", _hex_path, Limits(), Payload()),
    "hexapod-payload-rates": ("hexapod", _hex_path,
                              Limits(actuator_velocity=0.6, actuator_acceleration=60.0),
                              Payload(mass=1.0)),
    "hexapod-speeds-wrench": ("hexapod", _hex_path,
                              Limits(linear_speed=0.4, angular_speed=2.0),
                              Payload(wrench=(2.0, 0.0, -5.0, 0.0, 0.1, 0.0))),
    "hexapod-rotation": ("hexapod", _hex_rotation_path, Limits(actuator_acceleration=30.0),
                         Payload()),
    "planar": ("planar", _planar_path, Limits(actuator_force=30.0), Payload()),
    "planar-rotation": ("planar", _planar_rotation_path,
                        Limits(actuator_force=25.0, actuator_acceleration=20.0,
                               linear_speed=0.5), Payload()),
    "planar-payload": ("planar", _planar_path,
                       Limits(actuator_force=30.0, actuator_velocity=0.5),
                       Payload(mass=0.5, wrench=(1.0, 0.0, 0.05))),
}


#: finer grids where the acceleration limits' coefficients bend fast along the path (the
#: excess between grid points shrinks with the grid step: 0.63 % at 200 points, 0.15 % at
#: 800 on "hexapod-rotation")
GRIDS = {"hexapod-rotation": 800}


@pytest.fixture(scope="module")
def planned(robots):
    out = {}
    for name, (robot_name, path, limits, payload) in CASES.items():
        robot = robots[robot_name]
        out[name] = time_optimal(robot, path(robot), limits=limits, payload=payload,
                                 grid_points=GRIDS.get(name, GRID))
    return out


def _reference_values(robot, limits, payload, poses, twists, twist_dots):
    """Per-state ratios value / bound of every finite limit, single-state routes only."""
    heavy = _heavier(robot, payload.mass)
    bounds = limits.per_actuator(robot)
    lin = 3 if robot.pose_dim == 6 else 2
    gravity = np.zeros(robot.pose_dim)
    gravity[:lin] = np.asarray(robot.model.model.gravity.linear)[:lin]
    columns = []
    for pose, twist, twist_dot in zip(poses, twists, twist_dots):
        wrench = None if payload.wrench is None else np.asarray(payload.wrench, dtype=float)
        tau = heavy.inverse_dynamics(pose, twist, twist_dot, wrench,
                                     bounded=False).actuator_forces
        jac = robot.jacobian(pose)
        qd = jac @ twist
        qdd = jac @ twist_dot + robot.jacobian_derivative(pose, twist) @ twist
        columns.append(np.concatenate([
            np.abs(tau) / bounds["force"], np.abs(qd) / bounds["velocity"],
            np.abs(qdd) / bounds["acceleration"],
            [np.linalg.norm(twist[:lin]) / limits.linear_speed,
             np.linalg.norm(twist[lin:]) / limits.angular_speed]]))
    return np.array(columns)


@pytest.mark.parametrize("case", list(CASES))
def test_limits_hold_on_the_grid_and_between(robots, planned, case):
    traj = planned[case]
    robot_name, _, limits, payload = CASES[case]
    robot = robots[robot_name]
    at_grid = _reference_values(robot, limits, payload, traj.poses, traj.twists,
                                traj.twist_dots)
    assert np.max(at_grid) <= 1.0 + 1e-6
    # the returned forces are those of the Pinocchio route
    heavy = _heavier(robot, payload.mass)
    wrench = None if payload.wrench is None else np.asarray(payload.wrench, dtype=float)
    for k in range(0, len(traj.t), 17):
        ref = heavy.inverse_dynamics(traj.poses[k], traj.twists[k], traj.twist_dots[k],
                                     wrench, bounded=False).actuator_forces
        np.testing.assert_allclose(traj.actuator_forces[k], ref, atol=1e-8)
    dense = traj.sample(np.linspace(0.0, traj.duration, 10 * len(traj.t)))
    between = _reference_values(robot, limits, payload, dense.poses, dense.twists,
                                dense.twist_dots)
    assert np.max(between) <= 1.005


@pytest.mark.parametrize("case", list(CASES))
def test_rates_match_finite_differences_of_the_poses(robots, planned, case):
    traj = planned[case]
    h = 1e-6 * traj.duration
    times = np.linspace(0.05, 0.95, 40) * traj.duration
    # centred differences inside segments (constant s_ddot on each)
    mid = traj.sample(times)
    plus, minus = traj.sample(times + h), traj.sample(times - h)
    lin = 3 if traj.poses.shape[1] == 6 else 2
    vel = (plus.poses[:, :lin] - minus.poses[:, :lin]) / (2 * h)
    if lin == 3:
        rel = np.einsum("nij,nkj->nik", rotation_from_rpy(plus.poses[:, 3:]),
                        rotation_from_rpy(minus.poses[:, 3:]))
        omega = Rotation.from_matrix(rel).as_rotvec() / (2 * h)
    else:
        omega = (plus.poses[:, 2:] - minus.poses[:, 2:]) / (2 * h)
    scale = np.max(np.abs(mid.twists))
    np.testing.assert_allclose(np.hstack([vel, omega]), mid.twists, atol=1e-6 * scale)
    acc = (plus.twists - minus.twists) / (2 * h)
    np.testing.assert_allclose(acc, mid.twist_dots, atol=1e-5 * np.max(np.abs(mid.twist_dots)))
    # the grid samples are the same motion as the resampled one
    again = traj.sample(traj.t)
    np.testing.assert_allclose(again.poses, traj.poses, atol=1e-9)
    np.testing.assert_allclose(again.twists, traj.twists, atol=1e-9 * scale)


@pytest.mark.parametrize("case", list(CASES))
def test_a_limit_is_active_at_every_grid_point_but_isolated_switches(robots, planned, case):
    traj = planned[case]
    robot_name, _, limits, payload = CASES[case]
    robot = robots[robot_name]
    right = np.max(_reference_values(robot, limits, payload, traj.poses, traj.twists,
                                     traj.twist_dots), axis=1)
    left_samples = traj.sample(np.maximum(traj.t - 1e-9 * traj.duration, 0.0))
    left = np.max(_reference_values(robot, limits, payload, left_samples.poses,
                                    left_samples.twists, left_samples.twist_dots), axis=1)
    inactive = np.maximum(left, right) < 0.99
    runs = np.diff(np.flatnonzero(np.diff(np.concatenate([[0], inactive, [0]]))))[::2]
    assert inactive.sum() <= 0.05 * len(traj.t), np.flatnonzero(inactive)
    assert runs.size == 0 or runs.max() <= 2, np.flatnonzero(inactive)


def _quintic_feasible(robot, traj, limits, payload, duration, count=150):
    """Whether the rest-to-rest quintic timing of the same path, lasting ``duration``,
    meets every limit (single-state routes)."""
    tau = np.linspace(0.0, 1.0, count)
    length = traj.path.length
    sigma = 10 * tau ** 3 - 15 * tau ** 4 + 6 * tau ** 5
    dsigma = (30 * tau ** 2 - 60 * tau ** 3 + 30 * tau ** 4) / duration
    ddsigma = (60 * tau - 180 * tau ** 2 + 120 * tau ** 3) / duration ** 2
    samples = traj.path.sample(length * sigma)
    twists = samples.tangents * (length * dsigma)[:, None]
    twist_dots = samples.tangents * (length * ddsigma)[:, None] \
        + samples.curvatures * ((length * dsigma) ** 2)[:, None]
    ratios = _reference_values(robot, limits, payload, samples.poses, twists, twist_dots)
    return np.max(ratios) <= 1.0


def _best_uniform_duration(robot, traj, limits, payload) -> float:
    lo, hi = 0.01 * traj.duration, 10.0 * traj.duration
    assert _quintic_feasible(robot, traj, limits, payload, hi)
    for _ in range(30):
        mid = np.sqrt(lo * hi)
        if _quintic_feasible(robot, traj, limits, payload, mid):
            hi = mid
        else:
            lo = mid
    return hi


@pytest.mark.parametrize("case", ["hexapod", "planar-payload"])
def test_never_slower_than_the_best_uniform_time_scaling(robots, planned, case):
    traj = planned[case]
    robot_name, _, limits, payload = CASES[case]
    best = _best_uniform_duration(robots[robot_name], traj, limits, payload)
    assert traj.duration <= best * (1 + 1e-3)


def test_shorter_where_one_actuator_limits_part_of_the_path(robots):
    # a lift (the weight loads every actuator) then a sideways move along x that loads
    # the rails unevenly: different actuators saturate on different parts
    robot = robots["hexapod"]
    h = robot.home_pose
    waypoints = np.array([h, h + [0.0, 0.0, 0.01, 0, 0, 0], h + [0.03, 0.0, 0.01, 0, 0, 0]])
    limits = Limits(actuator_force=40.0)
    traj = time_optimal(robot, waypoints, limits=limits, grid_points=GRID)
    saturated = np.abs(traj.actuator_forces) >= 0.99 * 40.0
    owners = {int(np.argmax(row)) for row in saturated if row.any()}
    assert len(owners) >= 2          # the limiting actuator changes along the path
    best = _best_uniform_duration(robot, traj, limits, Payload())
    assert traj.duration <= 0.9 * best


def _open_loop_error(robot, traj, substeps=2) -> tuple[float, float]:
    """Integrate forward dynamics (RK4, Euler-angle pose) driven by the planned forces
    from the first sample, ``substeps`` steps per grid segment (the forces jump between
    segments, where ``s_ddot`` does); max position error (m) and rotation error (rad)."""
    dim = robot.pose_dim
    lin = 3 if dim == 6 else 2
    grid = traj.phase_times()
    edges = np.concatenate([np.linspace(a, b, substeps + 1)[:-1]
                            for a, b in itertools.pairwise(grid)] + [grid[-1:]])
    steps = len(edges) - 1
    eps = 1e-12 * traj.duration          # stay inside the step's own segment
    stage_times = np.concatenate([[a + eps, (a + b) / 2, b - eps]
                                  for a, b in itertools.pairwise(edges)])
    forces = traj.sample(stage_times).actuator_forces.reshape(steps, 3, -1)
    ref = traj.sample(edges)

    def rates(state, force):
        pose, twist = state[:dim], state[dim:]
        twist_dot = robot.forward_dynamics(pose, twist, force).twist_dot
        if dim == 6:
            angle_rates = np.linalg.solve(euler_rates_matrix(pose[3:]), twist[3:])
        else:
            angle_rates = twist[2:]
        return np.concatenate([twist[:lin], angle_rates, twist_dot])

    state = np.concatenate([traj.poses[0], traj.twists[0]])
    err_p, err_r = 0.0, 0.0
    for k in range(steps):
        dt = edges[k + 1] - edges[k]
        f0, fh, f1 = forces[k]
        k1 = rates(state, f0)
        k2 = rates(state + dt / 2 * k1, fh)
        k3 = rates(state + dt / 2 * k2, fh)
        k4 = rates(state + dt * k3, f1)
        state = state + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        err_p = max(err_p, np.linalg.norm(state[:lin] - ref.poses[k + 1, :lin]))
        if dim == 6:
            rel = rotation_from_rpy(state[3:6]).T @ rotation_from_rpy(ref.poses[k + 1, 3:])
            err_r = max(err_r, np.linalg.norm(Rotation.from_matrix(rel).as_rotvec()))
        else:
            err_r = max(err_r, abs(state[2] - ref.poses[k + 1, 2]))
    return err_p, err_r


@pytest.mark.parametrize("robot_name", ["hexapod", "planar"])
def test_open_loop_forward_dynamics_reproduces_a_short_path(robots, robot_name):
    # the path length is about 1 cm; the motion lasts a few hundredths of a second
    robot = robots[robot_name]
    if robot_name == "hexapod":
        h = robot.home_pose
        waypoints = np.array([h, h + [0.006, 0.004, 0.004, 0.02, -0.01, 0.03]])
        limits = Limits()
    else:
        waypoints = np.array([[0.0, 0.0, 0.0], [0.008, 0.005, 0.05]])
        limits = Limits(actuator_force=30.0)
    traj = time_optimal(robot, waypoints, limits=limits, grid_points=400)
    err_p, err_r = _open_loop_error(robot, traj)
    # bound: 1e-9 m and 1e-8 rad over the whole path (RK4 with the steps on the grid
    # segments, where the forces are smooth; measured about 1e-14 m and 1e-13 rad)
    assert err_p <= 1e-9 and err_r <= 1e-8, (err_p, err_r)


def test_payload_mass_needs_more_time(robots):
    robot = robots["hexapod"]
    light = time_optimal(robot, _hex_path(robot), grid_points=GRID)
    heavy = time_optimal(robot, _hex_path(robot), payload=Payload(mass=2.0), grid_points=GRID)
    assert heavy.duration > light.duration


def test_a_pose_that_cannot_be_held_statically_is_named(robots):
    # lowering the platform spreads the legs: the static forces grow past 2.5 N on the way
    robot = robots["hexapod"]
    h = robot.home_pose
    waypoints = np.array([h, h - [0.0, 0.0, 0.04, 0, 0, 0]])
    with pytest.raises(InfeasiblePathError) as info:
        time_optimal(robot, waypoints, limits=Limits(actuator_force=2.5), grid_points=GRID)
    err = info.value
    assert 0 < err.index < GRID - 1 and err.actuator is not None
    held = robot.static_forces(err.pose, bounded=False)
    assert abs(held[err.actuator]) > 2.5
    assert abs(held[err.actuator]) == pytest.approx(abs(err.value), rel=1e-9)
    before = GeometricPath(waypoints, 0.12).sample([err.s - 0.04 / (GRID - 1)]).poses[0]
    assert np.max(np.abs(robot.static_forces(before, bounded=False))) <= 2.5
    # with a payload: the heavier robot (payload at the platform origin) cannot hold it
    with pytest.raises(InfeasiblePathError) as info:
        time_optimal(robot, _hex_path(robot), payload=Payload(mass=3.0),
                     limits=Limits(actuator_force=3.0), grid_points=GRID)
    err = info.value
    heavy = _heavier(robot, 3.0)
    assert np.max(np.abs(heavy.static_forces(err.pose, bounded=False))) > 3.0
    planar = robots["planar"]
    with pytest.raises(InfeasiblePathError) as info:
        time_optimal(planar, _planar_path(planar), limits=Limits(actuator_force=5.0),
                     grid_points=GRID)
    assert "statically" in str(info.value) and info.value.index == 0


def test_a_path_leaving_the_strokes_is_rejected_at_its_point(robots):
    robot = robots["hexapod"]
    h = robot.home_pose
    waypoints = np.array([h, h + [0.2, 0.0, 0.0, 0, 0, 0]])
    with pytest.raises(InfeasiblePathError) as info:
        time_optimal(robot, waypoints, grid_points=GRID)
    err = info.value
    assert 0 < err.index < GRID - 1
    assert not robot.inverse_kinematics_batch(err.pose[None]).ok[0]
    before = GeometricPath(waypoints, 0.12).sample(np.linspace(0, err.s, 50)[:-1]).poses
    assert robot.inverse_kinematics_batch(before).ok.all()


def test_bad_requests_raise_input_errors(robots):
    planar = robots["planar"]
    with pytest.raises(InputError):          # no finite limit
        time_optimal(planar, _planar_path(planar), grid_points=GRID)
    with pytest.raises(InputError):
        time_optimal(planar, _planar_path(planar)[:1], limits=Limits(actuator_force=30.0))
    with pytest.raises(InputError):
        time_optimal(robots["hexapod"], _planar_path(planar))
    with pytest.raises(InfeasiblePathError):  # start speed beyond the limits
        time_optimal(planar, _planar_path(planar), limits=Limits(actuator_force=30.0),
                     start_speed=100.0, grid_points=GRID)


@pytest.mark.parametrize("case", ["hexapod", "planar-payload"])
def test_feasibility_report(robots, planned, case):
    traj = planned[case]
    robot_name, _, limits, payload = CASES[case]
    robot = robots[robot_name]
    report = check_feasibility(robot, traj, limits=limits, payload=payload)
    assert report.feasible
    assert 0.99 <= report.slow_down <= 1.0 + 1e-6
    # twice as fast: infeasible, and the slow-down factor brings it back (checked by
    # re-evaluating the slowed motion with the single-state routes)
    fast = {"t": traj.t / 2, "poses": traj.poses, "twists": traj.twists * 2,
            "twist_dots": traj.twist_dots * 4}
    report = check_feasibility(robot, fast, limits=limits, payload=payload)
    assert not report.feasible and report.worst.excess > 0
    k = report.slow_down
    assert 1.9 <= k <= 2.0 + 1e-6
    ratios = _reference_values(robot, limits, payload, traj.poses, fast["twists"] / k,
                               fast["twist_dots"] / k ** 2)
    assert np.max(ratios) <= 1 + 1e-6 and np.max(ratios) >= 0.99
    worst = report.worst
    assert report.values[worst.limit][worst.index, worst.component] == pytest.approx(worst.value)


def test_no_slow_down_helps_when_holding_the_pose_already_exceeds_the_bound(robots, planned):
    """A force bound below the static forces: ``slow_down`` is inf and the reason names the
    actuator, the sample and the static force, which the test computes with statics."""
    traj = planned["hexapod"]
    robot = robots["hexapod"]
    static = np.abs(robot.static_forces_batch(traj.poses, bounded=False))
    bound = 0.5 * float(np.max(static))
    report = check_feasibility(robot, traj, limits=Limits(actuator_force=bound))
    assert report.slow_down == np.inf and not report.feasible
    k, j = np.unravel_index(int(np.argmax(static)), static.shape)
    assert f"needs {static[k, j]:.6g} on actuator {j} at sample {k}" in report.slow_down_reason
    fine = check_feasibility(robot, traj, limits=Limits(actuator_force=1e3))
    assert fine.slow_down_reason == "" and fine.slow_down < np.inf


def test_feasibility_of_a_motion_file(robots, planned, tmp_path):
    from hexapod_pin.motion import Motion, write_motion

    traj = planned["hexapod"]
    path = write_motion(tmp_path / "m.csv", Motion(traj.t, traj.poses))
    report = check_feasibility(robots["hexapod"], path)
    # rates by finite differences of the poses: close to the planned ones
    assert report.slow_down == pytest.approx(1.0, abs=0.05)


def test_benchmark_smoke():
    done = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_planning.py"),
                           "--smoke"], check=False, capture_output=True, text=True,
                          timeout=600)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "grid points" in done.stdout


def test_cli_retime_and_check(tmp_path):
    from typer.testing import CliRunner

    from hexapod_pin.cli.main import app
    from hexapod_pin.motion import Motion, read_motion, write_motion

    robot = hp.Hexapod.default()
    poses = _hex_path(robot)
    src = write_motion(tmp_path / "path.csv", Motion(np.arange(3.0), poses))
    out, fig = tmp_path / "timed.csv", tmp_path / "fig.png"
    runner = CliRunner()
    done = runner.invoke(app, ["retime", str(src), "--out", str(out), "--grid", "200",
                               "--plot", str(fig), "--json"])
    assert done.exit_code == 0, done.output
    summary = json.loads(done.stdout)
    timed = read_motion(out)
    assert summary["duration_s"] == pytest.approx(timed.t[-1])
    assert fig.stat().st_size > 0
    done = runner.invoke(app, ["check", str(out), "--json"])
    assert done.exit_code == 0, done.output
    report = json.loads(done.stdout)
    assert report["feasible"] and report["slow_down"] <= 1.0 + 1e-6
    done = runner.invoke(app, ["check", str(out), "--max-force", "50", "--json"])
    assert done.exit_code == 1
    assert json.loads(done.stdout)["feasible"] is False
    # resampled between the grid points: within the 0.5 % of the planner's guarantee
    resampled = tmp_path / "resampled.json"
    done = runner.invoke(app, ["retime", str(src), "--out", str(resampled), "--grid", "400",
                               "--rate", "300", "--max-velocity", "0.5", "--json"])
    assert done.exit_code == 0, done.output
    done = runner.invoke(app, ["check", str(resampled), "--max-velocity", "0.5",
                               "--tolerance", "0.005", "--json"])
    assert done.exit_code == 0, done.output
    assert json.loads(done.stdout)["slow_down"] <= 1.005


def test_plots(planned, tmp_path):
    pytest.importorskip("matplotlib")
    from hexapod_pin.viz.planning_plots import plot_forces_against_limits, plot_phase_plane

    traj = planned["hexapod-payload-rates"]
    fig = plot_forces_against_limits(traj, path=tmp_path / "f.png")
    assert len(fig.axes) >= 1 and (tmp_path / "f.png").stat().st_size > 0
    fig = plot_phase_plane(traj, path=tmp_path / "p.svg")
    assert (tmp_path / "p.svg").stat().st_size > 0


@pytest.mark.parametrize("case", ["hexapod-payload-rates", "planar-payload"])
def test_solver_agrees_with_toppra_on_the_same_rows(robots, case):
    """The compiled TOPP-RA against toppra's (seidel LP solver wrapper, interpolation
    discretisation), both fed the same constraint rows: the same speed profile."""
    toppra = pytest.importorskip("toppra")
    import toppra.constraint as tc

    from hexapod_pin.planning import limits as planning_limits

    robot_name, path, limits, payload = CASES[case]
    robot = robots[robot_name]
    traj = time_optimal(robot, path(robot), limits=limits, payload=payload, grid_points=GRID)
    samples = traj.path.sample(traj.s)
    coeffs = planning_limits.path_coefficients(robot, samples, limits, payload)
    rows = planning_limits.constraint_rows(coeffs, robot, limits)

    class Rows(tc.LinearConstraint):
        def __init__(self):
            super().__init__()
            self.discretization_type = tc.DiscretizationType.Interpolation
            self.identical = True

        def compute_constraint_params(self, path, gridpoints, *args, **kwargs):
            m = rows.shape[1]
            a, b, c, f, g, _, _ = tc.canlinear_colloc_to_interpolate(
                rows[:, :, 0], rows[:, :, 1], rows[:, :, 2], np.eye(m), np.zeros(m),
                None, None, gridpoints, identical=True)
            xbound = np.stack([np.zeros(len(traj.s)), np.minimum(coeffs.speed_bound, 1e8)],
                              axis=1)
            return a, b, c, f, g, None, xbound

    algo = toppra.algorithm.TOPPRA([Rows()], toppra.SplineInterpolator(traj.s, traj.poses),
                                   gridpoints=traj.s, solver_wrapper="seidel")
    _, s_dot, _ = algo.compute_parameterization(0, 0)
    np.testing.assert_allclose(traj.s_dot, s_dot, atol=1e-6 * np.max(s_dot))


def test_given_start_and_end_path_speeds(robots):
    robot = robots["planar"]
    limits = Limits(actuator_force=30.0)
    rest = time_optimal(robot, _planar_path(robot), limits=limits, grid_points=GRID)
    moving = time_optimal(robot, _planar_path(robot), limits=limits, grid_points=GRID,
                          start_speed=0.05, end_speed=0.08)
    assert moving.s_dot[0] == pytest.approx(0.05, rel=1e-9)
    assert moving.s_dot[-1] == pytest.approx(0.08, rel=1e-9)
    assert moving.duration < rest.duration
    np.testing.assert_allclose(np.linalg.norm(moving.twists[0]),
                               0.05 * np.linalg.norm(moving.path.sample([0.0]).tangents[0]))
    ratios = _reference_values(robot, limits, Payload(), moving.poses, moving.twists,
                               moving.twist_dots)
    assert np.max(ratios) <= 1 + 1e-6


def test_a_margin_keeps_the_motion_between_grid_points_within_the_full_bounds(robots):
    robot_name, path, limits, payload = CASES["hexapod-rotation"]
    robot = robots[robot_name]
    # at 200 grid points this path exceeds its acceleration bound by 0.63 % between
    # grid points without a margin (see GRIDS)
    with_margin = dataclasses.replace(limits, margin=0.01)
    traj = time_optimal(robot, path(robot), limits=with_margin, payload=payload,
                        grid_points=GRID)
    at_grid = _reference_values(robot, limits, payload, traj.poses, traj.twists,
                                traj.twist_dots)
    assert np.max(at_grid) <= 0.99 + 1e-6
    dense = traj.sample(np.linspace(0.0, traj.duration, 10 * GRID))
    between = _reference_values(robot, limits, payload, dense.poses, dense.twists,
                                dense.twist_dots)
    assert np.max(between) <= 1.0
    report = check_feasibility(robot, dense, limits=limits, payload=payload)
    assert report.feasible
    with pytest.raises(InputError):
        time_optimal(robot, path(robot), limits=dataclasses.replace(limits, margin=1.0))
