"""Identification from synthetic data of a perturbed robot: exact recovery without noise,
standard errors that cover the truth with noise, held-out prediction no worse than plain
least squares (written here), the consistent robot, and the refusals."""

from __future__ import annotations

import numpy as np
import pytest
import robot_registry
from identification_helpers import perturbed

from hexapod_pin.errors import IdentifiabilityError, InputError
from hexapod_pin.identification import (
    ClosedLoopRegressor,
    MotionData,
    base_parameters,
    identify,
    identify_from_states,
    nominal_parameters,
    optimise_excitation,
    random_states,
)
from hexapod_pin.identification.consistent import MASS_FLOOR, pseudo_inertia

DRIVE = ("viscous", "coulomb", "offset")


def _data(robot, truth, n, seed):
    reg = ClosedLoopRegressor(robot, DRIVE)
    states = random_states(robot, n, seed=seed)
    forces = (reg.batch(*states) @ truth).reshape(n, -1)
    return states, forces, reg


@pytest.mark.parametrize("name", ["hexapod", "planar", "stewart"])
def test_noise_free_recovery(name):
    robot = robot_registry.get(name)
    truth = perturbed(robot, DRIVE, np.random.default_rng(1))
    base = base_parameters(robot, DRIVE)
    states, forces, _ = _data(robot, truth, 40, seed=2)
    res = identify_from_states(robot, *states, forces, base=base, consistent=False)
    expected = base.values(truth)
    assert np.max(np.abs(res.values - expected) / np.maximum(1.0, np.abs(expected))) < 1e-8
    assert res.after.rms < 1e-9 * res.before.rms


@pytest.mark.parametrize("name", ["hexapod", "planar"])
def test_noisy_estimates_within_three_standard_errors(name):
    robot = robot_registry.get(name)
    rng = np.random.default_rng(3)
    truth = perturbed(robot, DRIVE, rng)
    base = base_parameters(robot, DRIVE)
    states, clean, reg = _data(robot, truth, 150, seed=4)
    noise = 0.01 * (clean.max(axis=0) - clean.min(axis=0)) * rng.uniform(0.5, 2.0,
                                                                         clean.shape[1])
    measured = clean + rng.normal(size=clean.shape) * noise
    res = identify_from_states(robot, *states, measured, base=base)
    z = (res.values - base.values(truth)) / res.std_errors
    assert np.max(np.abs(z)) < 3.0
    assert np.allclose(res.noise_std, noise, rtol=0.3)
    # held-out states: predictions far below the noise, no worse than plain OLS
    held, held_clean, _ = _data(robot, truth, 40, seed=5)
    report = res.validate_states(*held, held_clean)
    wb = base.regressor(reg.batch(*states))
    ols = np.linalg.lstsq(wb, measured.reshape(-1), rcond=None)[0]
    ols_rms = np.sqrt(np.mean((base.regressor(reg.batch(*held)) @ ols
                               - held_clean.reshape(-1)) ** 2))
    assert report.identified.rms < 0.3 * float(np.sqrt(np.mean(noise ** 2)))
    assert report.identified.rms <= 1.05 * ols_rms
    assert report.identified.rms < report.nominal.rms
    # the consistent estimate: physically consistent, close to least squares in the base
    # measured: 1.3 standard errors on the hexapod
    assert res.consistent is not None and res.consistent_gap < 3.0
    for b in range(len(base.layout.bodies)):
        pi = res.consistent.parameters[10 * b:10 * b + 10]
        if pi[0] > 0:
            inertia = np.array([[pi[4], pi[5], pi[7]], [pi[5], pi[6], pi[8]],
                                [pi[7], pi[8], pi[9]]])
            com = pi[1:4] / pi[0]
            about_com = inertia - pi[0] * (com @ com * np.eye(3) - np.outer(com, com))
            moments = np.linalg.eigvalsh(about_com)
            assert moments[0] > 0 and moments[0] + moments[1] >= moments[2] * (1 - 1e-9)


def test_identified_robot_runs_every_route():
    robot = robot_registry.get("planar")
    rng = np.random.default_rng(6)
    truth = perturbed(robot, DRIVE, rng)
    states, clean, _ = _data(robot, truth, 100, seed=7)
    measured = clean + rng.normal(size=clean.shape) * 0.01 * np.ptp(clean, axis=0)
    res = identify_from_states(robot, *states, measured)
    ident = res.identified_robot
    pose, twist, twist_dot = (s[0] for s in states)
    u = ident.inverse_dynamics(pose, twist, twist_dot).actuator_forces
    off = res.consistent.parameters[res.base.layout.drive_slice("offset")]
    assert np.allclose(u + off, clean[0], atol=0.01 * np.max(np.abs(clean)))
    acc = ident.forward_dynamics(pose, twist, u).twist_dot
    assert np.allclose(acc, twist_dot, atol=1e-8)
    assert ident.static_forces(pose).shape == (3,)
    assert "m_slider_0" in res.table()
    # verified: every fitted body definite with margin, masses above the floor, the
    # mass matrix in actuator coordinates (from the identified robot's own route: the
    # forward dynamics' response to unit forces) well conditioned
    fit = res.consistent
    assert fit.smallest_eigenvalue > 1e-6 and fit.smallest_mass_ratio >= MASS_FLOOR
    for b in range(len(res.base.layout.bodies)):
        pi = fit.parameters[10 * b:10 * b + 10]
        if pi[0] > 0:
            assert np.linalg.eigvalsh(pseudo_inertia(pi))[0] > 0
    zero = np.zeros(3)
    bias = ident.forward_dynamics(pose, zero, zero).twist_dot
    inv_mass = np.column_stack([ident.forward_dynamics(pose, zero, e).twist_dot - bias
                                for e in np.eye(3)])
    assert np.linalg.cond(inv_mass) < 1e4
    assert res.consistent_gap < 3.0


def test_consistent_fit_stops_at_the_mass_floor(caplog):
    """Data of a robot whose first slider and link weigh 2 % of nominal (their masses
    enter the forces as a sum, with the link's first moment): the consistent fit stops
    at MASS_FLOOR of nominal, every body definite."""
    robot = robot_registry.get("planar")
    truth = perturbed(robot, DRIVE, np.random.default_rng(12))
    layout = ClosedLoopRegressor(robot, DRIVE).layout
    b = layout.bodies.index("link_0_joint")
    s = layout.bodies.index("slider_0")
    truth[10 * b:10 * b + 10] *= 0.02
    truth[10 * s:10 * s + 10] *= 0.02
    states, forces, _ = _data(robot, truth, 60, seed=13)
    with caplog.at_level("WARNING", logger="hexapod_pin.identification.estimate"):
        res = identify_from_states(robot, *states, forces, noise_std=1e-3)
    # the truth is outside the floor: the fit cannot reach least squares, and says so
    assert res.consistent_gap > 3.0
    assert "not physically consistent" in caplog.text
    masses = res.consistent.parameters[0:layout.n_inertial:10]
    nominal = nominal_parameters(robot, DRIVE)[0:layout.n_inertial:10]
    held = nominal == 0
    assert np.all(masses[~held] >= MASS_FLOOR * nominal[~held] * (1 - 1e-9))
    ratios = masses[[b, s]] / nominal[[b, s]]             # the bound is what holds them
    assert np.isclose(ratios.min(), MASS_FLOOR, rtol=1e-6)
    assert np.isclose(res.consistent.smallest_mass_ratio, MASS_FLOOR, rtol=1e-6)
    assert res.consistent.smallest_eigenvalue > 1e-9


def _fourier_motion(robot, truth, seed, duration, rate):
    """A smooth motion of the planar robot's platform (three harmonics per axis, 0.5-2
    Hz): its actuator positions (the robot's inverse kinematics), the truth's forces at
    the exact states, and the states."""
    reg = ClosedLoopRegressor(robot, DRIVE)
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration, 1.0 / rate)
    amp, freq, phase = rng.uniform(0.005, 0.015, (3, 3)), rng.uniform(0.5, 2.0, (3, 3)), \
        rng.uniform(0, 2 * np.pi, (3, 3))
    scale = np.array([1.0, 1.0, 5.0])
    poses, twists, twist_dots = (np.zeros((t.size, 3)) for _ in range(3))
    for h in range(3):
        w = 2 * np.pi * freq[h]
        poses += scale * amp[h] * np.sin(np.outer(t, w) + phase[h])
        twists += scale * amp[h] * w * np.cos(np.outer(t, w) + phase[h])
        twist_dots -= scale * amp[h] * w ** 2 * np.sin(np.outer(t, w) + phase[h])
    poses += robot.home_pose
    act = np.array([robot.inverse_kinematics(p) for p in poses])
    forces = (reg.batch(poses, twists, twist_dots) @ truth).reshape(t.size, -1)
    return t, act, forces, (poses, twists, twist_dots)


def test_motion_data_route_and_validation():
    """Positions and forces sampled in time (a Fourier motion of the actuators), filtered
    zero-phase: identification predicts held-out forces well."""
    robot = robot_registry.get("planar")
    truth = perturbed(robot, DRIVE, np.random.default_rng(8))
    data = MotionData(*_fourier_motion(robot, truth, 9, 4.0, 500.0)[:3])
    res = identify(robot, data, consistent=False, cutoff=10.0)
    report = res.validate(MotionData(*_fourier_motion(robot, truth, 10, 4.0, 500.0)[:3]))
    assert report.identified.rms < 0.02 * report.nominal.rms
    with_poses = identify(robot, MotionData(data.times, data.actuator_positions,
                                            data.actuator_forces, poses=None),
                          consistent=False, cutoff=10.0, trim=50)
    assert with_poses.trim == 50


def test_realistic_noise_on_positions_and_forces(caplog):
    """1 um Gaussian noise on the sampled actuator positions, 1 % of the range on the
    forces, 500 Hz, the default cut-off (50 Hz): every base parameter within 3 standard
    errors, held-out forces (noise-free truth, another motion) predicted far below the
    noise and no worse than ordinary least squares on the same filtered states (written
    here); the position noise's force errors (0.13 of the force noise) stay below the
    warning. Measured: max |z| 2.90, and 2.97 with the same force noise and exact
    positions: at this cut-off the position noise moves nothing (the compensation 0.08
    standard errors)."""
    from hexapod_pin.identification.motion_data import states_from_motion
    robot = robot_registry.get("planar")
    rng = np.random.default_rng(31)
    truth = perturbed(robot, DRIVE, np.random.default_rng(8))
    base = base_parameters(robot, DRIVE)
    t, act, clean, _ = _fourier_motion(robot, truth, 9, 5.0, 500.0)
    noise = 0.01 * np.ptp(clean, axis=0)
    data = MotionData(t, act + rng.normal(scale=1e-6, size=act.shape),
                      clean + rng.normal(size=clean.shape) * noise)
    with caplog.at_level("WARNING", logger="hexapod_pin.identification.estimate"):
        res = identify(robot, data, base=base, consistent=False, position_noise_std=1e-6)
    assert "position noise" not in caplog.text
    assert np.all(res.input_noise_force < 0.2 * res.noise_std)
    z = (res.values - base.values(truth)) / res.std_errors
    assert np.max(np.abs(z)) < 3.0
    assert np.allclose(res.noise_std, noise, rtol=0.2)
    _, _, held_clean, held = _fourier_motion(robot, truth, 10, 2.0, 500.0)
    report = res.validate_states(*held, held_clean)
    st = states_from_motion(robot, data)
    reg = ClosedLoopRegressor(robot, DRIVE)
    ols = np.linalg.lstsq(base.regressor(reg.batch(st.poses, st.twists, st.twist_dots)),
                          st.actuator_forces.reshape(-1), rcond=None)[0]
    ols_rms = np.sqrt(np.mean((base.regressor(reg.batch(*held)) @ ols
                               - held_clean.reshape(-1)) ** 2))
    assert report.identified.rms < 0.1 * float(np.sqrt(np.mean(noise ** 2)))
    assert report.identified.rms <= 1.05 * ols_rms


#: the library's excitation for the realistic-noise test: 500 Hz (25 times the 20 samples
#: per second of the optimisation). The hexapod's keeps 60 times the robot's type-I
#: threshold (a leg at least 0.12 |cos| off its rail): at the default 2 times, smooth
#: pose motions drive two carriages through reversals of 20 - 45 m/s^2 within 60 ms,
#: content above 20 Hz that the filter distorts (3 % acceleration errors at the default
#: 50 Hz cut-off even with exact positions).
EXCITATION = {name: {"harmonics": 3, "samples": 40, "singularity_margin": 60.0}
              for name in ("hexapod", "planar")}


def _excitation_data(robot, truth, reg, excitation, periods):
    """Times, actuator positions (the robot's inverse kinematics), the truth's forces and
    the exact states of an excitation sampled at 500 Hz over ``periods`` periods."""
    motion = excitation.motion(rate_factor=25, periods=periods)
    states = (motion.poses, motion.twists, motion.twist_dots)
    forces = (reg.batch(*states) @ truth).reshape(motion.t.size, -1)
    return motion.t, np.asarray(motion.q), forces, states


@pytest.mark.parametrize("name", ["hexapod", "planar"])
def test_realistic_noise_on_an_excitation_motion(name):
    """The library's optimised excitation (seed 1; two periods of 2 s at 500 Hz: 2001
    samples, 1941 after the trim), 1 um of position noise, 1 % of the range on the
    forces, the default cut-off (50 Hz), position_noise_std given: every base parameter
    within 3 standard errors; held-out forces (another excitation, seed 2, noise-free
    truth) predicted far below the noise, as the covariance predicts, and better than
    ordinary least squares on the same filtered states (numpy lstsq, written here).
    Measured: hexapod max |z| 2.25 (64 parameters: even exact standard errors put one
    beyond 3 in about 16 % of noise draws), held-out 0.39 of the noise (0.045 N
    predicted, 0.032 N); planar max |z| 2.34, held-out 0.2 of the noise. The optimiser's
    three iterations are sensitive to round-off: on another build of the same formulas
    the hexapod's excitation had condition number 450 instead of 1375 and its held-out
    error was 0.19 of the noise, so "far below the noise" is asserted as half of it,
    with the covariance's own prediction (within 2x) as the sharper check.
    """
    from hexapod_pin.identification.motion_data import states_from_motion
    robot = robot_registry.get(name)
    truth = perturbed(robot, DRIVE, np.random.default_rng(8))
    base = base_parameters(robot, DRIVE)
    reg = ClosedLoopRegressor(robot, DRIVE)
    excitation = optimise_excitation(robot, base=base, seed=1, max_iterations=3 if name ==
                                     "hexapod" else 2, **EXCITATION[name])
    t, act, clean, _ = _excitation_data(robot, truth, reg, excitation, 2)
    rng = np.random.default_rng(31)
    noise = 0.01 * np.ptp(clean, axis=0)
    data = MotionData(t, act + rng.normal(scale=1e-6, size=act.shape),
                      clean + rng.normal(size=clean.shape) * noise)
    res = identify(robot, data, base=base, consistent=False, position_noise_std=1e-6)
    z = (res.values - base.values(truth)) / res.std_errors
    assert np.max(np.abs(z)) < 3.0
    assert np.allclose(res.noise_std, noise, rtol=0.1)
    other = optimise_excitation(robot, base=base, seed=2, max_iterations=1,
                                **EXCITATION[name])
    _, _, held_clean, held = _excitation_data(robot, truth, reg, other, 1)
    report = res.validate_states(*held, held_clean)
    held_rows = base.regressor(reg.batch(*held))
    predicted = np.sqrt(np.mean(np.einsum("ij,jk,ik->i", held_rows, res.covariance,
                                          held_rows)))
    st = states_from_motion(robot, data)
    ols = np.linalg.lstsq(base.regressor(reg.batch(st.poses, st.twists, st.twist_dots)),
                          st.actuator_forces.reshape(-1), rcond=None)[0]
    ols_rms = np.sqrt(np.mean((held_rows @ ols - held_clean.reshape(-1)) ** 2))
    assert report.identified.rms < 0.5 * float(np.sqrt(np.mean(noise ** 2)))
    assert 0.5 * predicted < report.identified.rms < 2.0 * predicted
    assert report.identified.rms <= ols_rms


def test_position_noise_at_a_high_cut_off_is_compensated_and_flagged(caplog):
    """At 2 kHz the default cut-off (200 Hz) lets 1 um of position noise through as 0.25
    m/s^2 of acceleration noise (the gain checked against the spread of filtered white
    noise, written here): its force errors rival the force noise and the plain estimates
    leave their standard errors (measured: 7.3 of them, 11.3 before the compensation in
    the weighted fit). With position_noise_std the bias is compensated (measured max |z|
    1.58) and a warning says that the result leans on that noise, with the cut-off to
    use; without it the noise is estimated from the data (1.00 um), the estimates stay
    plain, and a warning gives the bias that the compensation would remove and says to
    give the noise; a noise given ten times too small is flagged too."""
    from hexapod_pin.identification.motion_data import (
        derivative_noise_gain,
        filtered_derivatives,
    )
    t = np.arange(0.0, 1.0, 1.0 / 2000.0)
    gain_v, gain_a = derivative_noise_gain(t, 200.0)
    white = np.random.default_rng(5).normal(size=(t.size, 40))
    _, vel, acc = filtered_derivatives(t, white, 200.0)
    middle = slice(t.size // 4, 3 * t.size // 4)
    assert np.isclose(np.std(vel[middle]), gain_v, rtol=0.05)
    assert np.isclose(np.std(acc[middle]), gain_a, rtol=0.05)
    robot = robot_registry.get("planar")
    base = base_parameters(robot, DRIVE)
    rng = np.random.default_rng(32)
    truth = perturbed(robot, DRIVE, np.random.default_rng(8))
    _, act, clean, _ = _fourier_motion(robot, truth, 9, 1.0, 2000.0)
    data = MotionData(t, act + rng.normal(scale=1e-6, size=act.shape),
                      clean + rng.normal(size=clean.shape) * 0.01 * np.ptp(clean, axis=0))
    logger = "hexapod_pin.identification.estimate"
    with caplog.at_level("WARNING", logger=logger):
        res = identify(robot, data, base=base, position_noise_std=1e-6)
    assert "compensated, but only as well as position_noise_std" in caplog.text
    # the consistent fit follows the compensated estimate (measured: 1.3 standard
    # errors from it, 1.3 from the truth)
    assert res.consistent_gap < 3.0
    assert np.max(np.abs(res.consistent_values - base.values(truth)) / res.std_errors) < 3.0
    assert "a cut-off of" in caplog.text
    assert np.max(res.input_noise_force / res.noise_std) > 0.2
    z = (res.values - base.values(truth)) / res.std_errors
    assert np.max(np.abs(z)) < 3.0
    assert np.max(np.abs(res.values - res.compensation - base.values(truth))
                  / res.std_errors) > 5.0                  # the plain weighted fit
    caplog.clear()
    with caplog.at_level("WARNING", logger=logger):
        estimated = identify(robot, data, base=base, consistent=False)
    assert "give position_noise_std" in caplog.text
    assert np.allclose(estimated.state_noise.position_std, 1e-6, rtol=0.05)
    assert not estimated.state_noise.compensate
    z = (estimated.values - base.values(truth)) / estimated.std_errors
    assert np.max(np.abs(z)) > 5.0                       # not compensated: biased
    assert np.max(np.abs(estimated.compensation) / estimated.std_errors) > 5.0   # said
    caplog.clear()
    with caplog.at_level("WARNING", logger=logger):
        identify(robot, data, base=base, consistent=False, position_noise_std=1e-7)
    assert "more than 1.5 times the noise given" in caplog.text
    with pytest.raises(InputError, match="position_noise_std"):
        identify(robot, data, consistent=False, position_noise_std=-1e-6)


def test_refusals():
    robot = robot_registry.get("planar")
    base = base_parameters(robot, DRIVE)
    states, forces, _ = _data(robot, perturbed(robot, DRIVE, np.random.default_rng(0)),
                              5, seed=1)
    with pytest.raises(IdentifiabilityError) as info:      # 15 rows for 23 parameters
        identify_from_states(robot, *states, forces, base=base)
    assert info.value.needed == base.count
    n = 20
    poses = np.tile(robot.home_pose, (n, 1))               # one pose, no motion
    with pytest.raises(IdentifiabilityError, match="rank"):
        identify_from_states(robot, poses, np.zeros((n, 3)), np.zeros((n, 3)),
                             np.ones((n, 3)), base=base)
    states, forces, _ = _data(robot, perturbed(robot, DRIVE, np.random.default_rng(0)),
                              20, seed=1)
    with pytest.raises(InputError, match="actuator_forces"):
        identify_from_states(robot, *states, forces[:4], base=base)
    with pytest.raises(InputError, match="noise_std"):
        identify_from_states(robot, *states, forces, base=base, noise_std=-1.0)
    with pytest.raises(InputError, match="base"):
        identify_from_states(robot, *states, forces, base="nope")
    with pytest.raises(InputError, match="data"):
        identify(robot, {"times": [0, 1]})
    with pytest.raises(InputError, match="data.times"):
        identify(robot, MotionData(np.zeros(50), np.zeros((50, 3)), np.zeros((50, 3))))
    with pytest.raises(InputError, match="data.actuator_forces"):
        identify(robot, MotionData(np.arange(50.0), np.zeros((50, 3)), np.zeros((49, 3))))


@pytest.mark.parametrize("chunk", [None, 7])
def test_reduced_least_squares_equals_the_full_problem(monkeypatch, chunk):
    """The per-actuator QR reduction (in chunks of 7 rows too) gives the estimate, the
    noise levels and the standard errors of weighted least squares on the full stacked
    matrix (numpy lstsq and the normal-matrix inverse, written here) to 1e-9."""
    from hexapod_pin.identification import estimate
    if chunk is not None:
        monkeypatch.setattr(estimate, "CHUNK_ROWS", chunk)
    robot = robot_registry.get("planar")
    rng = np.random.default_rng(21)
    truth = perturbed(robot, DRIVE, rng)
    base = base_parameters(robot, DRIVE)
    states, clean, reg = _data(robot, truth, 40, seed=22)
    measured = clean + rng.normal(size=clean.shape) * np.array([0.05, 0.2, 0.1])
    res = identify_from_states(robot, *states, measured, base=base, consistent=False)
    wb = base.regressor(reg.batch(*states))
    u = measured.reshape(-1)
    sigma = np.ones(3)
    for _ in range(estimate.NOISE_ITERATIONS):              # the documented re-weighting
        w = np.tile(1.0 / sigma, 40)
        beta = np.linalg.lstsq(wb * w[:, None], u * w, rcond=None)[0]
        e = (u - wb @ beta).reshape(40, 3)
        sigma = np.sqrt(np.sum(e ** 2, axis=0) / (40 - base.count / 3))
    assert np.allclose(res.noise_std, sigma, rtol=1e-9, atol=0.0)
    w = np.tile(1.0 / sigma, 40)
    ww, uw = wb * w[:, None], u * w
    beta = np.linalg.lstsq(ww, uw, rcond=None)[0]
    s2 = np.sum((uw - ww @ beta) ** 2) / (ww.shape[0] - base.count)
    std = np.sqrt(np.diag(s2 * np.linalg.inv(ww.T @ ww)))
    assert np.allclose(res.values, beta, rtol=1e-9, atol=1e-12 * np.max(np.abs(beta)))
    assert np.allclose(res.std_errors, std, rtol=1e-9, atol=0.0)
