"""Options that were never checked (issue 31, "Options never checked"): each bad value is
a library error naming the argument, never a bare TypeError / ValueError / LinAlgError,
a LAPACK message on stderr or a silently changed value.

Frame inverse kinematics, the frame Jacobian's reference, calibration, pose selection,
the as-built geometry, ``HexapodGeometry.replace`` and ``FastStepper``.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
from robot_registry import get

import hexapod_pin as hp
from hexapod_pin.calibration import calibrate, select_poses, synthetic_measurements
from hexapod_pin.calibration.problem import reference_poses
from hexapod_pin.errors import GeometryError, HexapodPinError, InputError
from hexapod_pin.hexapod.fast import FastStepper

POINTS = np.array([[0.03, 0.0, 0.01], [-0.02, 0.04, 0.0], [0.0, -0.05, 0.02]])


@pytest.fixture(scope="module")
def four_bar():
    return get("four-bar")


@pytest.fixture(scope="module")
def hexapod():
    return hp.Hexapod.default()


@pytest.fixture(scope="module")
def measured(hexapod):
    truth = hp.calibration.random_as_built(hexapod.geometry, 1e-3, seed=7)
    commanded = reference_poses(hexapod, 60, seed=3)
    return synthetic_measurements(hexapod, truth, commanded, target_points=POINTS)


# -- frame inverse kinematics ----------------------------------------------------------
def _ik(robot, **options):
    clm = robot.model
    frame = options.pop("frame", "coupler_point")
    target = options.pop("target", np.array([0.3, 0.0, 0.2]))
    q0 = np.array(clm.loops.robot.home)
    return clm.frame_inverse_kinematics(frame, target, q0,
                                        position_only=options.pop("position_only", True),
                                        **options)


IK_OPTIONS = [
    ("tol", "1e-10"), ("tol", None), ("tol", math.nan), ("tol", -1.0), ("tol", True),
    ("closure_tol", "x"), ("closure_tol", 0.0),
    ("max_iter", "200"), ("max_iter", 2.5), ("max_iter", 0), ("max_iter", True),
    ("damping", "1e-3"), ("damping", -1.0), ("damping", math.inf),
    ("limits", "no"), ("limits", 1), ("position_only", "no"),
    ("weights", "x"), ("weights", True), ("weights", [1.0, 2.0]), ("weights", 1e-3j),
    ("weights", -1.0), ("weights", [[1.0], [1.0, 2.0]]),
    ("method", None), ("method", ["qp"]),
]


@pytest.mark.parametrize("option, value", IK_OPTIONS)
def test_frame_ik_options_are_checked_by_name(four_bar, option, value):
    with pytest.raises(InputError, match=option) as caught:
        _ik(four_bar, **{option: value})
    assert caught.value.name == option


@pytest.mark.parametrize("frame", [None, 3.5, ["coupler_point", None], [], "nope"])
def test_frame_ik_refuses_a_missing_or_unknown_frame(four_bar, frame):
    with pytest.raises(InputError, match="frame"):
        _ik(four_bar, frame=frame)


@pytest.mark.parametrize("target", [np.array([1e300, 0.0, 0.0]), np.array([0.3, 0, -1e7])])
def test_frame_ik_refuses_a_target_beyond_any_robot(four_bar, target, capfd):
    with pytest.raises(InputError, match="target"):
        _ik(four_bar, target=target)
    assert "DLASCL" not in capfd.readouterr().err
    placement = np.eye(4)
    placement[:3, 3] = target
    with pytest.raises(InputError, match="target"):
        _ik(four_bar, target=placement, position_only=False)


@pytest.mark.parametrize("reference", ["LOCAL", "WORLD", "LOCAL_WORLD_ALIGNED"])
def test_frame_jacobian_takes_a_reference_name(four_bar, reference):
    clm = four_bar.model
    q = clm.assemble(clm.loops.robot.home).q
    by_name = clm.frame_jacobian_from_actuated(q, "coupler_point", reference=reference)
    by_enum = clm.frame_jacobian_from_actuated(q, "coupler_point",
                                               reference=getattr(pin.ReferenceFrame, reference))
    np.testing.assert_array_equal(by_name, by_enum)


@pytest.mark.parametrize("reference", ["local", 1, None, "BODY"])
def test_frame_jacobian_refuses_another_reference(four_bar, reference):
    clm = four_bar.model
    q = clm.assemble(clm.loops.robot.home).q
    with pytest.raises(InputError, match="reference"):
        clm.frame_jacobian_from_actuated(q, "coupler_point", reference=reference)


# -- calibration -----------------------------------------------------------------------
CALIBRATE_OPTIONS = [
    ("target", [0, 0]), ("target", "x"), ("target", [0, 0, 0, 0, 0, math.nan]),
    ("instrument", [0.0] * 5), ("max_nfev", 0), ("max_nfev", 2.5), ("max_nfev", "200"),
    ("max_nfev", True), ("identify", None), ("identify", 3), ("identify", ["lines", 4]),
    ("identify", "sensor_offset"), ("identify", ()), ("identify", ["chains", "chains"]),
    ("rcond", "1e-9"), ("method", None),
]


@pytest.mark.parametrize("option, value", CALIBRATE_OPTIONS)
def test_calibrate_options_are_checked_by_name(hexapod, measured, option, value):
    with pytest.raises(InputError, match=option) as caught:
        calibrate(hexapod, measured.poses, measured.actuators, **{option: value})
    assert caught.value.name == option


def test_calibrate_refuses_a_non_robot():
    with pytest.raises(InputError, match="robot"):
        calibrate(None, np.zeros((30, 6)), np.zeros((30, 6)))


SELECT_OPTIONS = [
    ("target_points", np.zeros((5, 3))), ("target_points", np.zeros((0, 3))),
    ("target", [0, 0]), ("instrument", "x"), ("identify", None), ("n", True), ("n", 2.0),
    ("method", None), ("criterion", None),
]


@pytest.mark.parametrize("option, value", SELECT_OPTIONS)
def test_select_poses_options_are_checked_by_name(hexapod, option, value):
    candidates = reference_poses(hexapod, 40, seed=9)
    options = {"n": 10, option: value}
    n = options.pop("n")
    with pytest.raises(InputError, match=option):
        select_poses(hexapod, candidates, n, **options)


def test_select_poses_refuses_a_selection_that_determines_nothing(hexapod):
    """Fewer rows than parameters: the information matrix is singular (log det -inf used
    to be returned as a selection)."""
    candidates = reference_poses(hexapod, 40, seed=9)
    with pytest.raises(HexapodPinError) as caught:
        select_poses(hexapod, candidates, 2)
    assert "log" in str(caught.value) or "rank" in str(caught.value)


def test_select_poses_with_target_points_matches_calibrate(hexapod):
    candidates = reference_poses(hexapod, 40, seed=9)
    chosen = select_poses(hexapod, candidates, 20, target_points=POINTS)
    assert np.isfinite(chosen.log_det)


# -- as-built geometry, replace, FastStepper -------------------------------------------
@pytest.mark.parametrize("value", [1e-3j * np.ones(6), np.ones(6, dtype=bool),
                                   np.array(["a"] * 6), [[1e-3] * 3, [1e-3] * 2]])
def test_as_built_refuses_what_is_not_real(hexapod, value):
    with pytest.raises(GeometryError, match="sensor_offsets"):
        hexapod.geometry.as_built(sensor_offsets=value)


def test_replace_refuses_an_unknown_field(hexapod):
    with pytest.raises(GeometryError, match="foo") as caught:
        hexapod.geometry.replace(foo=1)
    assert caught.value.field == "foo"
    with pytest.raises(GeometryError, match="leg_length"):
        hexapod.geometry.replace(leg_lenght=0.5)          # the suggestion


@pytest.mark.parametrize("dt", ["x", None, True, 1e-3j, math.inf, 0.0, -1e-3])
def test_fast_stepper_checks_dt(hexapod, dt):
    with pytest.raises(InputError, match="dt") as caught:
        FastStepper(hexapod, dt)
    assert caught.value.name == "dt"


@pytest.mark.parametrize("integrator", [[1], None, 3, "euler!"])
def test_fast_stepper_checks_the_integrator(hexapod, integrator):
    with pytest.raises(InputError, match="integrator"):
        FastStepper(hexapod, 1e-3, integrator=integrator)
