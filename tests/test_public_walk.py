"""A walk over every public callable with bad arguments (issue 31, "Reliability, second
pass"): each bad value is refused by a library exception, never by a numpy / Boost /
LAPACK exception, a returned NaN or a returned huge value.

The callables come from introspection: ``hexapod_pin.__all__``, the public methods of every
robot of ``tests/robot_registry.py``, and the planning, calibration and workspace entry
points. Their arguments come from their signatures and :func:`valid_arguments` (a small
map of argument names to valid values). Each callable is called once with valid
arguments (the call must succeed), then once per (argument, bad value) of
:func:`bad_values`, one argument substituted at a time.

A bad value of the wrong type, shape or finiteness must raise :class:`InputError` (a
:class:`GeometryError` for a design parameter) naming the argument; a finite value of
absurd magnitude (1e300) may raise any library error (an unreachable pose is one).
"""

from __future__ import annotations

import inspect
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from robot_registry import DATA, get, names

import hexapod_pin as hp
from hexapod_pin import planning
from hexapod_pin.calibration import calibrate, random_as_built, select_poses, synthetic_measurements
from hexapod_pin.calibration.problem import reference_poses
from hexapod_pin.core import stiffness_maps, workspace_maps
from hexapod_pin.errors import GeometryError, HexapodPinError, InputError

#: methods not walked: no argument, or an argument the walk has no value kind for
SKIP_METHODS = {"default", "urdf", "stroke_limits", "with_effects"}
#: the largest magnitude a result may hold (a returned 1e300 is refused)
HUGE = 1e100


@dataclass
class Case:
    """One callable: its label, the function, and valid keyword arguments (positional ones
    passed by name too); ``error``: what a bad argument must raise."""

    label: str
    call: Callable[..., Any]
    valid: dict[str, Any]
    error: type[HexapodPinError] = InputError
    optional: frozenset[str] = frozenset()


def _robot_values(robot) -> dict[str, list[Any]]:
    """Candidate valid values by argument name for ``robot`` (several where one name means
    different things on different robots: ``q`` a configuration or actuator positions)."""
    dim, n, nv = robot.pose_dim, robot.n_actuators, robot.model.nv
    home = np.array(robot.home_pose, dtype=float)
    forces = robot.static_forces(home, bounded=False)
    def two(x):                                            # a batch of two
        return np.array([x, x])
    return {
        "pose": [home], "poses": [two(home)],
        "twist": [np.full(dim, 0.01)], "twists": [two(np.full(dim, 0.01))],
        "twist_dot": [np.full(dim, 0.1)], "twist_dots": [two(np.full(dim, 0.1))],
        "wrench": [np.zeros(dim)], "wrenches": [two(np.zeros(dim))],
        "actuator_forces": [forces, two(forces)],
        "actuators": [np.array(robot.home_actuators, dtype=float)],
        "actuator_velocities": [np.full(n, 0.01)],
        "actuator_stiffness": [np.full(n, 1e5)],
        "q": [np.array(robot.home_configuration), np.array(robot.home_actuators, dtype=float)],
        "v": [np.zeros(nv)], "qdot": [np.zeros(nv), np.full(n, 0.01)],
        "dt": [1e-3], "integrator": ["rk4"], "method": ["kkt"], "bounded": [False],
        "check_limits": [True], "n_starts": [2], "seed": [0],
        "gravity": [np.array([0.0, 0.0, -9.81]), np.array([0.0, -9.81, 0.0])],
    }


def _robot_cases(name: str) -> list[Case]:
    robot = get(name)
    values = _robot_values(robot)
    cases = []
    for attr in sorted(dir(robot)):
        if attr.startswith("_") or attr in SKIP_METHODS or not callable(getattr(robot, attr)):
            continue
        method = getattr(robot, attr)
        params = inspect.signature(method).parameters
        required_names = [p for p, spec in params.items() if spec.default is spec.empty]
        given = [p for p in params if p in values]
        if any(p not in values for p in required_names):
            raise AssertionError(f"{name}.{attr}: no valid value for {required_names}")
        optional = frozenset(p for p in given if p not in required_names)
        choices: list[dict[str, Any]] = [{}]
        for p in given:                   # every combination of candidates (an option: or left out)
            choices = [dict(c, **{p: v}) for c in choices for v in values[p]] + \
                ([dict(c) for c in choices] if p in optional else [])
        valid = next((c for c in choices if _succeeds(method, c)), None)
        if valid is None:
            raise AssertionError(f"{name}.{attr}: no valid base call")
        cases.append(Case(f"{name}.{attr}", method, valid, optional=optional))
    return cases


def _succeeds(call, kwargs) -> bool:
    try:
        call(**kwargs)
    except HexapodPinError:
        return False
    return True


def _module_cases(tmp: Path) -> list[Case]:
    """The module-level entry points: ``hexapod_pin.__all__`` and planning, calibration,
    workspace and stiffness maps."""
    hexapod, planar, four_bar = get("hexapod"), get("planar"), get("four-bar")
    home = hexapod.home_pose
    waypoints = np.array([home, home + [0.01, 0.0, 0.0, 0.0, 0.0, 0.02]])
    plan = planning.time_optimal(hexapod, waypoints, grid_points=20)
    stewart = str(DATA / "stewart" / "stewart.urdf")
    truth = random_as_built(hexapod.geometry, 1e-3, seed=7)
    commanded = reference_poses(hexapod, 40, seed=3)
    measured = synthetic_measurements(hexapod, truth, commanded)
    return [
        Case("Hexapod", hp.Hexapod, {"geometry": hexapod.geometry}),
        Case("Planar3PRR", hp.Planar3PRR, {"geometry": planar.geometry}),
        Case("HexapodGeometry", hp.HexapodGeometry,
             {"leg_length": 0.45, "platform_mass": 1.0}, error=GeometryError),
        Case("PlanarGeometry", hp.PlanarGeometry,
             {"link_length": 0.3, "platform_mass": 1.0}, error=GeometryError),
        Case("load_robot", hp.load_robot, {"path": stewart}),
        Case("load_loops", hp.load_loops, {"path": str(DATA / "stewart" / "stewart.loops.yaml")}),
        Case("parse_loops", hp.parse_loops,
             {"text": (DATA / "stewart" / "stewart.loops.yaml").read_text()}),
        Case("simulate", hp.simulate, {"robot": hexapod, "duration": 0.003, "dt": 1e-3,
                                       "record_every": 1}),
        Case("model_energies", hp.model_energies,
             {"clm": hexapod.model, "q": hexapod.home_configuration,
              "v": np.zeros(hexapod.model.nv)}),
        Case("ActuatorPID", hp.ActuatorPID, {"kp": 100.0, "kd": 10.0}),
        Case("time_optimal", planning.time_optimal,
             {"robot": hexapod, "waypoints": waypoints, "start_speed": 0.0,
              "end_speed": 0.0, "grid_points": 20, "limits": planning.Limits(),
              "payload": planning.Payload()}),
        Case("check_feasibility", planning.check_feasibility,
             {"robot": hexapod, "motion": plan, "tolerance": 1e-9}),
        Case("Limits", planning.Limits, {"actuator_force": 100.0, "linear_speed": 1.0,
                                         "margin": 0.0}),
        Case("Payload", planning.Payload, {"mass": 1.0, "wrench": np.zeros(6)}),
        Case("TimedTrajectory.resample", plan.resample, {"rate": 100.0}),
        Case("TimedTrajectory.sample", plan.sample, {"times": np.array([0.0])}),
        Case("select_poses", select_poses,
             {"robot": hexapod, "candidates": reference_poses(hexapod, 40, seed=9), "n": 12}),
        Case("calibrate", calibrate,
             {"robot": hexapod, "poses": measured.poses, "actuators": measured.actuators,
              "identify": "chains", "max_nfev": 50, "method": "lm", "rcond": 1e-9}),
        Case("synthetic_measurements", synthetic_measurements,
             {"robot": hexapod, "true_geometry": truth, "commanded": commanded,
              "position_noise": 1e-6, "actuator_noise": 1e-6, "seed": 0}),
        Case("reference_poses", reference_poses,
             {"robot": hexapod, "count": 5, "seed": 0, "scale": 1.0}),
        Case("workspace.evaluate", workspace_maps.evaluate,
             {"robot": planar, "poses": np.array([planar.home_pose])}),
        Case("workspace.force_capability", workspace_maps.force_capability,
             {"robot": planar, "poses": np.array([planar.home_pose]),
              "direction": np.array([0.0, 1.0, 0.0])}),
        Case("workspace.grid", workspace_maps.grid,
             {"robot": planar, "center": planar.home_pose,
              "half_extent": np.array([0.01, 0.01, 0.01]), "n": 3}),
        Case("workspace.sample_box", workspace_maps.sample_box,
             {"robot": planar, "n": 4, "low": planar.home_pose - 0.01,
              "high": planar.home_pose + 0.01}),
        Case("workspace.volume", workspace_maps.volume,
             {"robot": planar, "n_samples": 4, "low": planar.home_pose - 0.01,
              "high": planar.home_pose + 0.01}),
        Case("stiffness_map", stiffness_maps.stiffness_map,
             {"robot": four_bar, "poses": np.array([four_bar.home_pose]),
              "actuator_stiffness": np.array([1e4])}),
    ]


# -- the bad values -------------------------------------------------------------------
def bad_values(name: str, value: Any, required: bool) -> list[tuple[str, Any, bool]]:
    """(label, bad value, strict) for one argument whose valid value is ``value``:
    ``strict`` bad values must raise InputError (GeometryError) naming it, the others
    (finite magnitudes) any library error."""
    out: list[tuple[str, Any, bool]] = []
    if required:
        out.append(("None", None, True))
    if isinstance(value, (bool, np.bool_)):
        return out + [("string", "no", True), ("int", 1, True)]
    if isinstance(value, str):
        return out + [("unknown name", "nope", True), ("int", 3, True),
                      ("list", [value], True)]
    if isinstance(value, (int, np.integer)):
        return out + [("bool", True, True), ("string", "3", True), ("float", 2.5, True),
                      ("negative", -1, True), ("1e300", 1e300, True)]
    if isinstance(value, (float, np.floating)):
        return out + [("bool", True, True), ("string", "0.5", True), ("complex", 1j, True),
                      ("NaN", math.nan, True), ("inf", math.inf, True),
                      ("1e300", 1e300, False), ("list", [value, value], True)]
    if isinstance(value, np.ndarray):
        arr = value.astype(float)
        nan, inf, big = arr.copy(), arr.copy(), arr.copy()
        nan.flat[0], inf.flat[0], big.flat[0] = math.nan, math.inf, 1e300
        wrong = np.zeros(arr.shape[:-1] + (arr.shape[-1] + 1,)) if arr.ndim else np.zeros(2)
        out += [("ragged", [[1.0, 2.0], [3.0]], True), ("complex", arr + 1j, True),
                ("bool", True, True), ("bool array", np.ones(arr.shape, dtype=bool), True),
                ("string", "abc", True), ("NaN", nan, True), ("inf", inf, True),
                ("1e300", big, False), ("wrong shape", wrong, True)]
        if arr.ndim:
            out.append(("0-d array", np.array(1.0), True))
        return out
    # an object argument (a robot, a geometry, limits, a motion): wrong types
    return out + [("string", "abc", True), ("float", 1.5, True)]


def _outcome(case: Case, arg: str, label: str, bad: Any, strict: bool) -> str | None:
    """None when the bad value is refused as required, else what went wrong."""
    kwargs = dict(case.valid, **{arg: bad})
    try:
        result = case.call(**kwargs)
    except HexapodPinError as exc:
        if not strict:
            return None
        if not isinstance(exc, case.error):
            return f"{type(exc).__name__}: {exc}"[:200]
        named = getattr(exc, "name", getattr(exc, "field", None))
        if named is not None and named != arg and arg not in str(exc):
            return f"names {named!r}: {exc}"[:200]
        if label == "unknown name" and str(case.valid[arg]) not in str(exc):
            return f"does not list the allowed values: {exc}"[:200]   # an enum option
        return None
    except Exception as exc:                     # noqa: BLE001 (the walk's finding)
        return f"{type(exc).__name__}: {exc}"[:200]
    return f"returned {_describe(result)}"


def _describe(result: Any) -> str:
    values = []
    for item in ([result] if not hasattr(result, "__dict__") else vars(result).values()):
        if item is None:
            continue
        try:
            arr = np.asarray(item, dtype=float)
        except (TypeError, ValueError):
            continue
        values.append(arr.ravel())
    flat = np.concatenate(values) if values else np.zeros(0)
    if not np.isfinite(flat).all():
        return "NaN / inf"
    if flat.size and np.abs(flat).max() > HUGE:
        return f"a huge value ({np.abs(flat).max():.3g})"
    return "normally"


#: (callable label or "*", argument, bad value label) that are valid there: a scalar
#: stiffness is broadcast, ``times`` takes a time or any 1-D array, inf is no bound, gains
#: and bounds may be per actuator, a payload learns the pose size from the robot, identify
#: takes a list of group names
VALID_THERE = {("*", "actuator_stiffness", "0-d array"), ("*", "times", "0-d array"),
               ("*", "times", "wrong shape"), ("Limits", "actuator_force", "inf"),
               ("Limits", "linear_speed", "inf"), ("Limits", "actuator_force", "list"),
               ("ActuatorPID", "kp", "list"), ("ActuatorPID", "kd", "list"),
               ("Payload", "wrench", "wrong shape"), ("calibrate", "identify", "list")}
#: (argument, bad value label) pairs where any library error will do: a string that is a
#: well-typed path or text, but not a file or a description
ANY_LIBRARY_ERROR = {("motion", "string"), ("path", "unknown name"), ("text", "unknown name")}


def _optional(case: Case) -> frozenset[str]:
    """The arguments of ``case`` that have a default (None is not bad for them)."""
    try:
        params = inspect.signature(case.call).parameters
    except (TypeError, ValueError):
        return case.optional
    return case.optional | {p for p, spec in params.items() if spec.default is not spec.empty}


def walk(cases: list[Case]) -> tuple[int, list[str]]:
    """(how many bad calls were tried, the failures)."""
    tried, failures = 0, []
    for case in cases:
        if not _succeeds(case.call, case.valid):
            failures.append(f"{case.label}: the valid base call raises")
            continue
        optional = _optional(case)
        for arg, value in case.valid.items():
            for label, bad, strict in bad_values(arg, value, arg not in optional):
                if {("*", arg, label), (case.label, arg, label)} & VALID_THERE:
                    continue
                tried += 1
                strict = strict and (arg, label) not in ANY_LIBRARY_ERROR
                problem = _outcome(case, arg, label, bad, strict)
                if problem is not None:
                    failures.append(f"{case.label}({arg}={label}): {problem}")
    return tried, failures


ROBOT_NAMES = names("shared")


@pytest.mark.parametrize("name", ROBOT_NAMES)
def test_every_robot_method_refuses_bad_arguments(name):
    start = time.perf_counter()
    tried, failures = walk(_robot_cases(name))
    assert tried > 100
    assert not failures, "\n".join(failures)
    assert time.perf_counter() - start < 30.0


def test_every_entry_point_refuses_bad_arguments(tmp_path):
    tried, failures = walk(_module_cases(tmp_path))
    assert tried > 100
    assert not failures, "\n".join(failures)
