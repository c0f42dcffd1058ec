"""``--effects FILE`` on ``statics``, ``fd``, ``id`` and ``simulate``: joint and drive
effects from a YAML or TOML file, for the hexapod, the planar 3-PRR, a planar five-bar and
a four-bar.

References written here: on an actuated joint the effects enter the actuator force one to
one, so the forces with effects are the rigid forces (the command without the file) plus
``A_i qdd_i + D_i qd_i + c_i sign(qd_i) + K_i (q_i - r_i)``, with ``q`` the robot's
inverse kinematics and its rates central differences along the motion; forward dynamics
under those forces with the effects equals forward dynamics of the rigid robot; the work
damping dissipates in a simulation is the trapezoidal integral of ``D qd^2`` over the
actuator positions the run writes. The Python API (``robot.with_effects``) is the second
route of each answer."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from conftest import one_line_error

import hexapod_pin as hp
from hexapod_pin.cli import app
from hexapod_pin.motion import read_motion

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "tests" / "data"
FOUR_BAR = DATA / "four_bar" / "four_bar.urdf"
FIVE_BAR = DATA / "parallel" / "five_bar_3d"
PLANAR = ROOT / "urdf" / "planar_3prr.urdf.xacro"
#: the command-line options of each robot, and the arguments of load_robot (None: the
#: hexapod of the defaults)
OPTIONS = {
    "hexapod": ([], None),
    "planar": (["--robot", str(PLANAR), "--platform", "platform", "--pose-axes", "x,y,yaw"],
               (PLANAR, "platform", "x,y,yaw")),
    "five_bar": (["--robot", str(FIVE_BAR), "--platform", "end_1", "--pose-axes", "x,z"],
                 (FIVE_BAR, "end_1", "x,z")),
    "four_bar": (["--robot", str(FOUR_BAR)], (FOUR_BAR,)),
}
#: a translation of each platform about home, amplitude per pose axis (m; rad for yaw)
AMPLITUDES = {"hexapod": [0.004, -0.003, 0.002, 0.0, 0.0, 0.0], "planar": [0.004, -0.003, 0.0],
              "five_bar": [0.004, -0.003], "four_bar": [0.002]}
#: the drive of every actuated joint (armature kg or kg m^2, damping, coulomb, stiffness;
#: the spring reference: 0.01 m or rad from home, :func:`references`) and, for the
#: hexapod, a gearbox (gear, rotor inertia: armature += gear^2 rotor_inertia)
DRIVE = {"armature": 0.02, "damping": 1.5, "coulomb": 0.3, "stiffness": 40.0}
GEARBOX = {"gear": 10.0, "rotor_inertia": 1.0e-4}
RUN = CliRunner()


@pytest.fixture(scope="module")
def robots() -> dict:
    return {name: hp.Hexapod.default() if args is None else hp.load_robot(*args)
            for name, (_, args) in OPTIONS.items()}


def invoke(*args: object):
    return RUN.invoke(app, [str(a) for a in args])


def ok_json(*args: object) -> dict:
    result = invoke(*args, "--json")
    assert result.exit_code == 0, result.output
    assert result.stderr == ""
    return json.loads(result.stdout)


def references(robot) -> np.ndarray:
    """The springs' reference of the actuated joints: 0.01 (m or rad) beyond home."""
    return np.round(robot.inverse_kinematics(robot.home_pose), 6) + 0.01


def drives(robot, name: str) -> dict[str, dict[str, float]]:
    """The effects of every actuated joint: ``{joint: {key: value}}``."""
    entry = {**DRIVE, **(GEARBOX if name == "hexapod" else {})}
    return {joint: {**entry, "spring_reference": float(r)}
            for joint, r in zip(robot.model.actuated_joints, references(robot))}


def write_yaml(path: Path, joints: dict[str, dict[str, float]], nested: bool = False) -> Path:
    """An effects file in YAML, written by hand (numbers with a dot: YAML reads 1e-4 as
    text)."""
    indent = "  " if nested else ""
    lines = ["effects:"] if nested else []
    lines.append(f"{indent}joints:")
    for joint, entry in joints.items():
        lines.append(f"{indent}  {joint}:")
        lines += [f"{indent}    {key}: {value!r}" for key, value in entry.items()]
    path.write_text("\n".join(lines) + "\n")
    return path


def write_toml(path: Path, joints: dict[str, dict[str, float]]) -> Path:
    lines = []
    for joint, entry in joints.items():
        lines.append(f"[joints.{joint}]")
        lines += [f"{key} = {value!r}" for key, value in entry.items()]
    path.write_text("\n".join(lines) + "\n")
    return path


def pose_arg(values) -> str:
    return ",".join(repr(float(v)) for v in values)


# -- samples of a motion and the actuators' motion along it ----------------------------------
def sine_motion(robot, name: str, n: int = 11) -> dict:
    """``home + A sin(w t)`` for t in [0, 0.2] s (the velocity never zero: Coulomb
    friction slides) with its exact rates."""
    t = np.linspace(0.0, 0.2, n)
    w = 2 * np.pi
    amp = np.array(AMPLITUDES[name])
    return {"t": t, "poses": robot.home_pose + np.sin(w * t)[:, None] * amp,
            "twists": w * np.cos(w * t)[:, None] * amp,
            "twist_dots": -w * w * np.sin(w * t)[:, None] * amp, "amp": amp, "w": w}


def actuator_motion(robot, samples: dict, h: float = 1e-4) -> tuple[np.ndarray, ...]:
    """q, qd, qdd (N, n_act) of the actuators: the inverse kinematics at the samples and
    central differences of it along the motion."""
    amp, w = samples["amp"], samples["w"]

    def q_at(t: float) -> np.ndarray:
        return robot.inverse_kinematics(robot.home_pose + np.sin(w * t) * amp)

    q = np.array([q_at(t) for t in samples["t"]])
    qd = np.array([(q_at(t + h) - q_at(t - h)) / (2 * h) for t in samples["t"]])
    qdd = np.array([(q_at(t + h) - 2 * q_at(t) + q_at(t - h)) / h ** 2 for t in samples["t"]])
    return q, qd, qdd


def write_csv(path: Path, robot, samples: dict) -> Path:
    axes = robot.pose_axes
    twist = {"x": "vx", "y": "vy", "z": "vz", "roll": "wx", "pitch": "wy", "yaw": "wz"}
    dot = {"x": "ax", "y": "ay", "z": "az", "roll": "alphax", "pitch": "alphay",
           "yaw": "alphaz"}
    names = ["t", *axes, *(twist[a] for a in axes), *(dot[a] for a in axes)]
    table = np.hstack([samples["t"][:, None], samples["poses"], samples["twists"],
                       samples["twist_dots"]])
    np.savetxt(path, table, delimiter=",", header=",".join(names), comments="")
    return path


def drive_terms(robot, name: str, q: np.ndarray, qd: np.ndarray,
                qdd: np.ndarray) -> np.ndarray:
    """``A qdd + D qd + c sign(qd) + K (q - r)`` of :data:`DRIVE` (and the hexapod's
    gearbox: ``A = armature + gear^2 rotor_inertia``)."""
    arm = DRIVE["armature"] + (GEARBOX["gear"] ** 2 * GEARBOX["rotor_inertia"]
                               if name == "hexapod" else 0.0)
    return (arm * qdd + DRIVE["damping"] * qd + DRIVE["coulomb"] * np.sign(qd)
            + DRIVE["stiffness"] * (q - references(robot)))


# -- id, statics, fd -----------------------------------------------------------------------
@pytest.mark.parametrize("name", OPTIONS)
def test_id_with_an_effects_file_adds_the_drive_terms(tmp_path, robots, name):
    robot = robots[name]
    samples = sine_motion(robot, name)
    motion = write_csv(tmp_path / "motion.csv", robot, samples)
    joints = drives(robot, name)
    effects = write_yaml(tmp_path / "drives.yaml", joints)
    rigid = np.array(ok_json("id", motion, *OPTIONS[name][0])["actuator_forces"])
    out = ok_json("id", motion, *OPTIONS[name][0], "--effects", effects)
    q, qd, qdd = actuator_motion(robot, samples)
    assert np.all(np.abs(qd) > 1e-4)                # every joint slides
    np.testing.assert_allclose(out["actuator_forces"], rigid + drive_terms(robot, name, q, qd, qdd),
                               rtol=1e-6, atol=1e-6)
    by_key = {key: {joint: entry[key] for joint, entry in joints.items()}
              for key in next(iter(joints.values()))}
    driven = robot.with_effects(**by_key)            # the Python API
    api = [driven.inverse_dynamics(p, v, a).actuator_forces for p, v, a in
           zip(samples["poses"], samples["twists"], samples["twist_dots"])]
    np.testing.assert_allclose(out["actuator_forces"], api, rtol=1e-9, atol=1e-9)
    actuated = list(robot.model.actuated_joints)
    on = out["effects"]["on"]
    assert out["effects"]["file"] == str(effects)
    for key in DRIVE:
        assert on[key] == actuated, key
    assert ("gear" in on) == (name == "hexapod")


@pytest.mark.parametrize("name", ["hexapod", "planar", "four_bar"])
def test_statics_with_springs_adds_their_force(tmp_path, robots, name):
    """At rest only the springs act: ``u = u_rigid + K (q - r)``."""
    robot = robots[name]
    pose = robot.home_pose + 0.5 * np.array(AMPLITUDES[name])
    effects = write_yaml(tmp_path / "drives.yaml", drives(robot, name))
    rigid = np.array(ok_json("statics", pose_arg(pose), *OPTIONS[name][0])["actuator_forces"])
    out = ok_json("statics", pose_arg(pose), *OPTIONS[name][0], "--effects", effects)
    q = robot.inverse_kinematics(pose)
    np.testing.assert_allclose(out["actuator_forces"], rigid + DRIVE["stiffness"]
                               * (q - references(robot)), rtol=1e-9, atol=1e-9)
    text = invoke("statics", pose_arg(pose), *OPTIONS[name][0], "--effects", effects)
    assert text.exit_code == 0, text.output
    n = robot.n_actuators
    which = robot.model.actuated_joints[0] if n == 1 else f"{n} joints"
    assert f"effects ({effects}): armature on {which}, damping on {which}" in text.stdout


@pytest.mark.parametrize("name", ["five_bar", "four_bar", "hexapod"])
def test_fd_with_effects_under_the_drive_forces_moves_as_the_rigid_robot(tmp_path, robots,
                                                                        name):
    """Forward dynamics with damping, friction and springs under ``u + D qd + c sign(qd) +
    K (q - r)`` gives the accelerations of the rigid robot under ``u``."""
    robot = robots[name]
    joints = {joint: {k: v for k, v in entry.items() if k not in ("armature", "gear",
                                                                   "rotor_inertia")}
              for joint, entry in drives(robot, name).items()}
    effects = write_toml(tmp_path / "drives.toml", joints)
    samples = sine_motion(robot, name)
    pose, twist = samples["poses"][3], samples["twists"][3]
    q = robot.inverse_kinematics(pose)
    qd = robot.jacobian(pose) @ twist
    assert np.all(np.abs(qd) > 1e-4)
    u = robot.static_forces(pose, bounded=False) + 0.1
    terms = DRIVE["damping"] * qd + DRIVE["coulomb"] * np.sign(qd) + \
        DRIVE["stiffness"] * (q - references(robot))
    rigid = ok_json("fd", pose_arg(pose), "--twist", pose_arg(twist), "--forces", pose_arg(u),
                    *OPTIONS[name][0])
    out = ok_json("fd", pose_arg(pose), "--twist", pose_arg(twist), "--forces",
                  pose_arg(u + terms), *OPTIONS[name][0], "--effects", effects)
    np.testing.assert_allclose(out["twist_dot"], rigid["twist_dot"], rtol=1e-7, atol=1e-7)
    assert set(out["effects"]["on"]) >= {"damping", "coulomb", "stiffness"}


def test_toml_yaml_and_an_effects_section_give_the_same_answer(tmp_path, robots):
    robot = robots["four_bar"]
    samples = sine_motion(robot, "four_bar")
    motion = write_csv(tmp_path / "motion.csv", robot, samples)
    joints = drives(robot, "four_bar")
    answers = []
    for path in (write_yaml(tmp_path / "a.yaml", joints),
                 write_yaml(tmp_path / "b.yml", joints, nested=True),
                 write_toml(tmp_path / "c.toml", joints)):
        out = ok_json("id", motion, *OPTIONS["four_bar"][0], "--effects", path)
        answers.append((out["actuator_forces"], out["effects"]["on"]))
    assert answers[0] == answers[1] == answers[2]
    rigid = ok_json("id", motion, *OPTIONS["four_bar"][0])["actuator_forces"]
    assert not np.allclose(answers[0][0], rigid)


#: a bad effects file of the four-bar: its text, its suffix, words of the message (the
#: file, the joint, the key and the line)
BAD_FILES = [
    ("joints:\n  crank: {damping: 1.0}\n  cranck: {damping: 1.0}\n", ".yaml",
     ["'cranck'", "not a joint of the tree", "effects.joints.cranck.damping (line 3)"]),
    ("joints:\n  crank:\n    dampin: 1.0\n", ".yaml",
     ["unknown key 'dampin'", "effects.joints.crank.dampin (line 3)"]),
    ("joints:\n  crank:\n    coulomb: 0.1\n    damping: -1.0\n", ".yaml",
     ["joint 'crank', damping", "must be >= 0", "effects.joints.crank.damping (line 4)"]),
    ("joints:\n  crank: {damping: 1e-9}\n", ".yaml",
     ["'1e-9'", "write 1.0e-9", "effects.joints.crank.damping (line 2)"]),
    ("[joints.crank]\ncoulomb = 0.1\ndamping = -1.0\n", ".toml",
     ["joint 'crank', damping", "must be >= 0", "effects.joints.crank.damping (line 3)"]),
    ("[joints]\ncrank = {damping = 1.0, stifness = 2.0}\n", ".toml",
     ["unknown key 'stifness'", "effects.joints.crank.stifness (line 2)"]),
    ("joints:\n  coupler_pin: {gear: 5}\n", ".yaml",
     ["not an actuated joint", "effects.joints.coupler_pin.gear (line 2)"]),
    ("effects:\n  joints: {}\nclosures: []\n", ".yaml", ["unknown key 'closures'"]),
    ("[joints.crank]\ndamping = \n", ".toml", ["malformed TOML", "line 2"]),
    ("joints: {crank: {damping: 1.0}}\n", ".json", ["ends in .yaml, .yml, .toml"]),
]


@pytest.mark.parametrize("text, suffix, words", BAD_FILES)
def test_a_bad_effects_file_names_the_file_the_key_and_the_line(tmp_path, text, suffix,
                                                                words):
    path = tmp_path / f"drives{suffix}"
    path.write_text(text)
    for command in (("statics",), ("simulate", "--duration", "0.01")):
        result = invoke(*command, *OPTIONS["four_bar"][0], "--effects", path)
        one_line_error(result, 1, str(path), *words)
    out = invoke("statics", *OPTIONS["four_bar"][0], "--effects", path, "--json")
    assert out.exit_code == 1
    assert json.loads(out.stdout)["error"]["type"] == "DescriptionError"


def test_a_missing_effects_file_exits_as_a_missing_description(tmp_path):
    missing = tmp_path / "none.yaml"
    robot_missing = invoke("statics", "--robot", tmp_path / "none.urdf")
    effects_missing = invoke("statics", *OPTIONS["four_bar"][0], "--effects", missing)
    assert robot_missing.exit_code == 1
    one_line_error(effects_missing, 1, str(missing), "file not found")
    one_line_error(invoke("statics", "--effects", missing), 1, "file not found")


def test_an_effects_file_of_another_robot_names_its_joint(tmp_path, robots):
    """A four-bar's file given to the hexapod: the joint is not in the hexapod's tree."""
    path = write_yaml(tmp_path / "drives.yaml", {"crank": {"damping": 1.0}})
    one_line_error(invoke("statics", "--effects", path), 1, str(path), "'crank'",
                   "not a joint of the tree", "effects.joints.crank.damping (line 3)")


# -- simulate ------------------------------------------------------------------------------
def trapezoid_dissipation(t: np.ndarray, q: np.ndarray, damping: float) -> float:
    """``int D qd^2 dt`` with ``qd`` the central differences of the positions ``q``."""
    qd = np.gradient(q, t, axis=0)
    power = damping * np.sum(qd ** 2, axis=1)
    return float(np.sum(0.5 * (power[1:] + power[:-1]) * np.diff(t)))


@pytest.mark.parametrize("name", ["four_bar", "five_bar"])
def test_simulate_reports_the_work_damping_dissipates(tmp_path, robots, name):
    robot = robots[name]
    damping = 2.0
    effects = write_yaml(tmp_path / "drives.yaml", {j: {"damping": damping}
                                                     for j in robot.model.actuated_joints})
    out_file = tmp_path / "run.csv"
    out = ok_json("simulate", *OPTIONS[name][0], "--duration", "0.2", "--dt", "1e-3",
                  "--effects", effects, "--out", out_file)
    assert out["status"] == "completed" and out["integrator"] == "rk4"
    motion = read_motion(out_file, robot)
    expected = trapezoid_dissipation(motion.t, motion.q, damping)
    assert expected > 1e-4
    assert out["dissipated_work_j"] == pytest.approx(expected, rel=2e-3)
    assert out["max_energy_balance_error_j"] < 1e-3 * expected
    assert out["effects"]["on"]["damping"] == list(robot.model.actuated_joints)
    rigid = ok_json("simulate", *OPTIONS[name][0], "--duration", "0.05")
    assert "dissipated_work_j" not in rigid or rigid["dissipated_work_j"] is None
    text = invoke("simulate", *OPTIONS[name][0], "--duration", "0.05", "--effects", effects)
    assert text.exit_code == 0, text.output
    assert "dissipated_work_j" in text.stdout and "effects (" in text.stdout


def test_simulate_with_coulomb_friction_runs_stick_slip(tmp_path):
    effects = write_yaml(tmp_path / "drives.yaml", {"crank": {"coulomb": 0.05}})
    out = ok_json("simulate", *OPTIONS["four_bar"][0], "--duration", "0.1", "--effects",
                  effects)
    assert out["integrator"] == "stick_slip" and out["status"] == "completed"
    assert out["dissipated_work_j"] > 0
    explicit = ok_json("simulate", *OPTIONS["four_bar"][0], "--duration", "0.1", "--effects",
                       effects, "--integrator", "stick_slip")
    assert explicit["final_pose"] == out["final_pose"]
    one_line_error(invoke("simulate", *OPTIONS["four_bar"][0], "--duration", "0.1",
                          "--effects", effects, "--integrator", "rk4"), 1, "stick_slip")
    one_line_error(invoke("simulate", *OPTIONS["four_bar"][0], "--integrator", "euler"), 1,
                   "integrator", "stick_slip")


@pytest.mark.parametrize("integrator", ["auto", "rk4", "semi_implicit_euler", "stick_slip"])
def test_simulate_takes_every_integrator(integrator):
    out = ok_json("simulate", *OPTIONS["four_bar"][0], "--duration", "0.02",
                  "--integrator", integrator)
    assert out["status"] == "completed"
    assert out["integrator"] == ("rk4" if integrator == "auto" else integrator)


def test_simulate_the_hexapod_with_damping_reports_its_dissipated_work(tmp_path, robots):
    """The compiled engine (PID) and the tree route (no control, positions written)."""
    robot = robots["hexapod"]
    damping = 40.0
    effects = write_yaml(tmp_path / "drives.yaml", {j: {"damping": damping}
                                                     for j in robot.model.actuated_joints})
    fast = ok_json("simulate", "--duration", "0.05", "--effects", effects)
    assert fast["engine"] == "fast" and fast["status"] == "completed"
    assert fast["dissipated_work_j"] > 0
    out_file = tmp_path / "fall.csv"
    tree = ok_json("simulate", "--duration", "0.05", "--controller", "none", "--engine",
                   "python", "--effects", effects, "--out", out_file)
    assert tree["engine"] == "python" and tree["integrator"] == "rk4"
    motion = read_motion(out_file)
    expected = trapezoid_dissipation(motion.t, motion.q, damping)
    assert expected > 1e-6
    assert tree["dissipated_work_j"] == pytest.approx(expected, rel=5e-3)


def test_simulate_the_hexapod_with_coulomb_friction_runs_stick_slip_on_the_tree(tmp_path,
                                                                             robots):
    robot = robots["hexapod"]
    effects = write_toml(tmp_path / "drives.toml", {j: {"coulomb": 1.5}
                                                     for j in robot.model.actuated_joints})
    out = ok_json("simulate", "--duration", "0.02", "--controller", "none", "--effects",
                  effects)
    assert out["engine"] == "python" and out["integrator"] == "stick_slip"
    assert out["dissipated_work_j"] > 0
    one_line_error(invoke("simulate", "--duration", "0.02", "--engine", "fast",
                          "--effects", effects), 1, "stick_slip", "python")
