"""Peer 2: the same closed-loop dynamics with direct Pinocchio calls, no hexapod_pin wrapper.

The Pinocchio model and its ``RigidConstraintModel`` closures are *built* by
``hexapod_pin.ClosedLoopModel`` (set-up only); everything a timed call does is a direct
``pinocchio`` call plus a numpy solve:

* inverse dynamics from a tree state: ``rnea`` (tree generalised forces) + closure
  Jacobian + the square solve ``rnea - J_w^T w = S^T tau + J_c^T lambda``;
* forward dynamics: ``constraintDynamics`` (proximal settings with ``mu = 0``: one exact
  Cholesky pass, Baumgarte gains 0), or ``crba`` + ``nonLinearEffects`` + a numpy KKT solve
  with the drift from ``getFrameClassicalAcceleration`` of the anchor frames;
* statics: ``computeGeneralizedGravity`` + the same reduction;
* a semi-implicit Euler step: ``constraintDynamics`` + ``integrate``.

Only point closures (``CONTACT_3D``) are handled. Conventions are Pinocchio's: ``q``, ``v``,
``a`` of the tree, the free-flyer velocity in the body frame.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

import numpy_hexapod as nh

LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


def cross3(a, b) -> np.ndarray:
    """``a x b`` of two 3-vectors (np.cross costs ~50 us per call on the benchmark machine)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                     a[0] * b[1] - a[1] * b[0]])


class RawPinocchio:
    """Direct-call routes on the tree and closures of a ``hexapod_pin.ClosedLoopModel``.

    Args:
        closed_loop: a ``ClosedLoopModel`` (only its model, closures and actuation are used).
        wrench_joint: name of a joint whose body receives an external wrench (``(f, m)``,
            world axes, moment about the joint origin), or None.
    """

    def __init__(self, closed_loop, wrench_joint: str | None = None):
        self.model = pin.Model(closed_loop.model)
        self.data = self.model.createData()
        if any(c.type != "point" for c in closed_loop.closures):
            raise ValueError("RawPinocchio handles point closures only")
        self.cms = pin.StdVec_RigidConstraintModel()
        for cm in closed_loop.constraint_models:
            self.cms.append(cm)
        self.cds = pin.StdVec_RigidConstraintData()
        for cm in self.cms:
            self.cds.append(cm.createData())
        pin.initConstraintDynamics(self.model, self.data, self.cms, self.cds)
        self.prox = pin.ProximalSettings(1e-12, 0.0, 1)
        self.redundant = False
        self.n_rows = 3 * len(self.cms)
        self.nv = self.model.nv
        self.actuated_v = np.asarray(closed_loop.actuated_v)
        self.selection = np.zeros((self.nv, len(self.actuated_v)))
        self.selection[self.actuated_v, np.arange(len(self.actuated_v))] = 1.0
        self.anchors = [(self.model.getFrameId(f"{c.name}/anchor1"),
                         self.model.getFrameId(f"{c.name}/anchor2"))
                        for c in closed_loop.closures]
        self.square = self.nv == len(self.actuated_v) + self.n_rows
        self.wrench_joint = None
        if wrench_joint is not None:
            jid = self.model.getJointId(wrench_joint)
            self.wrench_joint = jid
            joint = self.model.joints[jid]
            self.wrench_v = slice(joint.idx_v, joint.idx_v + joint.nv)
        self._tau = np.zeros(self.nv)

    def set_redundant(self, redundant: bool) -> None:
        """Redundant closures: ``constraintDynamics`` needs a proximal ``mu > 0`` (with
        ``mu = 0`` it returns NaN) and the KKT solves become least squares."""
        self.redundant = redundant
        self.prox = (pin.ProximalSettings(1e-12, 1e-2, 200) if redundant
                     else pin.ProximalSettings(1e-12, 0.0, 1))

    # -- pieces -----------------------------------------------------------------------
    def wrench_generalised(self, wrench) -> np.ndarray:
        """Generalised force (nv,) of a world wrench on the free-flyer body (body axes)."""
        out = np.zeros(self.nv)
        if wrench is not None and self.wrench_joint is not None:
            rot = self.data.oMi[self.wrench_joint].rotation
            out[self.wrench_v] = np.concatenate([rot.T @ wrench[:3], rot.T @ wrench[3:]])
        return out

    def closure_jacobian(self) -> np.ndarray:
        """``d(p1 - p2)/dv`` (n_rows, nv), world axes (after ``computeJointJacobians``)."""
        model, data = self.model, self.data
        out = np.empty((self.n_rows, self.nv))
        for k, (f1, f2) in enumerate(self.anchors):
            out[3 * k:3 * k + 3] = (pin.getFrameJacobian(model, data, f1, LWA)[:3]
                                    - pin.getFrameJacobian(model, data, f2, LWA)[:3])
        return out

    def closure_drift(self, q, v) -> np.ndarray:
        """``gamma = Jdot v`` (n_rows,): difference of the anchors' classical accelerations."""
        model, data = self.model, self.data
        pin.forwardKinematics(model, data, q, v, np.zeros(self.nv))
        out = np.empty(self.n_rows)
        for k, (f1, f2) in enumerate(self.anchors):
            out[3 * k:3 * k + 3] = (
                pin.getFrameClassicalAcceleration(model, data, f1, LWA).linear
                - pin.getFrameClassicalAcceleration(model, data, f2, LWA).linear)
        return out

    def reduce(self, generalised: np.ndarray, jac: np.ndarray) -> np.ndarray:
        """Actuator forces from ``generalised = S^T tau + J_c^T lambda`` (nv equations)."""
        mat = np.hstack([self.selection, jac.T])
        if self.square and not self.redundant:
            return np.linalg.solve(mat, generalised)[:self.selection.shape[1]]
        return np.linalg.lstsq(mat, generalised, rcond=None)[0][:self.selection.shape[1]]

    # -- routes -----------------------------------------------------------------------
    def inverse(self, q, v, a, wrench=None) -> np.ndarray:
        """Actuator forces from a consistent tree state: ``rnea`` + Jacobian + solve."""
        tau = pin.rnea(self.model, self.data, q, v, a)
        pin.computeJointJacobians(self.model, self.data, q)
        pin.updateFramePlacements(self.model, self.data)
        return self.reduce(tau - self.wrench_generalised(wrench), self.closure_jacobian())

    def static(self, q, wrench=None) -> np.ndarray:
        """Actuator forces holding ``q`` at rest: ``computeGeneralizedGravity`` + solve."""
        grav = pin.computeGeneralizedGravity(self.model, self.data, q)
        pin.computeJointJacobians(self.model, self.data, q)
        pin.updateFramePlacements(self.model, self.data)
        return self.reduce(grav - self.wrench_generalised(wrench), self.closure_jacobian())

    def tree_forces(self, actuator_forces, wrench=None) -> np.ndarray:
        """``S^T tau + J_w^T w`` (nv,) (needs the joint placements of the current q)."""
        out = self.selection @ actuator_forces
        if wrench is not None:
            out += self.wrench_generalised(wrench)
        return out

    def forward(self, q, v, actuator_forces, wrench=None) -> np.ndarray:
        """Tree acceleration (nv,) by ``constraintDynamics`` (exact, mu = 0)."""
        if wrench is not None:
            pin.forwardKinematics(self.model, self.data, q)
        tau = self.tree_forces(actuator_forces, wrench)
        return pin.constraintDynamics(self.model, self.data, q, v, tau, self.cms, self.cds,
                                      self.prox)

    def forward_kkt(self, q, v, actuator_forces, wrench=None) -> np.ndarray:
        """Tree acceleration (nv,) by ``crba`` + ``nonLinearEffects`` + a numpy KKT solve."""
        model, data = self.model, self.data
        mass = pin.crba(model, data, q)
        mass = np.triu(mass) + np.triu(mass, 1).T
        bias = pin.nonLinearEffects(model, data, q, v)
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        jac = self.closure_jacobian()
        tau = self.tree_forces(actuator_forces, wrench)
        gamma = self.closure_drift(q, v)
        n = self.nv
        kkt = np.zeros((n + self.n_rows, n + self.n_rows))
        kkt[:n, :n], kkt[:n, n:], kkt[n:, :n] = mass, jac.T, jac
        rhs = np.concatenate([tau - bias, -gamma])
        if self.redundant:
            return np.linalg.lstsq(kkt, rhs, rcond=None)[0][:n]
        return np.linalg.solve(kkt, rhs)[:n]

    def step(self, q, v, actuator_forces, dt: float, wrench=None):
        """Semi-implicit Euler: ``v+ = v + dt a``, ``q+ = integrate(q, dt v+)``."""
        acc = self.forward(q, v, actuator_forces, wrench)
        v_new = v + dt * acc
        return pin.integrate(self.model, q, dt * v_new), v_new

    def complete(self, q, known_v, known_values_v, known_values_a=None):
        """Tree v (and a) keeping the closures, given some coordinates (numpy solves:
        LU when the free columns of ``J_c`` are square, least squares otherwise)."""
        pin.computeJointJacobians(self.model, self.data, q)
        pin.updateFramePlacements(self.model, self.data)
        jac = self.closure_jacobian()
        free = np.setdiff1d(np.arange(self.nv), known_v)
        jac_free, jac_known = jac[:, free], jac[:, known_v]
        square = jac_free.shape[0] == jac_free.shape[1] and not self.redundant
        solve = (np.linalg.solve if square else
                 lambda m, b: np.linalg.lstsq(m, b, rcond=None)[0])
        v = np.zeros(self.nv)
        v[known_v] = known_values_v
        v[free] = solve(jac_free, -jac_known @ known_values_v)
        if known_values_a is None:
            return v, None
        gamma = self.closure_drift(q, v)
        a = np.zeros(self.nv)
        a[known_v] = known_values_a
        a[free] = solve(jac_free, -gamma - jac_known @ known_values_a)
        return v, a


class RawHexapod(RawPinocchio):
    """:class:`RawPinocchio` on a ``hexapod_pin.Hexapod``, with task-space state conversion.

    ``tree_state`` maps ``(pose, twist, twist_dot)`` to the Pinocchio tree ``(q, v, a)``:
    closed-form joint values (numpy), then velocity and acceleration completion through the
    closure Jacobian and drift (direct Pinocchio calls + numpy solves).
    """

    def __init__(self, robot):
        super().__init__(robot.model, wrench_joint="platform_joint")
        self.params = nh.params_from_geometry(robot.geometry)
        self.idx = robot.indices
        pv = self.idx.platform_v.start
        self.known_v = np.arange(pv, pv + 6)

    def configuration(self, pose) -> np.ndarray:
        """Tree q (nq,) for a pose (6,), closed form."""
        q = np.empty(self.model.nq)
        carriages, u_a, u_b, rot = nh.tree_coordinates_one(self.params, pose)
        q[self.idx.carriage_q], q[self.idx.u_a_q], q[self.idx.u_b_q] = carriages, u_a, u_b
        q[self.idx.platform_q] = np.concatenate([pose[:3], pin.Quaternion(rot).coeffs()])
        return q

    def tree_state(self, pose, twist, twist_dot=None):
        """Tree ``(q, v, a)`` for a platform state (``a`` None without ``twist_dot``)."""
        pose, twist = np.asarray(pose, float), np.asarray(twist, float)
        q = self.configuration(pose)
        rot = nh.rotation_one(pose[3:])
        v_ff = np.concatenate([rot.T @ twist[:3], rot.T @ twist[3:]])
        a_ff = None
        if twist_dot is not None:
            twist_dot = np.asarray(twist_dot, float)
            a_ff = np.concatenate([rot.T @ (twist_dot[:3] - cross3(twist[3:], twist[:3])),
                                   rot.T @ twist_dot[3:]])
        v, a = self.complete(q, self.known_v, v_ff, a_ff)
        return q, v, a

    def twist_dot_from_a(self, q, v, a) -> np.ndarray:
        """Platform ``twist_dot`` (world axes) from Pinocchio tree v and a."""
        quat = q[self.idx.platform_q][3:]
        rot = pin.Quaternion(quat[3], quat[0], quat[1], quat[2]).toRotationMatrix()
        vb, ab = v[self.idx.platform_v], a[self.idx.platform_v]
        lin, ang = rot @ vb[:3], rot @ vb[3:]
        return np.concatenate([rot @ ab[:3] + cross3(ang, lin), rot @ ab[3:]])

    def inverse_task(self, pose, twist, twist_dot, wrench=None) -> np.ndarray:
        """Actuator forces from a platform state: conversion + :meth:`inverse`."""
        q, v, a = self.tree_state(pose, twist, twist_dot)
        return self.inverse(q, v, a, wrench)


def pinocchio_calls_of_inverse(raw: RawPinocchio, q, v, a) -> None:
    """Exactly the Pinocchio calls one closed-loop ID from a platform state needs (no numpy
    solve, no closed form): closure Jacobian, closure drift, ``rnea``. Timing floor."""
    model, data = raw.model, raw.data
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    for f1, f2 in raw.anchors:
        pin.getFrameJacobian(model, data, f1, LWA)
        pin.getFrameJacobian(model, data, f2, LWA)
    pin.forwardKinematics(model, data, q, v, np.zeros(raw.nv))
    for f1, f2 in raw.anchors:
        pin.getFrameClassicalAcceleration(model, data, f1, LWA)
        pin.getFrameClassicalAcceleration(model, data, f2, LWA)
    pin.rnea(model, data, q, v, a)
