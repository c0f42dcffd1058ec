"""The library's motion files and geometry files (hexapod_pin.motion, hexapod_pin.files):
round trips, the reference circle against its formula, inverse dynamics along a motion."""

from __future__ import annotations

import dataclasses
import json
import os

import numpy as np
import pytest

import hexapod_pin as hp
from hexapod_pin import files
from hexapod_pin import motion as motions

HOME_STATIC_FORCE = 1.651   # N, at home for the default geometry (see test_cli)


def full_motion(n: int = 7) -> motions.Motion:
    rng = np.random.default_rng(3)
    return motions.Motion(np.linspace(0.0, 0.3, n), rng.normal(size=(n, 6)),
                          twists=rng.normal(size=(n, 6)), twist_dots=rng.normal(size=(n, 6)),
                          wrenches=rng.normal(size=(n, 6)), q=rng.normal(size=(n, 6)),
                          actuator_forces=rng.normal(size=(n, 6)),
                          closure_residual=np.abs(rng.normal(size=n)) * 1e-12)


@pytest.mark.parametrize("suffix", [".csv", ".json"])
def test_motion_file_round_trip_keeps_every_field_exactly(tmp_path, suffix):
    original = full_motion()
    path = motions.write_motion(tmp_path / f"m{suffix}", original)
    back = motions.read_motion(path)
    for field in dataclasses.fields(motions.Motion):
        np.testing.assert_array_equal(getattr(back, field.name), getattr(original, field.name),
                                      err_msg=field.name)
    # only the fields that are set are written
    bare = motions.write_motion(tmp_path / f"bare{suffix}", motions.Motion(original.t,
                                                                            original.poses))
    again = motions.read_motion(bare)
    assert again.twists is None and again.q is None and again.closure_residual is None
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []  # no temp files


def test_csv_columns_by_name_in_any_order(tmp_path):
    path = tmp_path / "m.csv"
    path.write_text("# comment\nyaw,t,x,y,z,roll,pitch\n0.3,0,1,2,3,0.1,0.2\n0.4,1,1,2,3,0.1,0.2\n")
    m = motions.read_motion(path)
    np.testing.assert_array_equal(m.t, [0.0, 1.0])
    np.testing.assert_array_equal(m.poses, [[1, 2, 3, 0.1, 0.2, 0.3], [1, 2, 3, 0.1, 0.2, 0.4]])
    np.testing.assert_array_equal(m.times, m.t)


def test_malformed_motion_files_name_file_and_column(tmp_path):
    partial = tmp_path / "p.csv"
    partial.write_text("t,x,y,z,roll,pitch,yaw,vx,vy\n" + "0,0,0,0,0,0,0,0,0\n")
    with pytest.raises(hp.DescriptionError, match="must come together") as err:
        motions.read_motion(partial)
    assert err.value.source == str(partial) and err.value.culprit == "vx"
    ragged = tmp_path / "r.csv"
    ragged.write_text("t,x,y,z,roll,pitch,yaw\n0,0,0,0,0,0\n")
    with pytest.raises(hp.DescriptionError, match="7 values"):
        motions.read_motion(ragged)
    with pytest.raises(hp.DescriptionError, match=r"row 0 \(line 2\) has 6 values"):
        motions.read_motion(ragged)
    word = tmp_path / "w.csv"
    word.write_text("# comment\nt,x,y,z,roll,pitch,yaw\n0,0,0,0.3,0,0,0\n\n1,0,0,abc,0,0,0\n")
    with pytest.raises(hp.DescriptionError, match=r"row 1 \(line 5\), column 'z': 'abc'") as err:
        motions.read_motion(word)
    assert err.value.culprit == "z"
    nan = tmp_path / "n.json"
    nan.write_text(json.dumps({"t": [0, 1], "pose": [[0] * 6, [0] * 6],
                               "q": [[0] * 6, [float("nan")] * 6]}))
    with pytest.raises(hp.DescriptionError, match="NaN") as err:
        motions.read_motion(nan)
    assert err.value.culprit == "q"
    other = tmp_path / "m.yaml"
    other.write_text("t: [0]\n")
    with pytest.raises(hp.DescriptionError, match=".csv or .json"):
        motions.read_motion(other)
    with pytest.raises(hp.InputError, match="csv or .json"):
        motions.write_motion(tmp_path / "m.txt", full_motion())


def test_circle_motion_follows_its_formula(robot):
    radius, period = 0.03, 0.8
    m = motions.circle_motion(robot, radius, period, duration=1.2, rate=100.0)
    w = 2 * np.pi / period
    assert len(m.t) == 121 and m.t[-1] == pytest.approx(1.2)
    home = robot.home_pose
    np.testing.assert_allclose(m.poses[:, 0], home[0] + radius * np.cos(w * m.t), atol=1e-15)
    np.testing.assert_allclose(m.poses[:, 1], home[1] + radius * np.sin(w * m.t), atol=1e-15)
    np.testing.assert_array_equal(m.poses[:, 2:], np.tile(home[2:], (len(m.t), 1)))
    # twist and its derivative: derivatives of the positions, by hand
    np.testing.assert_allclose(m.twists[:, :2], radius * w * np.stack(
        [-np.sin(w * m.t), np.cos(w * m.t)], 1), atol=1e-14)
    np.testing.assert_allclose(m.twist_dots[:, :2], -w * w * (m.poses[:, :2] - home[:2]),
                               atol=1e-13)
    assert not m.twists[:, 2:].any() and not m.twist_dots[:, 2:].any()
    still = motions.circle_motion(robot, 0.0, period)
    np.testing.assert_array_equal(still.poses, np.tile(home, (len(still.t), 1)))
    with pytest.raises(hp.InputError):
        motions.circle_motion(robot, -0.01, period)
    with pytest.raises(hp.InputError):
        motions.circle_motion(robot, 0.01, period, duration=0.0)


def test_motion_rates_need_three_samples_unless_given():
    two = motions.Motion(np.array([0.0, 1.0]), np.zeros((2, 6)))
    with pytest.raises(hp.DescriptionError, match="3 samples"):
        motions.motion_rates(two)
    given = dataclasses.replace(two, twists=np.ones((2, 6)), twist_dots=np.full((2, 6), 2.0))
    twists, dots = motions.motion_rates(given)
    assert (twists == 1).all() and (dots == 2).all()


def test_inverse_dynamics_at_rest_is_the_static_load_and_reports_progress(robot):
    t = np.linspace(0.0, 0.1, 5)
    rest = motions.Motion(t, np.tile(robot.home_pose, (5, 1)))
    seen = []
    forces = motions.inverse_dynamics_along(robot, rest, progress=lambda d, n: seen.append((d, n)))
    np.testing.assert_allclose(forces.actuator_forces,
                               np.tile(HOME_STATIC_FORCE * np.tile([1, -1], 3), (5, 1)), atol=1e-3)
    assert forces.closure_forces.shape == (5, 6, 3)
    # Newton on the platform at rest: the legs' forces on it carry its weight
    g = robot.geometry
    np.testing.assert_allclose(forces.closure_forces.sum(axis=1),
                               np.tile([0.0, 0.0, g.platform_mass * g.gravity], (5, 1)),
                               atol=1e-9)
    assert seen == [(k, 5) for k in range(1, 6)]


def test_inverse_dynamics_error_names_the_failing_row(robot):
    t = np.linspace(0.0, 0.4, 5)
    poses = np.tile(robot.home_pose, (5, 1))
    poses[3, 2] = 1.0                                   # out of reach at row 3
    with pytest.raises(hp.errors.MotionSampleError, match=r"row 3 \(t = 0.3 s\)") as err:
        motions.inverse_dynamics_along(robot, motions.Motion(t, poses, np.zeros((5, 6)),
                                                             np.zeros((5, 6))))
    assert err.value.index == 3 and err.value.time == pytest.approx(0.3)
    assert isinstance(err.value.error, hp.UnreachablePoseError)
    assert err.value.__cause__ is err.value.error
    assert isinstance(err.value, hp.HexapodPinError)


def test_simulate_circle_result_as_a_motion(robot, tmp_path):
    run = motions.simulate_circle(robot, 0.05, controller="computed-torque", radius=0.01,
                                  period=0.5)
    traj = run.trajectory
    m = motions.Motion.from_trajectory(traj)
    assert run.engine == "python" and run.status == "completed" and run.ok and len(m.t) == 51
    np.testing.assert_array_equal(m.q, traj.q)
    reference = motions.circle_reference(robot, 0.01, 0.5)
    worst = max(np.linalg.norm(p[:3] - reference(ti).pose[:3]) for ti, p in zip(m.t, m.poses))
    assert run.tracking_error == pytest.approx(worst, rel=1e-12)
    assert worst < 1e-3
    back = motions.read_motion(motions.write_motion(tmp_path / "sim.csv", m))
    np.testing.assert_array_equal(back.actuator_forces, m.actuator_forces)
    with pytest.raises(hp.InputError, match="controller"):
        motions.simulate_circle(robot, 0.05, controller="lqr")
    with pytest.raises(hp.InputError, match="engine"):
        motions.simulate_circle(robot, 0.05, controller="computed-torque", engine="fast")


def test_fast_and_python_engines_agree_on_the_pid_circle(robot):
    fast = motions.simulate_circle(robot, 0.1, controller="pid", radius=0.01, period=0.5)
    slow = motions.simulate_circle(robot, 0.1, controller="pid", radius=0.01, period=0.5,
                                   engine="python")
    assert fast.engine == "fast" and slow.engine == "python"
    assert fast.ok and slow.ok
    np.testing.assert_allclose(fast.trajectory.times, slow.trajectory.times, atol=1e-12)
    # two integrators of the same dynamics (platform coordinates / tree + projection)
    np.testing.assert_allclose(fast.trajectory.poses, slow.trajectory.poses, atol=1e-6)
    assert motions.Motion.from_trajectory(fast.trajectory).closure_residual is None


def test_a_run_tracking_worse_than_the_circle_is_not_a_success(robot):
    run = motions.simulate_circle(robot, 1.0, dt=0.01, controller="pid", radius=0.005,
                                  period=2.0)
    reference = motions.circle_reference(robot, 0.005, 2.0)
    worst = max(np.linalg.norm(p[:3] - reference(t).pose[:3])
                for t, p in zip(run.trajectory.times, run.trajectory.poses))
    assert worst > 0.005                         # the PID at 100 Hz loses the circle
    assert run.tracking_error == pytest.approx(worst, rel=1e-12)
    # the integration itself went through, its commands pinned at their bound
    assert run.trajectory.status == "saturated" and run.trajectory.saturated.mean() > 0.9
    assert run.status == "tracking_lost" and not run.ok and "0.005 m" in run.message


def test_circle_errors_name_the_bad_argument(robot):
    with pytest.raises(hp.InputError, match="period"):
        motions.circle_reference(robot, 0.02, 0.0)
    with pytest.raises(hp.InputError, match="radius"):
        motions.circle_reference(robot, -0.02, 1.0)


def test_an_unreachable_pose_is_reported_at_its_own_row(robot):
    t = np.linspace(0.0, 0.4, 5)
    poses = np.tile(robot.home_pose, (5, 1))
    poses[1, 2] = 1.0       # out of reach at row 1; its neighbours' rates blow up first
    with pytest.raises(hp.errors.MotionSampleError, match=r"row 1 ") as err:
        motions.inverse_dynamics_along(robot, motions.Motion(t, poses))
    assert isinstance(err.value.error, hp.UnreachablePoseError)
    with pytest.raises(hp.errors.MotionSampleError, match=r"row 1 "):
        motions.actuators_along(robot, motions.Motion(t, poses))
    with pytest.raises(hp.InputError, match="method"):     # checked before any row
        motions.inverse_dynamics_along(robot, motions.Motion(t, poses), method="foo")


# -- geometry files and atomic writes --------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class Toy:
    """Any geometry dataclass: load_geometry is not tied to the hexapod's."""

    length: float = 1.0
    inertia: tuple[float, float] = (0.1, 0.2)


def test_load_geometry_of_any_dataclass_with_overrides(tmp_path):
    path = tmp_path / "toy.json"
    path.write_text(json.dumps({"geometry": {"length": 2.0, "inertia": [1.0, 3.0]}}))
    assert files.load_geometry(path, geometry_type=Toy) == Toy(2.0, (1.0, 3.0))
    assert files.load_geometry(path, ["inertia=4,5", "length=0.5"], Toy) == Toy(0.5, (4.0, 5.0))
    with pytest.raises(hp.GeometryError, match="2 numbers"):
        files.load_geometry(None, ["inertia=4"], Toy)
    with pytest.raises(hp.GeometryError, match="unknown field"):
        files.load_geometry(None, ["mass=4"], Toy)
    with pytest.raises(hp.InputError, match="FIELD=VALUE"):
        files.load_geometry(None, ["length"], Toy)
    g = files.load_geometry(None, ["platform_inertia=0.005 0.005 0.009", "leg_length=0.5"])
    assert g == hp.HexapodGeometry(leg_length=0.5, platform_inertia=(0.005, 0.005, 0.009))
    ini = tmp_path / "g.ini"
    ini.write_text("length = 1\n")
    with pytest.raises(hp.DescriptionError, match="toml"):
        files.load_geometry(ini, geometry_type=Toy)


def test_write_text_atomic_replaces_and_keeps_plain_permissions(tmp_path):
    path = tmp_path / "a.txt"
    path.write_text("old")
    assert files.write_text_atomic(path, "new ü") == path
    assert path.read_text(encoding="utf-8") == "new ü"
    umask = os.umask(0)
    os.umask(umask)
    assert path.stat().st_mode & 0o777 == 0o666 & ~umask
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt"]
    with pytest.raises(hp.InputError, match="folder"):
        files.write_text_atomic(tmp_path / "no" / "a.txt", "x")
