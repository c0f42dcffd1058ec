"""The measurement models of the calibration: residuals and their analytic Jacobians.

Frames: the robot's world ``W``, the platform ``P``, the instrument ``I`` (its pose in
``W`` is a parameter) and the target ``T`` (its pose in ``P`` is a parameter); a measured
pose is the pose of ``T`` in ``I``, a measured point a point fixed in ``T`` seen in ``I``.

Closure residual of chain ``i`` (one formula for both models). With the platform pose
``(t, R)`` in ``W``, the leg ``n_i = t + R p_i - c_i``, ``c_i = a_i + (q_i + o_i) u_i``::

    e_i = (|n_i|^2 - L_i^2) / (2 n_i . u_i)        (m, actuator units)

``e_i`` vanishes exactly where the leg closes, and it is the Newton step of the leg's
quadratic from the reading, so ``e_i = q_i(IK) - q_i`` to first order in the misclosure
(the difference is ``O(e^2 / L)``, 1e-10 m at a 10 um residual). It is used instead of the
inverse kinematics itself because it stays defined where the current estimate cannot
reach a measured pose, needs no IK branch, and is smooth. Its derivative at fixed ``u``
is ``g_i . dn_i - L_i dL_i / (n_i . u_i)`` with ``g_i = (n_i - e_i u_i) / (n_i . u_i)``
(at ``e = 0`` the implicit derivative ``dq_i = (n_i . dn_i - L_i dL_i) / (n_i . u_i)``);
a change ``du`` adds ``-((q + o) g_i + e_i n_i / (n_i . u_i)) . du``. A platform twist
``(dt, w)`` (world axes, platform origin) gives ``de_i = g_i . dt + (r_i x g_i) . w``,
``r_i = R p_i``: at ``e = 0`` the row of the workspace Jacobian.

* Pose model (:func:`pose_residuals`): the platform pose is ``T_WP = T_WI T_IT T_PT^-1``
  from the measured ``T_IT``; residual ``e`` per chain and measurement (N, 6).
* Point model (:func:`point_residuals`): the platform pose is the forward kinematics of
  the readings (:func:`~hexapod_pin.hexapod.geometry.closure_pose`, ``e = 0``); residual
  ``y - T_IW T_WP T_PT s_j`` (measured minus predicted, instrument frame, m) per point;
  its Jacobian by implicit differentiation, ``twist = -A^-1 de/dtheta`` with ``A`` the
  ``de/dtwist`` above.

Jacobians are (rows, 66) over every parameter of :mod:`.parameters`; rows are the
residuals flattened measurement-major.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.pose import euler_rates_matrix, rotation_from_rpy, rpy_from_rotation, skew
from ..errors import AssemblyError
from ..hexapod.geometry import ChainGeometry, closure_pose
from .parameters import INSTRUMENT, N_CHAIN, N_PARAMETERS, TARGET, Frames, ParameterModel


@dataclass(frozen=True)
class Legs:
    """The legs of N measurements at a platform pose (world frame).

    Attributes:
        legs: ``n`` (N, 6, 3) m.
        arms: ``r = R p`` (N, 6, 3) m.
        e: residual (N, 6) m.
        dot: ``n . u`` (N, 6) m^2 / m.
        grad: ``g`` (N, 6, 3).
    """

    legs: np.ndarray
    arms: np.ndarray
    e: np.ndarray
    dot: np.ndarray
    grad: np.ndarray


def legs_at(chains: ChainGeometry, rot: np.ndarray, trans: np.ndarray, q: np.ndarray) -> Legs:
    """The legs for platform rotations ``rot`` (N, 3, 3), translations ``trans`` (N, 3) and
    readings ``q`` (N, 6) on the chain geometry ``chains``."""
    legs, arms = chains.legs(rot, trans, q)
    dot = np.einsum("nia,ia->ni", legs, chains.line_directions)
    e = (np.einsum("nia,nia->ni", legs, legs) - chains.leg_lengths ** 2) / (2.0 * dot)
    grad = (legs - e[..., None] * chains.line_directions[None]) / dot[..., None]
    return Legs(legs, arms, e, dot, grad)


def chain_jacobian(params: ParameterModel, theta: np.ndarray, chains: ChainGeometry,
                   rot: np.ndarray,
                   q: np.ndarray, lg: Legs) -> np.ndarray:
    """``de/d(chain parameters)`` at a fixed platform pose, (N, 6, 9): residual ``e_i``
    depends on chain ``i``'s nine parameters only."""
    u = chains.line_directions
    out = np.empty(lg.e.shape + (N_CHAIN,))
    v = params.basis                                    # (6, 2, 3)
    g = lg.grad
    out[..., 0] = -np.einsum("nia,ia->ni", g, v[:, 0])
    out[..., 1] = -np.einsum("nia,ia->ni", g, v[:, 1])
    # du/dt_k = (I - u u^T) v_k / |w|
    norms = params.direction_norms(theta)
    du_vec = -((q + chains.sensor_offsets)[..., None] * g
               + (lg.e / lg.dot)[..., None] * lg.legs)          # de/du (N, 6, 3)
    for k in range(2):
        vk = v[:, k]
        dudt = (vk - np.sum(u * vk, axis=1)[:, None] * u) / norms[:, None]
        out[..., 2 + k] = np.einsum("nia,ia->ni", du_vec, dudt)
    out[..., 4] = -np.einsum("nia,ia->ni", g, u)
    out[..., 5] = -chains.leg_lengths / lg.dot
    out[..., 6:9] = np.einsum("nia,nab->nib", g, rot)
    return out


def twist_jacobian(lg: Legs) -> np.ndarray:
    """``de/d(platform twist)`` (N, 6, 6): rows ``[g_i, r_i x g_i]``."""
    return np.concatenate([lg.grad, np.cross(lg.arms, lg.grad)], axis=2)


def scatter_chains(block: np.ndarray) -> np.ndarray:
    """The (N, 6, 9) chain blocks placed into (N, 6, 66) rows (zeros elsewhere)."""
    n = block.shape[0]
    out = np.zeros((n, 6, N_PARAMETERS))
    for i in range(6):
        out[:, i, N_CHAIN * i:N_CHAIN * (i + 1)] = block[:, i]
    return out


def platform_from_measured(params: ParameterModel, theta: np.ndarray,
                           poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Platform rotations (N, 3, 3) and translations (N, 3) in the world for measured
    target poses (N, 6) in the instrument frame: ``T_WP = T_WI T_IT T_PT^-1``."""
    fr = params.frames(theta)
    r_wt = fr.instrument_rotation @ rotation_from_rpy(poses[:, 3:])
    t_wt = poses[:, :3] @ fr.instrument_rotation.T + fr.instrument_translation
    rot = r_wt @ fr.target_rotation.T
    trans = t_wt - rot @ fr.target_translation
    return rot, trans


def pose_residuals(params: ParameterModel, theta: np.ndarray, poses: np.ndarray,
                   q: np.ndarray,
                   with_jacobian: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
    """Pose model: closure residuals (N, 6) (m) and, with ``with_jacobian``, their
    Jacobian (6N, 66).

    Args:
        params: the parameter model.
        theta: deviations (66,).
        poses: measured target poses in the instrument frame (N, 6) (m, rad).
        q: actuator readings (N, 6) (m).
    """
    chains = params.chains(theta)
    rot, trans = platform_from_measured(params, theta, poses)
    lg = legs_at(chains, rot, trans, q)
    if not with_jacobian:
        return lg.e, None
    jac = scatter_chains(chain_jacobian(params, theta, chains, rot, q, lg))
    dtw = twist_jacobian(lg)                                    # (N, 6, 6)
    inst, targ = params.frame_poses(theta)
    # instrument: dt moves the platform; d(rpy) turns it about the instrument origin
    w_i = euler_rates_matrix(inst[3:])                          # (3, 3)
    lever = trans - inst[:3]                                    # (N, 3)
    jac[..., INSTRUMENT:INSTRUMENT + 3] = dtw[..., :3]
    turn = np.concatenate([-skew(lever) @ w_i, np.broadcast_to(w_i, lever.shape + (3,))],
                          axis=1)                               # (N, 6, 3) twist / d(rpy)
    jac[..., INSTRUMENT + 3:TARGET] = dtw @ turn
    # target: dt_PT moves the platform by -R dt; d(rpy_PT) turns it about the target origin
    jac[..., TARGET:TARGET + 3] = -dtw[..., :3] @ rot
    w_t = rot @ euler_rates_matrix(targ[3:])                    # (N, 3, 3): w = R E d(rpy)
    arm_t = rot @ params.frames(theta).target_translation       # (N, 3)
    turn_t = np.concatenate([-skew(arm_t) @ w_t, -w_t], axis=1)
    jac[..., TARGET + 3:] = dtw @ turn_t
    return lg.e, jac.reshape(-1, N_PARAMETERS)


class PointModel:
    """Point model: residuals of measured target points against the forward kinematics.

    Args:
        params: the parameter model.
        points: measured points in the instrument frame (N, M, 3) (m), ``M`` = 1..3.
        target_points: the points in the target frame (M, 3) (m).
        q: actuator readings (N, 6) (m).
        start_poses: platform poses (N, 6) in the world where the forward kinematics
            starts (the last solutions are kept and reused as the next starts).
    """

    def __init__(self, params: ParameterModel, points: np.ndarray, target_points: np.ndarray,
                 q: np.ndarray, start_poses: np.ndarray):
        self.params = params
        self.points = points
        self.target_points = target_points
        self.q = q
        self.starts = np.array(start_poses, dtype=float)

    def platform_poses(self, chains: ChainGeometry) -> np.ndarray:
        """Forward kinematics of every reading on ``chains`` (N, 6), from the kept starts.

        Raises:
            AssemblyError: Newton's method fails on a measurement (which one is named).
        """
        out = np.empty_like(self.starts)
        for k in range(self.q.shape[0]):
            pose = closure_pose(chains, self.q[k], self.starts[k])
            if pose is None:
                raise AssemblyError(f"forward kinematics of measurement {k} (readings "
                                    f"{self.q[k]}) does not converge on the current "
                                    "estimate", float("nan"), 0)
            out[k] = pose
        self.starts = out
        return out

    def predicted(self, theta: np.ndarray,
                  platform: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Predicted points in the instrument frame (N, M, 3), the world points (N, M, 3)
        and the platform rotations (N, 3, 3) at platform poses ``platform`` (N, 6)."""
        fr = self.params.frames(theta)
        rot = rotation_from_rpy(platform[:, 3:])
        in_platform = self.target_points @ fr.target_rotation.T + fr.target_translation
        world = platform[:, None, :3] + np.einsum("nab,mb->nma", rot, in_platform)
        pred = (world - fr.instrument_translation) @ fr.instrument_rotation
        return pred, world, rot

    def residuals(self, theta: np.ndarray,
                  with_jacobian: bool = True) -> tuple[np.ndarray, np.ndarray | None]:
        """Residuals (N, M, 3) (m, measured minus predicted) and their Jacobian (3NM, 66)."""
        chains = self.params.chains(theta)
        platform = self.platform_poses(chains)
        pred, world, rot = self.predicted(theta, platform)
        res = self.points - pred
        if not with_jacobian:
            return res, None
        return res, self.jacobian(theta, chains, platform, world, rot)

    def jacobian(self, theta: np.ndarray, chains: ChainGeometry, platform: np.ndarray,
                 world: np.ndarray, rot: np.ndarray) -> np.ndarray:
        """``d(residual)/d(theta)`` (3NM, 66) at the forward-kinematics poses."""
        params = self.params
        fr = params.frames(theta)
        lg = legs_at(chains, rot, platform[:, :3], self.q)
        e_theta = scatter_chains(chain_jacobian(params, theta, chains, rot, self.q, lg))
        twist = -np.linalg.solve(twist_jacobian(lg), e_theta)      # (N, 6, 66)
        n, m = self.points.shape[:2]
        rel = world - platform[:, None, :3]                       # R s_P (N, M, 3)
        # world point: d s_W = dt + w x (R s_P) + R d s_P
        d_world = (twist[:, None, :3, :]
                   - np.einsum("nmab,nbk->nmak", skew(rel), twist[:, 3:, :]))
        inst, targ = params.frame_poses(theta)
        s_t = self.target_points @ fr.target_rotation.T               # R_PT s (M, 3)
        d_world[..., TARGET:TARGET + 3] += rot[:, None]
        w_t = euler_rates_matrix(targ[3:])
        d_world[..., TARGET + 3:] += np.einsum("nab,mbc->nmac", rot, -skew(s_t) @ w_t)
        # instrument frame: d(R_WI^T (s_W - t_WI)) = R_WI^T (d s_W - dt_WI - w_I x (s_W - t_WI))
        d_world[..., INSTRUMENT:INSTRUMENT + 3] -= np.eye(3)
        w_i = euler_rates_matrix(inst[3:])
        lever = world - fr.instrument_translation
        d_world[..., INSTRUMENT + 3:TARGET] += skew(lever) @ w_i
        d_pred = np.einsum("ba,nmbk->nmak", fr.instrument_rotation, d_world)
        return -d_pred.reshape(3 * n * m, N_PARAMETERS)


def measured_poses(rot: np.ndarray, trans: np.ndarray, frames: Frames) -> np.ndarray:
    """Target poses in the instrument frame (N, 6) of platform poses in the world
    (``T_IT = T_WI^-1 T_WP T_PT``), rotations (N, 3, 3), translations (N, 3)."""
    r_it = frames.instrument_rotation.T @ rot @ frames.target_rotation
    t_wt = trans + rot @ frames.target_translation
    t_it = (t_wt - frames.instrument_translation) @ frames.instrument_rotation
    return np.concatenate([t_it, rpy_from_rotation(r_it)], axis=1)


def closure_noise(params: ParameterModel, theta: np.ndarray, poses: np.ndarray, q: np.ndarray,
                  noise: tuple[float, float, float]) -> np.ndarray:
    """Standard deviation (N, 6) (m) of the pose model's residuals ``e`` caused by
    measurement noise, to first order: isotropic noise of the measured target position
    (``noise[0]``, m) and orientation (``noise[1]``, rad) and of the readings
    (``noise[2]``, m)::

        s_i^2 = sigma_q^2 (g_i . u_i)^2 + sigma_p^2 |g_i|^2
                + sigma_r^2 |(P_i - t_target) x g_i|^2

    with ``P_i`` the platform joint and ``t_target`` the target origin in the world (a
    target rotation turns the platform about the target origin)."""
    chains = params.chains(theta)
    rot, trans = platform_from_measured(params, theta, poses)
    lg = legs_at(chains, rot, trans, q)
    target_origin = trans + rot @ params.frames(theta).target_translation
    lever = trans[:, None, :] + lg.arms - target_origin[:, None, :]
    sp, sr, sq = noise
    var = (sq ** 2 * np.einsum("nia,ia->ni", lg.grad, chains.line_directions) ** 2
           + sp ** 2 * np.einsum("nia,nia->ni", lg.grad, lg.grad)
           + sr ** 2 * np.sum(np.cross(lever, lg.grad) ** 2, axis=2))
    return np.sqrt(var)
