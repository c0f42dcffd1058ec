"""``hexapod-pin stiffness``: the JSON of the command against the library's answers
(``robot.vibration_modes`` at the pose, :func:`hexapod_pin.core.stiffness_maps.stiffness_slice`
for ``--map``), on the hexapod and robots loaded with ``--robot``; bad input as exit codes
and one-line messages."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from conftest import one_line_error
from typer.testing import CliRunner

import hexapod_pin as hp
from hexapod_pin.cli import app
from hexapod_pin.core import stiffness_maps as sm

RUN = CliRunner()
DATA = Path(__file__).resolve().parents[1] / "data"
STEWART = ["--robot", str(DATA / "stewart" / "stewart.urdf")]
FOUR_BAR = ["--robot", str(DATA / "four_bar" / "four_bar.urdf")]
FIVE_BAR = ["--robot", str(DATA / "parallel" / "five_bar_3d"), "--platform", "end_1",
            "--pose-axes", "x,z"]


def invoke(*args: object):
    return RUN.invoke(app, ["stiffness", *(str(a) for a in args)])


def ok_json(*args: object) -> dict:
    result = invoke(*args, "--json")
    assert result.exit_code == 0, result.output
    assert result.stderr == ""
    return json.loads(result.stdout)


def block_min(matrix: np.ndarray, rows: list[int]) -> float | None:
    if not rows:
        return None
    block = matrix[np.ix_(rows, rows)]
    return float(np.linalg.eigvalsh(0.5 * (block + block.T))[0])


def check_pose_json(out: dict, robot, pose: np.ndarray, k) -> None:
    modes = robot.vibration_modes(pose, k)
    st = modes.stiffness
    np.testing.assert_allclose(out["stiffness"], st.matrix, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(out["elastic"], st.elastic, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(out["geometric"], st.geometric, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(out["frequencies"], modes.frequencies, rtol=1e-12)
    axes = tuple(robot.pose_axes)
    linear = [i for i, a in enumerate(axes) if a not in ("roll", "pitch", "yaw")]
    angular = [i for i, a in enumerate(axes) if a in ("roll", "pitch", "yaw")]
    for key, rows in (("translational_min", linear), ("rotational_min", angular)):
        expected = block_min(st.matrix, rows)
        assert (out[key] is None) == (expected is None)
        if expected is not None:
            assert out[key] == pytest.approx(expected, rel=1e-12)


def test_the_hexapod_at_home_and_at_a_pose():
    robot = hp.Hexapod.default()
    out = ok_json("-k", "1e5")
    check_pose_json(out, robot, robot.home_pose, 1e5)
    np.testing.assert_allclose(out["pose"], robot.home_pose)
    pose = robot.home_pose + np.array([0.01, -0.005, 0.0, 0.02, 0.0, -0.03])
    k = np.linspace(8e4, 1.3e5, 6)
    out = ok_json(*pose, "--actuator-stiffness", ",".join(repr(float(v)) for v in k))
    check_pose_json(out, robot, pose, k)
    degrees = ok_json(*np.r_[pose[:3], np.degrees(pose[3:])], "-k",
                      ",".join(repr(float(v)) for v in k), "--degrees")
    np.testing.assert_allclose(degrees["stiffness"], out["stiffness"], rtol=1e-9, atol=1e-6)
    np.testing.assert_allclose(degrees["pose"][3:], np.degrees(pose[3:]))


@pytest.mark.parametrize("flags, build", [
    (STEWART, lambda: hp.load_robot(DATA / "stewart" / "stewart.urdf")),
    (FOUR_BAR, lambda: hp.load_robot(DATA / "four_bar" / "four_bar.urdf")),
], ids=["stewart", "four-bar"])
def test_loaded_robots_equal_the_api(flags, build):
    robot = build()
    out = ok_json(*flags, "-k", "2e4")
    check_pose_json(out, robot, robot.home_pose, 2e4)
    assert out["pose_axes"] == list(robot.pose_axes)
    assert out["actuators"] == list(robot.model.actuated_joints)


def test_a_spring_on_the_actuated_joint_adds_its_stiffness(tmp_path):
    """``--effects``: a spring of 40 N m/rad on the four-bar's crank (its actuated joint,
    reference at home: no preload there) stiffens the coupler point by ``40 J^T J``."""
    effects = tmp_path / "spring.yaml"
    effects.write_text("joints:\n  crank: {stiffness: 40.0}\n")
    rigid = ok_json(*FOUR_BAR, "-k", "1e3")
    sprung = ok_json(*FOUR_BAR, "-k", "1e3", "--effects", effects)
    robot = hp.load_robot(DATA / "four_bar" / "four_bar.urdf")
    jac = robot.jacobian(robot.home_pose)
    np.testing.assert_allclose(np.array(sprung["stiffness"]) - np.array(rigid["stiffness"]),
                               40.0 * jac.T @ jac, rtol=1e-9)
    assert sprung["effects"]["on"]["stiffness"] == ["crank"]
    assert sprung["frequencies"][0] > rigid["frequencies"][0]


def test_text_output_names_the_units():
    result = invoke("-k", "1e5")
    assert result.exit_code == 0, result.output
    for words in ("Cartesian stiffness K_x", "smallest translational stiffness (N/m)",
                  "smallest rotational stiffness (N m/rad)", "natural frequencies (Hz)"):
        assert words in result.stdout
    result = invoke(*FOUR_BAR, "-k", "1e5")
    assert "translational" in result.stdout and "rotational" not in result.stdout


def test_map_json_equals_the_slice_and_writes_the_figure(tmp_path):
    robot = hp.load_robot(DATA / "parallel" / "five_bar_3d", platform="end_1",
                          pose_axes=("x", "z"))
    figure = tmp_path / "five_bar_stiffness.png"
    out = ok_json(*FIVE_BAR, "-k", "3e4", "--map", "--half-width", "0.1,0.15",
                  "--resolution", "5", "--out", figure)
    ws = sm.stiffness_slice(robot, 3e4, ("x", "z"), half_width=(0.1, 0.15), resolution=5)
    assert out["axes"] == ["x", "z"] and out["figure"] == str(figure)
    np.testing.assert_allclose(out["coordinates"][0], ws.coordinates[0])
    np.testing.assert_allclose(out["coordinates"][1], ws.coordinates[1])
    np.testing.assert_array_equal(out["status"], ws.grid(ws.map.status))
    assert out["status_names"] == list(sm.STATUS_NAMES)
    assert "rotational" not in out
    for key, valid in (("translational", ws.map.has_stiffness),
                       ("lowest_frequency", ws.map.ok)):
        got = np.array(out[key], dtype=float)             # None (no value) -> NaN
        want = ws.grid(np.where(valid, getattr(ws.map, key), np.nan))
        np.testing.assert_allclose(got, want, rtol=1e-12, equal_nan=True)
    assert np.any(np.isnan(np.array(out["translational"], dtype=float)))   # out of reach
    assert out["failures"] == dict(ws.map.failures)
    assert figure.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_map_text_on_the_hexapod_and_a_line():
    result = invoke("-k", "1e5", "--map", "--resolution", "3", "--quiet")
    assert result.exit_code == 0, result.output
    assert "smallest rotational stiffness (N m/rad): min" in result.stdout
    assert "poses ok" in result.stdout
    out = ok_json(*FOUR_BAR, "-k", "1e5", "--map", "--resolution", "4")
    assert out["axes"] == ["x"] and len(out["status"]) == 4


def test_bad_input():
    result = invoke("0", "0", "0.38", "0", "0", "0")
    assert result.exit_code != 0 and "Missing option '--actuator-stiffness'" in result.stderr
    one_line_error(invoke("-k", "-1"), 1, ">= 0")
    one_line_error(invoke("-k", "1,2"), 1, "actuator_stiffness")
    one_line_error(invoke("-k", "abc"), 1, "not a number")
    one_line_error(invoke("-k", "1e5", "0", "0", "5", "0", "0", "0"), 1)   # out of reach
    one_line_error(invoke("-k", "1e5", "--axes", "x"), 2, "--axes", "--map")
    one_line_error(invoke("-k", "1e5", "--out", "fig.png"), 2, "--out", "--map")
    one_line_error(invoke("-k", "1e5", "--map", "--out", "fig.txt"), 1, ".png")
    one_line_error(invoke("-k", "1e5", "--map", "--axes", "x,q"), 1, "pose axes")
    one_line_error(invoke("-k", "1e5", "--map", "--resolution", "1"), 1, "resolution")
    one_line_error(invoke("-k", "1e5", "--map", "--half-width", "0"), 1, "half_width")
    one_line_error(invoke(*STEWART, "-k", "1e5", "--set", "leg_length=0.5"), 2, "--robot")
    result = invoke("-k", "-1", "--json")
    assert result.exit_code == 1
    assert json.loads(result.stdout)["error"]["type"] == "InputError"
