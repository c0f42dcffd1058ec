"""``hexapod-pin COMMAND --robot PATH``: the command line of any closed-loop robot, on a
four-bar (its loops file names the platform: ``--robot PATH`` alone), a five-bar (an
example-parallel-robots folder, ``--platform end_1 --pose-axes x,z``) and a Gough-Stewart
platform. Answers are checked against independent routes: the Stewart platform's
leg-length closed form, finite differences of the inverse kinematics and of the potential
energy, forward dynamics against inverse dynamics, the energy balance of a simulation."""

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

import hexapod_pin as hp
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


def one_line_error(result, code: int, *words: str) -> str:
    assert result.exit_code == code, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:"), result.stderr
    assert "Traceback" not in result.output
    for word in words:
        assert word in lines[0], (word, lines[0])
    return lines[0]


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
    one_line_error(result, 1, "expected 2 values (fx, fz)")


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
    one_line_error(invoke("ik", "0.3", *OPTIONS["five_bar"][0]), 1,
                   "expected 2 values (x, z)", "got 1")
    one_line_error(invoke("fk", "0.1", "0.2", *OPTIONS["four_bar"][0]), 1,
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


def test_errors_as_json():
    result = invoke("ik", "0.3", *OPTIONS["five_bar"][0], "--json")
    assert result.exit_code == 1
    assert json.loads(result.stdout)["error"]["type"] == "InputError"
