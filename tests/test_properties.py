"""Property-based reliability suite (hypothesis, derandomised, bounded in time).

Properties, over both robots:

* bad inputs (NaN, inf, overflowing magnitudes, complex, text, None, wrong shapes) to
  every public entry point give a typed error (:class:`hexapod_pin.HexapodPinError`), or
  an answer whose every number is finite;
* valid states: the inverse and forward dynamics invert each other, ``J`` and its
  inverse map invert each other, single and batch routes agree;
* walks toward type-I and type-II singular poses: round trips within
  :data:`hexapod_pin.core.measures.ACCURACY`, or :class:`SingularityError`;
* malformed descriptions give :class:`DescriptionError`;
* the command line answers bad numbers with a one-line error, and ``--json`` is valid
  JSON (no ``NaN`` / ``Infinity``).

Checks are against independent routes (the other direction of each map), never against
the code's own output.
"""

import json
import math

import numpy as np
from conftest import TWO_LINKS
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

import hexapod_pin as hp
import robot_registry
from hexapod_pin.cli import app
from hexapod_pin.core.description import build_model
from hexapod_pin.core.measures import ACCURACY
from hexapod_pin.hexapod.fast import simulate_fast
from hexapod_pin.hexapod.simulation import simulate

ROBOTS = {name: robot_registry.get(name) for name in robot_registry.names("closed_form")}
PROFILE = settings(max_examples=60, deadline=None, database=None, derandomize=True,
                   suppress_health_check=[HealthCheck.filter_too_much, HealthCheck.too_slow])
SMALL = settings(PROFILE, max_examples=25)
WIDE = settings(PROFILE, max_examples=400)
robots = st.sampled_from(sorted(ROBOTS))


def dims(robot):
    return robot.pose_dim, robot.n_actuators


def valid_arguments(robot):
    """Entry points with valid positional arguments: name -> list of arguments."""
    d, n = dims(robot)
    pose, zero = robot.home_pose, np.zeros(d)
    act = robot.home_actuators
    twist = np.r_[[0.01] * (d // 2), [0.05] * (d - d // 2)]
    return {
        "inverse_kinematics": [pose],
        "jacobian": [pose],
        "singularity": [pose],
        "configuration": [pose],
        "platform_points_world": [pose],
        "jacobian_derivative": [pose, twist],
        "twist_from_actuator_velocities": [pose, np.ones(n) * 0.01],
        "forward_kinematics": [act],
        "assembly_modes": [act],
        "branch_of": [pose, act],
        "check_stroke": [act],
        "inverse_kinematics_batch": [pose[None]],
        "jacobian_batch": [pose[None]],
        "inverse_dynamics": [pose, twist, zero],
        "forward_dynamics": [pose, twist, np.zeros(n)],
        "static_forces": [pose],
        "reduced_dynamics": [pose, twist],
        "energies": [pose, twist],
        "inverse_dynamics_batch": [pose[None], twist[None], zero[None]],
        "forward_dynamics_batch": [pose[None], twist[None], np.zeros((1, n))],
        "static_forces_batch": [pose[None]],
        "reduced_dynamics_batch": [pose[None], twist[None]],
        "inverse_dynamics_derivatives": [pose, twist, zero],
    }


ENTRY_POINTS = sorted(valid_arguments(ROBOTS["planar"]))
SCALES = [1e20, 1e60, 1e100, 1e155, 1e160, 1e200, 1e300, 1e308]


def spoil(value, how: str, where: int, scale: float):
    """``value`` made bad in one of several ways."""
    arr = np.array(value, dtype=float)
    flat = arr.reshape(-1)
    k = where % flat.size
    if how in ("nan", "inf", "-inf"):
        flat[k] = float(how)
        return arr
    if how == "huge_entry":
        flat[k] = scale
        return arr
    if how == "huge_all":
        return arr + scale
    if how == "complex":
        return arr + 1e-3j
    if how == "short":
        return flat[:-1]
    if how == "long":
        return np.r_[flat, 0.0]
    if how == "matrix":
        return np.stack([arr, arr]) if arr.ndim < 2 else arr[None]
    return {"text": "abc", "none": None, "bool": np.ones(arr.shape, dtype=bool),
            "list_of_text": ["x"] * flat.size, "scalar": 1.0}[how]


HOWS = ["nan", "inf", "-inf", "huge_entry", "huge_all", "complex", "short", "long",
        "matrix", "text", "none", "bool", "list_of_text", "scalar"]


def numbers_in(value):
    """Every float of a returned value (arrays, dataclasses, tuples), for the NaN check."""
    if isinstance(value, np.ndarray) and value.dtype.kind == "f":
        yield from value.reshape(-1).tolist()
    elif isinstance(value, float):
        yield value
    elif hasattr(value, "__dataclass_fields__"):
        for name in value.__dataclass_fields__:
            if not name.startswith("_") and name != "condition_number":
                yield from numbers_in(getattr(value, name))
    elif isinstance(value, (tuple, list)):
        for item in value:
            yield from numbers_in(item)


@WIDE
@given(robots, st.sampled_from(ENTRY_POINTS), st.integers(0, 5), st.sampled_from(HOWS),
       st.integers(0, 40), st.sampled_from(SCALES))
def test_bad_inputs_give_typed_errors_or_finite_answers(name, method, arg, how, where, scale):
    robot = ROBOTS[name]
    args = valid_arguments(robot)[method]
    args = list(args)
    k = arg % len(args)
    args[k] = spoil(args[k], how, where, scale)
    try:
        out = getattr(robot, method)(*args)
    except hp.HexapodPinError as exc:
        assert "nan" not in str(exc).split("(got")[0].lower().replace("nan or inf", "")
        return
    # an answer: only huge-but-finite inputs may get one, and it is finite
    assert how in ("huge_entry", "huge_all", "scalar", "bool"), (method, how)
    assert all(math.isfinite(x) for x in numbers_in(out)), (method, how, out)


# -- valid states: round trips --------------------------------------------------------------
def workspace_state(name, offset, rates):
    robot = ROBOTS[name]
    d, _ = dims(robot)
    span = np.r_[[0.03] * (d // 2), [0.2] * (d - d // 2)]
    pose = robot.home_pose + np.array(offset[:d]) * span
    try:
        robot.inverse_kinematics(pose)
        measures = robot.singularity(pose)
    except hp.HexapodPinError:
        assume(False)
    assume(measures.type_one > 0.05 and measures.type_two > 0.05)
    rates = np.array(rates)
    twist = rates[:d] * np.r_[[0.2] * (d // 2), [1.0] * (d - d // 2)]
    twist_dot = rates[6:6 + d] * np.r_[[2.0] * (d // 2), [5.0] * (d - d // 2)]
    return robot, pose, twist, twist_dot


unit6 = st.lists(st.floats(-1.0, 1.0), min_size=6, max_size=6)
unit12 = st.lists(st.floats(-1.0, 1.0), min_size=12, max_size=12)


@PROFILE
@given(robots, unit6, unit12)
def test_dynamics_round_trips_and_batches_agree(name, offset, rates):
    robot, pose, twist, twist_dot = workspace_state(name, offset, rates)
    tau = robot.inverse_dynamics(pose, twist, twist_dot, bounded=False).actuator_forces
    back = robot.forward_dynamics(pose, twist, tau).twist_dot
    assert np.linalg.norm(back - twist_dot) <= ACCURACY * max(np.linalg.norm(twist_dot), 1.0)
    batch = robot.inverse_dynamics_batch(pose[None], twist[None], twist_dot[None],
                                         bounded=False).actuator_forces[0]
    np.testing.assert_allclose(batch, tau, rtol=0, atol=1e-9 * max(1.0, np.abs(tau).max()))
    jac = robot.jacobian(pose)
    np.testing.assert_allclose(robot.twist_from_actuator_velocities(pose, jac @ twist), twist,
                               rtol=0, atol=1e-10 * max(1.0, np.abs(twist).max()))
    q = robot.inverse_kinematics(pose)
    np.testing.assert_allclose(robot.forward_kinematics(q, pose), pose, rtol=0, atol=1e-10)


# -- walks toward singular poses ----------------------------------------------------------------
TYPE_I_HEIGHT = math.sqrt(0.45 ** 2 - 0.23 ** 2)
SINGULAR_POSES = {
    "hexapod": [np.array([0.0, 0.0, TYPE_I_HEIGHT, 0.0, 0.0, 0.0]),
                np.array([-0.020475341567368716, -0.013968434364764802, 0.31024850589967956,
                          0.2754338045906446, -0.7399207239621679, -0.13470940466330802]),
                np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0])],
    "planar": [np.array([0.0020209507676428916, 0.002521242674892949, 0.5855816720810173]),
               np.array([0.0, 0.35 - 0.12 - 0.3, 0.0])],
}


@PROFILE
@given(robots, st.integers(0, 2), st.floats(0.0, 15.0), unit12)
def test_walks_toward_singularities_answer_accurately_or_refuse(name, which, digits, rates):
    robot = ROBOTS[name]
    d = robot.pose_dim
    target = SINGULAR_POSES[name][which % len(SINGULAR_POSES[name])]
    pose = target + 10.0 ** -digits * (robot.home_pose - target)
    rates = np.array(rates)
    twist = rates[:d] * np.r_[[0.1] * (d // 2), [0.5] * (d - d // 2)]
    twist_dot = rates[6:6 + d] * np.r_[[1.0] * (d // 2), [3.0] * (d - d // 2)]
    assume(np.linalg.norm(twist_dot) > 0.1)
    try:
        tau = robot.inverse_dynamics(pose, twist, twist_dot, bounded=False).actuator_forces
        back = robot.forward_dynamics(pose, twist, tau).twist_dot
        jac = robot.jacobian(pose)
        twist_back = robot.twist_from_actuator_velocities(pose, jac @ twist_dot)
    except (hp.SingularityError, hp.UnreachablePoseError):
        return
    assert np.linalg.norm(back - twist_dot) <= ACCURACY * np.linalg.norm(twist_dot), \
        robot.singularity(pose)
    assert np.linalg.norm(twist_back - twist_dot) <= ACCURACY * np.linalg.norm(twist_dot)


# -- malformed descriptions ------------------------------------------------------------------------
GOOD = {"mass": "1.0", "ixx": "0.02", "x": "0", "axis": "0 0 1"}
BAD = {"mass": ["-1", "nan", "inf", "abc", "-1e300", ""],
       "ixx": ["-0.02", "nan", "1.0", "abc"],          # 1.0 breaks the triangle inequality
       "x": ["nan", "inf", "abc"],
       "axis": ["0 0 0", "nan 0 1", "abc", "0 0"]}


@SMALL
@given(st.sampled_from(sorted(BAD)), st.integers(0, 10))
def test_malformed_descriptions_are_refused(field, pick):
    values = dict(GOOD)
    values[field] = BAD[field][pick % len(BAD[field])]
    try:
        build_model(TWO_LINKS.format(**values), source="two.urdf")
    except hp.DescriptionError:
        return
    raise AssertionError(f"{field}={values[field]!r} loaded")


# -- the command line ------------------------------------------------------------------------------
RUN = CliRunner()
TOKENS = ["nan", "inf", "-inf", "1e308", "1e155", "abc", "", "0x1", "1,2", "--", "0.35"]


def strict_json(text):
    def refuse(constant):
        raise ValueError(f"non-standard JSON constant {constant}")
    return json.loads(text, parse_constant=refuse)


@SMALL
@given(st.sampled_from(["ik", "jacobian", "fk"]), st.integers(0, 5),
       st.sampled_from(TOKENS), st.booleans())
def test_cli_bad_numbers_one_line_error_and_valid_json(command, slot, token, as_json):
    numbers = ["0", "0", "0.35", "0", "0", "0"] if command != "fk" else \
        ["-0.15", "0.15", "-0.15", "0.15", "-0.15", "0.15"]
    numbers[slot] = token
    args = [command, *numbers] + (["--json"] if as_json else [])
    result = RUN.invoke(app, args)
    assert "Traceback" not in result.output
    assert result.exception is None or isinstance(result.exception, SystemExit), \
        repr(result.exception)
    if result.exit_code == 0:
        if as_json:
            strict_json(result.stdout)
        return
    lines = result.stderr.strip().splitlines()
    assert len(lines) <= 1 + 5 * (result.exit_code == 2), result.stderr  # usage: typer's box
    if as_json and result.exit_code == 1:
        strict_json(result.stdout or "{}")


# -- simulation options ------------------------------------------------------------------------------
BAD_OPTIONS = {"duration": [None, "x", math.nan, -1.0, 0.0, math.inf, 1e300, 1 + 2j],
               "dt": [None, "x", math.nan, -1e-3, 0.0, 1e-300, True],
               "record_every": ["x", 2.5, 0, -1, None, True],
               "kp": ["x", math.nan, -1.0, None, math.inf],
               "kd": ["x", math.nan, -5.0, None]}


@SMALL
@given(st.sampled_from(sorted(BAD_OPTIONS)), st.integers(0, 10), st.booleans())
def test_bad_simulation_options_are_input_errors_naming_them(option, pick, compiled):
    robot = ROBOTS["hexapod"]
    value = BAD_OPTIONS[option][pick % len(BAD_OPTIONS[option])]
    kwargs = {"duration": 0.01, "dt": 1e-3, "record_every": 1}
    reference = (robot.home_pose[None], np.zeros((1, 6)))
    if option in ("kp", "kd"):
        if not compiled:
            return                      # the Python route's gains live in its controller
        kwargs["reference"] = reference
    kwargs[option] = value
    try:
        if compiled:
            simulate_fast(robot, **kwargs)
        else:
            simulate(robot, **kwargs)
    except hp.InputError as exc:
        assert exc.name == option or (option == "duration" and exc.name == "dt"), exc
        return
    raise AssertionError(f"{option}={value!r} accepted")
