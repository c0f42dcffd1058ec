"""Peer 3: the rail-driven hexapod in plain numpy ("what a student would write").

Independent of hexapod_pin and of Pinocchio: closed-form inverse kinematics, the
workspace Jacobian, a Newton forward kinematics, and a Newton-Euler inverse dynamics
of the six thin legs and the platform, every function vectorised over N states.

Conventions (those of hexapod_pin, SI units):

* rail k: midpoint ``m_k = R (cos a_k, sin a_k, 0)``, direction ``u_k = (-sin a_k, cos a_k, 0)``,
  ``a_k = 90 deg + 120 deg k``; carriage i on rail ``k = i // 2`` at ``c_i = m_k + q_i u_k``;
* pose ``(x, y, z, roll, pitch, yaw)``, ``R = Rz(yaw) Ry(pitch) Rx(roll)``; twist ``(v, w)`` of
  the platform origin (= its centre of mass), world axes; wrench ``(f, m)`` on the platform,
  world axes, moment about the platform origin; gravity ``-g z``;
* ``tau_i`` is the force on carriage i along ``+u_k``.

The dynamics (derivation in benchmarks/README.md): a leg is a thin uniform rod with zero
axial inertia between its universal joint (on the carriage) and its spherical joint (on
the platform). Its axial moment equation shows that the universal joint then transmits no
torque, so each leg only exchanges forces with the carriage (``F_c``, carriage on leg) and
with the platform (``F_P``, platform on leg). With ``n = P - c`` (length L), the leg's
Newton and Euler equations give ``F_P + F_c = m_l (a_G - g)`` and the transverse part of
``F_P - F_c = (m_l / 6) n_ddot``; the six axial tensions ``T_i`` follow from the platform's
Newton-Euler equations (a 6 x 6 solve), then ``tau_i = m_c q_ddot_i + u_k . F_c``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

RAIL_OF = np.array([0, 0, 1, 1, 2, 2])
HOME_BRANCH = np.array([-1.0, 1.0, -1.0, 1.0, -1.0, 1.0])


@dataclass(frozen=True)
class Params:
    """Geometry and inertia in carriage order (every array has 6 rows)."""

    mids: np.ndarray        # (6, 3) rail midpoint of each carriage (m)
    dirs: np.ndarray        # (6, 3) rail direction u_k of each carriage
    points: np.ndarray      # (6, 3) platform point p_k of each carriage, platform frame (m)
    leg_length: float       # (m)
    carriage_mass: float    # (kg)
    leg_mass: float         # (kg)
    platform_mass: float    # (kg)
    platform_inertia: np.ndarray  # (3,) principal moments at the origin (kg m^2)
    gravity: float          # (m/s^2), along -z


def params_from_geometry(geometry) -> Params:
    """Params from a ``HexapodGeometry`` (or any object with the same fields)."""
    a = np.pi / 2 + 2 * np.pi / 3 * np.arange(3)
    mids = geometry.rail_radius * np.stack([np.cos(a), np.sin(a), np.zeros(3)], 1)
    dirs = np.stack([-np.sin(a), np.cos(a), np.zeros(3)], 1)
    pts = geometry.platform_radius * np.stack([np.cos(a), np.sin(a), np.zeros(3)], 1)
    return Params(mids[RAIL_OF], dirs[RAIL_OF], pts[RAIL_OF], float(geometry.leg_length),
                  float(geometry.carriage_mass), float(geometry.leg_mass),
                  float(geometry.platform_mass), np.array(geometry.platform_inertia, float),
                  float(geometry.gravity))


def rotation(rpy: np.ndarray) -> np.ndarray:
    """``Rz(yaw) Ry(pitch) Rx(roll)``, (N, 3) -> (N, 3, 3)."""
    cr, sr = np.cos(rpy[:, 0]), np.sin(rpy[:, 0])
    cp, sp = np.cos(rpy[:, 1]), np.sin(rpy[:, 1])
    cy, sy = np.cos(rpy[:, 2]), np.sin(rpy[:, 2])
    return np.stack([
        np.stack([cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr], -1),
        np.stack([sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr], -1),
        np.stack([-sp, cp * sr, cp * cr], -1)], -2)


def _dot(a, b):
    return np.einsum("...i,...i->...", a, b)


def _platform_points(p: Params, poses):
    rot = rotation(poses[:, 3:])
    r = np.einsum("nij,kj->nki", rot, p.points)          # R p_k, (N, 6, 3)
    return rot, r, poses[:, None, :3] + r                 # P = t + R p_k


def inverse_kinematics(p: Params, poses: np.ndarray, branch=HOME_BRANCH) -> np.ndarray:
    """Carriage positions (N, 6) for poses (N, 6); NaN where a leg cannot reach."""
    _, _, tips = _platform_points(p, poses)
    d = tips - p.mids
    along = _dot(d, p.dirs)
    disc = p.leg_length ** 2 - (_dot(d, d) - along ** 2)
    with np.errstate(invalid="ignore"):
        return along + branch * np.sqrt(disc)


def jacobian(p: Params, poses: np.ndarray, q: np.ndarray | None = None) -> np.ndarray:
    """``J`` (N, 6, 6) with ``qdot = J @ twist``: row i is ``[n_i, r_i x n_i] / (n_i . u_i)``."""
    if q is None:
        q = inverse_kinematics(p, poses)
    _, r, tips = _platform_points(p, poses)
    n = tips - (p.mids + q[..., None] * p.dirs)
    nu = _dot(n, p.dirs)[..., None]
    return np.concatenate([n / nu, np.cross(r, n) / nu], axis=-1)


def tree_coordinates(p: Params, poses: np.ndarray):
    """Closed-form tree coordinates for poses (N, 6): carriages, u_a, u_b, each (N, 6).

    Carriage frame axes: x = u_k, y = z x u_k, z = world z; the leg axis is
    ``Rx(u_a) Ry(u_b) e_z`` in that frame, so ``u_b = asin(nhat . x)``,
    ``u_a = atan2(-nhat . y, nhat . z)``.
    """
    q = inverse_kinematics(p, poses)
    _, _, tips = _platform_points(p, poses)
    unit = (tips - (p.mids + q[..., None] * p.dirs)) / p.leg_length
    lateral = np.cross([0.0, 0.0, 1.0], p.dirs)
    u_b = np.arcsin(np.clip(_dot(unit, p.dirs), -1.0, 1.0))
    u_a = np.arctan2(-_dot(unit, lateral), unit[..., 2])
    return q, u_a, u_b


def rotation_one(rpy) -> np.ndarray:
    """``Rz(yaw) Ry(pitch) Rx(roll)`` of one ``rpy`` (3,) -> (3, 3) (scalar math)."""
    cr, sr = math.cos(rpy[0]), math.sin(rpy[0])
    cp, sp = math.cos(rpy[1]), math.sin(rpy[1])
    cy, sy = math.cos(rpy[2]), math.sin(rpy[2])
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


def tree_coordinates_one(p: Params, pose: np.ndarray):
    """:func:`tree_coordinates` of one pose (6,): ``(q, u_a, u_b, R)``, lean for N = 1."""
    rot = rotation_one(pose[3:])
    tips = pose[:3] + p.points @ rot.T
    d = tips - p.mids
    along = (d * p.dirs).sum(1)
    q = along + HOME_BRANCH * np.sqrt(p.leg_length ** 2 - ((d * d).sum(1) - along ** 2))
    unit = (d - q[:, None] * p.dirs) / p.leg_length
    # lateral axis z x u = (-u_y, u_x, 0)
    dy = -unit[:, 0] * p.dirs[:, 1] + unit[:, 1] * p.dirs[:, 0]
    u_b = np.arcsin(np.clip((unit * p.dirs).sum(1), -1.0, 1.0))
    u_a = np.arctan2(-dy, unit[:, 2])
    return q, u_a, u_b, rot


def euler_rates(rpy: np.ndarray) -> np.ndarray:
    """``E`` (N, 3, 3) with ``w = E @ d(rpy)/dt`` for ``R = Rz Ry Rx``."""
    cp, sp = np.cos(rpy[:, 1]), np.sin(rpy[:, 1])
    cy, sy = np.cos(rpy[:, 2]), np.sin(rpy[:, 2])
    zero, one = np.zeros_like(cp), np.ones_like(cp)
    return np.stack([np.stack([cy * cp, -sy, zero], -1),
                     np.stack([sy * cp, cy, zero], -1),
                     np.stack([-sp, zero, one], -1)], -2)


def forward_kinematics(p: Params, q: np.ndarray, guess: np.ndarray, tol: float = 1e-13,
                       max_iter: int = 30):
    """Pose (N, 6) from carriage positions (N, 6) by Newton on the closed-form IK.

    Returns ``(poses, iterations, max_residual)``; the residual is ``max |IK(pose) - q|`` (m).
    """
    poses = np.array(np.broadcast_to(guess, q.shape), dtype=float)
    res = inverse_kinematics(p, poses) - q
    norm = np.max(np.abs(res), axis=1)
    for it in range(max_iter + 1):
        err = float(np.max(norm))
        if err <= tol or it == max_iter:
            return poses, it, err
        jac = jacobian(p, poses)
        jac[..., 3:] = jac[..., 3:] @ euler_rates(poses[:, 3:])
        step = np.linalg.solve(jac, res[..., None])[..., 0]
        alpha = np.ones(len(poses))
        for _ in range(20):       # halve the step where a leg would not reach or res grows
            trial = poses - alpha[:, None] * step
            trial_res = inverse_kinematics(p, trial) - q
            trial_norm = np.max(np.abs(trial_res), axis=1)
            bad = ~(trial_norm < norm) & (norm > tol)
            if not bad.any():
                break
            alpha[bad] *= 0.5
        ok = ~bad[:, None]
        poses, res = np.where(ok, trial, poses), np.where(ok, trial_res, res)
        norm = np.max(np.abs(res), axis=1)
    return poses, max_iter, err


def _leg_terms(p: Params, poses, twists, twist_dots):
    """Kinematics of the legs up to accelerations, and the known parts of the leg forces."""
    rot, r, tips = _platform_points(p, poses)
    v, w = twists[:, None, :3], twists[:, None, 3:]
    vd, wd = twist_dots[:, None, :3], twist_dots[:, None, 3:]
    tip_vel = v + np.cross(w, r)
    tip_acc = vd + np.cross(wd, r) + np.cross(w, np.cross(w, r))
    d = tips - p.mids
    along = _dot(d, p.dirs)
    q = along + HOME_BRANCH * np.sqrt(p.leg_length ** 2 - (_dot(d, d) - along ** 2))
    n = tips - (p.mids + q[..., None] * p.dirs)             # leg vector, |n| = L
    nu = _dot(n, p.dirs)
    qd = _dot(n, tip_vel) / nu
    n_dot = tip_vel - qd[..., None] * p.dirs
    qdd = (_dot(n, tip_acc) + _dot(n_dot, n_dot)) / nu
    n_ddot = tip_acc - qdd[..., None] * p.dirs
    nhat = n / p.leg_length
    gvec = np.array([0.0, 0.0, -p.gravity])
    a_centre = 0.5 * (qdd[..., None] * p.dirs + tip_acc)
    force_sum = p.leg_mass * (a_centre - gvec)                     # F_P + F_c
    transverse = n_ddot - nhat * _dot(nhat, n_ddot)[..., None]
    diff = (p.leg_mass / 6.0) * transverse                          # transverse part of F_P - F_c
    return rot, r, q, qd, qdd, nhat, force_sum, diff, gvec


def inverse_dynamics(p: Params, poses, twists, twist_dots, wrenches=None) -> np.ndarray:
    """Actuator forces (N, 6) (N) for a platform motion and an external wrench (N, 6)."""
    poses, twists, twist_dots = (np.atleast_2d(np.asarray(a, float)) for a in
                                 (poses, twists, twist_dots))
    rot, r, _, _, qdd, nhat, force_sum, diff, gvec = _leg_terms(p, poses, twists, twist_dots)
    known = 0.5 * (force_sum + diff)                      # F_P = known + T nhat
    inertia = np.einsum("nij,j,nkj->nik", rot, p.platform_inertia, rot)
    w, vd, wd = twists[:, 3:], twist_dots[:, :3], twist_dots[:, 3:]
    rhs_f = p.platform_mass * (gvec - vd) - known.sum(1)
    rhs_m = -(np.einsum("nij,nj->ni", inertia, wd)
              + np.cross(w, np.einsum("nij,nj->ni", inertia, w))) - np.cross(r, known).sum(1)
    if wrenches is not None:
        wrenches = np.atleast_2d(np.asarray(wrenches, float))
        rhs_f = rhs_f + wrenches[:, :3]
        rhs_m = rhs_m + wrenches[:, 3:]
    lines = np.concatenate([nhat, np.cross(r, nhat)], axis=-1)    # (N, 6 legs, 6)
    tension = np.linalg.solve(np.swapaxes(lines, 1, 2),
                              np.concatenate([rhs_f, rhs_m], -1)[..., None])[..., 0]
    f_platform = known + tension[..., None] * nhat
    f_carriage = force_sum - f_platform                     # carriage on leg
    return p.carriage_mass * qdd + _dot(f_carriage, p.dirs) - p.carriage_mass * (gvec @ p.dirs.T)


def static_forces(p: Params, poses, wrenches=None) -> np.ndarray:
    """Actuator forces (N, 6) holding the platform still at ``poses`` under gravity + wrench."""
    poses = np.atleast_2d(np.asarray(poses, float))
    zero = np.zeros_like(poses)
    return inverse_dynamics(p, poses, zero, zero, wrenches)


def forward_dynamics(p: Params, poses, twists, forces, wrenches=None):
    """Platform acceleration and carriage accelerations for actuator forces.

    Inverse dynamics is affine in ``twist_dot``: ``tau = A twist_dot + b``; ``b`` and the
    columns of ``A`` come from seven inverse-dynamics evaluations (vectorised), then
    ``twist_dot = A^-1 (tau - b)``.

    Returns:
        ``(twist_dot (N, 6), qddot (N, 6))``.
    """
    poses, twists, forces = (np.atleast_2d(np.asarray(a, float)) for a in
                             (poses, twists, forces))
    n = poses.shape[0]
    accs = np.zeros((7, n, 6))
    accs[np.arange(1, 7), :, np.arange(6)] = 1.0
    rep = lambda a: np.broadcast_to(a, (7,) + a.shape).reshape(7 * n, 6)  # noqa: E731
    wr = None if wrenches is None else rep(np.atleast_2d(np.asarray(wrenches, float)))
    tau = inverse_dynamics(p, rep(poses), rep(twists), accs.reshape(7 * n, 6), wr)
    tau = tau.reshape(7, n, 6)
    bias = tau[0]
    mass = np.swapaxes(tau[1:] - bias, 0, 1)            # (N, column j, row i)
    twist_dot = np.linalg.solve(np.swapaxes(mass, 1, 2), (forces - bias)[..., None])[..., 0]
    _, _, _, _, qdd, *_ = _leg_terms(p, poses, twists, twist_dot)
    return twist_dot, qdd


def _exp_so3(phi: np.ndarray) -> np.ndarray:
    """Rotation matrices exp([phi]x), (N, 3) -> (N, 3, 3) (Rodrigues)."""
    angle = np.linalg.norm(phi, axis=-1)[:, None, None]
    k = np.zeros(phi.shape[:1] + (3, 3))
    k[:, 0, 1], k[:, 0, 2], k[:, 1, 2] = -phi[:, 2], phi[:, 1], -phi[:, 0]
    k[:, 1, 0], k[:, 2, 0], k[:, 2, 1] = phi[:, 2], -phi[:, 1], phi[:, 0]
    small = angle < 1e-8
    safe = np.where(small, 1.0, angle)
    a = np.where(small, 1.0 - angle ** 2 / 6, np.sin(safe) / safe)
    b = np.where(small, 0.5 - angle ** 2 / 24, (1 - np.cos(safe)) / safe ** 2)
    return np.eye(3) + a * k + b * (k @ k)


def rpy_from_rotation(rot: np.ndarray) -> np.ndarray:
    """(N, 3, 3) -> (N, 3) roll, pitch, yaw (pitch in [-pi/2, pi/2])."""
    pitch = np.arctan2(-rot[:, 2, 0], np.hypot(rot[:, 0, 0], rot[:, 1, 0]))
    return np.stack([np.arctan2(rot[:, 2, 1], rot[:, 2, 2]), pitch,
                     np.arctan2(rot[:, 1, 0], rot[:, 0, 0])], -1)


def step(p: Params, poses, twists, forces, dt: float, wrenches=None):
    """One semi-implicit Euler step (MuJoCo's ``Euler`` scheme) of the platform.

    ``twist+ = twist + dt twist_dot``; ``t+ = t + dt v+``; ``R+ = exp(dt [w+]x) R``.

    Returns:
        ``(poses+, twists+)``, each (N, 6).
    """
    twist_dot, _ = forward_dynamics(p, poses, twists, forces, wrenches)
    twists_new = twists + dt * twist_dot
    rot = _exp_so3(dt * twists_new[:, 3:]) @ rotation(poses[:, 3:])
    poses_new = np.concatenate([poses[:, :3] + dt * twists_new[:, :3], rpy_from_rotation(rot)], -1)
    return poses_new, twists_new
