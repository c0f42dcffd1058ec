"""Excitation trajectories: every limit re-checked at 10x the sampling rate with the
robot's own single-state routes (not the batch check the optimiser uses), the condition
number lowered, twists against finite differences of the poses, the motion file."""

from __future__ import annotations

import numpy as np
import pytest
import robot_registry

import hexapod_pin as hp
from hexapod_pin.errors import InputError
from hexapod_pin.identification import ClosedLoopRegressor, base_parameters
from hexapod_pin.identification.excitation import FourierSeries, _null_basis, optimise_excitation
from hexapod_pin.motion import read_motion


@pytest.fixture(scope="module")
def bounded_planar():
    """The planar robot with a force bound close to the forces of a fast motion."""
    return hp.Planar3PRR(hp.PlanarGeometry(max_actuator_force=13.0))


@pytest.fixture(scope="module")
def excitation(bounded_planar):
    fractions = []
    ex = optimise_excitation(bounded_planar, harmonics=2, base_frequency=0.5, samples=30,
                             max_iterations=12, progress=fractions.append)
    return ex, fractions


def test_every_limit_holds_at_ten_times_the_rate(bounded_planar, excitation):
    ex, fractions = excitation
    robot = bounded_planar
    dense = ex.motion(rate_factor=10)
    assert dense.t.size == 10 * ex.times.size + 1
    bound = robot.geometry.max_actuator_force
    worst = 0.0
    for pose, twist, twist_dot in zip(dense.poses, dense.twists, dense.twist_dots):
        robot.inverse_kinematics(pose, check_limits=True)        # raises outside a stroke
        assert robot.singularity(pose).regular
        u = robot.inverse_dynamics(pose, twist, twist_dot, bounded=False).actuator_forces
        worst = max(worst, float(np.max(np.abs(u))))
    assert worst <= bound
    assert worst > 0.5 * bound                   # the bound matters to this motion
    # starts and ends at rest at the centre
    for k in (0, -1):
        assert np.allclose(dense.poses[k], robot.home_pose, atol=1e-12)
        assert np.allclose(dense.twists[k], 0.0, atol=1e-12)
        assert np.allclose(dense.twist_dots[k], 0.0, atol=1e-10)
    # the optimisation improved the conditioning, reported progress, and its number is
    # the condition number of the base regressor at the samples (computed here)
    assert ex.condition_number < 0.5 * ex.initial_condition_number
    assert fractions and fractions[-1] == 1.0 and all(0 < f <= 1 for f in fractions)
    reg = ClosedLoopRegressor(robot)
    wb = ex.base.regressor(reg.batch(ex.poses, ex.twists, ex.twist_dots))
    assert np.isclose(np.linalg.cond(wb / np.linalg.norm(wb, axis=0)), ex.condition_number,
                      rtol=1e-6)
    assert np.allclose(ex.actuator_positions,
                       [robot.inverse_kinematics(p) for p in ex.poses], atol=1e-12)


def test_motion_file_round_trip(bounded_planar, excitation, tmp_path):
    ex, _ = excitation
    path = ex.write(tmp_path / "excite.csv", periods=2)
    back = read_motion(path, bounded_planar)
    assert back.t.size == 2 * ex.times.size + 1
    again = ex.motion(periods=2)
    for field in ("t", "poses", "twists", "twist_dots", "q", "actuator_forces"):
        assert np.allclose(getattr(back, field), getattr(again, field), rtol=0, atol=1e-12)


def test_twists_against_finite_differences():
    """A hexapod series (full rotation: w = E(rpy) d(rpy)/dt): twists and their
    derivatives against central differences of the poses and twists."""
    robot = robot_registry.get("hexapod")
    rng = np.random.default_rng(1)
    basis = _null_basis(3)
    coeffs = basis @ rng.normal(size=(4, 6)) * 0.1
    series = FourierSeries(robot.home_pose, 0.7, coeffs[:3], coeffs[3:], True,
                           np.array([False] * 3 + [True] * 3))
    t = np.linspace(0.0, 1.0, 20001)
    poses, twists, twist_dots = series.evaluate(t)
    layout = hp.core.robot_api.pose_layout(robot)
    fd = layout.twists_from_poses(t, poses)
    assert np.max(np.abs(fd - twists)[1:-1]) < 1e-6 * np.max(np.abs(twists))
    fd_dot = np.gradient(twists, t, axis=0)
    assert np.max(np.abs(fd_dot - twist_dots)[1:-1]) < 1e-5 * np.max(np.abs(twist_dots))
    assert np.allclose(twists[0], 0.0, atol=1e-14) and np.allclose(twist_dots[0], 0, atol=1e-12)


def test_bad_options_name_the_argument():
    robot = robot_registry.get("planar")
    base = base_parameters(robot)
    for kwargs, name in (({"harmonics": 1}, "harmonics"), ({"amplitude": (0.0, 1.0)},
                                                           "amplitude"),
                         ({"force_margin": 1.0}, "force_margin"),
                         ({"centre": [0.0, 0.0]}, "centre"), ({"base": "b"}, "base"),
                         ({"singularity_margin": 0.5}, "singularity_margin")):
        with pytest.raises(InputError, match=name):
            optimise_excitation(robot, base=kwargs.pop("base", base), **kwargs)
