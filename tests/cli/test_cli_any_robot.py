"""``hexapod-pin COMMAND --robot PATH``: the command line of any closed-loop robot, on a
four-bar (its loops file names the platform: ``--robot PATH`` alone), a five-bar (an
example-parallel-robots folder, ``--platform end_1 --pose-axes x,z``) and a Gough-Stewart
platform. Answers are checked against independent routes: the Stewart platform's
leg-length closed form, finite differences of the inverse kinematics and of the potential
energy, forward dynamics against inverse dynamics, the energy balance of a simulation;
motion files (``id``, ``retime``, ``check``, ``view --trajectory``, ``simulate --out``)
against the robot's own inverse dynamics and simulation at their samples."""

from __future__ import annotations

import base64
import json
import re
import shutil
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from typer.testing import CliRunner

from conftest import one_line_error

import hexapod_pin as hp
from hexapod_pin.motion import read_motion
from hexapod_pin.cli import app

DATA = Path(__file__).resolve().parents[1] / "data"
FOUR_BAR = DATA / "four_bar" / "four_bar.urdf"
FIVE_BAR = DATA / "parallel" / "five_bar_3d"
STEWART = DATA / "stewart" / "stewart.urdf"
#: the command-line options of each robot, and the arguments of load_robot
OPTIONS = {
    "four_bar": (["--robot", str(FOUR_BAR)], (FOUR_BAR,)),
    "five_bar": (["--robot", str(FIVE_BAR), "--platform", "end_1", "--pose-axes", "x,z"],
                 (FIVE_BAR, "end_1", "x,z")),
    "stewart": (["--robot", str(STEWART)], (STEWART,)),
}
#: a pose near home of each robot, as an offset from its home pose
OFFSETS = {"four_bar": [0.004], "five_bar": [0.01, -0.008],
           "stewart": [0.01, -0.02, 0.03, 0.0, 0.0, 0.0]}
#: Stewart platform (tests/data/stewart/README.md): base and platform points, leg offset
ALPHA = np.radians([-15, 15, 105, 135, 225, 255])
BETA = np.radians([-45, 45, 75, 165, 195, 285])
BASE = 0.5 * np.stack([np.cos(ALPHA), np.sin(ALPHA), np.zeros(6)], 1)
PLATFORM = 0.3 * np.stack([np.cos(BETA), np.sin(BETA), np.zeros(6)], 1)
LEG_OFFSET = 0.65
RUN = CliRunner()


@pytest.fixture(scope="module")
def robots() -> dict:
    return {name: hp.load_robot(*args) for name, (_, args) in OPTIONS.items()}


def invoke(*args: object):
    return RUN.invoke(app, [str(a) for a in args])


def ok_json(command: str, name: str, *args: object) -> dict:
    result = invoke(command, *args, *OPTIONS[name][0], "--json")
    assert result.exit_code == 0, result.output
    assert result.stderr == ""
    return json.loads(result.stdout)


def pose_arg(pose) -> str:
    return ",".join(repr(float(v)) for v in pose)


def stewart_ik(pose: np.ndarray) -> np.ndarray:
    """Leg extensions of the closed form ``||p + R b_i - a_i|| - 0.65``."""
    rot = Rotation.from_euler("ZYX", pose[3:][::-1]).as_matrix()
    return np.linalg.norm(pose[:3] + PLATFORM @ rot.T - BASE, axis=1) - LEG_OFFSET


# -- kinematics ---------------------------------------------------------------------------
@pytest.mark.parametrize("name", OPTIONS)
def test_ik_matches_the_robot(robots, name):
    robot = robots[name]
    pose = robot.home_pose + OFFSETS[name]
    out = ok_json("ik", name, pose_arg(pose))
    assert out["pose_axes"] == list(robot.geometry.pose_axes)
    assert out["actuators"] == list(robot.model.actuated_joints)
    np.testing.assert_allclose(out["q"], robot.inverse_kinematics(pose), atol=1e-12)


def test_ik_of_the_stewart_platform_is_the_leg_length_closed_form():
    pose = np.array([0.02, -0.01, 0.62, 0.05, -0.04, 0.1])
    out = ok_json("ik", "stewart", pose_arg(pose))
    np.testing.assert_allclose(out["q"], stewart_ik(pose), atol=1e-10)
    deg = ok_json("ik", "stewart", pose_arg(np.r_[pose[:3], np.degrees(pose[3:])]),
                  "--degrees")
    np.testing.assert_allclose(deg["q"], stewart_ik(pose), atol=1e-10)


@pytest.mark.parametrize("name", OPTIONS)
def test_fk_inverts_ik(robots, name):
    pose = robots[name].home_pose + OFFSETS[name]
    q = ok_json("ik", name, pose_arg(pose))["q"]
    back = ok_json("fk", name, pose_arg(q))
    np.testing.assert_allclose(back["pose"], pose, atol=1e-9)


def test_ik_table_names_the_actuators():
    result = invoke("ik", "0.12", *OPTIONS["four_bar"][0])
    assert result.exit_code == 0, result.output
    assert "crank" in result.stdout and "Traceback" not in result.output


def fd_ik_jacobian(robot, pose: np.ndarray, eps: float = 1e-6) -> np.ndarray:
    """Central differences of the inverse kinematics (at zero roll, pitch and yaw the
    Euler-angle rates are the angular velocity)."""
    cols = []
    for j in range(robot.pose_dim):
        step = np.zeros(robot.pose_dim)
        step[j] = eps
        cols.append((robot.inverse_kinematics(pose + step, check_limits=False)
                     - robot.inverse_kinematics(pose - step, check_limits=False)) / (2 * eps))
    return np.array(cols).T


@pytest.mark.parametrize("name", ["five_bar", "four_bar"])
def test_jacobian_against_finite_differences_of_ik(robots, name):
    robot = robots[name]
    pose = robot.home_pose + OFFSETS[name]
    out = ok_json("jacobian", name, pose_arg(pose))
    jac = np.array(out["jacobian"])
    assert jac.shape == (robot.n_actuators, robot.pose_dim)
    np.testing.assert_allclose(jac, fd_ik_jacobian(robot, pose), rtol=1e-6, atol=1e-7)
    assert out["condition_number"] >= 1.0 and "type_two" in out["singularity"]


def test_jacobian_of_the_stewart_platform_against_the_closed_form():
    pose = np.array([0.01, -0.02, 0.63, 0.0, 0.0, 0.0])
    jac = np.array(ok_json("jacobian", "stewart", pose_arg(pose))["jacobian"])
    eps, cols = 1e-6, []
    for j in range(6):
        step = np.zeros(6)
        step[j] = eps
        cols.append((stewart_ik(pose + step) - stewart_ik(pose - step)) / (2 * eps))
    np.testing.assert_allclose(jac, np.array(cols).T, atol=1e-7)
    table = invoke("jacobian", pose_arg(pose), *OPTIONS["stewart"][0])
    assert table.exit_code == 0 and "leg_0_prismatic" in table.stdout


# -- statics and dynamics -----------------------------------------------------------------
@pytest.mark.parametrize("name", ["four_bar", "five_bar"])
def test_statics_is_the_gradient_of_the_potential(robots, name):
    """Holding forces u = dV/dq_act: the potential along forward kinematics with one
    actuator moved at a time."""
    robot = robots[name]
    pose = robot.home_pose + OFFSETS[name]
    tau = np.array(ok_json("statics", name, pose_arg(pose))["actuator_forces"])
    act = robot.inverse_kinematics(pose)
    eps, grad = 1e-6, []
    for k in range(robot.n_actuators):
        step = np.zeros(robot.n_actuators)
        step[k] = eps
        v = [robot.energies(robot.forward_kinematics(act + s * step, guess=pose),
                            np.zeros(robot.pose_dim)).potential for s in (1.0, -1.0)]
        grad.append((v[0] - v[1]) / (2 * eps))
    np.testing.assert_allclose(tau, grad, rtol=1e-6, atol=1e-8)


def test_statics_with_a_wrench_names_its_components():
    result = invoke("statics", "--wrench", "1,2,3", *OPTIONS["five_bar"][0])
    one_line_error(result, 2, "expected 2 values (fx, fz)")     # a usage error


@pytest.mark.parametrize("name", OPTIONS)
def test_fd_inverts_inverse_dynamics(robots, name):
    robot = robots[name]
    pose = robot.home_pose + OFFSETS[name]
    rng = np.random.default_rng(1)
    twist, twist_dot = rng.uniform(-0.1, 0.1, (2, robot.pose_dim))
    tau = robot.inverse_dynamics(pose, twist, twist_dot, bounded=False).actuator_forces
    out = ok_json("fd", name, pose_arg(pose), "--twist", pose_arg(twist),
                  "--forces", pose_arg(tau))
    np.testing.assert_allclose(out["twist_dot"], twist_dot, atol=1e-8)
    rest = ok_json("fd", name)            # default: home, at rest, the static forces
    np.testing.assert_allclose(rest["twist_dot"], 0.0, atol=1e-9)


def test_fd_of_the_hexapod_holds_at_rest():
    result = invoke("fd", "--json")
    assert result.exit_code == 0, result.output
    np.testing.assert_allclose(json.loads(result.stdout)["twist_dot"], 0.0, atol=1e-9)


def test_simulate_free_fall_balances_energy(tmp_path):
    html = tmp_path / "fall.html"
    out = ok_json("simulate", "four_bar", "--duration", "0.2", "--dt", "1e-3",
                  "--html", html)
    assert out["status"] == "completed" and out["samples"] == 201
    assert out["max_energy_balance_error_j"] < 1e-8
    assert out["max_closure_residual"] < 1e-9
    assert html.stat().st_size > 10_000
    plain = invoke("simulate", "--duration", "0.05", *OPTIONS["four_bar"][0])
    assert plain.exit_code == 0, plain.output


def test_simulate_computed_torque_holds_home(robots):
    out = ok_json("simulate", "stewart", "--duration", "0.03", "--controller",
                  "computed-torque")
    assert out["status"] == "completed"
    np.testing.assert_allclose(out["final_pose"], robots["stewart"].home_pose, atol=1e-9)


def test_simulate_saturated_exits_with_code_1():
    args = ("simulate", "--duration", "0.02", "--forces", "100,100", *OPTIONS["five_bar"][0])
    result = invoke(*args)
    assert result.exit_code == 1, result.output
    assert "saturated" in result.stdout and "warning" in result.stderr
    as_json = invoke(*args, "--json")           # --json: the summary, exit code 0
    assert as_json.exit_code == 0 and json.loads(as_json.stdout)["status"] == "saturated"


# -- pictures and export --------------------------------------------------------------------
def object_paths(html: Path) -> str:
    """Every meshcat command of a page, decoded, as one string (paths name the links)."""
    import umsgpack

    blobs = json.loads(re.search(r"var hexapodPinCommands = (\[.*?\]);", html.read_text(),
                                 re.DOTALL).group(1))
    return " ".join(str(umsgpack.unpackb(base64.b64decode(b)).get("path", ""))
                    for b in blobs)


@pytest.mark.parametrize("name,links", [("four_bar", ("crank_link", "coupler", "rocker")),
                                        ("five_bar", ("proximal_1", "distal_2")),
                                        ("stewart", ("platform", "leg_0_upper"))])
def test_view_writes_the_robot(tmp_path, name, links):
    html = tmp_path / f"{name}.html"
    out = ok_json("view", name, "-o", html, "--forces")
    assert out["kind"] == "pose" and html.stat().st_size > 10_000
    paths = object_paths(html)
    for link in links:
        assert link in paths, link


def test_modes_of_the_four_bar(tmp_path, robots):
    html = tmp_path / "modes.html"
    out = ok_json("modes", "four_bar", "--html", html)
    robot = robots["four_bar"]
    assert len(out["modes"]) == 2 and html.stat().st_size > 10_000
    np.testing.assert_allclose(out["modes"], robot.assembly_modes(robot.home_actuators))
    assert abs(out["modes"][0][0] - out["modes"][1][0]) > 0.01    # two distinct modes
    assert object_paths(html).count("four_bar.urdf_1/") > 0     # the second copy drawn
    view = ok_json("view", "four_bar", "--modes", "-o", tmp_path / "v.html")
    assert view["modes"] == out["modes"]


def test_mjcf_export_has_one_motor_per_actuator(tmp_path):
    path = tmp_path / "stewart.xml"
    result = invoke("mjcf", "-o", path, *OPTIONS["stewart"][0])
    assert result.exit_code == 0, result.output
    motors = ET.parse(path).getroot().findall("./actuator/motor")
    assert len(motors) == 6


# -- errors -------------------------------------------------------------------------------------
def test_a_wrong_number_of_pose_values_names_the_axes():
    one_line_error(invoke("ik", "0.3", *OPTIONS["five_bar"][0]), 2,
                   "expected 2 values (x, z)", "got 1")
    one_line_error(invoke("fk", "0.1", "0.2", *OPTIONS["four_bar"][0]), 2,
                   "expected 1 values (crank)")


def test_an_unknown_frame_is_refused():
    one_line_error(invoke("ik", "0.1", "--robot", FOUR_BAR, "--platform", "nowhere"), 1,
                   "nowhere")


def test_a_missing_loops_file_is_refused(tmp_path):
    lonely = tmp_path / "four_bar.urdf"
    shutil.copy(FOUR_BAR, lonely)
    one_line_error(invoke("ik", "0.1", "--robot", lonely), 1, "four_bar.loops.yaml")


def test_options_of_the_hexapod_are_usage_errors(tmp_path):
    geometry = tmp_path / "g.toml"
    geometry.write_text("leg_length = 0.5\n")
    one_line_error(invoke("ik", "0.1", "--robot", FOUR_BAR, "--geometry", geometry), 2,
                   "--robot", "--geometry")
    one_line_error(invoke("statics", "--robot", FOUR_BAR, "--set", "leg_length=0.5"), 2,
                   "--set")
    one_line_error(invoke("ik", "0.1", "--robot", FOUR_BAR, "--branch", "+"), 2, "--branch")
    one_line_error(invoke("simulate", "--robot", FOUR_BAR, "--radius", "0.1"), 2, "--radius")
    one_line_error(invoke("ik", "0", "0", "0.3", "0", "0", "0", "--platform", "p"), 2,
                   "--robot")


def test_view_circle_is_an_option_of_the_hexapod():
    one_line_error(invoke("view", "--circle", "0.01", *OPTIONS["four_bar"][0]), 2, "--circle")


def test_errors_as_json():
    result = invoke("ik", "0.3", "zz", *OPTIONS["five_bar"][0], "--json")
    assert result.exit_code == 1
    assert json.loads(result.stdout)["error"]["type"] == "InputError"
    result = invoke("ik", "0.3", *OPTIONS["five_bar"][0], "--json")
    assert result.exit_code == 2
    assert json.loads(result.stdout)["error"]["type"] == "ValueCountError"


# -- motion files: id, retime, check, view --trajectory, simulate --out -------------------
#: a translation of each robot's platform about home: amplitude (m) per pose axis; the
#: Stewart platform keeps its orientation, so the twist is the pose's derivative
AMPLITUDES = {"four_bar": [0.002], "five_bar": [0.004, -0.003],
              "stewart": [0.004, -0.003, 0.002, 0.0, 0.0, 0.0]}


def sine_motion(robot, name: str, n: int = 41, period: float = 1.0) -> dict:
    """Samples of ``home + A sin(w t)`` with their exact rates, written independently of
    hexapod_pin.motion: columns t, the pose axes, their twists and derivatives."""
    t = np.linspace(0.0, 0.5, n)
    w = 2 * np.pi / period
    amp = np.array(AMPLITUDES[name])
    return {"t": t, "poses": robot.home_pose + np.sin(w * t)[:, None] * amp,
            "twists": w * np.cos(w * t)[:, None] * amp,
            "twist_dots": -w * w * np.sin(w * t)[:, None] * amp}


TWIST_DOT_OF = {"x": "ax", "y": "ay", "z": "az", "roll": "alphax", "pitch": "alphay",
                "yaw": "alphaz"}


def write_csv(path: Path, robot, samples: dict, rates: bool = True) -> Path:
    axes = robot.geometry.pose_axes
    names = ["t", *axes]
    blocks = [samples["t"][:, None], samples["poses"]]
    if rates:
        names += [f"v{a}" if a in "xyz" else "w" + {"roll": "x", "pitch": "y", "yaw": "z"}[a]
                  for a in axes] + [TWIST_DOT_OF[a] for a in axes]
        blocks += [samples["twists"], samples["twist_dots"]]
    np.savetxt(path, np.hstack(blocks), delimiter=",", header=",".join(names), comments="")
    return path


@pytest.mark.parametrize("name", OPTIONS)
def test_id_is_the_inverse_dynamics_at_the_samples(tmp_path, robots, name):
    robot = robots[name]
    samples = sine_motion(robot, name)
    motion_file = write_csv(tmp_path / "motion.csv", robot, samples)
    out = ok_json("id", name, motion_file, "--out", tmp_path / "forces.csv")
    expected = np.array([robot.inverse_dynamics(p, v, a).actuator_forces for p, v, a in
                         zip(samples["poses"], samples["twists"], samples["twist_dots"])])
    assert out["actuators"] == list(robot.model.actuated_joints)
    np.testing.assert_allclose(out["actuator_forces"], expected, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(out["max_abs_actuator_forces"], np.abs(expected).max(0),
                               rtol=1e-9, atol=1e-9)
    back = read_motion(tmp_path / "forces.csv", robot)
    np.testing.assert_allclose(back.actuator_forces, expected, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(back.poses, samples["poses"], atol=1e-15)
    table = invoke("id", motion_file, *OPTIONS[name][0])
    assert table.exit_code == 0 and robot.model.actuated_joints[0] in table.stdout


def test_id_differentiates_the_poses_of_a_file_without_rates(tmp_path, robots):
    """Poses only: the rates by finite differences agree with the exact ones in the
    interior to O(h^2)."""
    robot = robots["five_bar"]
    samples = sine_motion(robot, "five_bar", n=201)
    out = ok_json("id", "five_bar", write_csv(tmp_path / "poses.csv", robot, samples,
                                              rates=False))
    expected = np.array([robot.inverse_dynamics(p, v, a).actuator_forces for p, v, a in
                         zip(samples["poses"], samples["twists"], samples["twist_dots"])])
    np.testing.assert_allclose(np.array(out["actuator_forces"])[5:-5], expected[5:-5],
                               rtol=1e-3, atol=1e-3)


FIVE_BAR_WAYPOINTS = "x,z\n0.333,-0.050\n0.343,-0.045\n0.350,-0.055\n"


def test_retime_stays_within_the_force_bound_and_check_agrees(tmp_path, robots):
    robot = robots["five_bar"]
    waypoints = tmp_path / "waypoints.csv"
    waypoints.write_text(FIVE_BAR_WAYPOINTS)
    timed, html = tmp_path / "timed.csv", tmp_path / "timed.html"
    out = ok_json("retime", "five_bar", waypoints, "--max-force", "20", "--grid", "100",
                  "--out", timed, "--html", html)
    assert out["duration_s"] > 0 and out["pose_axes"] == ["x", "z"]
    motion = read_motion(timed, robot)
    np.testing.assert_allclose(motion.poses[[0, -1]], [[0.333, -0.050], [0.350, -0.055]],
                               atol=1e-12)
    np.testing.assert_allclose(motion.twists[[0, -1]], 0.0, atol=1e-9)     # rest to rest
    # the forces of the file are the robot's inverse dynamics at its samples, within the bound
    forces = np.array([robot.inverse_dynamics(p, v, a, bounded=False).actuator_forces
                       for p, v, a in zip(motion.poses, motion.twists, motion.twist_dots)])
    np.testing.assert_allclose(motion.actuator_forces, forces, rtol=1e-8, atol=1e-8)
    assert np.abs(forces).max() <= 20 * (1 + 1e-6)
    assert np.abs(forces).max() > 0.9 * 20                 # time-optimal: a bound is active
    np.testing.assert_allclose(motion.q, [robot.inverse_kinematics(p) for p in motion.poses],
                               atol=1e-9)
    np.testing.assert_allclose(motion.twists[1:-1], np.gradient(
        motion.poses, motion.t, axis=0)[1:-1], rtol=0.05, atol=0.02)
    assert "proximal_1" in object_paths(html)
    check = ok_json("check", "five_bar", timed, "--max-force", "20", "--tolerance", "1e-6")
    assert check["feasible"] and check["samples"] == len(motion.t)
    assert check["slow_down"] == pytest.approx(1.0, abs=1e-3)
    tight = invoke("check", timed, "--max-force", "10", *OPTIONS["five_bar"][0], "--json")
    assert tight.exit_code == 1 and json.loads(tight.stdout)["feasible"] is False


def test_check_of_a_slow_motion_finds_its_slow_down(tmp_path, robots):
    """The slow-down factor k of a motion run k times faster (twists / k, their
    derivatives / k^2) puts the largest force on its bound."""
    robot = robots["four_bar"]
    samples = sine_motion(robot, "four_bar")
    out = ok_json("check", "four_bar", write_csv(tmp_path / "slow.csv", robot, samples))
    bound = robot.geometry.max_actuator_force

    def peak(k: float) -> float:
        return max(np.abs(robot.inverse_dynamics(p, v / k, a / k ** 2, bounded=False)
                          .actuator_forces).max() for p, v, a in
                   zip(samples["poses"], samples["twists"], samples["twist_dots"]))

    assert out["feasible"] and 0 < out["slow_down"] < 1.0
    assert out["largest_ratio_to_limit"]["actuator_force"] == pytest.approx(
        peak(1.0) / bound, rel=1e-9)
    assert peak(out["slow_down"]) == pytest.approx(bound, rel=1e-6)


@pytest.mark.parametrize("suffix", [".csv", ".json"])
def test_simulate_out_is_the_trajectory(tmp_path, robots, suffix):
    robot = robots["four_bar"]
    path, plot = tmp_path / f"sim{suffix}", tmp_path / "sim.png"
    out = ok_json("simulate", "four_bar", "--duration", "0.1", "--out", path, "--plot", plot)
    assert out["status"] == "completed" and out["out"] == str(path)
    traj = hp.simulate(robot, 0.1, 1e-3, actuator_forces=np.zeros(robot.n_actuators))
    motion = read_motion(path, robot)
    np.testing.assert_allclose(motion.t, traj.times, atol=1e-15)
    np.testing.assert_allclose(motion.poses, traj.poses, atol=1e-13)
    np.testing.assert_allclose(motion.twists, traj.twists, atol=1e-12)
    np.testing.assert_allclose(motion.q, traj.actuator_positions, atol=1e-13)
    np.testing.assert_allclose(motion.actuator_forces, traj.actuator_forces, atol=1e-13)
    np.testing.assert_allclose(motion.closure_residual, traj.closure_residual, atol=1e-15)
    # the actuator positions are those of the poses (forward kinematics of the crank)
    np.testing.assert_allclose([robot.inverse_kinematics(p) for p in motion.poses[::20]],
                               motion.q[::20], atol=1e-8)
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("name,links", [("five_bar", ("proximal_1", "distal_2")),
                                        ("stewart", ("platform", "leg_0_upper"))])
def test_view_trajectory_draws_the_robot_along_the_motion(tmp_path, robots, name, links):
    robot = robots[name]
    motion_file = write_csv(tmp_path / "motion.csv", robot, sine_motion(robot, name),
                            rates=False)
    html = tmp_path / "motion.html"
    out = ok_json("view", name, "--trajectory", motion_file, "--forces", "-o", html)
    assert out["kind"] == "trajectory" and out["samples"] == 41
    assert out["duration_s"] == pytest.approx(0.5)
    paths = object_paths(html)
    for link in links:
        assert link in paths, link
    assert "animations" in html.read_text().lower()


def hexapod_motion_file(tmp_path: Path) -> Path:
    """A motion file of the hexapod (its 6 pose columns, q0..q5, tau0..tau5)."""
    result = invoke("simulate", "--duration", "0.02", "--out", tmp_path / "hexapod.csv",
                    "--quiet")
    assert result.exit_code == 0, result.output
    return tmp_path / "hexapod.csv"


@pytest.mark.parametrize("command", ["id", "check", "view"])
def test_a_motion_file_of_another_robot_names_the_columns_expected(tmp_path, command):
    """A hexapod file has x and z columns, q0 and q1: the five-bar refuses it rather than
    reading those and ignoring the rest."""
    hexapod_csv = hexapod_motion_file(tmp_path)
    args = {"id": [hexapod_csv], "check": [hexapod_csv],
            "view": ["--trajectory", hexapod_csv, "-o", tmp_path / "v.html"]}[command]
    result = invoke(command, *args, *OPTIONS["five_bar"][0])
    one_line_error(result, 1, "five_bar_3d", "expected columns t, x, z", "q0, q1",
                   "roll, pitch, yaw")
    assert not (tmp_path / "v.html").exists()


def test_a_motion_file_of_another_width_names_the_columns_expected(tmp_path, robots):
    pose = np.tile(robots["stewart"].home_pose, (3, 1))
    as_json = tmp_path / "stewart.json"
    as_json.write_text(json.dumps({"t": [0.0, 0.1, 0.2], "pose": pose.tolist()}))
    one_line_error(invoke("id", as_json, *OPTIONS["five_bar"][0]), 1,
                   "expected columns t, x, z", "(3, 2)")
    five_bar_csv = write_csv(tmp_path / "five.csv", robots["five_bar"],
                             sine_motion(robots["five_bar"], "five_bar"))
    one_line_error(invoke("id", five_bar_csv, *OPTIONS["four_bar"][0]), 1,
                   "expected columns t, x;", "z")
    one_line_error(invoke("id", five_bar_csv, *OPTIONS["stewart"][0]), 1,
                   "missing columns y, roll, pitch, yaw")


# -- workspace ---------------------------------------------------------------------------------
def five_bar_reachable(poses: np.ndarray) -> np.ndarray:
    """Both arms reach (the annulus |L1 - L2| <= |tip - motor| <= L1 + L2, motors at
    x = -0.1 and 0.1 m, links 0.25 and 0.3 m)."""
    motors = np.array([[-0.1, 0.0], [0.1, 0.0]])
    dist = np.linalg.norm(poses[:, None, :] - motors[None], axis=2)
    return np.all((dist >= 0.05) & (dist <= 0.55), axis=1)


def test_workspace_of_a_loaded_robot(robots):
    """The five-bar in a box that reaches past its arms' reach: the fraction counted is at
    most the annulus fraction of the same samples (computed here) and near it (the rest is
    the singular rim and the motors' stroke), and it equals the library's estimate."""
    robot = robots["five_bar"]
    out = ok_json("workspace", "five_bar", "--samples", 400, "--half-extent", "0.3,0.3",
                  "--seed", 3)
    est = out["estimates"]["workspace"]
    low, high = np.array(out["low"]), np.array(out["high"])
    poses = hp.core.workspace_maps.sample_box(robot, 400, low, high, 3)
    annulus = five_bar_reachable(poses).mean()
    assert 0.05 < est["fraction"] <= annulus + 1e-12
    assert est["fraction"] > annulus - 0.15
    assert out["units"] == "m^2" and out["pose_axes"] == ["x", "z"]
    ref = hp.core.workspace_maps.volume(robot, 400, low, high, 3)
    assert est["volume"] == pytest.approx(ref.volume) and est["fraction"] == ref.fraction
    table = invoke("workspace", *OPTIONS["five_bar"][0], "--samples", 50)
    assert table.exit_code == 0 and "m^2" in table.stdout
    one_line_error(invoke("workspace", *OPTIONS["five_bar"][0], "--half-extent", "0.1"),
                   2, "x, z")                          # a wrong number of values: usage


@pytest.mark.parametrize("args, words", [
    (["--samples", "10000000000000"], ["--samples"]),
    (["--half-extent", "-0.1,0.1"], ["--half-extent"]),
    (["--half-extent", "1e200,1e200"], ["--half-extent", "beyond 1e+150"]),
    (["--max-condition", "0"], ["--max-condition"]),
])
def test_workspace_bad_options_are_one_line_errors(args, words):
    one_line_error(invoke("workspace", *OPTIONS["five_bar"][0], *args), 1, *words)
