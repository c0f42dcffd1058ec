"""Kinematics of the rail-driven hexapod: closed forms, vectorised over poses.

Carriage i rides on rail ``k = i // 2``; it sits at ``c_i = m_k + q_i u_k`` and its
leg reaches the platform point ``P_k = t + R p_k`` (world). The leg vector is
``n_i = P_k - c_i`` and the loop closes when ``|n_i| = leg_length``.

Inverse kinematics is the quadratic along the rail
``q_i = u_k . d_i + s_i sqrt(leg_length^2 - |d_i - (u_k . d_i) u_k|^2)``,
``d_i = P_k - m_k``, with the root sign ``s_i = branch[i]``; the home branch is
``(-1, +1, -1, +1, -1, +1)`` (even carriages on the smaller root).

Workspace Jacobian (``qdot = J @ twist``, twist = (v, w) in world axes): from
``d/dt |n_i|^2 = 0`` with ``dP_k/dt = v + w x r_k``, ``r_k = R p_k``::

    J[i] = [n_i, r_k x n_i] / (n_i . u_k)

which is singular (type I) where a leg is perpendicular to its rail.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from .errors import InputError, StrokeLimitError, UnreachablePoseError
from .pose import as_array, rotation_from_rpy

HOME_BRANCH = np.array([-1.0, 1.0, -1.0, 1.0, -1.0, 1.0])
RAIL_OF = np.array([0, 0, 1, 1, 2, 2])


def check_branch(branch) -> np.ndarray:
    """Validate a branch (six values, each +1 or -1); ``None`` -> the home branch."""
    if branch is None:
        return HOME_BRANCH.copy()
    arr = np.asarray(branch, dtype=float)
    if arr.shape != (6,) or not np.all(np.isin(arr, (-1.0, 1.0))):
        raise InputError("branch", branch, "expected six values, each +1 or -1")
    return arr


class HexapodKinematics:
    """Kinematics methods of :class:`hexapod_pin.Hexapod` (a mixin; needs ``geometry``)."""

    geometry = None  # set by Hexapod

    # -- shared geometry in carriage order -------------------------------------------
    def _carriage_frames(self):
        g = self.geometry
        return g.rail_midpoints[RAIL_OF], g.rail_directions[RAIL_OF], g.platform_points[RAIL_OF]

    def platform_points_world(self, pose) -> np.ndarray:
        """World positions ``P_k`` of the three spherical joints (m), shape (3, 3)."""
        pose = as_array(pose, (6,), "pose")
        rot = rotation_from_rpy(pose[3:])
        return pose[:3] + self.geometry.platform_points @ rot.T

    def _leg_solution(self, poses: np.ndarray, branch: np.ndarray):
        """Vectorised IK core. poses (N, 6) -> q (N, 6), disc (N, 6), P (N, 6, 3), r (N, 6, 3)."""
        mids, dirs, pts = self._carriage_frames()
        rot = rotation_from_rpy(poses[:, 3:])                       # (N, 3, 3)
        r = np.einsum("nij,kj->nki", rot, pts)                     # (N, 6, 3): R p_k
        tips = poses[:, None, :3] + r                              # (N, 6, 3)
        d = tips - mids                                            # (N, 6, 3)
        along = np.einsum("nki,ki->nk", d, dirs)                   # u . d
        disc = self.geometry.leg_length ** 2 - (np.einsum("nki,nki->nk", d, d) - along ** 2)
        q = along + branch * np.sqrt(np.maximum(disc, 0.0))
        return q, disc, tips, r

    def inverse_kinematics(self, pose, branch: Sequence[float] | None = None,
                           check_limits: bool = True) -> np.ndarray:
        """Carriage positions for a platform pose (closed form).

        Args:
            pose: ``(x, y, z, roll, pitch, yaw)`` (m, rad), shape (6,).
            branch: six signs ``+1`` / ``-1`` choosing the root of each carriage's
                quadratic (``+1``: the larger q); default the home branch
                ``(-1, +1, -1, +1, -1, +1)``.
            check_limits: check ``abs(q_i) <= rail_half_length`` and
                ``q_{2k+1} - q_{2k} >= carriage_min_gap``.

        Returns:
            q, shape (6,) (m along ``u_k`` from the rail midpoint).

        Raises:
            InputError: wrong shape, NaN / inf, or a malformed branch.
            UnreachablePoseError: a leg cannot reach (which carriage, how short).
            StrokeLimitError: with ``check_limits``, a stroke or gap violation.
        """
        pose = as_array(pose, (6,), "pose")
        branch = check_branch(branch)
        q, disc, _, _ = self._leg_solution(pose[None, :], branch)
        q, disc = q[0], disc[0]
        if np.any(disc < 0.0):
            bad = np.flatnonzero(disc < 0.0)
            dist = np.sqrt(self.geometry.leg_length ** 2 - disc[bad])
            raise UnreachablePoseError(bad, dist - self.geometry.leg_length)
        if check_limits:
            self.check_stroke(q)
        return q

    def stroke_violations(self, q) -> list[str]:
        """Human-readable stroke and gap violations of carriage positions ``q`` (6,)."""
        g = self.geometry
        q = as_array(q, (6,), "q")
        out = [f"carriage {i}: |q|={abs(q[i]):.6g} > rail_half_length={g.rail_half_length:g}"
               for i in range(6) if abs(q[i]) > g.rail_half_length]
        for k in range(3):
            gap = q[2 * k + 1] - q[2 * k]
            if gap < g.carriage_min_gap:
                what = "cross" if gap < 0 else "are too close"
                out.append(f"rail {k}: carriages {2 * k} and {2 * k + 1} {what} "
                           f"(gap {gap:.6g} < carriage_min_gap={g.carriage_min_gap:g})")
        return out

    def check_stroke(self, q) -> None:
        """Raise :class:`StrokeLimitError` when ``q`` violates a stroke or gap limit."""
        violations = self.stroke_violations(q)
        if violations:
            raise StrokeLimitError(q, violations)

    def jacobian(self, pose) -> np.ndarray:
        """Workspace Jacobian ``J`` (6, 6) with ``qdot = J @ twist``.

        Rows in carriage order; columns ``(v, w)`` of the world-axes twist of the
        platform origin. Rows follow the legs of the home branch as solved by
        :meth:`inverse_kinematics` (without stroke checks).

        Raises:
            UnreachablePoseError: the pose cannot be reached.
        """
        pose = as_array(pose, (6,), "pose")
        q = self.inverse_kinematics(pose, check_limits=False)
        return self._jacobian_rows(pose[None], q[None])[0]

    def _jacobian_rows(self, poses: np.ndarray, q: np.ndarray) -> np.ndarray:
        """J for poses (N, 6) and matching carriage positions q (N, 6) -> (N, 6, 6)."""
        mids, dirs, pts = self._carriage_frames()
        rot = rotation_from_rpy(poses[:, 3:])
        r = np.einsum("nij,kj->nki", rot, pts)
        legs = poses[:, None, :3] + r - (mids + q[..., None] * dirs)  # n_i (N, 6, 3)
        denom = np.einsum("nki,ki->nk", legs, dirs)
        out = np.empty(poses.shape[:1] + (6, 6))
        out[..., :3] = legs / denom[..., None]
        out[..., 3:] = np.cross(r, legs) / denom[..., None]
        return out

    def twist_from_qdot(self, pose, qdot) -> np.ndarray:
        """Platform twist (6,) from carriage velocities: solves ``J @ twist = qdot``.

        Raises:
            SingularityError: where ``J`` is singular (type II).
        """
        from .errors import SingularityError

        jac = self.jacobian(pose)
        qdot = as_array(qdot, (6,), "qdot")
        sv = np.linalg.svd(jac, compute_uv=False)
        if sv[-1] <= 1e-12 * sv[0]:
            raise SingularityError("workspace Jacobian", sv[-1])
        return np.linalg.solve(jac, qdot)
