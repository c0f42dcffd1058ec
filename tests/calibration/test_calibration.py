"""Kinematic calibration (hexapod_pin.calibration): synthetic data from the Pinocchio tree
of a perturbed robot, identification checked against the known truth (expressed in the
measurement frames by a numpy transform written here), the analytic identification
Jacobians against finite differences, the closure residual against the robot's inverse
kinematics, identifiability errors on degenerate data, pose selection, the CLI."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from typer.testing import CliRunner

import hexapod_pin as hp
from hexapod_pin.calibration import (
    IdentifiabilityError,
    calibrate,
    plots,
    random_as_built,
    synthetic_measurements,
)
from hexapod_pin.calibration import model as cm
from hexapod_pin.calibration.measurements import read_measurements, write_measurements
from hexapod_pin.calibration.parameters import N_PARAMETERS, NAMES, ParameterModel
from hexapod_pin.calibration.problem import reference_poses
from hexapod_pin.calibration.selection import candidate_blocks, observability, select_poses
from hexapod_pin.cli import app
from hexapod_pin.errors import DescriptionError, InputError
from hexapod_pin.files import load_geometry

INSTRUMENT = np.array([2e-3, -1e-3, 1.5e-3, 1e-3, -2e-3, 1.5e-3])
TARGET = np.array([1e-3, 2e-3, -1e-3, 2e-3, -1e-3, 1e-3])
POINTS = np.array([[0.03, 0.0, 0.01], [-0.02, 0.04, 0.0], [0.0, -0.05, 0.02]])


def rot(rpy):
    return Rotation.from_euler("ZYX", np.asarray(rpy)[::-1]).as_matrix()   # Rz Ry Rx


@pytest.fixture(scope="module")
def nominal():
    return hp.Hexapod.default()


@pytest.fixture(scope="module")
def truth(nominal):
    """Millimetre-level deviations in every chain parameter."""
    return random_as_built(nominal.geometry, 1e-3, seed=7)


def in_measurement_frames(chains, instrument, target):
    """Numpy reference: the lines in the instrument frame, the joints in the target frame,
    as ``(c_i(0), u_i, L_i, p_i)`` (``c_i(0) = a_i + o_i u_i`` does not depend on where the
    line point sits on its line)."""
    ri, ti = rot(instrument[3:]), instrument[:3]
    rt, tt = rot(target[3:]), target[:3]
    zero = chains.line_points + chains.sensor_offsets[:, None] * chains.line_directions
    return ((zero - ti) @ ri, chains.line_directions @ ri, chains.leg_lengths,
            (chains.platform_joints - tt) @ rt)


def gauge_chains(parts, instrument, target):
    """The chains in the robot's frames whose view from the frames ``instrument`` and
    ``target`` is ``parts`` (the inverse of :func:`in_measurement_frames`)."""
    zero, u, lengths, joints = parts
    ri, ti = rot(instrument[3:]), instrument[:3]
    rt, tt = rot(target[3:]), target[:3]
    return hp.ChainGeometry(line_points=zero @ ri.T + ti, line_directions=u @ ri.T,
                            sensor_offsets=np.zeros(6), leg_lengths=lengths,
                            platform_joints=joints @ rt.T + tt)


@pytest.fixture(scope="module")
def commanded(nominal):
    return reference_poses(nominal, 160, seed=3)          # 87 poses


@pytest.fixture(scope="module")
def exact(nominal, truth, commanded):
    return synthetic_measurements(nominal, truth, commanded, instrument=INSTRUMENT,
                                  target=TARGET, target_points=POINTS)


def test_synthetic_pinocchio_route_closes_the_true_legs(nominal, truth, exact):
    """The poses of the Pinocchio route close the true chains (numpy leg lengths)."""
    chains = truth.chain_geometry
    for pose, q in zip(exact.true_poses[:10], exact.actuators[:10]):
        joints = pose[:3] + chains.platform_joints @ rot(pose[3:]).T
        centres = chains.line_points + (q + chains.sensor_offsets)[:, None] \
            * chains.line_directions
        assert np.allclose(np.linalg.norm(joints - centres, axis=1), chains.leg_lengths,
                           atol=1e-11)
    assert np.max(np.abs(exact.true_poses - exact.commanded)) > 1e-4   # the deviations show


def test_parameter_map_round_trip(nominal):
    params = ParameterModel(nominal.geometry.chain_geometry, INSTRUMENT, TARGET)
    theta = np.random.default_rng(1).normal(scale=1e-3, size=N_PARAMETERS)
    back = params.deviations_of(params.chains(theta), *params.frame_poses(theta))
    assert np.allclose(back, theta, atol=1e-14)
    assert params.chains(np.zeros(N_PARAMETERS)) == nominal.geometry.chain_geometry


def test_closure_residual_is_the_inverse_kinematics_error(nominal, truth):
    """e_i = q_i(IK) - q_i to first order, checked with the true robot's closed-form IK."""
    robot = hp.Hexapod(truth)
    params = ParameterModel(nominal.geometry.chain_geometry)
    theta = params.deviations_of(truth.chain_geometry)
    poses = reference_poses(nominal, 10, seed=5)
    q_ik = robot.inverse_kinematics_batch(poses).actuator_positions
    shift = np.random.default_rng(2).normal(scale=1e-6, size=q_ik.shape)
    e, _ = cm.pose_residuals(params, theta, poses, q_ik + shift, with_jacobian=False)
    assert np.allclose(e, -shift, atol=1e-10, rtol=0)


def finite_difference(func, theta, step=1e-6):
    cols = []
    for k in range(theta.size):
        d = np.zeros_like(theta)
        d[k] = step
        cols.append((func(theta + d) - func(theta - d)) / (2 * step))
    return np.column_stack(cols)


def test_pose_model_jacobian_matches_finite_differences(nominal, exact):
    params = ParameterModel(nominal.geometry.chain_geometry, INSTRUMENT * 5, TARGET * 5)
    theta = np.random.default_rng(3).normal(scale=1e-3, size=N_PARAMETERS)
    poses, q = exact.poses[:6], exact.actuators[:6]
    _, jac = cm.pose_residuals(params, theta, poses, q)
    fd = finite_difference(lambda t: cm.pose_residuals(params, t, poses, q, False)[0].ravel(),
                           theta)
    scale = np.max(np.abs(fd), axis=0)
    assert np.all(scale > 0)
    assert np.max(np.abs(jac - fd) / scale) < 1e-7


def test_point_model_jacobian_matches_finite_differences(nominal, exact):
    params = ParameterModel(nominal.geometry.chain_geometry, INSTRUMENT * 5, TARGET * 5)
    theta = np.random.default_rng(4).normal(scale=1e-3, size=N_PARAMETERS)
    model = cm.PointModel(params, exact.points[:5, :2], POINTS[:2], exact.actuators[:5],
                          exact.true_poses[:5])
    _, jac = model.residuals(theta)
    fd = finite_difference(lambda t: model.residuals(t, False)[0].ravel(), theta, step=1e-5)
    scale = np.max(np.abs(fd), axis=0)
    assert np.all(scale > 0)
    # finite differences of a Newton solution converged to 1e-12 m: about 1e-7 relative
    assert np.max(np.abs(jac - fd) / scale) < 1e-5


def test_noise_free_data_recover_the_base_parameters(nominal, truth, exact):
    result = calibrate(nominal, exact.poses, exact.actuators)
    report = result.identifiability
    assert len(report.base) == 54 and report.rank == 54
    assert set(report.fixed) == {n for n in NAMES if n.startswith(("instrument", "target"))}
    assert any("rigid motion of all six lines" in t for t in report.unidentifiable)
    assert any("platform joints" in t for t in report.unidentifiable)
    # the instrument and target frames are held at their guesses (the instrument
    # registered, the target the identity): seen from them, the identified chains are the
    # truth seen from the true measurement frames
    assert np.array_equal(result.target, np.zeros(6))
    # registered onto the nominal robot: within what the deviations move the platform
    assert np.max(np.abs(result.instrument - INSTRUMENT)) < 3e-2
    want = in_measurement_frames(truth.chain_geometry, INSTRUMENT, TARGET)
    got = in_measurement_frames(result.chains, result.instrument, result.target)
    for a, b in zip(got, want):
        assert np.allclose(a, b, atol=1e-9, rtol=0)
    params = ParameterModel(nominal.geometry.chain_geometry)
    theta = params.deviations_of(gauge_chains(want, result.instrument, result.target))
    est = result.estimates()
    assert max(abs(est[NAMES[k]] - theta[k]) for k in range(54)) < 1e-9
    assert result.residuals_after.max < 1e-10
    # result.robot is commanded in the measurement frames
    q = result.robot.inverse_kinematics(exact.poses[0], check_limits=False)
    assert np.allclose(q, exact.actuators[0], atol=1e-9)


def test_noisy_calibration_end_to_end(nominal, truth, commanded):
    data = synthetic_measurements(nominal, truth, commanded[:60], instrument=INSTRUMENT,
                                  target=TARGET, position_noise=1e-5, rotation_noise=2e-5,
                                  seed=11)
    result = calibrate(nominal, data.poses, data.actuators, noise=(1e-5, 2e-5, 1e-9))
    want = in_measurement_frames(truth.chain_geometry, INSTRUMENT, TARGET)
    params = ParameterModel(nominal.geometry.chain_geometry)
    theta = params.deviations_of(gauge_chains(want, result.instrument, result.target))
    errors = [(p.deviation - theta[NAMES.index(p.name)]) / p.std_error
              for p in result.parameters if p.identified]
    assert len(errors) == 54
    assert np.max(np.abs(errors)) < 3.0
    assert 0.5 < result.residuals_after.normalized_rms < 1.5      # the noise model fits
    # held-out poses: the nominal model is off by millimetres, the identified one by
    # about what the true model itself shows on the same noisy data
    held = synthetic_measurements(nominal, truth, commanded[60:], instrument=INSTRUMENT,
                                  target=TARGET, position_noise=1e-5, rotation_noise=2e-5,
                                  seed=12)
    report = result.validate(held.poses, held.actuators)
    true_robot = hp.Hexapod(nominal.geometry.with_chains(gauge_chains(want, np.zeros(6),
                                                                      np.zeros(6))))
    floor = np.sqrt(np.mean((true_robot.inverse_kinematics_batch(held.poses)
                             .actuator_positions - held.actuators) ** 2))
    nominal_err, identified = report.nominal.summary(), report.identified.summary()
    # (the nominal model sees the instrument registered: about 1 mm, 6 mrad off)
    assert nominal_err["actuator_rms"] > 5e-4 and nominal_err["position_rms"] > 5e-4
    assert nominal_err["position_rms"] > 30 * identified["position_rms"]
    assert identified["actuator_rms"] < 1.5 * floor
    assert identified["position_rms"] < 4e-5 and identified["rotation_rms"] < 1e-4


def test_a_far_instrument_is_registered(nominal, truth, commanded):
    """A tracker 1.5 m away and turned by 0.4 rad: the registration starts the fit."""
    far = np.array([1.5, -0.8, 0.2, 0.05, -0.03, 0.4])
    data = synthetic_measurements(nominal, truth, commanded[:30], instrument=far,
                                  route="closed_form")
    result = calibrate(nominal, data.poses, data.actuators)
    assert np.max(np.abs(result.instrument - far)) < 3e-2
    assert result.residuals_after.max < 1e-10
    q = result.robot.inverse_kinematics(data.poses[0], check_limits=False)
    assert np.allclose(q, data.actuators[0], atol=1e-9)


def test_frames_alone_are_identified_exactly(nominal, commanded):
    """Chains known (the nominal robot): the instrument and target frames are recovered."""
    data = synthetic_measurements(nominal, nominal.geometry, commanded[:20],
                                  instrument=INSTRUMENT, target=TARGET, route="closed_form")
    result = calibrate(nominal, data.poses, data.actuators, identify=("instrument", "target"))
    assert result.identifiability.unidentifiable == ()
    assert np.allclose(result.instrument, INSTRUMENT, atol=1e-10)
    assert np.allclose(result.target, TARGET, atol=1e-10)


def test_three_points_recover_the_chains(nominal, truth, exact):
    result = calibrate(nominal, None, exact.actuators[:40], points=exact.points[:40],
                       target_points=POINTS)
    assert len(result.identifiability.base) == 54
    want = in_measurement_frames(truth.chain_geometry, INSTRUMENT, TARGET)
    got = in_measurement_frames(result.chains, result.instrument, result.target)
    for a, b in zip(got, want):
        assert np.allclose(a, b, atol=1e-8, rtol=0)
    report = result.validate(actuators=exact.actuators[40:], points=exact.points[40:])
    assert report.identified.summary()["position_max"] < 1e-9
    assert report.nominal.summary()["position_max"] > 1e-3


def test_one_point_leaves_the_target_rotation_unidentified(nominal, exact):
    result = calibrate(nominal, None, exact.actuators[:40], points=exact.points[:40, :1],
                       target_points=POINTS[:1], identify=("sensor_offsets", "target"))
    fixed = set(result.identifiability.fixed)
    assert {"target.roll", "target.pitch", "target.yaw"} <= fixed
    assert any("rotation about the point" in t for t in result.identifiability.unidentifiable)


def test_too_few_poses_is_an_identifiability_error(nominal, exact):
    with pytest.raises(IdentifiabilityError, match="too few") as info:
        calibrate(nominal, exact.poses[:5], exact.actuators[:5])
    assert info.value.needed == 54


def test_one_orientation_is_an_identifiability_error(nominal, truth):
    poses = reference_poses(nominal, 200, seed=8)[:40].copy()
    poses[:, 3:] = 0.0
    data = synthetic_measurements(nominal, truth, poses, route="closed_form")
    flat = data.poses.copy()
    flat[:, 3:] = data.poses[0, 3:]            # the instrument sees one orientation
    # a platform joint's shift then trades with its line's point and sensor zero
    with pytest.raises(IdentifiabilityError, match="same orientation") as info:
        calibrate(nominal, flat, data.actuators)
    assert info.value.needed - info.value.rank == 18 and info.value.combinations
    # the joints alone are still determined by translations
    result = calibrate(nominal, flat, data.actuators, identify="platform_joints")
    assert len(result.identifiability.base) == 18


def test_bad_inputs_raise_typed_errors(nominal, exact):
    poses, q = exact.poses[:30], exact.actuators[:30]
    with pytest.raises(InputError, match="identify"):
        calibrate(nominal, poses, q, identify=("legs",))
    with pytest.raises(InputError, match="poses"):
        calibrate(nominal, poses[:, :5], q)
    bad = poses.copy()
    bad[3, 2] = np.nan
    with pytest.raises(InputError):
        calibrate(nominal, bad, q)
    with pytest.raises(InputError, match="either poses or points"):
        calibrate(nominal, poses, q, points=exact.points[:30], target_points=POINTS)
    with pytest.raises(InputError, match="30 actuator"):
        calibrate(nominal, poses[:20], q)
    with pytest.raises(InputError, match="Hexapod"):
        calibrate(hp.Planar3PRR.default(), poses, q)
    with pytest.raises(InputError, match="method"):
        calibrate(nominal, poses, q, method="newton")
    with pytest.raises(InputError, match="noise"):
        calibrate(nominal, poses, q, noise=(-1.0, 0.0, 0.0))
    with pytest.raises(InputError, match="one to three"):
        calibrate(nominal, None, q, points=np.zeros((30, 4, 3)), target_points=np.zeros((4, 3)))


def test_selected_poses_beat_random_ones(nominal):
    candidates = reference_poses(nominal, 300, seed=9)
    greedy = select_poses(nominal, candidates, 12, identify=("sensor_offsets", "leg_lengths",
                                                             "platform_joints"))
    exchange = select_poses(nominal, candidates, 12, method="exchange",
                            identify=("sensor_offsets", "leg_lengths", "platform_joints"))
    assert len(set(greedy.indices.tolist())) == 12
    assert exchange.log_det >= greedy.log_det - 1e-9
    blocks, ok = candidate_blocks(nominal, candidates, identify=(
        "sensor_offsets", "leg_lengths", "platform_joints"))
    rows = np.flatnonzero(ok).searchsorted(exchange.indices)
    assert np.isclose(observability(blocks[rows])[1], exchange.log_det)
    # the index of the chosen set: O1 from a plain SVD of the stacked blocks
    sigma = np.linalg.svd(blocks[rows].reshape(-1, blocks.shape[2]), compute_uv=False)
    assert np.isclose(exchange.o1, np.prod(sigma) ** (1 / sigma.size) / np.sqrt(72))
    rng = np.random.default_rng(0)
    randoms = [observability(blocks[rng.choice(len(blocks), 12, replace=False)])[0]
               for _ in range(20)]
    assert greedy.o1 > max(randoms)
    with pytest.raises(InputError, match="n"):
        select_poses(nominal, candidates, 0)
    with pytest.raises(InputError, match="criterion"):
        select_poses(nominal, candidates, 3, criterion="A")


def test_measurement_file_round_trip_and_errors(tmp_path, exact):
    path = write_measurements(tmp_path / "m.csv", exact.actuators[:4], exact.poses[:4])
    back = read_measurements(path)
    assert np.array_equal(back.poses, exact.poses[:4])
    assert np.array_equal(back.actuators, exact.actuators[:4])
    pts = write_measurements(tmp_path / "p.csv", exact.actuators[:4], points=exact.points[:4])
    assert np.array_equal(read_measurements(pts, POINTS).points, exact.points[:4])
    (tmp_path / "bad.csv").write_text("x,y,z,roll,pitch,yaw,q0,q1,q2,q3,q4,q5,extra\n")
    with pytest.raises(DescriptionError, match="unknown columns"):
        read_measurements(tmp_path / "bad.csv")
    (tmp_path / "nan.csv").write_text("x,y,z,roll,pitch,yaw,q0,q1,q2,q3,q4,q5\n"
                                      "0,0,0.3,0,0,0,a,0,0,0,0,0\n")
    with pytest.raises(DescriptionError, match="row 2, column q0"):
        read_measurements(tmp_path / "nan.csv")


def test_cli_calibrate_round_trip(tmp_path, nominal, exact):
    csv = write_measurements(tmp_path / "m.csv", exact.actuators[:50], exact.poses[:50])
    out = tmp_path / "asbuilt.toml"
    own = tmp_path / "robot_frame.json"
    run = CliRunner().invoke(app, ["calibrate", str(csv), "--out", str(out), "--json",
                                   "--select-poses", "40", "--out-robot-frame", str(own)])
    assert run.exit_code == 0, run.output
    payload = json.loads(run.stdout)
    assert len(payload["rows_used"]) == 40
    assert payload["identifiability"]["rank"] == 54
    assert payload["validation"]["identified"]["actuator_max"] < 1e-8
    # the geometry file loads with --geometry and commands the measurement frames
    robot = hp.Hexapod(load_geometry(out))
    q = robot.inverse_kinematics_batch(exact.poses[50:60]).actuator_positions
    assert np.allclose(q, exact.actuators[50:60], atol=1e-9)
    # the robot-frame file: the same robot seen from the held (registered) frames
    inst, seen = np.array(payload["instrument"]), exact.poses[50]
    assert payload["target"] == [0.0] * 6
    turn = rot(inst[3:]) @ rot(seen[3:])                # T_WP = T_WI T_IT (target held)
    pose = np.r_[rot(inst[3:]) @ seen[:3] + inst[:3], Rotation.from_matrix(turn)
                 .as_euler("ZYX")[::-1]]
    robot_frame = hp.Hexapod(load_geometry(own))
    assert np.allclose(robot_frame.inverse_kinematics(pose, check_limits=False),
                       exact.actuators[50], atol=1e-9)
    shown = CliRunner().invoke(app, ["ik", "--geometry", str(out), "--json",
                                     *map(str, exact.poses[55])])
    assert shown.exit_code == 0, shown.output
    bad = CliRunner().invoke(app, ["calibrate", str(tmp_path / "missing.csv")])
    assert bad.exit_code == 1 and "not found" in bad.stderr
    few = write_measurements(tmp_path / "few.csv", exact.actuators[:3], exact.poses[:3])
    err = CliRunner().invoke(app, ["calibrate", str(few), "--json"])
    assert err.exit_code == 1
    assert json.loads(err.stdout)["error"]["type"] == "IdentifiabilityError"


def test_validation_figure(tmp_path, nominal, truth, exact):
    pytest.importorskip("matplotlib")
    result = calibrate(nominal, exact.poses[:40], exact.actuators[:40])
    report = result.validate(exact.poses[40:], exact.actuators[40:])
    fig = plots.plot_validation_errors(report, path=tmp_path / "v.png")
    assert len(fig.axes) == 3 and (tmp_path / "v.png").stat().st_size > 0


def test_chains_alone_absorb_the_frames(nominal, exact):
    """Frames held: the chains take the instrument and target offsets exactly (a rigid
    motion of the lines and of the joints), nothing is structurally unidentifiable."""
    result = calibrate(nominal, exact.poses[:40], exact.actuators[:40], identify="chains",
                       instrument=np.zeros(6))
    assert result.identifiability.unidentifiable == () and result.identifiability.fixed == ()
    assert result.residuals_after.max < 1e-10
    assert np.array_equal(result.instrument, np.zeros(6))


@pytest.mark.parametrize("seed", range(3))
def test_parameter_map_inverts_for_random_chains(nominal, seed):
    """deviations_of(chains(theta)) == theta for deviations up to 1 cm / 10 mrad."""
    params = ParameterModel(nominal.geometry.chain_geometry)
    theta = np.random.default_rng(seed).uniform(-1e-2, 1e-2, size=N_PARAMETERS)
    theta[54:] = 0.0
    assert np.allclose(params.deviations_of(params.chains(theta)), theta, atol=1e-13)


def test_random_as_built_draws_every_chain_parameter_and_checks_its_options():
    """random_as_built: the deviations of the geometry's chains from the drawing have the
    asked standard deviation (one seed: 66 draws within 4 sigma, spread near ``scale``),
    the same seed gives the same robot, scale 0 the drawing; bad options are refused."""
    nominal = hp.HexapodGeometry()
    built = random_as_built(nominal, 2e-3, seed=11)
    drawing = nominal.chain_geometry.as_vector()
    dev = built.chains.as_vector() - drawing
    assert dev.size == 66 and np.all(np.abs(dev) <= 4 * 2e-3)
    assert 1e-3 < np.std(dev) < 3e-3
    again = random_as_built(nominal, 2e-3, seed=np.random.default_rng(11))
    np.testing.assert_array_equal(again.chains.as_vector(), built.chains.as_vector())
    zero = random_as_built(nominal, 0.0, seed=3)
    np.testing.assert_allclose(zero.chains.as_vector(), drawing, rtol=0, atol=1e-15)
    for bad in (-1e-3, float("nan"), "1e-3"):
        with pytest.raises(InputError, match="scale"):
            random_as_built(nominal, bad)
    with pytest.raises(InputError, match="seed"):
        random_as_built(nominal, 1e-3, seed=1.5)
