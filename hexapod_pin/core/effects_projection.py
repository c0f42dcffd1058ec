"""The joint and drive effects of :mod:`hexapod_pin.core.effects` carried into the closed
forms of the robots (the hexapod's and the planar 3-PRR's compiled kernels).

A closed form computes the rigid mechanism in platform coordinates; the effects of the
tree's coordinates reach it in two ways, both exact:

* **actuated coordinates** (carriages, sliders: one velocity coordinate per actuator,
  ``q_k``, ``qd_k = J_k twist``, ``qdd_k = J_k twist_dot + qdd0_k``): the compiled kernels
  read them from a flat *drive vector* (:func:`pack_drives`, appended to the robot's packed
  geometry) and add, for actuator ``k`` with armature ``a``, damping ``d``, Coulomb
  friction ``c``, stiffness ``K`` and spring reference ``r``:

  ==================  ======================================================================
  route               term
  ==================  ======================================================================
  inverse dynamics    ``u_k += a qdd_k + d qd_k + K (q_k - r) + c s``, ``s = sign(qd_k)``
                      while sliding, ``sign(qdd_k)`` at rest when ``|qdd_k|`` exceeds the
                      velocity threshold, else 0 (:func:`inverse_load`)
  reduced dynamics    ``M_x += J^T diag(a) J``, ``h_x += J^T (a qdd0 + d qd + K (q - r) +
                      c sign(qd))`` (sliding coordinates only; :func:`add_reduced`): inertia,
                      never weight (the armature is a rotor's, it has no mass on the rail)
  forward dynamics    that ``M_x``, ``h_x``; the friction ``f`` of the coordinates at rest
                      (``|qd_k| <= velocity_threshold``) solved exactly (:func:`stick_slip`)
  ==================  ======================================================================

  The stick / slip problem is the box QP of
  :meth:`ClosedLoopDynamics._stick_slip <hexapod_pin.core.dynamics.ClosedLoopDynamics>` in
  platform coordinates: ``G = J_r M_x^-1 J_r^T`` (the response of the resting actuators'
  accelerations to unit forces on them), ``a0`` their accelerations without that friction,
  ``min 1/2 f^T G f + a0^T f`` subject to ``|f| <= c``; :func:`box_qp` solves it by a primal
  active-set method (finite, exact on its final active set; compiled, so that the batches and
  the simulators run it), whose KKT conditions are stick (``|f_k| < c_k``, ``qdd_k = 0``) or
  slip (``f_k = -c_k sign(qdd_k)``).

* **passive coordinates** (universal joints, links, a platform's joints): through the tree
  maps, generically. With ``T`` (nv, dim) the tree velocity per twist (``v = T twist``),
  ``a0`` the tree acceleration at ``twist_dot = 0`` and ``tau_e`` the effects' generalised
  force (:func:`~hexapod_pin.core.effects.passive_forces` and
  :func:`~hexapod_pin.core.effects.friction_forces`), the reduced dynamics gain
  ``M_x += T^T A T`` and ``h_x += T^T (A a0 - tau_e)`` (:func:`reduced_effects`); a robot
  whose passive coordinates carry effects answers its inverse and forward dynamics on the
  tree routes (:func:`~hexapod_pin.core.dynamics.inverse_dynamics_tree`,
  :func:`~hexapod_pin.core.dynamics.forward_dynamics_tree`) from its closed-form tree state
  and says so in the result's status (:data:`PASSIVE_STATUS`).

Energies: :func:`~hexapod_pin.core.energy.energy_totals` (Pinocchio's kinetic energy holds
the rotors' ``1/2 a qd^2``, the potential the springs' ``sum K dq^2 / 2``) serves the closed
forms as it serves the tree.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import (ActuatorSaturationError, BatchActuatorSaturationError,
                      BatchSingularityError, BatchUnreachablePoseError, DescriptionError,
                      InputError, SingularityError, UnreachablePoseError)
from .closed_loop import ClosedLoopModel
from .compiled import jit_inline
from .effects import JointEffects, friction_forces, passive_forces
from .kernel_status import NOT_PD, OK, RESIDUAL
from .linear_kernels import cholesky_lower

#: the note a result's status carries when the passive coordinates' effects sent it to
#: the tree routes
PASSIVE_STATUS = "effects on passive coordinates: solved on the tree"

# -- the drive vector: a head, then one block per actuator ---------------------------------
#: head: 1.0 when any actuated coordinate has an effect (else the kernels skip them), the
#: velocity threshold of Coulomb friction (m/s or rad/s), and ``v_eps`` of a smooth
#: friction ``-c tanh(qd / v_eps)`` (0: the exact, set-valued friction; a simulator's
#: ``friction_regularisation``)
FLAG, THRESHOLD, SMOOTH = 0, 1, 2
HEAD = 3
#: per actuator: armature, damping, Coulomb friction, stiffness, spring reference
ARM, DAMP, COUL, STIFF, REF = range(5)
BLOCK = 5


def drive_size(n_actuators: int) -> int:
    """The length of the drive vector of ``n_actuators`` actuators."""
    return HEAD + BLOCK * n_actuators


def pack_drives(clm: ClosedLoopModel) -> np.ndarray:
    """The effects of the actuated coordinates of ``clm`` (``clm.effects``; the order of
    ``clm.actuated_joints``) as the flat vector the kernels read (:data:`HEAD` then a
    :data:`BLOCK` per actuator: armature, damping, Coulomb, stiffness in the joint's units,
    the spring reference in its coordinate (m or rad)).

    Raises:
        DescriptionError: an actuated joint with more than one coordinate (the kernels
            model one per actuator).
    """
    eff = clm.effects
    model = clm.model
    out = np.zeros(drive_size(clm.n_actuated))
    out[THRESHOLD] = eff.velocity_threshold
    for k, name in enumerate(clm.actuated_joints):
        joint = model.joints[model.getJointId(name)]
        if joint.nq != 1 or joint.nv != 1:
            raise DescriptionError(clm.name, f"actuated joint {name!r} has {joint.nq} "
                                   "configuration coordinates: the closed form's drives need "
                                   "one")
        iv, iq = joint.idx_v, joint.idx_q
        start = HEAD + BLOCK * k
        out[start:start + BLOCK] = (eff.armature[iv], eff.damping[iv], eff.coulomb[iv],
                                    eff.stiffness[iv], eff.spring_reference[iq])
    blocks = out[HEAD:].reshape(-1, BLOCK)
    out[FLAG] = float(np.any(blocks[:, ARM:REF] != 0.0))
    return out


class PackedDrives:
    """A robot's packed kernel vector (geometry, drives, passive flag) kept in step with its
    model's effects: ``pack(drives, passive)`` builds it from :func:`pack_drives` and
    whether :func:`passive_effect_coordinates` is not empty; an armature written into
    ``clm.model.armature`` by hand (which ``clm.effects`` adopts) rebuilds it at the next
    access of :attr:`vector` (one comparison of the armature's bytes).

    Args:
        clm: the robot's closed-loop model.
        pack: the robot's packing function.
    """

    def __init__(self, clm: ClosedLoopModel,
                 pack: Callable[[np.ndarray, bool], np.ndarray]) -> None:
        self._clm, self._pack = clm, pack
        self._armature = clm.model.armature          # a view of Pinocchio's vector
        self._seen = b""
        self._vector = self.vector

    @property
    def vector(self) -> np.ndarray:
        """The packed vector (a new array after a hand-written armature)."""
        arm = self._armature.tobytes()
        if arm != self._seen:
            clm = self._clm          # clm.effects (read by both) adopts a new armature
            passive = passive_effect_coordinates(clm).size > 0
            self._vector = self._pack(pack_drives(clm), passive)
            self._seen = arm
        return self._vector


def at_rest_error(value: Any, which: str, drives: np.ndarray, at: int) -> InputError:
    """The :class:`InputError` (on the twist ``value``) of an actuated coordinate ``which``
    (e.g. ``"carriage 2"``) whose exact Coulomb friction is at rest: the dynamics is not
    differentiable there (stick / slip). ``drives``: the packed vector holding the drive
    vector at ``at`` (its velocity threshold)."""
    return InputError("twist", value, f"{which} with Coulomb friction is at rest (rate <= "
                      f"{drives[at + THRESHOLD]:g} in magnitude): the dynamics is not "
                      "differentiable there (stick / slip)")


def passive_effect_coordinates(clm: ClosedLoopModel) -> np.ndarray:
    """Indices into ``v`` of the passive (not actuated) coordinates that carry an effect
    (sorted; empty when every effect sits on the actuators)."""
    coords = clm.effects.effective_coordinates()
    return np.setdiff1d(coords, clm.actuated_v)


# -- compiled pieces (read by the kernels of every closed form) ----------------------------
@jit_inline
def friction_force(drives, at, k, qd):
    """The Coulomb friction force (N or N m) of drive ``k`` at the rate ``qd``: ``-c
    sign(qd)`` while ``|qd| > threshold`` (0 at rest: set-valued, solved for), or the
    smooth ``-c tanh(qd / v_eps)`` with a regularisation."""
    c = drives[at + HEAD + BLOCK * k + COUL]
    if c == 0.0:
        return 0.0
    eps = drives[at + SMOOTH]
    if eps > 0.0:
        return -c * math.tanh(qd / eps)
    if abs(qd) > drives[at + THRESHOLD]:
        return -c if qd > 0.0 else c
    return 0.0


@jit_inline
def drive_force(drives, at, k, q, qd):
    """The force (N or N m) drive ``k`` applies to its coordinate at ``(q, qd)``, armature
    and the friction of a coordinate at rest excluded: ``-d qd - K (q - r)`` plus
    :func:`friction_force`. ``at``: where the drive vector starts in ``drives``."""
    b = at + HEAD + BLOCK * k
    return (-drives[b + DAMP] * qd - drives[b + STIFF] * (q - drives[b + REF])
            + friction_force(drives, at, k, qd))


@jit_inline
def at_rest(drives, at, k, qd):
    """Whether drive ``k`` has exact Coulomb friction and its coordinate is at rest
    (``|qd| <= threshold``): its friction is then solved for."""
    return (drives[at + HEAD + BLOCK * k + COUL] != 0.0 and drives[at + SMOOTH] == 0.0
            and abs(qd) <= drives[at + THRESHOLD])


@jit_inline
def dissipated_power(drives, at, n, qd, qd_next):
    """``sum_k (d_k qd_k - friction_force_k(qd_k)) qd_next_k`` (W): the power against the
    dissipative forces of the ``n`` drives at the rates ``qd`` along the rates
    ``qd_next`` (the same rates: the dissipated power; an Euler step's end rates: the
    work of the held forces per unit time)."""
    out = 0.0
    for k in range(n):
        out += (drives[at + HEAD + BLOCK * k + DAMP] * qd[k]
                - friction_force(drives, at, k, qd[k])) * qd_next[k]
    return out


@jit_inline
def any_at_rest(drives, at, n, qd, friction):
    """Whether one of the ``n`` drives is :func:`at_rest` (then :func:`stick_slip` solves
    its friction); ``friction`` (n,) is zeroed (the solved forces of none)."""
    rest = False
    for k in range(n):
        friction[k] = 0.0
        rest = rest or at_rest(drives, at, k, qd[k])
    return rest


@jit_inline
def inverse_load(drives, at, k, q, qd, qdd):
    """What actuator ``k`` spends on its own drive for a known motion (N or N m): ``a qdd
    - drive_force + c sign(qdd)`` for a coordinate at rest that accelerates (``|qdd| >
    threshold``): the term inverse dynamics adds to the rigid actuator force."""
    b = at + HEAD + BLOCK * k
    out = drives[b + ARM] * qdd - drive_force(drives, at, k, q, qd)
    if at_rest(drives, at, k, qd) and abs(qdd) > drives[at + THRESHOLD]:
        c = drives[b + COUL]
        out += c if qdd > 0.0 else -c
    return out


@jit_inline
def inverse_load_rate(drives, at, k, qd, dq, dqd, dqdd):
    """The derivative of :func:`inverse_load` at the rate ``qd`` (a coordinate not at rest)
    along ``(dq, dqd, dqdd)``: ``a dqdd + d dqd + K dq``, plus ``c (1 - tanh^2(qd / eps))
    / eps dqd`` for a smooth friction (exact Coulomb friction is constant while sliding)."""
    b = at + HEAD + BLOCK * k
    out = drives[b + ARM] * dqdd + drives[b + DAMP] * dqd + drives[b + STIFF] * dq
    eps, c = drives[at + SMOOTH], drives[b + COUL]
    if eps > 0.0 and c != 0.0:
        th = math.tanh(qd / eps)
        out += c * (1.0 - th * th) / eps * dqd
    return out


@jit_inline
def add_reduced(drives, at, n, dim, jac_t, q, qd, qdd0, mass, bias):
    """``mass += J^T diag(a) J`` (dim, dim) and ``bias += J^T (a qdd0 - drive_force)``
    (dim,) for ``n`` actuators with ``J^T`` ``jac_t`` (dim, n), positions ``q``, rates ``qd``
    and accelerations at ``twist_dot = 0`` ``qdd0`` (n,)."""
    for k in range(n):
        arm = drives[at + HEAD + BLOCK * k + ARM]
        load = arm * qdd0[k] - drive_force(drives, at, k, q[k], qd[k])
        for r in range(dim):
            jr = jac_t[r, k]
            bias[r] += jr * load
            if arm != 0.0:
                for c in range(dim):
                    mass[r, c] += arm * jr * jac_t[c, k]


@jit_inline
def _substitute(low, n, vec):
    """``vec = (low low^T)^-1 vec`` in place (leading n entries)."""
    for i in range(n):
        s = vec[i]
        for k in range(i):
            s -= low[i, k] * vec[k]
        vec[i] = s / low[i, i]
    for i in range(n - 1, -1, -1):
        s = vec[i]
        for k in range(i + 1, n):
            s -= low[k, i] * vec[k]
        vec[i] = s / low[i, i]


@jit_inline
def box_qp(hess, grad, bound, n, f, state, sub, free, x):
    """``f = argmin 1/2 f^T H f + g^T f`` subject to ``-bound <= f <= bound`` (``H``
    (n, n) symmetric positive definite, ``bound > 0``), by a primal active-set method from
    ``f = 0``: solve on the free coordinates with the others at their bounds, step to the
    first bound met, release the bound whose multiplier has the wrong sign; exact on the
    final active set. Scratch: ``state``, ``free``, ``x`` (n,), ``sub`` (n, n). Returns OK,
    NOT_PD (a free block not positive definite) or RESIDUAL (no convergence in 8 n + 8
    steps)."""
    scale = 0.0
    for i in range(n):
        f[i] = 0.0
        state[i] = 0.0
        row = abs(grad[i])
        for j in range(n):
            row += abs(hess[i, j]) * bound[j]
        scale = max(scale, row)
    tol = 1e-13 * scale
    for _ in range(8 * n + 8):
        nf = 0
        for i in range(n):
            if state[i] == 0.0:
                free[nf] = i
                nf += 1
        for a in range(nf):
            i = int(free[a])
            s = -grad[i]
            for j in range(n):
                if state[j] != 0.0:
                    s -= hess[i, j] * f[j]
            x[a] = s
            for b in range(nf):
                sub[a, b] = hess[i, int(free[b])]
        if nf and not cholesky_lower(sub, nf, sub):
            return NOT_PD
        _substitute(sub, nf, x)
        alpha, block, side = 1.0, -1, 0.0
        for a in range(nf):
            i = int(free[a])
            p = x[a] - f[i]
            if p > 0.0 and f[i] + p > bound[i]:
                t, s = (bound[i] - f[i]) / p, 1.0
            elif p < 0.0 and f[i] + p < -bound[i]:
                t, s = (-bound[i] - f[i]) / p, -1.0
            else:
                continue
            if t < alpha:
                alpha, block, side = t, i, s
        for a in range(nf):
            i = int(free[a])
            f[i] += alpha * (x[a] - f[i])
        if block >= 0:
            state[block] = side
            f[block] = side * bound[block]
            continue
        worst, excess = -1, tol
        for i in range(n):
            if state[i] != 0.0:
                g = grad[i]
                for j in range(n):
                    g += hess[i, j] * f[j]
                if state[i] * g > excess:      # at +bound the gradient must be <= 0
                    worst, excess = i, state[i] * g
        if worst < 0:
            return OK
        state[worst] = 0.0
    return RESIDUAL


@jit_inline
def stick_slip(drives, at, n, dim, mass, jac_t, qd, qdd0, rhs, twist_dot, friction, mats,
               vecs):
    """Forward dynamics ``M_x twist_dot = rhs + J_r^T f`` with the Coulomb friction ``f``
    of the actuators at rest solved exactly (the box QP of the module docstring).

    ``mass`` (dim, dim) is ``M_x`` (the drives' armature included), ``rhs`` (dim,) the
    right-hand side without that friction, ``jac_t`` (dim, n) ``J^T``, ``qd`` and ``qdd0``
    (n,) the actuator rates and accelerations at ``twist_dot = 0``. Writes ``twist_dot``
    (dim,) and ``friction`` (n,) (the solved force on each actuator at rest, 0 on the
    others). Scratch ``mats`` (4, >= max(n, dim), >= max(n, dim)), ``vecs`` (8, >= max(n,
    dim)). Returns OK, NOT_PD or RESIDUAL (the QP)."""
    low, cols, resp, sub = mats[0], mats[1], mats[2], mats[3]
    rest, a0, bound, f, state, free, x = (vecs[0], vecs[1], vecs[2], vecs[3], vecs[4],
                                          vecs[5], vecs[6])
    if not cholesky_lower(mass, dim, low):
        return NOT_PD
    for r in range(dim):
        twist_dot[r] = rhs[r]
    _substitute(low, dim, twist_dot)
    m = 0
    for k in range(n):
        friction[k] = 0.0
        if at_rest(drives, at, k, qd[k]):
            rest[m] = k
            m += 1
    if m == 0:
        return OK
    col = vecs[7]
    for j in range(m):
        k = int(rest[j])
        acc = qdd0[k]
        for r in range(dim):
            col[r] = jac_t[r, k]
            acc += jac_t[r, k] * twist_dot[r]
        a0[j] = acc
        bound[j] = drives[at + HEAD + BLOCK * k + COUL]
        _substitute(low, dim, col)
        for r in range(dim):
            cols[r, j] = col[r]
    for i in range(m):
        ki = int(rest[i])
        for j in range(i, m):
            s = 0.0
            for r in range(dim):
                s += jac_t[r, ki] * cols[r, j]
            resp[i, j] = s
            resp[j, i] = s
    code = box_qp(resp, a0, bound, m, f, state, sub, free, x)
    if code != OK:
        return code
    for j in range(m):
        friction[int(rest[j])] = f[j]
        for r in range(dim):
            twist_dot[r] += cols[r, j] * f[j]
    return OK


# -- passive coordinates: through the tree maps --------------------------------------------
def reduced_effects(clm: ClosedLoopModel, coordinates: npt.ArrayLike, vmap: np.ndarray,
                    q: np.ndarray, v: np.ndarray, a0: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray]:
    """The reduced dynamics' share ``(dM_x, dh_x)`` of the effects of some tree coordinates.

    ``dM_x = T_c^T diag(A_c) T_c`` (dim, dim) and ``dh_x = T_c^T (A_c a0_c - tau_e,c)``
    (dim,) with ``T_c`` the rows ``coordinates`` of the velocity map ``vmap`` (nv, dim)
    (``v = T twist``), ``a0`` (nv,) the tree acceleration at ``twist_dot = 0`` and ``tau_e``
    the effects' force at ``(q, v)`` (damping, springs, the friction of the sliding
    coordinates: that of a coordinate at rest is set-valued and left out). Units: those of
    ``M_x`` (kg, kg m, kg m^2) and ``h_x`` (N, N m).

    Args:
        clm: the closed-loop model (its effects and tree).
        coordinates: indices into ``v`` (e.g. :func:`passive_effect_coordinates`).
        vmap: ``T`` (nv, dim).
        q: the tree configuration (nq,).
        v: the tree velocity (nv,), ``T twist``.
        a0: the tree acceleration (nv,) at ``twist_dot = 0``.

    Raises:
        InputError: ``q`` or ``v`` of the wrong shape or not finite.
    """
    q, v = clm.check_q(q), clm.check_v(v)
    idx = np.asarray(coordinates, dtype=int)
    eff: JointEffects = clm.effects
    tau = passive_forces(clm.model, eff, q, v) + friction_forces(eff, v)
    rows = vmap[idx]
    arm = eff.armature[idx]
    d_mass = rows.T @ (arm[:, None] * rows)
    d_bias = rows.T @ (arm * a0[idx] - tau[idx])
    return 0.5 * (d_mass + d_mass.T), d_bias


def batch_of_states(n: int, call: Callable[[int], Any]) -> list[Any]:
    """``[call(0), ..., call(n - 1)]``: a batch answered state by state (a robot whose
    passive coordinates carry effects runs its batches on its single-state routes), the
    errors of state ``k`` raised as their Batch* variants with ``index`` ``k``.

    Raises:
        BatchActuatorSaturationError: a state beyond the actuator bounds.
        BatchUnreachablePoseError: a pose out of reach.
        BatchSingularityError: a singular state.
    """
    out = []
    for k in range(n):
        try:
            out.append(call(k))
        except ActuatorSaturationError as exc:
            raise BatchActuatorSaturationError(k, exc.needed, exc.limit) from exc
        except UnreachablePoseError as exc:
            raise BatchUnreachablePoseError(k, exc.carriages, exc.shortfall) from exc
        except SingularityError as exc:
            raise BatchSingularityError(k, exc.what, exc.sigma_min, exc.threshold,
                                        exc.measure) from exc
    return out


def batch_row(rows: np.ndarray | None, k: int) -> np.ndarray | None:
    """Row ``k`` of an optional batch array (None stays None)."""
    return None if rows is None else rows[k]


def stacked(results: list[Any], name: str, shape: tuple[int, ...]) -> np.ndarray:
    """The attribute ``name`` of every result of :func:`batch_of_states`, stacked
    (N, *shape)."""
    return np.array([getattr(r, name) for r in results], dtype=float).reshape(
        (len(results),) + shape)
