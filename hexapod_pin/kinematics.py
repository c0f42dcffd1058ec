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

i.e. ``J = B^-1 A`` with ``A[i] = [n_i, r_k x n_i]`` (the closure Jacobian with
the carriages held) and ``B = diag(n_i . u_k)``. ``B`` is singular where a leg is
perpendicular to its rail (type I: the two IK roots merge, ``n_i . u_k =
-s_i sqrt(disc_i)``), ``A`` where the platform can move with the carriages
locked (type II).

Forward kinematics and the assembly modes use the three-circle formulation of
:mod:`hexapod_pin.assembly_modes`.

Units: m, rad, s; every vector in world axes unless stated.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import Sequence

import numpy as np

from . import assembly_modes as am
from .errors import (AssemblyError, InputError, SingularityError, StrokeLimitError,
                     UnreachablePoseError)
from .pose import as_array, rotation_from_rpy

HOME_BRANCH = np.array([-1.0, 1.0, -1.0, 1.0, -1.0, 1.0])
RAIL_OF = np.array([0, 0, 1, 1, 2, 2])
#: ``|cos(leg, rail)|`` below which a leg counts as perpendicular to its rail (type I).
#: Near that singularity the cosine comes from ``sqrt(disc)`` of the IK quadratic, whose
#: rounding (~1e-16 L^2) limits it to about ``sqrt(eps) ~ 1.5e-8``: smaller values cannot
#: be told from 0, so the threshold sits above that noise (J entries ~ 1e7 there).
TYPE_I_TOL = 1e-7
#: ``1 - cos(leg, rail)^2`` below which a leg counts as lying along its rail (the
#: universal joint is in gimbal lock and the leg's spin is undefined)
GIMBAL_TOL = 1e-10
#: relative smallest singular value of J below which ``twist_from_qdot`` refuses
TYPE_II_RTOL = 1e-12
#: poses per chunk of the batch kernels (keeps the temporaries in cache)
BATCH_CHUNK = 2048
#: position of a leg's centre of mass along the leg, as a fraction of its length
#: from the universal joint (a uniform rod, as in the URDF)
LEG_COM_FRACTION = 0.5

_HOME_SIGNS = tuple(HOME_BRANCH.tolist())


def check_branch(branch) -> np.ndarray:
    """Validate a branch (six values, each +1 or -1); ``None`` -> the home branch."""
    if branch is None:
        return HOME_BRANCH.copy()
    try:
        arr = np.asarray(branch, dtype=float)
    except (TypeError, ValueError):
        raise InputError("branch", branch, "expected six values, each +1 or -1") from None
    if arr.shape != (6,) or not np.all((arr == 1.0) | (arr == -1.0)):
        raise InputError("branch", branch, "expected six values, each +1 or -1")
    return arr


# -- result types ----------------------------------------------------------------------
@dataclass(frozen=True)
class InverseKinematicsBatch:
    """Result of :meth:`HexapodKinematics.inverse_kinematics_batch`.

    Attributes:
        q: carriage positions (N, 6) (m). Where a leg cannot reach, that
            carriage holds the point of its rail nearest to the platform point
            (the discriminant clipped at 0): finite, but not a solution.
        reachable: (N,) bool, every leg reaches its platform point.
        within_stroke: (N,) bool, ``abs(q_i) <= rail_half_length`` and
            ``q_2k+1 - q_2k >= carriage_min_gap`` (evaluated on ``q`` as returned).
        ok: (N,) bool, ``reachable & within_stroke``: the rows where
            :meth:`HexapodKinematics.inverse_kinematics` would return instead of raise.
    """

    q: np.ndarray
    reachable: np.ndarray
    within_stroke: np.ndarray
    ok: np.ndarray


@dataclass(frozen=True)
class JacobianBatch:
    """Result of :meth:`HexapodKinematics.jacobian_batch`.

    Attributes:
        jacobian: (N, 6, 6), ``qdot = J @ twist`` per pose; rows where ``ok`` is
            False are all zeros (never NaN or inf).
        q: carriage positions (N, 6) (m), as in :class:`InverseKinematicsBatch`.
        reachable: (N,) bool, every leg reaches.
        regular: (N,) bool, no leg perpendicular to its rail (``|cos| >= TYPE_I_TOL``).
        within_stroke: (N,) bool, stroke and gap limits hold.
        ok: (N,) bool, ``reachable & regular`` (the rows where
            :meth:`HexapodKinematics.jacobian` returns; stroke limits are not required).
    """

    jacobian: np.ndarray
    q: np.ndarray
    reachable: np.ndarray
    regular: np.ndarray
    within_stroke: np.ndarray
    ok: np.ndarray


@dataclass(frozen=True)
class LegMotion:
    """Motion of the six legs (rigid rods) for a platform motion; arrays in carriage order.

    The angular velocity is that of the rigid leg body of the tree: a
    universal joint (first axis along the rail ``u_k``, second axis ``b``
    perpendicular to the rail and to the leg) lets the leg turn only about
    ``u_k`` and ``b``. With the unit direction ``e`` and ``c = u_k . e``::

        w = e x de/dt + lambda e,    lambda = c (e x de/dt) . u_k / (1 - c^2)

    (``e x de/dt`` is the part perpendicular to the leg; ``lambda e`` the spin
    about the leg that the universal joint imposes). It equals Pinocchio's
    ``LOCAL_WORLD_ALIGNED`` angular velocity of the ``leg_i`` body.

    Attributes:
        direction: unit leg directions ``e_i = n_i / L``, from carriage to platform (6, 3).
        com_position: leg centres of mass ``c_i + L/2 e_i`` (6, 3) (m).
        angular_velocity: leg angular velocities ``w_i`` (6, 3) (rad/s).
        com_velocity: velocities of the centres of mass (6, 3) (m/s).
        qdot: carriage velocities (6,) (m/s).
        angular_acceleration: ``dw_i/dt`` (6, 3) (rad/s^2), None without ``twist_dot``.
        com_acceleration: accelerations of the centres of mass (6, 3) (m/s^2), None
            without ``twist_dot``.
        qddot: carriage accelerations (6,) (m/s^2), None without ``twist_dot``.
    """

    direction: np.ndarray
    com_position: np.ndarray
    angular_velocity: np.ndarray
    com_velocity: np.ndarray
    qdot: np.ndarray
    angular_acceleration: np.ndarray | None = None
    com_acceleration: np.ndarray | None = None
    qddot: np.ndarray | None = None


@dataclass(frozen=True)
class SingularityMeasures:
    """Distance-like measures of a pose from the hexapod's singularities.

    ``J = B^-1 A`` with ``B = diag(n_i . u_k)`` and ``A[i] = [n_i, r_k x n_i]``.

    Attributes:
        jacobian_singular_values: singular values of ``J`` (6,), descending
            (mixed units: columns m/s and rad/s); None at a type-I singularity,
            where ``J`` is unbounded.
        condition_number: ``sigma_max / sigma_min`` of ``J``; ``inf`` at a type-I
            singularity or where ``sigma_min = 0``.
        type_one: ``min_i |n_i . u_k| / L``, the smallest cosine between a leg and
            its rail, in [0, 1]; 0 at a type-I (inverse-kinematic) singularity,
            where a carriage can move without moving the platform (its two IK
            roots merge).
        type_one_carriage: the carriage attaining ``type_one``.
        type_two: smallest singular value of the dimensionless matrix ``A_hat``
            with rows ``[e_i, (r_k x e_i) / platform_radius]`` (``e_i`` the unit
            leg direction); 0 at a type-II (direct-kinematic) singularity, where
            the platform can move with the carriages locked. It is at most 1.
        type_two_singular_values: singular values of ``A_hat`` (6,), descending.
    """

    jacobian_singular_values: np.ndarray | None
    condition_number: float
    type_one: float
    type_one_carriage: int
    type_two: float
    type_two_singular_values: np.ndarray


@dataclass(frozen=True)
class _LegState:
    """Legs of one pose: q (6,), n (6, 3), r = R p_k per carriage (6, 3), n.u (6,)."""

    q: np.ndarray
    legs: np.ndarray
    arms: np.ndarray
    along: np.ndarray


class HexapodKinematics:
    """Kinematics methods of :class:`hexapod_pin.Hexapod` (a mixin; needs ``geometry``)."""

    geometry = None  # set by Hexapod

    # -- shared geometry in carriage order -------------------------------------------
    def _carriage_frames(self):
        g = self.geometry
        return g.rail_midpoints[RAIL_OF], g.rail_directions[RAIL_OF], g.platform_points[RAIL_OF]

    @cached_property
    def _circles(self) -> am.CircleGeometry:
        return am.CircleGeometry.from_geometry(self.geometry)

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

    # -- scalar core (single pose, plain floats: small-array numpy is slower) --------
    def _solve_legs(self, pose: np.ndarray, signs):
        """IK of one pose in plain floats.

        Returns lists: q (6), disc (6), legs n_i (6 tuples), arms r_k (3 tuples).
        """
        cg = self._circles
        x, y, z, roll, pitch, yaw = pose.tolist()
        rot = am.rotation_from_rpy_t(roll, pitch, yaw)
        arms = [(rot[0][0] * px + rot[0][1] * py + rot[0][2] * pz,
                 rot[1][0] * px + rot[1][1] * py + rot[1][2] * pz,
                 rot[2][0] * px + rot[2][1] * py + rot[2][2] * pz) for px, py, pz in cg.points_t]
        length2 = cg.leg_length * cg.leg_length
        q, disc, legs = [], [], []
        for i in range(6):
            k = i >> 1
            (rx, ry, rz), (mx, my, mz), (ux, uy, uz) = arms[k], cg.mids_t[k], cg.dirs_t[k]
            dx, dy, dz = x + rx - mx, y + ry - my, z + rz - mz
            along = dx * ux + dy * uy + dz * uz
            dsc = length2 - (dx * dx + dy * dy + dz * dz - along * along)
            qi = along + signs[i] * math.sqrt(dsc) if dsc > 0.0 else along
            q.append(qi)
            disc.append(dsc)
            legs.append((dx - qi * ux, dy - qi * uy, dz - qi * uz))
        return q, disc, legs, arms

    def _raise_unreachable(self, disc) -> None:
        length = self.geometry.leg_length
        bad = [i for i, d in enumerate(disc) if d < 0.0]
        raise UnreachablePoseError(bad, [math.sqrt(length * length - disc[i]) - length
                                         for i in bad])

    def _signs(self, branch):
        return _HOME_SIGNS if branch is None else tuple(check_branch(branch).tolist())

    # -- inverse kinematics -----------------------------------------------------------
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
            StrokeLimitError: with ``check_limits``, a stroke or gap violation
                (including carriages of a rail that cross).
        """
        pose = as_array(pose, (6,), "pose")
        q, disc, _, _ = self._solve_legs(pose, self._signs(branch))
        if min(disc) < 0.0:
            self._raise_unreachable(disc)
        if check_limits:
            self._check_stroke_list(q)
        return np.array(q)

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

    def _check_stroke_list(self, q: list) -> None:
        g = self.geometry
        if (max(abs(v) for v in q) <= g.rail_half_length
                and min(q[1] - q[0], q[3] - q[2], q[5] - q[4]) >= g.carriage_min_gap):
            return
        self.check_stroke(q)

    def branch_of(self, pose, q) -> np.ndarray:
        """The branch (six signs) on which ``q`` solves the inverse kinematics of ``pose``.

        ``s_i = sign(q_i - u_k . d_i)``, so that
        ``inverse_kinematics(pose, branch_of(pose, q)) == q``; a carriage exactly
        at the double root (leg perpendicular to its rail) gets ``+1``.

        Raises:
            InputError: bad shapes, or ``q`` does not assemble at ``pose`` (a leg
                length off by more than 1e-9 m).
        """
        pose = as_array(pose, (6,), "pose")
        q = as_array(q, (6,), "q")
        _, disc, legs, _ = self._solve_legs(pose, _HOME_SIGNS)
        mids, dirs, _ = self._carriage_frames()
        tips = self.platform_points_world(pose)[RAIL_OF]
        rel = tips - mids - q[:, None] * dirs
        err = np.abs(np.linalg.norm(rel, axis=1) - self.geometry.leg_length)
        if np.max(err) > 1e-9:
            raise InputError("q", q, f"does not assemble at the pose (leg length errors {err})")
        along = np.einsum("ij,ij->i", tips - mids, dirs)
        return np.where(q - along >= 0.0, 1.0, -1.0)

    # -- batch ------------------------------------------------------------------------------
    def _batch_signs(self, branch, n: int) -> np.ndarray:
        if branch is None:
            return HOME_BRANCH
        try:
            arr = np.asarray(branch, dtype=float)
        except (TypeError, ValueError):
            raise InputError("branch", branch, "expected six values, each +1 or -1") from None
        if arr.ndim == 2 and arr.shape == (n, 6) and np.all((arr == 1.0) | (arr == -1.0)):
            return arr
        return check_branch(branch)

    def inverse_kinematics_batch(self, poses, branch=None) -> InverseKinematicsBatch:
        """Inverse kinematics of many poses at once, with masks instead of exceptions.

        Args:
            poses: (N, 6) poses ``(x, y, z, roll, pitch, yaw)`` (m, rad).
            branch: None (home branch), six signs for every pose, or (N, 6) signs.

        Returns:
            :class:`InverseKinematicsBatch` (q (N, 6), masks (N,)).

        Raises:
            InputError: wrong shape, NaN / inf anywhere, or a malformed branch.
        """
        poses = as_array(poses, (6,), "poses", batch=True)
        signs = self._batch_signs(branch, poses.shape[0])
        q, reachable, within, _, _ = self._batch_kernel(poses, signs, jacobian=False)
        return InverseKinematicsBatch(q, reachable, within, reachable & within)

    def jacobian_batch(self, poses, branch=None) -> JacobianBatch:
        """Inverse kinematics and workspace Jacobians of many poses (vectorised).

        Args:
            poses: (N, 6) poses (m, rad).
            branch: None (home branch), six signs, or (N, 6) signs.

        Returns:
            :class:`JacobianBatch`: ``jacobian`` (N, 6, 6) with ``qdot = J @ twist``
            (twist ``(v, w)`` in world axes), ``q`` (N, 6) and the masks.

        Raises:
            InputError: wrong shape, NaN / inf anywhere, or a malformed branch.
        """
        poses = as_array(poses, (6,), "poses", batch=True)
        signs = self._batch_signs(branch, poses.shape[0])
        q, reachable, within, regular, jac = self._batch_kernel(poses, signs, jacobian=True)
        return JacobianBatch(jac, q, reachable, regular, within, reachable & regular)

    def _batch_kernel(self, poses: np.ndarray, signs: np.ndarray, jacobian: bool):
        """Chunked structure-of-arrays kernel of the batch API.

        Relies on the hexapod's conventions that rails and platform points lie in
        the planes z = 0 of their frames (``m_k``, ``u_k``, ``p_k`` have no z
        component), which :class:`HexapodGeometry` guarantees.
        """
        g = self.geometry
        mids, dirs, pts = self._carriage_frames()
        mx, my, ux, uy, px, py = mids[:, 0], mids[:, 1], dirs[:, 0], dirs[:, 1], pts[:, 0], pts[:, 1]
        length2 = g.leg_length ** 2
        tol = TYPE_I_TOL * g.leg_length
        n = poses.shape[0]
        q = np.empty((n, 6))
        reachable = np.empty(n, dtype=bool)
        regular = np.empty(n, dtype=bool)
        jac = np.zeros((n, 6, 6)) if jacobian else None
        per_row = signs.ndim == 2
        for start in range(0, n, BATCH_CHUNK):
            stop = min(start + BATCH_CHUNK, n)
            chunk = poses[start:stop]
            sign = signs[start:stop] if per_row else signs
            cr, sr = np.cos(chunk[:, 3]), np.sin(chunk[:, 3])
            cp, sp = np.cos(chunk[:, 4]), np.sin(chunk[:, 4])
            cy, sy = np.cos(chunk[:, 5]), np.sin(chunk[:, 5])
            spsr, spcr = sp * sr, sp * cr
            r00, r10, r20 = (cy * cp)[:, None], (sy * cp)[:, None], (-sp)[:, None]
            r01 = (cy * spsr - sy * cr)[:, None]
            r11 = (sy * spsr + cy * cr)[:, None]
            r21 = (cp * sr)[:, None]
            rx = r00 * px + r01 * py                                   # (n, 6): R p_k
            ry = r10 * px + r11 * py
            rz = r20 * px + r21 * py
            dx = rx + (chunk[:, 0:1] - mx)
            dy = ry + (chunk[:, 1:2] - my)
            dz = rz + chunk[:, 2:3]
            along = dx * ux + dy * uy
            disc = length2 - (dx * dx + dy * dy + dz * dz) + along * along
            root = np.sqrt(np.maximum(disc, 0.0))
            qc = along + sign * root
            q[start:stop] = qc
            reachable[start:stop] = np.all(disc >= 0.0, axis=1)
            regular[start:stop] = np.all(root >= tol, axis=1)
            if jacobian:
                nx, ny, nz = dx - qc * ux, dy - qc * uy, dz
                denom = nx * ux + ny * uy
                ok = np.abs(denom) >= tol
                inv = np.divide(1.0, denom, out=np.zeros_like(denom), where=ok)
                block = jac[start:stop]
                block[:, :, 0] = nx * inv
                block[:, :, 1] = ny * inv
                block[:, :, 2] = nz * inv
                block[:, :, 3] = (ry * nz - rz * ny) * inv
                block[:, :, 4] = (rz * nx - rx * nz) * inv
                block[:, :, 5] = (rx * ny - ry * nx) * inv
                regular[start:stop] &= np.all(ok, axis=1)
        within = (np.all(np.abs(q) <= g.rail_half_length, axis=1)
                  & np.all(q[:, 1::2] - q[:, 0::2] >= g.carriage_min_gap, axis=1))
        if jacobian:
            jac[~(reachable & regular)] = 0.0
        return q, reachable, within, regular, jac

    # -- velocity level ---------------------------------------------------------------
    def jacobian(self, pose, branch: Sequence[float] | None = None) -> np.ndarray:
        """Workspace Jacobian ``J`` (6, 6) with ``qdot = J @ twist``.

        Rows in carriage order, ``J[i] = [n_i, r_k x n_i] / (n_i . u_k)``; columns
        ``(v, w)`` of the world-axes twist of the platform origin (m/s, rad/s).
        The legs are those of :meth:`inverse_kinematics` on ``branch`` (default
        the home branch), stroke limits not checked.

        Raises:
            InputError: wrong shape, NaN / inf, malformed branch.
            UnreachablePoseError: the pose cannot be reached.
            SingularityError: type-I singularity, a leg perpendicular to its rail
                (``|cos| < TYPE_I_TOL``): J is unbounded there.
        """
        pose = as_array(pose, (6,), "pose")
        q, disc, legs, arms = self._solve_legs(pose, self._signs(branch))
        if min(disc) < 0.0:
            self._raise_unreachable(disc)
        cg = self._circles
        tol = TYPE_I_TOL * cg.leg_length
        rows = []
        for i, (nx, ny, nz) in enumerate(legs):
            k = i >> 1
            ux, uy, uz = cg.dirs_t[k]
            denom = nx * ux + ny * uy + nz * uz
            if not abs(denom) >= tol:
                raise SingularityError(f"workspace Jacobian: type-I singularity, the leg of "
                                       f"carriage {i} is perpendicular to its rail (|cos|)",
                                       abs(denom) / cg.leg_length)
            rx, ry, rz = arms[k]
            inv = 1.0 / denom
            rows.append((nx * inv, ny * inv, nz * inv, (ry * nz - rz * ny) * inv,
                         (rz * nx - rx * nz) * inv, (rx * ny - ry * nx) * inv))
        return np.array(rows)

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

    def twist_from_qdot(self, pose, qdot, branch: Sequence[float] | None = None) -> np.ndarray:
        """Platform twist (6,) from carriage velocities (6,): solves ``J @ twist = qdot``.

        Twist ``(v, w)``: velocity of the platform origin and angular velocity,
        world axes (m/s, rad/s).

        Raises:
            InputError: bad shapes or values.
            UnreachablePoseError: the pose cannot be reached.
            SingularityError: type I (from :meth:`jacobian`) or type II (``J``
                numerically singular: ``sigma_min <= 1e-12 sigma_max``).
        """
        jac = self.jacobian(pose, branch)
        qdot = as_array(qdot, (6,), "qdot")
        sv = np.linalg.svd(jac, compute_uv=False)
        if sv[-1] <= TYPE_II_RTOL * sv[0]:
            raise SingularityError("workspace Jacobian (type-II singularity)", sv[-1])
        return np.linalg.solve(jac, qdot)

    def _leg_state(self, pose: np.ndarray, branch) -> _LegState:
        """Legs of a (validated) pose as arrays; raises on unreachable or type-I poses."""
        q, disc, legs, arms = self._solve_legs(pose, self._signs(branch))
        if min(disc) < 0.0:
            self._raise_unreachable(disc)
        legs = np.array(legs)
        dirs = self.geometry.rail_directions[RAIL_OF]
        along = np.einsum("ij,ij->i", legs, dirs)
        worst = int(np.argmin(np.abs(along)))
        if not abs(along[worst]) >= TYPE_I_TOL * self.geometry.leg_length:
            raise SingularityError(f"workspace Jacobian: type-I singularity, the leg of carriage "
                                   f"{worst} is perpendicular to its rail (|cos|)",
                                   abs(along[worst]) / self.geometry.leg_length)
        return _LegState(np.array(q), legs, np.array(arms)[RAIL_OF], along)

    def _rates(self, state: _LegState, twist: np.ndarray):
        """``qdot`` (6,) and ``dn_i/dt`` (6, 3) for a twist."""
        v, w = twist[:3], twist[3:]
        tip_vel = v + np.cross(w, state.arms)                      # dP_k/dt (6, 3)
        qdot = np.einsum("ij,ij->i", state.legs, tip_vel) / state.along   # J @ twist
        dirs = self.geometry.rail_directions[RAIL_OF]
        return qdot, tip_vel - qdot[:, None] * dirs

    def jacobian_derivative(self, pose, twist, branch: Sequence[float] | None = None) -> np.ndarray:
        """Time derivative ``dJ/dt`` (6, 6) of the workspace Jacobian along a twist.

        With ``dn_i/dt = v + w x r_k - qdot_i u_k`` and ``dr_k/dt = w x r_k``::

            dJ[i]/dt = [dn_i, (w x r_k) x n_i + r_k x dn_i] / (n_i . u_k)
                       - J[i] (dn_i . u_k) / (n_i . u_k)

        Args:
            pose: (6,) (m, rad).
            twist: ``(v, w)`` (6,), world axes (m/s, rad/s).
            branch: IK branch, default the home branch.

        Returns:
            dJ/dt, shape (6, 6) (units of J per second).

        Raises:
            InputError, UnreachablePoseError, SingularityError: as :meth:`jacobian`.
        """
        pose = as_array(pose, (6,), "pose")
        twist = as_array(twist, (6,), "twist")
        state = self._leg_state(pose, branch)
        _, dlegs = self._rates(state, twist)
        return self._jacobian_derivative_from(state, twist, dlegs)

    def _jacobian_derivative_from(self, state: _LegState, twist: np.ndarray,
                                  dlegs: np.ndarray) -> np.ndarray:
        dirs = self.geometry.rail_directions[RAIL_OF]
        w = twist[3:]
        inv = 1.0 / state.along[:, None]
        jac = np.concatenate([state.legs, np.cross(state.arms, state.legs)], axis=1) * inv
        dalong = np.einsum("ij,ij->i", dlegs, dirs)[:, None]
        darm = np.cross(w, state.arms)
        djac = np.concatenate([dlegs, np.cross(darm, state.legs)
                               + np.cross(state.arms, dlegs)], axis=1) * inv
        return djac - jac * dalong * inv

    def qddot(self, pose, twist, twist_dot, branch: Sequence[float] | None = None) -> np.ndarray:
        """Carriage accelerations (6,) (m/s^2): ``qddot = J twist_dot + dJ/dt twist``.

        Args:
            pose: (6,) (m, rad).
            twist: ``(v, w)`` (6,) world axes (m/s, rad/s).
            twist_dot: plain time derivative of ``twist`` (6,) (m/s^2, rad/s^2).
            branch: IK branch, default the home branch.

        Raises:
            InputError, UnreachablePoseError, SingularityError: as :meth:`jacobian`.
        """
        pose = as_array(pose, (6,), "pose")
        twist = as_array(twist, (6,), "twist")
        twist_dot = as_array(twist_dot, (6,), "twist_dot")
        state = self._leg_state(pose, branch)
        _, dlegs = self._rates(state, twist)
        jac = np.concatenate([state.legs, np.cross(state.arms, state.legs)], axis=1)
        jac /= state.along[:, None]
        return jac @ twist_dot + self._jacobian_derivative_from(state, twist, dlegs) @ twist

    def leg_motion(self, pose, twist, twist_dot=None,
                   branch: Sequence[float] | None = None) -> LegMotion:
        """Direction, angular velocity / acceleration and centre-of-mass motion of each leg.

        See :class:`LegMotion` for the definitions (the angular velocity is the
        true one of the rigid leg behind its universal joint). With
        ``e = n / L``: ``de/dt = dn/dt / L``, ``d2e/dt2 = d2n/dt2 / L``,
        ``d2n/dt2 = vdot + wdot x r_k + w x (w x r_k) - qddot_i u_k``; centre of mass
        ``c_i + L/2 e``, velocity ``qdot_i u_k + dn/dt / 2``.

        Args:
            pose: (6,) (m, rad).
            twist: ``(v, w)`` (6,) world axes (m/s, rad/s).
            twist_dot: its time derivative (6,), or None (no accelerations).
            branch: IK branch, default the home branch.

        Raises:
            InputError, UnreachablePoseError, SingularityError: as :meth:`jacobian`;
                also SingularityError where a leg lies along its rail (the
                universal joint's gimbal lock: the leg's spin is undefined).
        """
        pose = as_array(pose, (6,), "pose")
        twist = as_array(twist, (6,), "twist")
        if twist_dot is not None:
            twist_dot = as_array(twist_dot, (6,), "twist_dot")
        state = self._leg_state(pose, branch)
        length = self.geometry.leg_length
        dirs = self.geometry.rail_directions[RAIL_OF]
        qdot, dlegs = self._rates(state, twist)
        e, de = state.legs / length, dlegs / length
        cosine = state.along / length                                 # u . e
        gimbal = 1.0 - cosine ** 2
        worst = int(np.argmin(gimbal))
        if not gimbal[worst] >= GIMBAL_TOL:
            raise SingularityError(f"leg of carriage {worst} lies along its rail (universal "
                                   "joint in gimbal lock; 1 - cos^2)", gimbal[worst])
        perp = np.cross(e, de)                                        # e x de
        sigma = np.einsum("ij,ij->i", perp, dirs)
        spin = cosine * sigma / gimbal
        omega = perp + spin[:, None] * e
        carriages = self.geometry.rail_midpoints[RAIL_OF] + state.q[:, None] * dirs
        com = carriages + LEG_COM_FRACTION * state.legs
        com_vel = qdot[:, None] * dirs + LEG_COM_FRACTION * dlegs
        if twist_dot is None:
            return LegMotion(e, com, omega, com_vel, qdot)
        w = twist[3:]
        jac = np.concatenate([state.legs, np.cross(state.arms, state.legs)], axis=1)
        jac /= state.along[:, None]
        qddot = jac @ twist_dot + self._jacobian_derivative_from(state, twist, dlegs) @ twist
        tip_acc = (twist_dot[:3] + np.cross(twist_dot[3:], state.arms)
                   + np.cross(w, np.cross(w, state.arms)))
        ddlegs = tip_acc - qddot[:, None] * dirs
        dde = ddlegs / length
        dcos = np.einsum("ij,ij->i", de, dirs)
        dperp = np.cross(e, dde)
        dsigma = np.einsum("ij,ij->i", dperp, dirs)
        dspin = (dcos * sigma + cosine * dsigma) / gimbal + 2.0 * cosine ** 2 * dcos * sigma \
            / gimbal ** 2
        alpha = dperp + dspin[:, None] * e + spin[:, None] * de
        com_acc = qddot[:, None] * dirs + LEG_COM_FRACTION * ddlegs
        return LegMotion(e, com, omega, com_vel, qdot, alpha, com_acc, qddot)

    # -- singularities ----------------------------------------------------------------------
    def singularity(self, pose, branch: Sequence[float] | None = None) -> SingularityMeasures:
        """Measures of the distance to type-I and type-II singularities (see
        :class:`SingularityMeasures`). Does not raise at a singular pose.

        Raises:
            InputError: bad shapes or values.
            UnreachablePoseError: the pose cannot be reached.
        """
        pose = as_array(pose, (6,), "pose")
        q, disc, legs, arms = self._solve_legs(pose, self._signs(branch))
        if min(disc) < 0.0:
            self._raise_unreachable(disc)
        g = self.geometry
        legs = np.array(legs)
        arms = np.array(arms)[RAIL_OF]
        e = legs / g.leg_length
        cosine = np.abs(np.einsum("ij,ij->i", e, g.rail_directions[RAIL_OF]))
        worst = int(np.argmin(cosine))
        a_hat = np.concatenate([e, np.cross(arms, e) / g.platform_radius], axis=1)
        sv_a = np.linalg.svd(a_hat, compute_uv=False)
        if cosine[worst] < TYPE_I_TOL:
            sv_j, cond = None, math.inf
        else:
            a_mat = np.concatenate([legs, np.cross(arms, legs)], axis=1)
            sv_j = np.linalg.svd(a_mat / (cosine * g.leg_length)[:, None], compute_uv=False)
            cond = float(sv_j[0] / sv_j[-1]) if sv_j[-1] > 0.0 else math.inf
        return SingularityMeasures(sv_j, cond, float(cosine[worst]), worst, float(sv_a[-1]), sv_a)

    # -- forward kinematics and assembly modes -------------------------------------------------
    def forward_kinematics(self, q, guess=None, max_iter: int = 50) -> np.ndarray:
        """Platform pose for carriage positions ``q``: Newton's method from ``guess``.

        The 18 closure equations reduce exactly to three (see
        :mod:`hexapod_pin.assembly_modes`): each platform point lies on the circle
        where its two legs' spheres meet, at angle ``theta_k``; the unknowns are
        the three angles and the equations the three sides of the platform
        triangle. Newton's method on this 3x3 system converges quadratically (its
        Jacobian is singular exactly where the full closure Jacobian is, the
        type-II singularities); it stops at side errors below 1e-14 m. The pose
        is then rebuilt from the three points and checked on the six original
        leg-length equations: every leg within 1e-12 m of ``leg_length``, else
        :class:`AssemblyError` (never a wrong pose). Both tolerances are scaled
        by ``leg_length`` when it exceeds 1 m.

        Newton converges to the assembly mode whose basin holds ``guess``; to
        follow a motion, pass the previous pose. :meth:`assembly_modes` lists all.
        Stroke limits are not checked.

        Args:
            q: carriage positions (6,) (m).
            guess: a pose (6,) near the wanted one; default the home pose.
            max_iter: Newton iteration limit.

        Returns:
            pose ``(x, y, z, roll, pitch, yaw)`` (6,) (m, rad), pitch in [-pi/2, pi/2].

        Raises:
            InputError: bad shapes or NaN / inf.
            AssemblyError: no assembly (two carriages of a rail more than
                ``2 leg_length`` apart), degenerate carriages (coincident, or
                exactly ``2 leg_length`` apart), a singular Jacobian (type II), no
                convergence, or a final leg-length error above 1e-12 m.
        """
        q = as_array(q, (6,), "q")
        guess = self.geometry.home_pose if guess is None else as_array(guess, (6,), "guess")
        cg = self._circles
        system = am.circle_system(cg, q)
        if system is None:
            excess = float(np.max(np.abs(q[1::2] - q[0::2]))) - 2 * cg.leg_length
            raise AssemblyError("no assembly: two carriages of a rail are more than "
                                "2 leg_length apart", excess, 0)
        theta = system.angles_of_t(am.platform_points_t(cg, guess.tolist()))
        scale = max(1.0, cg.leg_length)
        result = am.newton_circles(system, theta, max_iter=max_iter, tol=am.INNER_TOL * scale)
        pose = am.pose_from_points_t(cg, system.points_t(*result.theta))
        err = am.leg_length_error(cg, pose, q.tolist())
        if not err <= am.POSE_TOL * scale:
            raise AssemblyError("the converged pose misses the leg lengths", err,
                                result.iterations)
        return np.array(pose)

    def assembly_modes(self, q) -> list[np.ndarray]:
        """Every real assembly of the closed chain for carriage positions ``q``.

        Method (details and the completeness argument in
        :func:`hexapod_pin.assembly_modes.enumerate_assemblies`): with the
        carriages held, platform point k lies on a circle (the two leg spheres of
        rail k meet there) at an angle ``theta_k``; the three sides of the platform
        triangle give three equations bilinear in ``(cos, sin)`` of two angles.
        Eliminating two angles by Sylvester resultants leaves a trigonometric
        polynomial of degree 8 in ``theta_0`` (a polynomial of degree 16 in
        ``exp(i theta_0)``: the 16 complex assemblies of a 6-3 Stewart platform);
        its coefficients come exactly from 32 samples and a DFT, all its roots
        from a companion matrix, and every root on the unit circle is completed
        exhaustively by closed-form circle intersections, polished by Newton and
        deduplicated. Each assembly is verified on the six leg-length equations
        (1e-12 m). For the default geometry at home there are 8 (4 above the rail
        plane and their mirror images).

        An assembly is a platform pose; the universal-joint angles follow from it
        (each up to the joint's own ``(a, b) ~ (a + pi, pi - b)`` ambiguity, which
        is not a different assembly). Stroke limits and collisions are ignored.
        The branch of each carriage in a mode is :meth:`branch_of`.

        Args:
            q: carriage positions (6,) (m).

        Returns:
            list of poses (6,) (m, rad), sorted by height z, highest first; empty
            when two carriages of a rail are more than ``2 leg_length`` apart.

        Raises:
            InputError: bad shape or NaN / inf.
            AssemblyError: degenerate carriage positions with a continuum of
                assemblies (two carriages of a rail coincide, stand exactly
                ``2 leg_length`` apart, or the eliminant vanishes identically).
        """
        q = as_array(q, (6,), "q")
        cg = self._circles
        system = am.circle_system(cg, q)
        if system is None:
            return []
        poses = []
        for theta in am.enumerate_assemblies(system):
            pose = am.pose_from_points_t(cg, system.points_t(*theta.tolist()))
            err = am.leg_length_error(cg, pose, q.tolist())
            if err <= am.POSE_TOL * max(1.0, cg.leg_length):
                poses.append(np.array(pose))
        poses.sort(key=lambda p: (-p[2], tuple(p)))
        return poses
