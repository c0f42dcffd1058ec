"""Time-optimal planning and motion files on robots loaded from descriptions.

``hp.planning.time_optimal`` on a five-bar (pose ``(x, z)``), a 3-RUU delta (``(x, y,
z)``), a 6-UPS Gough-Stewart platform (all six) and a four-bar (``(x,)``), each a
``hp.ClosedLoopRobot`` with no closed form. Independent routes: the forces against the
robot's single-state ``inverse_dynamics`` at the states of the trajectory (the planner
uses affine coefficients from one batch call), the payload's wrench written here from the
model's gravity, the twists against finite differences of the poses in time (angles of
the Stewart platform through the Euler-rate map and rotation matrices), the path through
the waypoints; the time-optimal property as a limit active at almost every grid point.
Motion files: a five-bar round trip (2 pose columns, 2 actuators) and a hexapod file
written before robots had pose axes.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

import hexapod_pin as hp
import robot_registry
from hexapod_pin import motion as motions
from hexapod_pin.core.pose import rotation_from_rpy
from hexapod_pin.core.robot_api import pose_layout
from hexapod_pin.errors import DescriptionError, InputError
from hexapod_pin.planning import (GeometricPath, Limits, Payload, check_feasibility,
                                  read_waypoints, time_optimal)

GRID = 120

#: robot (of tests/robot_registry.py) -> (waypoint offsets from home, pose axes)
ROBOTS = {
    "five-bar": ([[0.0, 0.0], [0.02, 0.01], [-0.01, 0.03]], ("x", "z")),
    "delta": ([[0.0, 0.0, 0.0], [0.02, 0.0, 0.01], [0.0, 0.02, -0.01]], ("x", "y", "z")),
    "stewart": ([[0.0] * 6, [0.02, 0.0, 0.01, 0.03, 0.0, 0.05],
                 [0.0, 0.02, -0.01, 0.0, 0.04, -0.05]],
                ("x", "y", "z", "roll", "pitch", "yaw")),
    "four-bar": ([[0.0], [0.01], [-0.01]], ("x",)),
}
_robot = robot_registry.get


def _waypoints(name):
    robot = _robot(name)
    return robot.home_pose + np.array(ROBOTS[name][0], dtype=float)


def _force_bound(name) -> float:
    """Three times the largest static force along the waypoints (N or N m)."""
    robot = _robot(name)
    return 3.0 * float(np.max(np.abs(robot.static_forces_batch(_waypoints(name),
                                                               bounded=False)))) + 0.5


#: case -> (robot, limits, payload mass (kg))
CASES = {
    "five-bar": ("five-bar", {}, 0.0),
    "five-bar-payload-speed": ("five-bar", {"linear_speed": 0.3}, 0.2),
    "delta": ("delta", {"actuator_acceleration": 60.0}, 0.0),
    "stewart": ("stewart", {"angular_speed": 1.5}, 0.5),
    "four-bar": ("four-bar", {}, 0.0),
}
_PLANS: dict = {}


def _plan(case):
    if case not in _PLANS:
        name, extra, mass = CASES[case]
        limits = Limits(actuator_force=_force_bound(name), **extra)
        payload = Payload(mass=mass)
        _PLANS[case] = time_optimal(_robot(name), _waypoints(name), limits=limits,
                                    payload=payload, grid_points=GRID)
    return _PLANS[case]


def _gravity(robot):
    """The model's gravity on the robot's linear pose axes, written out per axis (m/s^2)."""
    g = np.asarray(robot.model.model.gravity.linear, dtype=float)
    world = {"x": 0, "y": 1, "z": 2}
    return {axis: g[world[axis]] for axis in robot.pose_axes if axis in world}


def _payload_wrench(robot, mass, twist_dot):
    """``m (g - a)`` on the linear pose axes, 0 on the angles (N)."""
    gravity = _gravity(robot)
    return np.array([mass * (gravity[axis] - twist_dot[k]) if axis in gravity else 0.0
                     for k, axis in enumerate(robot.pose_axes)])


def _reference_forces(robot, mass, poses, twists, twist_dots):
    """Actuator forces (N, n_act) from the single-state ``robot.inverse_dynamics``."""
    return np.array([robot.inverse_dynamics(
        pose, twist, twist_dot, _payload_wrench(robot, mass, twist_dot) if mass else None,
        bounded=False).actuator_forces
        for pose, twist, twist_dot in zip(poses, twists, twist_dots)])


# -- the pose layout of every robot -----------------------------------------------------------
@pytest.mark.parametrize("name", sorted(ROBOTS))
def test_loaded_robots_have_their_pose_axes(name):
    robot = _robot(name)
    assert robot.pose_axes == ROBOTS[name][1] == robot.geometry.pose_axes
    layout = pose_layout(robot)
    assert len(layout.linear) + len(layout.angular) == robot.pose_dim
    assert layout.full_rotation == (name == "stewart")
    assert hp.Hexapod.default().pose_axes == ("x", "y", "z", "roll", "pitch", "yaw")
    assert hp.Planar3PRR.default().pose_axes == ("x", "y", "yaw")


def test_payload_weight_goes_to_the_selected_axes():
    five_bar, delta = _robot("five-bar"), _robot("delta")
    g = np.asarray(five_bar.model.model.gravity.linear)
    w = Payload(mass=2.0).wrenches(five_bar, np.zeros((1, 2)))
    np.testing.assert_array_equal(w, [[2.0 * g[0], 2.0 * g[2]]])        # (x, z)
    w = Payload(mass=2.0).wrenches(delta, np.array([[1.0, 2.0, 3.0]]))
    np.testing.assert_allclose(w, [2.0 * (np.asarray(delta.model.model.gravity.linear)
                                          - [1.0, 2.0, 3.0])])


# -- planning -----------------------------------------------------------------------------------
def _worst_ratio(case, motion):
    """Per sample (N,): the largest value / bound of the case's limits, single-state
    routes (forces: ``inverse_dynamics``; actuator accelerations ``J a + dJ/dt v``)."""
    name, extra, mass = CASES[case]
    robot = _robot(name)
    ratios = [np.abs(_reference_forces(robot, mass, motion.poses, motion.twists,
                                       motion.twist_dots)) / _force_bound(name)]
    if "actuator_acceleration" in extra:
        acc = np.array([robot.jacobian(p) @ a + robot.jacobian_derivative(p, v) @ v
                        for p, v, a in zip(motion.poses, motion.twists, motion.twist_dots)])
        ratios.append(np.abs(acc) / extra["actuator_acceleration"])
    layout = pose_layout(robot)
    for key, part in (("linear_speed", layout.linear), ("angular_speed", layout.angular)):
        if key in extra:
            ratios.append(np.linalg.norm(motion.twists[:, part], axis=1)[:, None] / extra[key])
    return np.max(np.hstack(ratios), axis=1)


@pytest.mark.parametrize("case", sorted(CASES))
def test_forces_within_the_bounds_and_tight(case):
    traj = _plan(case)
    name, extra, _ = CASES[case]
    ratio = np.abs(traj.actuator_forces) / _force_bound(name)
    assert np.max(ratio) <= 1.0 + 1e-6
    if not extra:
        assert np.max(ratio) >= 1.0 - 1e-6         # the only limit is tight somewhere
    right = _worst_ratio(case, traj)
    assert np.max(right) <= 1.0 + 1e-6
    # time-optimal: some limit is tight at every grid point but isolated switches (the
    # segment's constant acceleration meets the limit of its left or of its right end)
    left = _worst_ratio(case, traj.sample(np.maximum(traj.t - 1e-9 * traj.duration, 0.0)))
    slack = np.flatnonzero(np.maximum(left, right)[1:-1] < 1.0 - 1e-6) + 1
    assert slack.size <= 0.05 * len(traj.t), slack


@pytest.mark.parametrize("case", sorted(CASES))
def test_forces_agree_with_the_single_state_inverse_dynamics(case):
    traj = _plan(case)
    name, _, mass = CASES[case]
    robot = _robot(name)
    scale = _force_bound(name)
    grid = np.arange(0, len(traj.t), 13)
    np.testing.assert_allclose(
        traj.actuator_forces[grid],
        _reference_forces(robot, mass, traj.poses[grid], traj.twists[grid],
                          traj.twist_dots[grid]), atol=1e-8 * scale)
    dense = traj.sample(np.linspace(0.0, traj.duration, 11))
    np.testing.assert_allclose(
        dense.actuator_forces,
        _reference_forces(robot, mass, dense.poses, dense.twists, dense.twist_dots),
        atol=1e-8 * scale)
    np.testing.assert_allclose(dense.actuator_velocities,
                               np.einsum("nij,nj->ni", robot.jacobian_batch(
                                   dense.poses).jacobian, dense.twists), atol=1e-10)


@pytest.mark.parametrize("case", sorted(CASES))
def test_poses_follow_the_waypoints_and_the_twists_their_rates(case):
    traj = _plan(case)
    name = CASES[case][0]
    robot, waypoints = _robot(name), _waypoints(name)
    np.testing.assert_allclose(traj.poses[0], waypoints[0], atol=1e-12)
    np.testing.assert_allclose(traj.poses[-1], waypoints[-1], atol=1e-12)
    # the path passes through every waypoint, at the knots (chord lengths)
    at_knots = traj.path.sample(traj.path.knots).poses
    np.testing.assert_allclose(at_knots, waypoints, atol=1e-10)
    # a grid pose near each waypoint (the grid step bounds the distance)
    step = np.max(np.linalg.norm(np.diff(traj.poses, axis=0), axis=1))
    for w in waypoints:
        assert np.min(np.linalg.norm(traj.poses - w, axis=1)) <= step
    # twists and their derivatives: centred differences in time inside segments
    h = 1e-6 * traj.duration
    times = np.linspace(0.05, 0.95, 30) * traj.duration
    mid, plus, minus = traj.sample(times), traj.sample(times + h), traj.sample(times - h)
    layout = pose_layout(robot)
    rates = np.empty_like(mid.twists)
    lin, ang = layout.linear, layout.angular
    rates[:, lin] = (plus.poses[:, lin] - minus.poses[:, lin]) / (2 * h)
    if layout.full_rotation:
        rel = np.einsum("nij,nkj->nik", rotation_from_rpy(plus.poses[:, ang]),
                        rotation_from_rpy(minus.poses[:, ang]))
        rates[:, ang] = Rotation.from_matrix(rel).as_rotvec() / (2 * h)
    scale = np.max(np.abs(mid.twists))
    np.testing.assert_allclose(rates, mid.twists, atol=1e-6 * scale)
    acc = (plus.twists - minus.twists) / (2 * h)
    np.testing.assert_allclose(acc, mid.twist_dots, atol=1e-5 * np.max(np.abs(mid.twist_dots)))


@pytest.mark.parametrize("case", sorted(CASES))
def test_check_feasibility_of_the_result_passes(case):
    traj = _plan(case)
    name, extra, mass = CASES[case]
    robot = _robot(name)
    limits = Limits(actuator_force=_force_bound(name), **extra)
    report = check_feasibility(robot, traj, limits=limits, payload=Payload(mass=mass),
                               tolerance=1e-6)
    assert report.feasible, report.worst
    assert 1.0 - 1e-3 <= report.slow_down <= 1.0 + 1e-6
    # the same motion from its poses only (rates by finite differences, per pose layout)
    dense = traj.resample(400.0 / traj.duration)
    again = check_feasibility(robot, {"t": dense.t, "poses": dense.poses}, limits=limits,
                              payload=Payload(mass=mass))
    assert again.slow_down == pytest.approx(1.0, abs=0.05)


def test_a_speed_the_pose_lacks_is_ignored():
    """The delta's pose has no angle: an angular-speed bound changes nothing; the
    four-bar's (x,) pose has no angle either."""
    name = "delta"
    base = Limits(actuator_force=_force_bound(name))
    free = time_optimal(_robot(name), _waypoints(name), limits=base, grid_points=GRID)
    bound = time_optimal(_robot(name), _waypoints(name), grid_points=GRID,
                         limits=dataclasses.replace(base, angular_speed=1e-3))
    assert bound.duration == free.duration
    assert check_feasibility(_robot(name), bound, limits=dataclasses.replace(
        base, angular_speed=1e-3), tolerance=1e-6).feasible


def test_partial_angles_are_scalar_splines():
    """A pose with one angle: that angle is a natural cubic spline of ``s`` and its rate
    the matching twist component (finite differences along ``s``)."""
    waypoints = np.array([[0.0, 0.0, 0.0], [0.02, 0.01, 0.3], [0.0, 0.03, -0.2]])
    path = GeometricPath(waypoints, 0.1, ("x", "z", "pitch"))
    assert path.pose_axes == ("x", "z", "pitch")
    s = np.linspace(0.01, path.length - 0.01, 25)
    ds = 1e-6
    mid, plus, minus = path.sample(s), path.sample(s + ds), path.sample(s - ds)
    np.testing.assert_allclose((plus.poses - minus.poses) / (2 * ds), mid.tangents, atol=1e-7)
    np.testing.assert_allclose((plus.tangents - minus.tangents) / (2 * ds), mid.curvatures,
                               atol=1e-5)
    np.testing.assert_allclose(path.sample(path.knots).poses, waypoints, atol=1e-12)
    # the planar default of 3 columns is (x, y, theta): the same path as given axes
    legacy, given = GeometricPath(waypoints, 0.1), GeometricPath(waypoints, 0.1,
                                                                 ("x", "y", "yaw"))
    np.testing.assert_array_equal(legacy.sample(s).tangents, given.sample(s).tangents)


def test_read_waypoints_by_the_robots_axes(tmp_path):
    robot = _robot("five-bar")
    path = tmp_path / "w.csv"
    path.write_text("# five-bar waypoints\nt,z,x\n0,0.1,0.3\n1,0.12,0.31\n")
    np.testing.assert_array_equal(read_waypoints(path, robot), [[0.3, 0.1], [0.31, 0.12]])
    with pytest.raises(DescriptionError, match="missing columns"):
        read_waypoints(path)                          # the hexapod's six columns
    (tmp_path / "w.json").write_text('{"pose": [[0.3, 0.1], [0.31, 0.12, 0.0]]}')
    with pytest.raises(DescriptionError):
        read_waypoints(tmp_path / "w.json", robot)


def test_bad_waypoint_files_name_the_file_once_and_the_row(tmp_path):
    """A missing column names the file once; a NaN or a word names its waypoint."""
    cols = tmp_path / "cols.csv"
    cols.write_text("t,x,y,z,roll,pitch\n0,0,0,0.35,0,0\n")
    with pytest.raises(DescriptionError) as err:
        read_waypoints(cols)
    assert str(err.value).count("cols.csv") == 1 and "missing columns ['yaw']" in str(err.value)
    nan = tmp_path / "nan.csv"
    nan.write_text("x,y,z,roll,pitch,yaw\n0,0,0.35,0,0,0\n0,0,0.35,0,0,0\n0.01,nan,0.35,0,0,0\n")
    with pytest.raises(DescriptionError, match="waypoint 3 has a value that is not finite"):
        read_waypoints(nan)
    word = tmp_path / "word.csv"
    word.write_text("x,y,z,roll,pitch,yaw\n0,0,0.35,0,0,0\n0.01,abc,0.35,0,0,0\n")
    with pytest.raises(DescriptionError, match=r"waypoint 2 \(data row 2.*'abc'"):
        read_waypoints(word)


# -- bad waypoints ------------------------------------------------------------------------------
@settings(max_examples=15, deadline=None)
@given(name=st.sampled_from(sorted(ROBOTS)), width=st.integers(1, 7),
       count=st.integers(2, 5))
def test_waypoints_of_the_wrong_width_raise_input_errors(name, width, count):
    robot = _robot(name)
    if width == robot.pose_dim:
        width += 1
    bad = np.zeros((count, width))
    with pytest.raises(InputError) as err:
        time_optimal(robot, bad, limits=Limits(actuator_force=10.0))
    assert err.value.name == "waypoints" and err.value.value is bad
    assert f"(K, {robot.pose_dim})" in str(err.value)


@settings(max_examples=15, deadline=None)
@given(name=st.sampled_from(sorted(ROBOTS)), data=st.data(),
       value=st.sampled_from([np.nan, np.inf, -np.inf]))
def test_waypoints_with_nan_or_inf_raise_input_errors(name, data, value):
    robot = _robot(name)
    waypoints = _waypoints(name)
    row = data.draw(st.integers(0, len(waypoints) - 1))
    col = data.draw(st.integers(0, robot.pose_dim - 1))
    waypoints[row, col] = value
    with pytest.raises(InputError) as err:
        time_optimal(robot, waypoints, limits=Limits(actuator_force=10.0))
    assert err.value.name == "waypoints"
    assert "NaN or inf" in str(err.value) and f"[{row}, {col}]" in str(err.value)


# -- motion files -------------------------------------------------------------------------------
def test_five_bar_motion_file_round_trip(tmp_path):
    robot = _robot("five-bar")
    dense = _plan("five-bar").resample(200.0)
    n = len(dense.t)
    motion = motions.Motion(dense.t, dense.poses, dense.twists, dense.twist_dots,
                            wrenches=np.full((n, 2), 0.5), q=dense.actuator_positions,
                            actuator_forces=dense.actuator_forces,
                            closure_residual=np.full(n, 1e-15))
    columns = motions.motion_columns(robot)
    assert columns.pose == ("x", "z") and columns.twists == ("vx", "vz")
    assert columns.q == ("q0", "q1") and columns.actuator_forces == ("tau0", "tau1")
    for suffix in (".csv", ".json"):
        path = motions.write_motion(tmp_path / f"five{suffix}", motion, robot)
        back = motions.read_motion(path, robot)
        for field in dataclasses.fields(motion):
            np.testing.assert_array_equal(getattr(back, field.name),
                                          getattr(motion, field.name), field.name)
        with pytest.raises(DescriptionError):
            motions.read_motion(path)                 # read as a hexapod file: no y, roll...
    header = (tmp_path / "five.csv").read_text().splitlines()[0].split(",")
    assert header == ["t", "x", "z", "vx", "vz", "ax", "az", "fx", "fz", "q0", "q1",
                      "tau0", "tau1", "residual"]
    with pytest.raises(InputError, match="motion.poses"):
        motions.write_motion(tmp_path / "hex.csv", motion)     # not a hexapod motion
    np.testing.assert_allclose(motions.actuators_along(robot, dataclasses.replace(
        motion, q=None)), dense.actuator_positions, atol=1e-10)


def test_five_bar_forces_along_a_file_of_poses(tmp_path):
    """A smooth motion written with its poses only: the rates by finite differences, the
    forces along it against the single-state inverse dynamics at the exact rates."""
    robot = _robot("five-bar")
    t = np.linspace(0.0, 1.0, 401)
    w, amp = 2 * np.pi, np.array([0.01, 0.015])
    phase = np.stack([np.sin(w * t), 1 - np.cos(w * t)], axis=1)
    poses = robot.home_pose + amp * phase
    twists = amp * w * np.stack([np.cos(w * t), np.sin(w * t)], axis=1)
    twist_dots = amp * w ** 2 * np.stack([-np.sin(w * t), np.cos(w * t)], axis=1)
    bare = motions.write_motion(tmp_path / "bare.csv", motions.Motion(t, poses), robot)
    read = motions.read_motion(bare, robot)
    rates = motions.motion_rates(read, robot)
    np.testing.assert_allclose(rates.twists, twists, atol=1e-4 * np.max(np.abs(twists)))
    forces = motions.inverse_dynamics_along(robot, read).actuator_forces
    want = _reference_forces(robot, 0.0, poses, twists, twist_dots)
    np.testing.assert_allclose(forces, want, atol=1e-3 * np.max(np.abs(want)))
    peak = float(np.max(np.abs(want)))
    assert check_feasibility(robot, bare, limits=Limits(actuator_force=1.01 * peak)).feasible
    assert not check_feasibility(robot, bare, limits=Limits(actuator_force=0.9 * peak)).feasible


def test_a_motion_that_does_not_fit_the_robot_raises_input_errors():
    robot = _robot("five-bar")
    t = np.linspace(0.0, 1.0, 5)
    wrong = motions.Motion(t, np.zeros((5, 3)) + robot.home_pose[0])
    with pytest.raises(InputError, match=r"motion\.poses.*\(5, 2\)"):
        motions.actuators_along(robot, wrong)
    with pytest.raises(InputError, match="motion.q"):
        motions.inverse_dynamics_along(robot, motions.Motion(
            t, np.tile(robot.home_pose, (5, 1)), q=np.zeros((5, 6))))


def test_a_hexapod_motion_file_from_before_still_reads(tmp_path):
    """The format of motion files written before robots had pose axes (6 pose columns,
    q0..q5, tau0..tau5), read with and without the robot."""
    hexapod = hp.Hexapod.default()
    home = hexapod.home_pose
    rows = ["# hexapod-pin motion file", "t,x,y,z,roll,pitch,yaw," + ",".join(
        f"q{i}" for i in range(6)) + "," + ",".join(f"tau{i}" for i in range(6))]
    values = []
    for k, t in enumerate((0.0, 0.1, 0.2)):
        pose = home + [0.001 * k, 0.0, 0.0, 0.0, 0.0, 0.01 * k]
        row = [t, *pose, *np.full(6, 0.2), *np.full(6, 3.0 + k)]
        values.append(row)
        rows.append(",".join(repr(float(v)) for v in row))
    path = tmp_path / "old.csv"
    path.write_text("\n".join(rows) + "\n")
    expected = np.array(values)
    for motion in (motions.read_motion(path), motions.read_motion(path, hexapod)):
        np.testing.assert_array_equal(motion.t, expected[:, 0])
        np.testing.assert_array_equal(motion.poses, expected[:, 1:7])
        np.testing.assert_array_equal(motion.q, expected[:, 7:13])
        np.testing.assert_array_equal(motion.actuator_forces, expected[:, 13:19])
        assert motion.twists is None and motion.wrenches is None
    json_path = tmp_path / "old.json"
    json_path.write_text('{"t": [0, 1, 2], "pose": %s}' % np.tile(home, (3, 1)).tolist())
    np.testing.assert_array_equal(motions.read_motion(json_path).poses, np.tile(home, (3, 1)))


def test_waypoints_of_another_robot_are_refused(tmp_path):
    """A waypoint file with pose columns the robot does not have (another robot's pose) is
    refused naming them, not planned on the columns that match (review finding)."""
    from hexapod_pin.planning import read_waypoints
    from hexapod_pin.errors import DescriptionError

    bad = tmp_path / "w.csv"
    bad.write_text("x,y,z\n0.3,0.5,0.0\n0.31,0.5,0.01\n")
    with pytest.raises(DescriptionError, match=r"\['y'\]"):
        read_waypoints(bad, pose_axes=("x", "z"))
    bad.write_text("t,x,z,x\n0,0.3,0.0,0.2\n1,0.31,0.01,0.2\n")
    with pytest.raises(DescriptionError, match="duplicate column 'x'"):
        read_waypoints(bad, pose_axes=("x", "z"))
    good = tmp_path / "g.csv"
    good.write_text("t,x,z\n0,0.3,0.0\n1,0.31,0.01\n")
    np.testing.assert_allclose(read_waypoints(good, pose_axes=("x", "z")),
                               [[0.3, 0.0], [0.31, 0.01]])
