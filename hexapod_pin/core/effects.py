"""The physical model of the joints and drives: one record, :class:`JointEffects`, and
the one function that turns it into forces, :func:`passive_forces`.

Every :class:`~hexapod_pin.core.closed_loop.ClosedLoopModel` carries a
:class:`JointEffects` (``clm.effects``); :meth:`ClosedLoopModel.with_effects
<hexapod_pin.core.closed_loop.ClosedLoopModel.with_effects>` returns a model with other
effects, and every robot has the same ``robot.with_effects(...)``. The effects, per
velocity coordinate ``i`` of the tree (Pinocchio's ``v`` order):

==================  ===========================  ===========================================
field               units                        enters as
==================  ===========================  ===========================================
``armature``        kg (prismatic), kg m^2       ``M(q) + diag(armature)``: Pinocchio's
                    (revolute)                   ``model.armature`` (``crba``, ``rnea``,
                                                 ``constraintDynamics``, kinetic energy);
                                                 inertia only, no weight
``damping``         N s/m, N m s/rad             force ``-damping_i v_i``
``stiffness``       N/m, N m/rad                 force ``-stiffness_i dq_i`` with
                                                 ``dq = pin.difference(spring_reference, q)``
``coulomb``         N, N m                       force ``-coulomb_i sign(v_i)`` while the
                                                 joint slides; while it is at rest
                                                 (``|v_i| <= velocity_threshold``) any force
                                                 in ``[-coulomb_i, coulomb_i]`` that keeps it
                                                 at rest (stick), else ``-coulomb_i
                                                 sign(a_i)`` (slip)
==================  ===========================  ===========================================

and per actuator (``clm.actuated_joints`` order): ``gear`` (the actuator force is ``gear *``
the motor torque; a rotor inertia ``J_m`` given per motor enters the armature of its joint
as ``gear^2 J_m``) and ``effort_limit`` (joint side, N or N m; ``inf`` for none; exported
to MuJoCo; the default force bound of planning and of the workspace force capability, with
``geometry.max_actuator_force``: :func:`~hexapod_pin.core.workspace_maps.actuator_force_bounds`;
the dynamics routes take their own ``bounds``).

The generalised force of the effects, ``tau_e = passive_forces(q, v) + friction``, is
applied with the actuator and external forces: forward dynamics solves ``(M + A) a + h =
S^T u + tau_ext + tau_e + J_c^T lambda``; inverse dynamics finds ``u`` for the same
equation. Their energy: the springs store ``sum(stiffness dq^2) / 2`` (part of the
potential energy), damping and friction dissipate ``sum(damping v^2 + coulomb |v|)`` (W).
The derivation and the tests: ``docs/drives.md``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..errors import InputError, SolverError

#: default speed (m/s or rad/s) at or below which a joint with Coulomb friction counts
#: as at rest (its friction force is then set by stick / slip instead of ``sign(v)``)
VELOCITY_THRESHOLD = 1e-9

#: the per-coordinate fields (shape (nv,)), each >= 0
COORDINATE_FIELDS = ("armature", "damping", "coulomb", "stiffness")
#: the per-actuator fields (shape (n_act,))
ACTUATOR_FIELDS = ("gear", "effort_limit")


def _frozen(arr: np.ndarray) -> np.ndarray:
    arr = np.array(arr, dtype=float)
    arr.flags.writeable = False
    return arr


@dataclass(frozen=True, eq=False)
class JointEffects:
    """The joint and drive effects of a tree (see the module docstring for units and
    equations). Build it with :meth:`rigid` or :func:`resolve_effects`; read-only arrays.

    Attributes:
        armature: reflected rotor inertia (nv,), kg or kg m^2.
        damping: viscous coefficient (nv,), N s/m or N m s/rad.
        coulomb: dry-friction force magnitude (nv,), N or N m.
        stiffness: spring stiffness (nv,), N/m or N m/rad.
        spring_reference: the configuration (nq,) at which the springs are relaxed.
        gear: actuator force per motor torque (n_act,), nonzero.
        effort_limit: joint-side force bound of each actuator (n_act,), > 0 (``inf``:
            none); exported, and a default bound of planning and of the force capability
            (:func:`~hexapod_pin.core.workspace_maps.actuator_force_bounds`).
        velocity_threshold: speed at or below which a joint counts as at rest for
            Coulomb friction (m/s or rad/s), >= 0.
    """

    armature: np.ndarray
    damping: np.ndarray
    coulomb: np.ndarray
    stiffness: np.ndarray
    spring_reference: np.ndarray
    gear: np.ndarray
    effort_limit: np.ndarray
    velocity_threshold: float = VELOCITY_THRESHOLD

    @classmethod
    def rigid(cls, model: pin.Model, n_actuated: int) -> "JointEffects":
        """No effects: zero armature, damping, friction and stiffness, unit gears, no
        effort limits, springs relaxed at ``pin.neutral(model)``."""
        zero = np.zeros(model.nv)
        return cls(_frozen(zero), _frozen(zero), _frozen(zero), _frozen(zero),
                   _frozen(pin.neutral(model)), _frozen(np.ones(n_actuated)),
                   _frozen(np.full(n_actuated, np.inf)))

    # -- what is there --------------------------------------------------------------------
    @property
    def is_rigid(self) -> bool:
        """Whether there is no armature, damping, friction or spring at all."""
        return not (self.armature.any() or self.has_forces)

    @property
    def has_forces(self) -> bool:
        """Whether damping, friction or springs give a force (armature alone gives none)."""
        return bool(self.damping.any() or self.coulomb.any() or self.stiffness.any())

    @property
    def has_coulomb(self) -> bool:
        """Whether any coordinate has Coulomb friction."""
        return bool(self.coulomb.any())

    def effective_coordinates(self) -> np.ndarray:
        """Indices into ``v`` of the coordinates with any effect (sorted)."""
        mask = (self.armature != 0) | (self.damping != 0) | (self.coulomb != 0) | \
            (self.stiffness != 0)
        return np.flatnonzero(mask)

    def only_on(self, coordinates: npt.ArrayLike) -> bool:
        """Whether every effect sits on the given velocity coordinates (e.g. the actuated
        ones: what a closed form that models drives only can carry)."""
        allowed = np.zeros(self.armature.size, dtype=bool)
        allowed[np.asarray(coordinates, dtype=int)] = True
        return bool(np.all(allowed[self.effective_coordinates()]))

    def replace(self, **changes: Any) -> "JointEffects":
        """A copy with some fields replaced (arrays frozen; no other check: use
        :func:`resolve_effects` for user input)."""
        changes = {k: (_frozen(v) if isinstance(v, np.ndarray) else v)
                   for k, v in changes.items()}
        return dataclasses.replace(self, **changes)

    def as_dict(self) -> dict[str, Any]:
        """The fields as plain lists and floats (for files and messages)."""
        out: dict[str, Any] = {f: getattr(self, f).tolist()
                               for f in COORDINATE_FIELDS + ("spring_reference",)
                               + ACTUATOR_FIELDS}
        out["velocity_threshold"] = self.velocity_threshold
        return out

    def __repr__(self) -> str:
        if self.is_rigid:
            return "JointEffects(rigid)"
        parts = [f"{f}={np.count_nonzero(getattr(self, f))} coords"
                 for f in COORDINATE_FIELDS if getattr(self, f).any()]
        return f"JointEffects({', '.join(parts)})"


# -- the forces --------------------------------------------------------------------------
def spring_displacement(model: pin.Model, effects: JointEffects, q: np.ndarray) -> np.ndarray:
    """``dq = pin.difference(model, spring_reference, q)`` (nv,): the spring stretch (m,
    rad), in the tangent space (a ball or free joint's rotation as a rotation vector)."""
    return pin.difference(model, effects.spring_reference, q)


def passive_forces(model: pin.Model, effects: JointEffects, q: np.ndarray,
                   v: np.ndarray) -> np.ndarray:
    """The generalised force of damping and springs (nv,) (N, N m): ``-damping * v -
    D^T (stiffness * dq)`` with ``dq`` of :func:`spring_displacement` and ``D = d dq / d q``
    (``pin.dDifference``: the identity on vector-space joints, so ``-stiffness * dq``
    there; on a ball or free joint the exact gradient of :func:`spring_energy`, which
    keeps the energy balance); the force the joints apply to the
    mechanism, added to ``S^T u + tau_ext``. Coulomb friction is set-valued and is
    :func:`friction_forces`."""
    out = -effects.damping * v
    if effects.stiffness.any():
        dq = spring_displacement(model, effects, q)
        # the gradient of sum(K dq^2) / 2: dDifference is the identity on vector-space
        # joints and the inverse right Jacobian of SO(3) / SE(3) on ball and free joints
        jac = pin.dDifference(model, effects.spring_reference, q, pin.ArgumentPosition.ARG1)
        out -= jac.T @ (effects.stiffness * dq)
    return out


def sliding(effects: JointEffects, v: np.ndarray) -> np.ndarray:
    """Mask (nv,) of the coordinates with Coulomb friction that slide (``|v| >
    velocity_threshold``)."""
    return (effects.coulomb != 0) & (np.abs(v) > effects.velocity_threshold)


def at_rest(effects: JointEffects, v: np.ndarray) -> np.ndarray:
    """Indices into ``v`` of the coordinates with Coulomb friction at rest (``|v| <=
    velocity_threshold``): the ones whose friction force forward dynamics solves for."""
    return np.flatnonzero((effects.coulomb != 0) & (np.abs(v) <= effects.velocity_threshold))


def friction_forces(effects: JointEffects, v: np.ndarray,
                    a: np.ndarray | None = None) -> np.ndarray:
    """The Coulomb friction force (nv,) (N, N m) of a known motion: ``-coulomb *
    sign(v)`` on the sliding coordinates; on those at rest ``-coulomb * sign(a)`` when
    ``a`` is given and ``|a| > velocity_threshold`` (a joint that starts to move slides
    against its friction), else 0 (at rest and staying there, the friction force is
    anything in ``[-coulomb, coulomb]``; inverse dynamics then returns the force of the
    frictionless joint, and the holding band is ``u +- coulomb`` for an actuated one)."""
    c = effects.coulomb
    out = np.where(np.abs(v) > effects.velocity_threshold, -c * np.sign(v), 0.0)
    if a is not None:
        rest = (c != 0) & (np.abs(v) <= effects.velocity_threshold) & \
            (np.abs(a) > effects.velocity_threshold)
        out[rest] = -c[rest] * np.sign(a[rest])
    return out


def effect_forces(model: pin.Model, effects: JointEffects, q: np.ndarray, v: np.ndarray,
                  a: np.ndarray | None = None) -> np.ndarray:
    """:func:`passive_forces` plus :func:`friction_forces` (nv,): the generalised force of
    every effect for a known motion (what inverse dynamics balances)."""
    out = passive_forces(model, effects, q, v)
    if effects.has_coulomb:
        out += friction_forces(effects, v, a)
    return out


#: relative margin below the friction bound inside which a friction force counts as
#: sticking (``|f| < (1 - STICK_MARGIN) coulomb``), at or beyond it as slipping
STICK_MARGIN = 1e-9


def check_stick_slip(friction: np.ndarray, bound: np.ndarray, motion: np.ndarray,
                     tol: float, solver: str, coordinates: np.ndarray,
                     motion_name: str) -> None:
    """Check that every coordinate's friction force and motion meet stick / slip.

    A coordinate sticks when ``|f| < (1 - STICK_MARGIN) bound`` and its motion (the
    acceleration, or the next velocity of a step) is within ``tol`` of zero; it slips when
    ``f`` is at ``+bound`` with motion ``<= tol``, or at ``-bound`` with motion ``>= -tol``
    (the friction opposes it).

    Args:
        friction: the friction forces (k,) (N, N m).
        bound: their bounds (k,), >= 0.
        motion: the accelerations or next velocities (k,).
        tol: the tolerance of "at rest" in the units of ``motion``.
        solver: the route, for the message.
        coordinates: the coordinates' labels (k,) for the message (e.g. indices into v).
        motion_name: what ``motion`` is, for the message.

    Raises:
        SolverError: a coordinate that neither sticks nor slips, naming its force, bound
            and motion.
    """
    edge = bound * (1.0 - STICK_MARGIN)
    inner = np.abs(friction) < edge
    bad = (inner & (np.abs(motion) > tol)) | ((friction >= edge) & (motion > tol)) | \
        ((friction <= -edge) & (motion < -tol))
    if np.any(bad):
        raise SolverError(solver, "stick-slip",
                          f"coordinates {np.asarray(coordinates)[bad].tolist()} miss stick / "
                          f"slip: friction {friction[bad].tolist()} (bounds "
                          f"{bound[bad].tolist()}), {motion_name} {motion[bad].tolist()}")


def spring_energy(model: pin.Model, effects: JointEffects, q: np.ndarray) -> float:
    """Potential energy of the springs, ``sum(stiffness dq^2) / 2`` (J)."""
    if not effects.stiffness.any():
        return 0.0
    dq = spring_displacement(model, effects, q)
    return float(0.5 * np.dot(effects.stiffness * dq, dq))


def dissipated_power(effects: JointEffects, v: np.ndarray) -> float:
    """Power dissipated by damping and Coulomb friction, ``sum(damping v^2 + coulomb
    |v|)`` (W, >= 0)."""
    return float(np.dot(effects.damping * v, v) + np.dot(effects.coulomb, np.abs(v)))


# -- building a record from user input ---------------------------------------------------
def resolve_effects(model: pin.Model, actuated_joints: tuple[str, ...], base: JointEffects,
                    **values: Any) -> JointEffects:
    """``base`` with the given fields replaced, each checked.

    Args:
        model: the tree (its joint names and sizes).
        actuated_joints: the actuated joints' names (order of the per-actuator fields).
        base: the effects kept where a field is not given.
        **values: ``armature``, ``damping``, ``coulomb``, ``stiffness`` (each an (nv,)
            array in the tree's velocity order, or ``{joint name: value}`` with a scalar
            or an (nv_joint,) array per joint; other joints keep ``base``), ``spring_reference``
            (an (nq,) configuration or ``{joint name: (nq_joint,) values}``), ``gear``,
            ``effort_limit``, ``rotor_inertia`` (each (n_act,) or ``{actuated joint:
            value}``; ``rotor_inertia`` is added to the armature as ``gear^2 *
            rotor_inertia``), ``velocity_threshold`` (a number >= 0).

    Raises:
        InputError: an unknown field or joint name, a wrong shape, NaN / inf, a negative
            coefficient, a zero gear, a non-positive effort limit, a spring reference that
            is not a valid configuration (e.g. a quaternion that is not unit).
    """
    known = set(COORDINATE_FIELDS + ACTUATOR_FIELDS) | {"spring_reference", "rotor_inertia",
                                                         "velocity_threshold"}
    for name in values:
        if name not in known:
            raise InputError(name, values[name], f"not a joint effect (expected one of "
                                                 f"{sorted(known)})")
    changes: dict[str, Any] = {}
    for name in COORDINATE_FIELDS:
        if values.get(name) is not None:
            arr = _per_joint(model, values[name], getattr(base, name), name, "v")
            _non_negative(arr, name)
            changes[name] = arr
    if values.get("spring_reference") is not None:
        ref = _per_joint(model, values["spring_reference"], base.spring_reference,
                         "spring_reference", "q")
        if not pin.isNormalized(model, ref, 1e-9):
            raise InputError("spring_reference", values["spring_reference"],
                             "not a valid configuration (a quaternion or (cos, sin) pair "
                             "that is not unit)")
        changes["spring_reference"] = ref
    gear = base.gear
    if values.get("gear") is not None:
        gear = _per_actuator(actuated_joints, values["gear"], base.gear, "gear")
        if np.any(gear == 0):
            raise InputError("gear", values["gear"], "a gear ratio must be nonzero")
        changes["gear"] = gear
    if values.get("effort_limit") is not None:
        limit = _per_actuator(actuated_joints, values["effort_limit"], base.effort_limit,
                              "effort_limit", allow_inf=True)
        if np.any(~(limit > 0)):
            raise InputError("effort_limit", values["effort_limit"],
                             "effort limits must be > 0 (inf for none)")
        changes["effort_limit"] = limit
    if values.get("rotor_inertia") is not None:
        rotor = _per_actuator(actuated_joints, values["rotor_inertia"],
                              np.zeros(len(actuated_joints)), "rotor_inertia")
        _non_negative(rotor, "rotor_inertia")
        arm = np.array(changes.get("armature", base.armature), dtype=float)
        for k, joint in enumerate(actuated_joints):
            arm[model.joints[model.getJointId(joint)].idx_v] += gear[k] ** 2 * rotor[k]
        changes["armature"] = arm
    if values.get("velocity_threshold") is not None:
        thr = values["velocity_threshold"]
        if isinstance(thr, bool) or not isinstance(thr, (int, float, np.floating)) \
                or not (0.0 <= float(thr) < np.inf):
            raise InputError("velocity_threshold", thr, "expected a finite number >= 0")
        changes["velocity_threshold"] = float(thr)
    return base.replace(**changes)


def _non_negative(arr: np.ndarray, name: str) -> None:
    if np.any(arr < 0):
        bad = np.flatnonzero(arr < 0)
        raise InputError(name, arr.tolist(), f"must be >= 0 (negative at coordinates "
                                             f"{bad[:5].tolist()})")


def _real(value: Any, name: str, allow_inf: bool = False) -> np.ndarray:
    """Real numbers (at least 1-D float64); NaN refused, inf only with ``allow_inf``."""
    try:
        raw = np.asarray(value)
    except (TypeError, ValueError):
        raise InputError(name, value, "not a regular array of numbers") from None
    if raw.dtype.kind not in "iuf":
        raise InputError(name, value, f"expected real numbers, got dtype {raw.dtype}")
    arr = np.atleast_1d(raw.astype(float))
    bad = np.isnan(arr) | (np.isinf(arr) if not allow_inf else False)
    if np.any(bad):
        raise InputError(name, value, f"contains NaN{'' if allow_inf else ' or inf'} at "
                                      f"{np.flatnonzero(bad)[:5].tolist()}")
    return arr


def _per_joint(model: pin.Model, value: Any, base: np.ndarray, name: str,
               space: str) -> np.ndarray:
    """An (nv,) or (nq,) array from an array or a ``{joint: value}`` mapping."""
    size = model.nv if space == "v" else model.nq
    if isinstance(value, Mapping):
        out = np.array(base, dtype=float)
        for joint, entry in value.items():
            if not isinstance(joint, str) or not model.existJointName(joint) \
                    or model.getJointId(joint) == 0:
                raise InputError(name, joint, f"not a joint of the tree (joints: "
                                              f"{list(model.names)[1:]})")
            jm = model.joints[model.getJointId(joint)]
            start, n = (jm.idx_v, jm.nv) if space == "v" else (jm.idx_q, jm.nq)
            arr = _real(entry, f"{name}[{joint!r}]")
            if arr.size == 1 and n > 1 and space == "v":
                arr = np.full(n, float(arr[0]))
            if arr.shape != (n,):
                kind = "velocity" if space == "v" else "configuration"
                raise InputError(f"{name}[{joint!r}]", entry,
                                 f"joint {joint!r} has {n} {kind} coordinates")
            out[start:start + n] = arr
        return out
    arr = _real(value, name)
    if arr.shape != (size,):
        raise InputError(name, value, f"expected shape ({size},) (the tree's "
                                      f"{'nv' if space == 'v' else 'nq'}) or a "
                                      "{joint name: value} mapping")
    return arr


def _per_actuator(actuated: tuple[str, ...], value: Any, base: np.ndarray, name: str,
                  allow_inf: bool = False) -> np.ndarray:
    """An (n_act,) array from an array or an ``{actuated joint: value}`` mapping."""
    if isinstance(value, Mapping):
        out = np.array(base, dtype=float)
        for joint, entry in value.items():
            if joint not in actuated:
                raise InputError(name, joint, f"not an actuated joint ({list(actuated)})")
            arr = _real(entry, f"{name}[{joint!r}]", allow_inf)
            if arr.shape != (1,):
                raise InputError(f"{name}[{joint!r}]", entry, "expected one number")
            out[actuated.index(joint)] = arr[0]
        return out
    arr = _real(value, name, allow_inf)
    if arr.shape != (len(actuated),):
        raise InputError(name, value, f"expected shape ({len(actuated)},) (one per actuator, "
                                      "in clm.actuated_joints order) or an {actuated joint: "
                                      "value} mapping")
    return arr
