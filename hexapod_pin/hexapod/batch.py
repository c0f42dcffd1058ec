"""Batches of hexapod states: the kernels of :mod:`hexapod_pin.hexapod.kernels` over N states.

Every batch function runs the single-state kernels in a ``numba.prange`` loop (chunks of
:data:`CHUNK` states per thread, each with its own scratch), so a batch answer equals the
single-state answer of the same state. Inputs are (N, 6) float64 arrays, C-contiguous and
finite (the callers validate them: :func:`check_batch`); the branch is one row of six signs
for every state or one row per state. Conventions: those of the kernels.

Small batches run the same loop on the calling thread
(:data:`~hexapod_pin.core.batching.PARALLEL_MIN`). The Python
functions raise for the first state whose kernel failed (lowest index; states
the mechanism cannot take before saturated ones), with the Batch* exceptions of
:mod:`hexapod_pin.errors` naming it (``index``); the kinematics batches return masks.
"""

from __future__ import annotations

import numba
import numpy as np

from ..core.batching import CHUNK, n_chunks, prange_jit
from ..core.checks import as_array
from ..core.compiled import FAST_FLAGS
from ..core.results import (BatchForwardDynamics, BatchInverseDynamics, BatchReducedDynamics,
                            InverseKinematicsBatch, JacobianBatch)
from ..errors import BatchActuatorSaturationError, InputError, NonFiniteResultError
from . import kernels as K

#: the batch loops: states are argument 2 (``poses``), fast-math kernels
batch_jit = prange_jit(2, FAST_FLAGS)


@batch_jit
def _inverse(geo, signs, poses, twists, twist_dots, wrenches, bounded, tau, closure,
             residual, codes):
    n = poses.shape[0]
    ss, ws = signs.shape[0] > 1, wrenches.shape[0] > 1
    for c in numba.prange(n_chunks(n)):
        rot, wk, mats = np.empty(9), np.zeros((K.WK_ROWS, 6)), np.empty((K.N_MATS, 6, 6))
        for k in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            code = K.inverse_dynamics(geo, signs[k if ss else 0], poses[k], twists[k],
                                      twist_dots[k], wrenches[k if ws else 0], bounded,
                                      tau[k], rot, wk, mats)
            codes[k] = code
            if code == K.OK or code == K.SATURATED:
                K.closure_forces(wk, closure[k])
                residual[k] = K.platform_residual(wk)


@batch_jit
def _static(geo, signs, poses, wrenches, bounded, tau, codes):
    n = poses.shape[0]
    ss, ws = signs.shape[0] > 1, wrenches.shape[0] > 1
    for c in numba.prange(n_chunks(n)):
        rot, wk, mats = np.empty(9), np.zeros((K.WK_ROWS, 6)), np.empty((K.N_MATS, 6, 6))
        for k in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            codes[k] = K.static_forces(geo, signs[k if ss else 0], poses[k],
                                       wrenches[k if ws else 0], bounded, tau[k], rot, wk, mats)


@batch_jit
def _forward(geo, signs, poses, twists, forces, wrenches, twist_dot, qddot, closure, codes):
    n = poses.shape[0]
    ss, ws = signs.shape[0] > 1, wrenches.shape[0] > 1
    for c in numba.prange(n_chunks(n)):
        rot, wk, mats = np.empty(9), np.zeros((K.WK_ROWS, 6)), np.empty((K.N_MATS, 6, 6))
        for k in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            code = K.forward_dynamics(geo, signs[k if ss else 0], poses[k], twists[k],
                                      forces[k], wrenches[k if ws else 0], twist_dot[k],
                                      qddot[k], rot, wk, mats)
            codes[k] = code
            if code == K.OK:
                K.forward_closure_forces(geo, wk, twist_dot[k], forces[k], closure[k])


@batch_jit
def _reduced(geo, signs, poses, twists, mass, bias, jac, codes):
    n = poses.shape[0]
    ss = signs.shape[0] > 1
    for c in numba.prange(n_chunks(n)):
        rot, wk, mats = np.empty(9), np.zeros((K.WK_ROWS, 6)), np.empty((K.N_MATS, 6, 6))
        for k in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            codes[k] = K.reduced_dynamics(geo, signs[k if ss else 0], poses[k], twists[k],
                                          mass[k], bias[k], jac[k], rot, wk, mats)


@batch_jit
def _regressor(geo, signs, poses, twists, twist_dots, rows, qd, qdd, codes):
    n = poses.shape[0]
    ss = signs.shape[0] > 1
    for c in numba.prange(n_chunks(n)):
        rot, wk, mats = np.empty(9), np.zeros((K.WK_ROWS, 6)), np.empty((K.N_MATS, 6, 6))
        motion, actuated, body = np.empty((6, 6, 3)), np.empty((24, 6)), np.empty((6, 10))
        for k in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            codes[k] = K.regressor(geo, signs[k if ss else 0], poses[k], twists[k],
                                   twist_dots[k], rows[k], qd[k], qdd[k], rot, wk, mats,
                                   motion, actuated, body)


@batch_jit
def _kinematics(geo, signs, poses, with_jacobian, q, jac, codes, within):
    n = poses.shape[0]
    ss = signs.shape[0] > 1
    for c in numba.prange(n_chunks(n)):
        rot, wk = np.empty(9), np.zeros((K.WK_ROWS, 6))
        for k in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            code = K.leg_state(geo, signs[k if ss else 0], poses[k], rot, wk)
            codes[k] = code
            for i in range(6):
                q[k, i] = wk[K.Q, i]
            within[k] = K.limits(geo, wk) == K.OK
            if with_jacobian:
                if code == K.OK or code == K.GIMBAL:
                    K.jacobian(wk, jac[k])
                else:
                    for i in range(6):
                        for j in range(6):
                            jac[k, i, j] = 0.0


@batch_jit
def _leg_reach(geo, signs, poses, out):
    n = poses.shape[0]
    ss = signs.shape[0] > 1
    for c in numba.prange(n_chunks(n)):
        rot, wk = np.empty(9), np.zeros((K.WK_ROWS, 6))
        for k in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            K.leg_state(geo, signs[k if ss else 0], poses[k], rot, wk)
            for i in range(6):
                out[k, i] = wk[K.DISC, i] >= 0.0


@batch_jit
def _closure_measures(geo, signs, poses, cosine, a_hat):
    n = poses.shape[0]
    ss = signs.shape[0] > 1
    for c in numba.prange(n_chunks(n)):
        rot, wk = np.empty(9), np.zeros((K.WK_ROWS, 6))
        for k in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            K.leg_state(geo, signs[k if ss else 0], poses[k], rot, wk)
            small = np.inf
            for i in range(6):
                small = min(small, abs(wk[K.NU, i]) / geo[K.BLOCK * i + K.LENI])
            cosine[k] = small
            K.closure_matrix_hat(geo, wk, a_hat[k])


# --------------------------------------------------------------------------------------
# Python boundary
# --------------------------------------------------------------------------------------
def check_batch(poses, twists=None, twist_dots=None, wrenches=None, forces=None):
    """Validate batch inputs: (N, 6) each with the same N; None passes through.

    Raises:
        InputError: bad shapes, NaN / inf, or a different number of rows than ``poses``.
    """
    poses = as_array(poses, (6,), "poses", batch=True)
    n = poses.shape[0]
    out = [poses]
    for name, arr in (("twists", twists), ("twist_dots", twist_dots), ("wrenches", wrenches),
                      ("actuator_forces", forces)):
        if arr is None:
            out.append(None)
            continue
        arr = as_array(arr, (6,), name, batch=True)
        if arr.shape[0] != n:
            raise InputError(name, arr, f"expected {n} rows like poses, got {arr.shape[0]}")
        out.append(arr)
    return out


def batch_signs(branch, n: int) -> np.ndarray:
    """Branch signs as a (1, 6) or (n, 6) array: None (home), six signs, or (n, 6) signs.

    Raises:
        InputError: anything else, or a value other than +1 / -1.
    """
    if branch is None:
        return K.HOME_BRANCH[None]
    try:
        arr = np.asarray(branch, dtype=float)
    except (TypeError, ValueError):
        raise InputError("branch", branch, "expected six values, each +1 or -1") from None
    ok = np.all((arr == 1.0) | (arr == -1.0))
    if arr.shape == (6,) and ok:
        return np.ascontiguousarray(arr[None])
    if arr.ndim == 2 and arr.shape == (n, 6) and ok:
        return np.ascontiguousarray(arr)
    raise InputError("branch", branch, f"expected six values or ({n}, 6), each +1 or -1")


def _raise_first(codes: np.ndarray, geo, signs, poses, needed=None) -> None:
    """Raise the Batch* error of the first failed state (lowest index), if any; a state
    the mechanism cannot take (unreachable, singular) before any saturated one."""
    bad = np.flatnonzero((codes != K.OK) & (codes != K.SATURATED))
    if bad.size == 0:
        bad = np.flatnonzero(codes)
    if bad.size == 0:
        return
    k = int(bad[0])
    code = int(codes[k])
    if code == K.SATURATED:
        raise BatchActuatorSaturationError(k, needed[k], np.full(6, geo[K.BOUND]))
    scratch = K.Scratch()
    K.leg_state(geo, signs[k if signs.shape[0] > 1 else 0], poses[k], scratch.rot, scratch.wk)
    raise K.error_of(code, geo, scratch.wk, scratch.mats[1], index=k)


def _zero_wrenches(wrenches):
    return np.zeros((1, 6)) if wrenches is None else wrenches


def inverse_dynamics_batch(geo, poses, twists, twist_dots, wrenches=None, bounded=True,
                           signs=None) -> BatchInverseDynamics:
    """Inverse dynamics of N states (validated (N, 6) arrays; ``wrenches`` may be None).

    Raises:
        BatchUnreachablePoseError: a pose out of reach (the first such state).
        BatchSingularityError: a singular state (type I, gimbal lock, type II; the first).
        BatchActuatorSaturationError: with ``bounded``, forces beyond the bound (the first
            such state).
    """
    signs = K.HOME_BRANCH[None] if signs is None else signs
    n = poses.shape[0]
    tau, closure = np.empty((n, 6)), np.zeros((n, 6, 3))
    residual, codes = np.zeros(n), np.zeros(n, dtype=np.int64)
    _inverse(geo, signs, poses, twists, twist_dots, _zero_wrenches(wrenches), bool(bounded),
             tau, closure, residual, codes)
    _raise_first(codes, geo, signs, poses, tau)
    return BatchInverseDynamics(tau, closure, residual)


def static_forces_batch(geo, poses, wrenches=None, bounded=True, signs=None) -> np.ndarray:
    """Actuator forces (N, 6) holding N poses at rest (validated arrays).

    Raises:
        BatchUnreachablePoseError: a pose out of reach.
        BatchSingularityError: a singular state.
        BatchActuatorSaturationError: with ``bounded``, forces beyond
            ``geometry.max_actuator_force``.
    """
    signs = K.HOME_BRANCH[None] if signs is None else signs
    tau, codes = static_forces_codes(geo, poses, wrenches, bounded, signs)
    _raise_first(codes, geo, signs, poses, tau)
    return tau


def static_forces_codes(geo, poses, wrenches, bounded, signs):
    """:func:`static_forces_batch` without raising: ``(tau (N, 6), codes (N,))``, the
    kernels' status per state (``wrenches`` (1, 6) or (N, 6), or None)."""
    n = poses.shape[0]
    tau, codes = np.zeros((n, 6)), np.zeros(n, dtype=np.int64)
    _static(geo, signs, poses, _zero_wrenches(wrenches), bool(bounded), tau, codes)
    return tau, codes


def closure_measures(geo, poses, signs):
    """Per pose the smallest ``|cos(leg, rail)|`` (N,) and ``A_hat`` (N, 6, 6) of
    :class:`~hexapod_pin.core.results.SingularityMeasures` (legs of unreachable poses: the
    nearest rail points)."""
    n = poses.shape[0]
    cosine, a_hat = np.empty(n), np.empty((n, 6, 6))
    _closure_measures(geo, signs, poses, cosine, a_hat)
    return cosine, a_hat


def forward_dynamics_batch(geo, poses, twists, forces, wrenches=None,
                           signs=None) -> BatchForwardDynamics:
    """Forward dynamics of N states (validated arrays).

    Raises:
        BatchUnreachablePoseError: a pose out of reach.
        BatchSingularityError: a singular state (type I, gimbal lock).
    """
    signs = K.HOME_BRANCH[None] if signs is None else signs
    n = poses.shape[0]
    twist_dot, qddot = np.empty((n, 6)), np.empty((n, 6))
    closure, codes = np.zeros((n, 6, 3)), np.zeros(n, dtype=np.int64)
    _forward(geo, signs, poses, twists, forces, _zero_wrenches(wrenches), twist_dot, qddot,
             closure, codes)
    _raise_first(codes, geo, signs, poses)
    return BatchForwardDynamics(twist_dot, qddot, closure)


def reduced_dynamics_batch(geo, poses, twists, signs=None) -> BatchReducedDynamics:
    """``M_x`` (N, 6, 6), ``h_x`` (N, 6) and ``J`` (N, 6, 6) of N states.

    Raises:
        BatchUnreachablePoseError: a pose out of reach.
        BatchSingularityError: a singular state (type I, gimbal lock).
    """
    signs = K.HOME_BRANCH[None] if signs is None else signs
    n = poses.shape[0]
    mass, bias, jac = np.empty((n, 6, 6)), np.empty((n, 6)), np.empty((n, 6, 6))
    codes = np.zeros(n, dtype=np.int64)
    _reduced(geo, signs, poses, twists, mass, bias, jac, codes)
    _raise_first(codes, geo, signs, poses)
    return BatchReducedDynamics(mass, bias, jac)


def regressor_batch(geo, poses, twists, twist_dots, signs=None):
    """The inertial regressor of N states (:func:`~hexapod_pin.hexapod.kernels.regressor`;
    validated (N, 6) arrays): ``(rows (N, 6, N_INERTIAL), qd (N, 6), qdd (N, 6))``.

    Raises:
        BatchUnreachablePoseError: a pose out of reach (the first such state).
        BatchSingularityError: a singular state (type I, gimbal lock, type II; the first).
        NonFiniteResultError: the rows of the first failed state are not finite (inputs
            near the largest magnitude accepted).
    """
    signs = K.HOME_BRANCH[None] if signs is None else signs
    n = poses.shape[0]
    rows, qd, qdd = np.empty((n, 6, K.N_INERTIAL)), np.empty((n, 6)), np.empty((n, 6))
    codes = np.zeros(n, dtype=np.int64)
    _regressor(geo, signs, poses, twists, twist_dots, rows, qd, qdd, codes)
    bad = np.flatnonzero(codes)
    if bad.size and codes[bad[0]] == K.NONFINITE:
        raise NonFiniteResultError("regressor_batch", f"rows of state {int(bad[0])}")
    _raise_first(codes, geo, signs, poses)
    return rows, qd, qdd


def kinematics_batch(geo, poses, signs, with_jacobian: bool):
    """Inverse kinematics (and Jacobians) of N poses with masks, never raising.

    Returns:
        :class:`InverseKinematicsBatch`, or :class:`JacobianBatch` with
        ``with_jacobian`` (rows of ``J`` where the pose is unreachable or type-I singular
        are zeros).
    """
    n = poses.shape[0]
    q, codes = np.empty((n, 6)), np.zeros(n, dtype=np.int64)
    within = np.empty(n, dtype=np.bool_)
    jac = np.empty((n, 6, 6)) if with_jacobian else np.empty((1, 6, 6))
    _kinematics(geo, signs, poses, with_jacobian, q, jac, codes, within)
    reachable = codes != K.UNREACHABLE
    if not with_jacobian:
        return InverseKinematicsBatch(q, reachable, within, reachable & within)
    regular = reachable & (codes != K.TYPE_I)
    return JacobianBatch(jac, q, reachable, regular, within, reachable & regular)


def leg_reachable_batch(geo, poses, signs) -> np.ndarray:
    """Per-leg reach masks (N, 6): leg i reaches its platform point."""
    out = np.empty((poses.shape[0], 6), dtype=np.bool_)
    _leg_reach(geo, signs, poses, out)
    return out
