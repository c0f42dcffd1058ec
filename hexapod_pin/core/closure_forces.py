"""Closure forces of the generic closed-loop core: the multipliers in our row convention
(from Pinocchio's LOCAL contact forces, or the minimum-norm ones of a generalised force),
the spatial forces they exert on the bodies, and the joint reaction wrenches of the tree.

Row conventions (those of :mod:`hexapod_pin.core.dynamics`): a point closure's three
multipliers are the force (N, world axes) that the body of ``frame2`` exerts on the body
of ``frame1`` at the joint; Pinocchio's are the same force in the LOCAL axes of anchor 1,
so ``lambda = R_c1 lambda_pin`` (``J_c = R_c1 J_pin``). A weld's six pair with its
``log6`` rows: ``lambda = Jlog6^-T lambda_pin`` (``J_c = Jlog6 J_pin``; at an assembled
configuration ``Jlog6 = I`` and they are the spatial force in anchor-1 axes).
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
import pinocchio as pin

from .closure_terms import ClosureFrames, closure_jacobian


def rows_from_pinocchio(frames: Sequence[ClosureFrames], n_rows: int, lam_pin: np.ndarray,
                        data: pin.Data) -> np.ndarray:
    """Pinocchio's LOCAL contact forces ``lam_pin`` (n_rows,) in our rows (see the module
    docstring); ``data`` holds the frame placements at the state of the solve."""
    out = np.empty(n_rows)
    for is_point, rows, f1, f2, _, _ in frames:
        if is_point:
            out[rows] = data.oMf[f1].rotation @ lam_pin[rows]
        else:
            jlog = pin.Jlog6(data.oMf[f2].actInv(data.oMf[f1]))
            out[rows] = np.linalg.solve(jlog.T, lam_pin[rows])
    return out


def closure_world_force(frame: ClosureFrames, lam: np.ndarray, data: pin.Data) -> pin.Force:
    """Spatial force (world frame, about the world origin) on body 1 of one closure, from
    its multipliers ``lam`` in our rows; ``data`` holds the frame placements."""
    _, _, f1, f2, _, _ = frame
    if frame.is_point:
        return pin.Force(lam, np.cross(data.oMf[f1].translation, lam))
    m21 = data.oMf[f2].actInv(data.oMf[f1])
    local = pin.Force(pin.Jlog6(m21).T @ lam)      # in anchor-1 frame
    return data.oMf[f1].act(local)


def closure_world_forces(frames: Sequence[ClosureFrames], multipliers: np.ndarray,
                         data: pin.Data) -> list[pin.Force]:
    """:func:`closure_world_force` of each closure, from the multipliers (n_rows,) in our
    rows; ``data`` holds the frame placements."""
    return [closure_world_force(frame, multipliers[frame.rows], data) for frame in frames]


def closure_linear_forces(model: pin.Model, data: pin.Data, frames: Sequence[ClosureFrames],
                          q: np.ndarray, multipliers: np.ndarray) -> np.ndarray:
    """The force part (n_closures, 3) (N, world axes) of :func:`closure_world_force` of
    each closure at ``q``: a point closure's is its three multipliers themselves (no
    kinematics needed), a weld's that of its spatial force (the frame placements of ``q``
    computed on ``data`` once, when there is a weld)."""
    out = np.empty((len(frames), 3))
    placed = False
    for k, frame in enumerate(frames):
        lam = multipliers[frame.rows]
        if frame.is_point:
            out[k] = lam
            continue
        if not placed:
            pin.framesForwardKinematics(model, data, q)
            placed = True
        out[k] = closure_world_force(frame, lam, data).linear
    return out


def joint_wrenches(model: pin.Model, data: pin.Data, frames: Sequence[ClosureFrames],
                   q: np.ndarray, v: np.ndarray, a: np.ndarray, multipliers: np.ndarray,
                   fext: Mapping[int, pin.Force] | None = None
                   ) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """Spatial force transmitted by every joint of the tree: ``data.f[j]`` after
    ``pin.rnea`` with the closure forces and ``fext`` applied, the force (N) and moment
    (N m) that the parent body exerts on the child body of joint ``j``, in the joint's
    LOCAL frame (see :meth:`hexapod_pin.core.dynamics.ClosedLoopDynamics.joint_wrenches`,
    which checks the inputs; none here). Runs on ``data``; returns the wrenches by joint
    name and the generalised force ``tau`` (nv,) that rnea needs with those forces."""
    pin.forwardKinematics(model, data, q)
    pin.updateFramePlacements(model, data)
    forces = pin.StdVec_Force()
    for _ in range(model.njoints):
        forces.append(pin.Force.Zero())
    for world, (_, _, _, _, j1, j2) in zip(closure_world_forces(frames, multipliers, data),
                                           frames):
        forces[j1] = forces[j1] + data.oMi[j1].actInv(world)
        forces[j2] = forces[j2] - data.oMi[j2].actInv(world)
    for joint, force in (fext or {}).items():
        forces[joint] = forces[joint] + force
    tau = pin.rnea(model, data, q, v, a, forces)
    out = {model.names[j]: data.f[j].vector.copy() for j in range(1, model.njoints)}
    return out, tau.copy()


class MultiplierConversion:
    """The multiplier conversions of one model, on their own ``pin.Data`` under a lock (a
    result may compute its multipliers on any thread, after its workspace moved on).

    Args:
        model: the tree.
        frames: the closures' :class:`~hexapod_pin.core.closure_terms.ClosureFrames`.
        n_rows: number of closure rows.
    """

    def __init__(self, model: pin.Model, frames: Sequence[ClosureFrames],
                 n_rows: int) -> None:
        self.model, self.frames, self.n_rows = model, frames, n_rows
        self._data = model.createData()
        self._lock = threading.Lock()

    def from_pinocchio(self, q: np.ndarray, lam_pin: np.ndarray,
                       jac: np.ndarray | None = None) -> np.ndarray:
        """Our row multipliers (n_rows,) from Pinocchio's LOCAL ones at ``q``. With ``jac``
        (Pinocchio's constraint Jacobian at ``q``), ``lam_pin`` is first replaced by the
        minimum-norm multipliers of the same generalised force, ``(J^T)^+ J^T lam_pin``
        (the rows differ from ours by rotations: the same minimum)."""
        if jac is not None:
            lam_pin, *_ = np.linalg.lstsq(jac.T, jac.T @ lam_pin, rcond=None)
        with self._lock:
            pin.framesForwardKinematics(self.model, self._data, q)
            return rows_from_pinocchio(self.frames, self.n_rows, lam_pin, self._data)

    def minimum_norm(self, q: np.ndarray, v: np.ndarray, acc: np.ndarray,
                     tau: np.ndarray) -> np.ndarray:
        """Minimum-norm multipliers in our rows, ``lambda = (J_c^T)^+ (M a + h - tau)`` at
        ``(q, v)``, from a fresh ``crba`` / ``nonLinearEffects`` / ``J_c``."""
        model, aux = self.model, self._data
        with self._lock:
            mass = pin.crba(model, aux, q)
            mass = np.triu(mass) + np.triu(mass, 1).T
            force = mass @ acc + pin.nonLinearEffects(model, aux, q, v) - tau
            pin.computeJointJacobians(model, aux, q)
            pin.updateFramePlacements(model, aux)
            jac = closure_jacobian(model, aux, self.frames, self.n_rows)
        value, *_ = np.linalg.lstsq(jac.T, force, rcond=None)
        return value


class LazyMultipliers:
    """A zero-argument callable giving multipliers computed on its first call by
    ``convert(*args)`` (one of :class:`MultiplierConversion`'s methods) and kept."""

    __slots__ = ("args", "convert", "value")

    def __init__(self, convert: Callable[..., np.ndarray], *args: Any) -> None:
        self.convert, self.args = convert, args
        self.value: np.ndarray | None = None

    def __call__(self) -> np.ndarray:
        if self.value is None:
            self.value = self.convert(*self.args)
        return self.value
