"""The single-state fast path of the hexapod's inverse and forward dynamics (issue 32 item 3):
inputs scanned by the kernel, the default inverse dynamics as the compiled closed form in
one call (tree state, Newton-Euler, closure forces, the verification of its answer, the
bound test; no Pinocchio call), results built without the dataclass ``__init__``, the
result check four vectors to a compiled call. Each check here compares the fast path with
the route it replaces (or with the exact check); the closed form's agreement with the
Pinocchio tree routes is tests/hexapod/test_tree_map.py's."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pinocchio as pin
import pytest

import hexapod_pin as hp
from hexapod_pin.core.checks import MAX_MAGNITUDE, check_finite_result
from hexapod_pin.core.results import new_result
from hexapod_pin.hexapod import kernels

POSE = np.array([0.01, -0.02, 0.34, 0.05, -0.03, 0.1])
TWIST = np.array([0.05, 0.02, -0.01, 0.1, -0.2, 0.05])
TWIST_DOT = np.array([0.1, -0.2, 0.3, 0.5, 0.2, -0.1])


@pytest.fixture(scope="module")
def robot():
    return hp.Hexapod.default()


def _fields(result) -> dict:
    return {f.name: getattr(result, f.name) for f in dataclasses.fields(result)}


@pytest.mark.parametrize("route", ["inverse", "forward"])
def test_a_fast_result_is_the_dataclass_its_constructor_makes(robot, route):
    if route == "inverse":
        res = robot.inverse_dynamics(POSE, TWIST, TWIST_DOT)
    else:
        tau = robot.inverse_dynamics(POSE, TWIST, TWIST_DOT).actuator_forces
        res = robot.forward_dynamics(POSE, TWIST, tau)
    again = type(res)(**_fields(res))
    assert set(vars(res)) == set(vars(again))          # every field, nothing else
    for name, value in _fields(res).items():
        assert getattr(again, name) is value
    with pytest.raises(dataclasses.FrozenInstanceError):
        res.method = "other"
    assert res.closure_forces.shape == (6, 3)                       # lazy parts work
    assert res.singularity.condition_number > 1


def test_new_result_keeps_the_frozen_semantics():
    @dataclasses.dataclass(frozen=True, eq=False)
    class Pair:
        a: np.ndarray
        b: str

    made = new_result(Pair, {"a": np.ones(2), "b": "x"})
    assert type(made) is Pair and made.b == "x" and repr(made).startswith("test_")
    with pytest.raises(dataclasses.FrozenInstanceError):
        made.b = "y"


@pytest.mark.parametrize("name", ["pose", "twist", "twist_dot"])
@pytest.mark.parametrize("bad", [math.nan, math.inf, 1e200])
def test_the_kernel_scan_names_the_input(robot, name, bad):
    args = {"pose": POSE.copy(), "twist": TWIST.copy(), "twist_dot": TWIST_DOT.copy()}
    args[name][1] = bad
    with pytest.raises(hp.InputError, match=name):
        robot.inverse_dynamics(**args)
    if name != "twist_dot":
        tau = robot.inverse_dynamics(POSE, TWIST, TWIST_DOT).actuator_forces
        with pytest.raises(hp.InputError, match=name):
            robot.forward_dynamics(args["pose"], args["twist"], tau)


def test_inputs_off_the_fast_path_give_the_same_numbers(robot):
    """A list, a strided view and a big-endian array take the checked route."""
    want = robot.inverse_dynamics(POSE, TWIST, TWIST_DOT).actuator_forces
    strided = np.repeat(POSE, 2)[::2]
    swapped = TWIST.astype(">f8")
    got = robot.inverse_dynamics(strided, swapped, TWIST_DOT.tolist()).actuator_forces
    assert np.array_equal(got, want)


def test_the_bound_test_in_the_kernel_matches_check_bounds():
    """Forces just inside the bound (with its relative slack) pass, just outside raise."""
    robot = hp.Hexapod.default()
    tau = robot.inverse_dynamics(POSE, TWIST, TWIST_DOT, bounded=False).actuator_forces
    peak = float(np.abs(tau).max())
    inside = hp.Hexapod(hp.HexapodGeometry(max_actuator_force=peak))
    assert np.array_equal(inside.inverse_dynamics(POSE, TWIST, TWIST_DOT).actuator_forces, tau)
    outside = hp.Hexapod(hp.HexapodGeometry(max_actuator_force=peak * (1 - 1e-6)))
    with pytest.raises(hp.ActuatorSaturationError):
        outside.inverse_dynamics(POSE, TWIST, TWIST_DOT)
    assert outside.inverse_dynamics(POSE, TWIST, TWIST_DOT, bounded=False).status == "solved"
    with pytest.raises(hp.ActuatorSaturationError):
        outside.inverse_dynamics(POSE, TWIST, TWIST_DOT, method="qp")


@dataclasses.dataclass
class _Six:
    a: np.ndarray
    b: np.ndarray
    nested: object
    c: np.ndarray
    d: np.ndarray
    e: np.ndarray
    label: str = "x"


@pytest.mark.parametrize("bad, named", [
    (("b", "e"), "b"), (("e",), "e"), (("nested", "c"), "nested"), (("c", "nested"), "nested"),
    (("d", "e"), "d")])
def test_the_grouped_scan_names_the_first_bad_field_in_order(bad, named):
    """Vectors are scanned four to a call; the error still names the first field, in
    field order, that is not finite (the exact walk names it)."""
    values = {k: np.ones(3) for k in "abcde"}
    values["nested"] = [1.0]
    for key in bad:
        if key == "nested":
            values["nested"] = [math.nan]
        else:
            values[key] = np.array([1.0, math.nan, 1.0])
    first = next(k for k in ("a", "b", "nested", "c", "d", "e") if k in bad)
    with pytest.raises(hp.NonFiniteResultError, match=first) as info:
        check_finite_result("f", _Six(**values))
    assert named in str(info.value)
    assert check_finite_result("f", _Six(**{k: np.ones(3) for k in "abcde"}, nested=[1.0]))


@pytest.mark.parametrize("field, bad", [("actuator_forces", math.nan),
                                        ("acceleration", math.inf),
                                        ("iterations", math.nan),       # not a count
                                        ("configuration", "matrix")])   # not a vector
def test_the_result_type_fast_path_finds_every_bad_field(robot, field, bad):
    """A result of a known layout (vectors and labels / counts) is checked in one compiled
    call; a NaN / inf in a vector, or a field of another kind, goes to the exact walk."""
    res = robot.inverse_dynamics(POSE, TWIST, TWIST_DOT)
    values = _fields(res)
    if field in ("actuator_forces", "acceleration"):
        values[field] = values[field].copy()
        values[field][3] = bad
    elif field == "configuration":
        values[field] = np.array([[1.0, math.nan]])           # 2-D: walked, NaN found
    else:
        values[field] = bad
    broken = type(res)(**values)
    with pytest.raises(hp.NonFiniteResultError, match=field):
        check_finite_result("f", broken)
    assert check_finite_result("f", res) is res


# -- the default inverse dynamics: the closed form, verified in its own call ------------------
def _closed_form_state(robot, wrench=kernels.ZERO6):
    """The closed-form kernel at (POSE, TWIST, TWIST_DOT): its outputs and scratch."""
    ck = robot.dynamics.closed_form
    q, v, a = np.empty(25), np.empty(24), np.empty(24)
    tau, closure = np.empty(6), np.empty((6, 3))
    rot, wk, mats = np.empty(9), np.zeros((kernels.WK_ROWS, 6)), np.empty((kernels.N_MATS, 6, 6))
    code = kernels.inverse_dynamics_tree(ck.dynamics_geo, ck.signs, POSE, TWIST, TWIST_DOT,
                                         wrench, False, MAX_MAGNITUDE, q, v, a, tau, closure,
                                         rot, wk, mats)
    return code, ck.dynamics_geo, wk, tau, closure


def test_the_default_route_calls_no_pinocchio_dynamics(robot, monkeypatch):
    """"kkt" answers without ``pin.rnea`` (the closed form); its lazy residual, "qp" and
    the tree route use it (the reference stays Pinocchio's)."""
    want = robot.inverse_dynamics(POSE, TWIST, TWIST_DOT)
    calls = []
    rnea = pin.rnea

    def counted(*args):
        calls.append(len(args))
        return rnea(*args)

    monkeypatch.setattr(pin, "rnea", counted)
    res = robot.inverse_dynamics(POSE, TWIST, TWIST_DOT)
    assert calls == [] and np.array_equal(res.actuator_forces, want.actuator_forces)
    assert res.residual < 1e-10 and len(calls) == 1           # the tree equation, on access
    robot.inverse_dynamics(POSE, TWIST, TWIST_DOT, method="qp")
    assert len(calls) == 2


def test_the_closed_form_verification_catches_a_corrupted_answer(robot):
    """The check run inside the kernel (the residual of the platform equation ``A^T t =
    rhs`` relative to its data, finite forces and closure forces) passes the computed
    answer and fails each corruption: an axial force off by 1e-7 relative, a NaN force, a
    NaN closure force."""
    code, geo, wk, tau, closure = _closed_form_state(robot, np.array([1.0, -2, 3, 0.1, 0, 0.2]))
    assert code == kernels.OK and kernels.inverse_verified(geo, wk, tau, closure)
    for corrupt in ("axial", "tau", "closure"):
        wk2, tau2, closure2 = wk.copy(), tau.copy(), closure.copy()
        if corrupt == "axial":
            wk2[kernels.AXIAL, 3] *= 1.0 + 1e-7
        elif corrupt == "tau":
            tau2[2] = math.nan
        else:
            closure2[4, 1] = math.nan
        assert not kernels.inverse_verified(geo, wk2, tau2, closure2), corrupt


def test_an_unverified_closed_form_answer_is_a_typed_error(robot, monkeypatch):
    """A kernel that refuses its answer (RESIDUAL) reaches the caller as a SolverError that
    gives the residual and the forces; no result is returned."""
    real = kernels.inverse_dynamics_tree

    def corrupted(*args):
        code = real(*args)
        wk = args[-2]
        wk[kernels.AXIAL, 0] += 1.0                 # as a wrong solve would leave it
        assert not kernels.inverse_verified(args[0], wk, args[11], args[12])
        return kernels.RESIDUAL if code == kernels.OK else code

    monkeypatch.setattr(kernels, "inverse_dynamics_tree", corrupted)
    with pytest.raises(hp.SolverError, match=r"A\^T t = rhs off by .*forces"):
        robot.inverse_dynamics(POSE, TWIST, TWIST_DOT)


@pytest.mark.parametrize("where", ["velocity", "acceleration"])
def test_a_motion_that_overflows_names_the_input(robot, monkeypatch, where):
    """Finite inputs whose motion overflows double precision in the closed form (reachable
    only near the singularities with inputs up to MAX_MAGNITUDE: planted here) fail its
    verification and are refused naming the argument: ``twist`` for an overflowed tree
    velocity, else the largest motion input; no NaN in the message."""
    real = kernels.inverse_dynamics_tree

    def overflowed(*args):
        real(*args)
        args[9 if where == "velocity" else 10][3] = math.inf      # v or a
        args[11][2] = math.nan                                     # tau
        return kernels.RESIDUAL

    monkeypatch.setattr(kernels, "inverse_dynamics_tree", overflowed)
    big = TWIST_DOT * 1e6
    with pytest.raises(hp.InputError, match="overflow") as info:
        robot.inverse_dynamics(POSE, TWIST, big, bounded=False)
    assert info.value.name == ("twist" if where == "velocity" else "twist_dot")
    assert "nan" not in str(info.value).lower()


# -- the default forward dynamics: the closed form, verified in its own call -----------------
def test_the_default_forward_route_calls_no_pinocchio_dynamics(robot, monkeypatch):
    """"nullspace" answers without ``pin.crba`` / ``pin.rnea`` (the reduced closed form)
    and agrees with Pinocchio's constrained forward dynamics (the "pinocchio" route), the
    closure forces and multipliers included."""
    tau = robot.inverse_dynamics(POSE, TWIST, TWIST_DOT).actuator_forces
    want = robot.forward_dynamics(POSE, TWIST, tau, method="pinocchio")
    calls = []
    for name in ("crba", "rnea"):
        real = getattr(pin, name)
        monkeypatch.setattr(pin, name, lambda *a, real=real, name=name: (calls.append(name),
                                                                          real(*a))[1])
    res = robot.forward_dynamics(POSE, TWIST, tau)
    assert calls == [] and res.method == "nullspace"
    for field in ("twist_dot", "tree_acceleration", "closure_forces", "multipliers"):
        np.testing.assert_allclose(getattr(res, field), getattr(want, field), rtol=0,
                                   atol=1e-10, err_msg=field)
    np.testing.assert_allclose(res.twist_dot, TWIST_DOT, rtol=0, atol=1e-10)


def test_the_forward_verification_catches_a_corrupted_answer(robot):
    """The check run inside the kernel (the residual of ``M_x twist_dot = J^T tau + wrench
    - h_x`` relative to its data, a finite answer) passes the computed answer and fails an
    acceleration off by 1e-7 relative, and a NaN."""
    ck = robot.dynamics.closed_form
    tau = robot.inverse_dynamics(POSE, TWIST, TWIST_DOT).actuator_forces
    q, v, a = np.empty(25), np.empty(24), np.empty(24)
    twist_dot, closure = np.empty(6), np.empty((6, 3))
    rot, wk, mats = np.empty(9), np.zeros((kernels.WK_ROWS, 6)), np.empty((kernels.N_MATS, 6, 6))
    code = kernels.forward_dynamics_tree(ck.dynamics_geo, ck.signs, POSE, TWIST, tau,
                                         kernels.ZERO6, MAX_MAGNITUDE, q, v, a, twist_dot,
                                         closure, rot, wk, mats)
    assert code == kernels.OK and kernels.forward_verified(wk, mats, twist_dot)
    off = twist_dot.copy()
    off[4] += 1e-7 * np.abs(twist_dot).max()
    assert not kernels.forward_verified(wk, mats, off)
    off[4] = math.nan
    assert not kernels.forward_verified(wk, mats, off)


@pytest.mark.parametrize("code, error", [("RESIDUAL", hp.SolverError),
                                         ("NOT_PD", hp.SolverError)])
def test_a_refused_forward_answer_is_a_typed_error(robot, monkeypatch, code, error):
    real = kernels.forward_dynamics_tree

    def refused(*args):
        real(*args)
        return getattr(kernels, code)

    monkeypatch.setattr(kernels, "forward_dynamics_tree", refused)
    tau = np.ones(6)
    with pytest.raises(error, match="null-space forward dynamics"):
        robot.forward_dynamics(POSE, TWIST, tau)


@pytest.mark.parametrize("name", ["actuator_forces", "wrench"])
@pytest.mark.parametrize("bad", [math.nan, -math.inf, 1e200])
def test_the_forward_kernel_scan_names_the_input(robot, name, bad):
    """The forces and the wrench, passed unscanned, are scanned by the closed-form kernel;
    a refused one is named (the wrench of the inverse dynamics too)."""
    args = {"actuator_forces": np.ones(6), "wrench": np.zeros(6)}
    args[name][2] = bad
    with pytest.raises(hp.InputError, match=name):
        robot.forward_dynamics(POSE, TWIST, **args)
    if name == "wrench":
        with pytest.raises(hp.InputError, match=name):
            robot.inverse_dynamics(POSE, TWIST, TWIST_DOT, args["wrench"])
