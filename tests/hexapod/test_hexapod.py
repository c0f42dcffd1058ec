"""Hexapod: pose <-> tree configuration, reference states, CLI demo."""

import json
import subprocess
import sys

import numpy as np
import pytest
from typer.testing import CliRunner

import hexapod_pin as hp
from hexapod_pin.cli import app

from conftest import geometry_from_reference, load_reference, random_pose


def test_default_constructors(robot):
    assert robot.geometry == hp.HexapodGeometry()
    assert isinstance(robot.model, hp.ClosedLoopModel)
    np.testing.assert_array_equal(robot.home_q, [-0.15, 0.15, -0.15, 0.15, -0.15, 0.15])
    with pytest.raises(TypeError):
        hp.Hexapod("not a geometry")


def test_configuration_round_trip(any_robot, rng):
    for _ in range(10):
        pose = random_pose(any_robot, rng)
        q = any_robot.configuration(pose)
        assert np.max(np.abs(any_robot.model.residual(q))) <= 1e-12
        np.testing.assert_allclose(any_robot.pose_from_configuration(q), pose, atol=1e-14)
        np.testing.assert_allclose(any_robot.carriage_positions(q), any_robot.inverse_kinematics(pose),
                                   atol=1e-15)


def test_home_configuration_puts_carriages_at_home(any_robot):
    q = any_robot.home_configuration
    np.testing.assert_allclose(any_robot.carriage_positions(q), any_robot.home_q, atol=1e-14)
    np.testing.assert_allclose(any_robot.pose_from_configuration(q), any_robot.home_pose, atol=1e-15)


def test_second_geometry_end_to_end(robot2, rng):
    g = robot2.geometry
    assert (g.rail_radius, g.platform_radius, g.leg_length, g.carriage_home) == (0.40, 0.10, 0.50, 0.18)
    expected_height = np.sqrt(0.5**2 - 0.3**2 - 0.18**2)
    assert robot2.home_pose[2] == pytest.approx(expected_height, abs=1e-15)
    q = robot2.home_configuration
    assert np.max(np.abs(robot2.model.residual(q))) <= 1e-12
    assert robot2.model.rank(q).rank == 18
    pose = random_pose(robot2, rng)
    q0 = robot2.configuration(pose)
    assert robot2.model.assemble(q0).iterations == 0


def test_reference_states_kinematics():
    """Agree with the independently computed reference states (conventions check)."""
    for entry in load_reference()["hexapod"]:
        robot = hp.Hexapod(geometry_from_reference(entry))
        pose = np.array(entry["pose"])
        np.testing.assert_allclose(robot.inverse_kinematics(pose, check_limits=False), entry["q"],
                                   rtol=1e-9, atol=1e-12)
        jac = robot.jacobian(pose)
        np.testing.assert_allclose(jac, entry["jacobian"], rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(jac @ entry["twist"], entry["qdot"], rtol=1e-9, atol=1e-12)


def test_cli_demo_reports_closed_home():
    result = CliRunner().invoke(app, ["demo", "--json"])
    assert result.exit_code == 0, result.output
    payload = json.loads(result.output)
    assert payload["closure_residual_max_abs_m"] <= 1e-12
    assert payload["mobility"] == 6
    assert payload["home_pose"][2] == pytest.approx(0.35651086939951776, abs=1e-12)


def test_cli_bad_input_is_one_line_and_nonzero():
    proc = subprocess.run([sys.executable, "-m", "hexapod_pin", "demo", "--set", "leg_length=-1"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 1
    assert "Traceback" not in proc.stderr
    assert "leg_length" in proc.stderr
