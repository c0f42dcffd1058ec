"""Mechanical energies of any closed-loop model, whole and per body.

:func:`model_energies` reads a tree state ``(q, v)`` (Pinocchio conventions) of any
:class:`~hexapod_pin.core.closed_loop.ClosedLoopModel` and returns its kinetic and
potential energies (J) with the part of each body, of the rotors and of the springs.

Conventions:

* a *body* is what one joint of the tree moves: its child link with every link welded to it
  (Pinocchio's ``model.inertias[i]``, ``i = 1 .. njoints - 1``), named after the first
  BODY frame of that joint (the joint's own name when it has none);
* kinetic energy ``1/2 v^T M(q) v``, ``M`` with the armature of the drives
  (``clm.effects.armature``, which Pinocchio's ``crba`` and ``computeKineticEnergy``
  include); per body ``1/2 m |v_c|^2 + 1/2 w^T I_c w`` with ``v_c`` the velocity of its
  centre of mass and ``I_c`` its rotational inertia about it; the rotors' part
  ``1/2 sum(armature v^2)``;
* potential energy: gravity with Pinocchio's convention, ``-sum_i m_i g . c_i`` (``g`` =
  ``model.gravity.linear``, ``c_i`` the world position of body ``i``'s centre of mass),
  zero when every centre of mass is at height zero (on the plane through the world origin
  normal to gravity), positive above it; plus the joint springs'
  ``1/2 sum(stiffness dq^2)`` (:func:`~hexapod_pin.core.effects.spring_energy`).

The closures do not enter: the energies are those of the tree's state as given (a state on
the closures is the mechanism's state).
"""

from __future__ import annotations

import threading

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from .checks import check_finite_result, of_type
from .closed_loop import ClosedLoopModel
from .effects import spring_energy
from .results import Energies


def model_energies(clm: ClosedLoopModel, q: npt.ArrayLike, v: npt.ArrayLike) -> Energies:
    """Kinetic, potential and total energy of a tree state, with the part of each body,
    of the rotors and of the springs.

    Args:
        clm: any closed-loop model (its Pinocchio tree ``clm.model``).
        q: the tree configuration (nq,) (Pinocchio conventions).
        v: the tree velocity (nv,) (Pinocchio conventions: each joint's velocity in its
            own frame).

    Returns:
        :class:`~hexapod_pin.core.results.Energies` (J): ``kinetic`` ``1/2 v^T M v`` (the
        armature included), ``potential`` ``-sum m_i g . c_i`` (zero when every centre of
        mass is at height zero) plus the springs', ``total`` their sum, ``bodies``
        (n_bodies,) names, ``kinetic_per_body`` and ``potential_per_body`` (n_bodies,)
        arrays, ``rotor_kinetic`` ``1/2 sum(armature v^2)`` and ``spring_potential``
        ``1/2 sum(stiffness dq^2)``: ``sum(kinetic_per_body) + rotor_kinetic = kinetic``
        and ``sum(potential_per_body) + spring_potential = potential``
        (``n_bodies = model.njoints - 1``).

    Raises:
        ArgumentTypeError: ``clm`` is not a closed-loop model.
        InputError: ``q`` or ``v`` of the wrong shape, not real, or with NaN / inf.
        NonFiniteResultError: finite inputs whose energies overflow.
    """
    clm = of_type(clm, ClosedLoopModel, "clm")
    q = clm.check_q(q)
    v = clm.check_v(v)
    model, data, names = _workspace(clm)
    pin.forwardKinematics(model, data, q, v)
    gravity = np.asarray(model.gravity.linear, dtype=float)
    n = model.njoints - 1
    kinetic = np.empty(n)
    potential = np.empty(n)
    for i in range(1, model.njoints):
        inertia = model.inertias[i]
        mass, lever = inertia.mass, np.asarray(inertia.lever)
        motion = data.v[i]                       # body velocity, local frame
        w = np.asarray(motion.angular)
        v_com = np.asarray(motion.linear) + (w[1] * lever[2] - w[2] * lever[1],
                                             w[2] * lever[0] - w[0] * lever[2],
                                             w[0] * lever[1] - w[1] * lever[0])
        kinetic[i - 1] = 0.5 * (mass * v_com @ v_com + w @ np.asarray(inertia.inertia) @ w)
        placement = data.oMi[i]
        com = np.asarray(placement.rotation) @ lever + np.asarray(placement.translation)
        potential[i - 1] = -mass * (gravity @ com)
    kin, pot = _totals(clm, model, data, q, v)
    effects = clm.effects
    rotor = float(0.5 * np.dot(effects.armature * v, v))
    springs = spring_energy(model, effects, q)
    return check_finite_result("model_energies", Energies(kin, pot, kin + pot, names,
                                                          kinetic, potential, rotor, springs))


def energy_totals(clm: ClosedLoopModel, q: npt.ArrayLike, v: npt.ArrayLike
                  ) -> tuple[float, float]:
    """``(kinetic, potential)`` (J) of :func:`model_energies` without the parts
    (Pinocchio's ``computeKineticEnergy``, the armature included, and
    ``computePotentialEnergy`` plus the springs' energy: for a simulation's every sample).

    Args:
        clm: any closed-loop model.
        q: the tree configuration (nq,).
        v: the tree velocity (nv,).

    Raises:
        InputError: ``q`` or ``v`` of the wrong shape, not real, or with NaN / inf.
    """
    q = clm.check_q(q)
    v = clm.check_v(v)
    model, data, _ = _workspace(clm)
    return _totals(clm, model, data, q, v)


def _totals(clm: ClosedLoopModel, model: pin.Model, data: pin.Data, q: np.ndarray,
            v: np.ndarray) -> tuple[float, float]:
    """``(kinetic with the armature, gravity + spring potential)`` (J) of checked
    ``q``, ``v``."""
    return (float(pin.computeKineticEnergy(model, data, q, v)),
            float(pin.computePotentialEnergy(model, data, q))
            + spring_energy(model, clm.effects, q))


def body_names(clm: ClosedLoopModel) -> tuple[str, ...]:
    """The name of each body of the tree, in joint order (``n_bodies = njoints - 1``): the
    first BODY frame of each joint, or the joint's name when it has none."""
    model = clm.model
    first: dict[int, str] = {}
    for frame in model.frames:
        if frame.type == pin.FrameType.BODY and frame.parentJoint not in first:
            first[frame.parentJoint] = frame.name
    return tuple(first.get(i, model.names[i]) for i in range(1, model.njoints))


def _workspace(clm: ClosedLoopModel):
    """This thread's Pinocchio data for the energies of ``clm`` and the body names (kept in
    ``clm.workspaces``, collected with the model)."""
    key = ("energy", threading.get_ident())
    ws = clm.workspaces.get(key)
    if ws is None:
        ws = clm.workspaces[key] = (clm.model, clm.model.createData(), body_names(clm))
    return ws
