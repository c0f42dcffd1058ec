"""``hexapod-pin excite`` and ``hexapod-pin identify`` on a four-bar (``--robot``): the
written trajectory against the robot's own inverse dynamics at its samples, at rest at
both ends; identification of a perturbed robot's forces from that file; the errors."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest
from conftest import one_line_error
from typer.testing import CliRunner

import hexapod_pin as hp
from hexapod_pin.cli import app
from hexapod_pin.identification import ClosedLoopRegressor, nominal_parameters
from hexapod_pin.motion import Motion, read_motion, write_motion

FOUR_BAR = Path(__file__).resolve().parents[1] / "data" / "four_bar" / "four_bar.urdf"
ROBOT = ["--robot", str(FOUR_BAR)]
RUN = CliRunner()
DRIVE = ("viscous", "coulomb", "offset")


def invoke(*args: object):
    return RUN.invoke(app, [str(a) for a in args])


@pytest.fixture(scope="module")
def robot():
    return hp.load_robot(FOUR_BAR)


@pytest.fixture(scope="module")
def excite_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("excite") / "excite.csv"
    result = invoke("excite", *ROBOT, "--out", path, "--samples", 16, "--iterations", 3,
                    "--harmonics", 2, "--rate", 5, "--periods", 3, "--json")
    assert result.exit_code == 0, result.output
    return path, json.loads(result.stdout)


def test_excite_writes_a_trajectory_at_rest_at_both_ends(robot, excite_file):
    path, summary = excite_file
    motion = read_motion(path, robot)
    assert motion.t.size == summary["samples_written"] == 3 * 16 * 5 + 1
    assert summary["condition_number"] < summary["initial_condition_number"]
    for k in (0, -1):
        assert np.allclose(motion.twists[k], 0.0, atol=1e-12)
        assert np.allclose(motion.poses[k], robot.home_pose, atol=1e-12)
    for k in range(0, motion.t.size, 37):                 # the robot's own routes
        assert np.allclose(motion.q[k], robot.inverse_kinematics(motion.poses[k]),
                           atol=1e-10)
        u = robot.inverse_dynamics(motion.poses[k], motion.twists[k],
                                   motion.twist_dots[k]).actuator_forces
        assert np.allclose(motion.actuator_forces[k], u, atol=1e-9)


def test_identify_recovers_a_perturbed_robot(robot, excite_file, tmp_path):
    """Forces of a robot with other masses and drive friction, at the file's exact states:
    identification from positions and forces brings the residual far below the nominal
    robot's."""
    path, _ = excite_file
    motion = read_motion(path, robot)
    truth = nominal_parameters(robot, DRIVE) * 1.3
    reg = ClosedLoopRegressor(robot, DRIVE)
    truth[reg.layout.drive_slice("viscous")] = 0.05
    truth[reg.layout.drive_slice("coulomb")] = 0.02
    truth[reg.layout.drive_slice("offset")] = 0.01
    forces = (reg.batch(motion.poses, motion.twists, motion.twist_dots) @ truth)
    data = tmp_path / "measured.csv"
    write_motion(data, Motion(motion.t, motion.poses, q=motion.q,
                              actuator_forces=forces.reshape(-1, 1)), robot)
    result = invoke("identify", data, *ROBOT, "--json", "--no-consistent")
    assert result.exit_code == 0, result.output
    out = json.loads(result.stdout)
    assert out["residual_rms_after"] < 0.05 * out["residual_rms_before"]
    assert len(out["names"]) == len(out["values"]) == len(out["std_errors"])
    text = invoke("identify", data, *ROBOT, "--no-consistent")
    assert text.exit_code == 0 and "rms after" in text.stdout and "off_crank" in text.stdout
    if importlib.util.find_spec("matplotlib") is not None:
        figure = tmp_path / "fit.png"
        done = invoke("identify", data, *ROBOT, "--no-consistent", "--figure", figure)
        assert done.exit_code == 0, done.output
        assert figure.is_file() and (tmp_path / "fit_parameters.png").is_file()


def test_errors(robot, excite_file, tmp_path):
    path, _ = excite_file
    motion = read_motion(path, robot)
    no_forces = tmp_path / "no_forces.csv"
    write_motion(no_forces, Motion(motion.t, motion.poses, q=motion.q), robot)
    one_line_error(invoke("identify", no_forces, *ROBOT), 1, "no_forces.csv", "tau0")
    one_line_error(invoke("identify", path, *ROBOT, "--drive", "viscous,friction"), 1,
                   "drive")
    one_line_error(invoke("excite", *ROBOT, "--harmonics", 1, "--out", tmp_path / "x.csv"),
                   1, "harmonics")
    one_line_error(invoke("excite", "--platform", "crank", "--out", tmp_path / "x.csv"), 2,
                   "--robot")
    one_line_error(invoke("excite", *ROBOT, "--out", tmp_path / "x.txt"), 1, "out")


def _log_file(path, columns, rows):
    """A CSV log written here with the csv module (no library writer)."""
    import csv
    with open(path, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(columns)
        writer.writerows(rows)
    return path


def test_identify_reads_a_log_without_pose_columns(robot, excite_file, tmp_path):
    """A real log has times, actuator positions and forces only: identification from it
    equals identification from the same samples with the pose columns (poses are
    recomputed from the positions either way), CSV and JSON; --use-poses needs poses."""
    path, _ = excite_file
    motion = read_motion(path, robot)
    truth = nominal_parameters(robot, DRIVE) * 1.2
    reg = ClosedLoopRegressor(robot, DRIVE)
    truth[reg.layout.drive_slice("viscous")] = 0.04
    forces = (reg.batch(motion.poses, motion.twists, motion.twist_dots) @ truth)
    with_poses = tmp_path / "with_poses.csv"
    write_motion(with_poses, Motion(motion.t, motion.poses, q=motion.q,
                                    actuator_forces=forces.reshape(-1, 1)), robot)
    rows = np.column_stack([motion.t, motion.q, forces]).tolist()
    log = _log_file(tmp_path / "log.csv", ["t", "q0", "tau0"], rows)
    log_json = tmp_path / "log.json"
    log_json.write_text(json.dumps({"t": motion.t.tolist(), "q": motion.q.tolist(),
                                    "actuator_forces": forces.reshape(-1, 1).tolist()}))
    runs = [invoke("identify", f, *ROBOT, "--json", "--no-consistent")
            for f in (with_poses, log, log_json)]
    for run in runs:
        assert run.exit_code == 0, run.output
    ref, *others = (json.loads(run.stdout) for run in runs)
    assert ref["residual_rms_after"] < 0.05 * ref["residual_rms_before"]
    for out in others:
        assert out["samples"] == ref["samples"]
        assert np.allclose(out["values"], ref["values"], rtol=1e-9, atol=1e-12)
        assert np.allclose(out["std_errors"], ref["std_errors"], rtol=1e-9)
    one_line_error(invoke("identify", log, *ROBOT, "--use-poses"), 1, "use_poses",
                   "no pose columns")
    no_tau = _log_file(tmp_path / "no_tau.csv", ["t", "q0"],
                       np.column_stack([motion.t, motion.q]).tolist())
    one_line_error(invoke("identify", no_tau, *ROBOT), 1, "no_tau.csv", "tau0")
    foreign = _log_file(tmp_path / "foreign.csv", ["t", "q0", "q1", "tau0", "tau1"],
                        np.column_stack([motion.t, motion.q, motion.q, forces,
                                         forces]).tolist())
    one_line_error(invoke("identify", foreign, *ROBOT), 1, "q1")


def test_identify_takes_the_position_noise(robot, excite_file, tmp_path):
    """``--position-noise`` reaches ``identify(position_noise_std=...)``: the command's
    numbers equal the library call's with the same noise, which differ from the call
    without it (the errors-in-the-variables steps run); a negative noise is refused."""
    from hexapod_pin.identification import MotionData, identify

    path, _ = excite_file
    motion = read_motion(path, robot)
    truth = nominal_parameters(robot, DRIVE) * 1.2
    reg = ClosedLoopRegressor(robot, DRIVE)
    truth[reg.layout.drive_slice("viscous")] = 0.05
    forces = reg.batch(motion.poses, motion.twists, motion.twist_dots) @ truth
    q = motion.q + 1e-6 * np.random.default_rng(3).standard_normal(motion.q.shape)
    data = _log_file(tmp_path / "noisy.csv", ["t", "q0", "tau0"],
                     np.column_stack([motion.t, q, forces]).tolist())
    run = invoke("identify", data, *ROBOT, "--json", "--no-consistent",
                 "--position-noise", "1e-6")
    assert run.exit_code == 0, run.output
    out = json.loads(run.stdout)
    measured = MotionData(motion.t, q, forces.reshape(len(motion.t), -1))
    given = identify(robot, measured, drive=DRIVE, position_noise_std=1e-6, consistent=False)
    plain = identify(robot, measured, drive=DRIVE, consistent=False)
    np.testing.assert_allclose(out["std_errors"], given.std_errors, rtol=1e-9)
    np.testing.assert_allclose(out["values"], given.values, rtol=1e-9, atol=1e-12)
    assert not np.allclose(given.std_errors, plain.std_errors, rtol=1e-6)
    one_line_error(invoke("identify", data, *ROBOT, "--position-noise", "-1e-6"), 1,
                   "position_noise_std")
