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
from collections.abc import Sequence

import numpy as np

from . import assembly_modes as am
from ..errors import (AssemblyError, InputError, SingularityError, StrokeLimitError,
                     UnreachablePoseError)
from ..core.pose import rotation_from_rpy, rotation_tuple
from ..core.checks import as_array, check_signs

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
BATCH_CHUNK = 8192
#: position of a leg's centre of mass along the leg, as a fraction of its length
#: from the universal joint (a uniform rod, as in the URDF)
LEG_COM_FRACTION = 0.5

_HOME_SIGNS = tuple(HOME_BRANCH.tolist())


def _cross3(a, b) -> tuple:
    """Cross product of two 3-sequences of floats."""
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _dot3(a, b) -> float:
    """Dot product of two 3-sequences of floats."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _floats6(value, name: str) -> list:
    """A validated 6-vector as a list of floats (fast path for float64 arrays of shape (6,)).

    Raises:
        InputError: not numeric, wrong shape, or NaN / inf (via :func:`as_array`).
    """
    if type(value) is np.ndarray and value.dtype == np.float64 and value.shape == (6,):
        vals = value.tolist()
        if all(map(math.isfinite, vals)):
            return vals
    return as_array(value, (6,), name).tolist()


def check_branch(branch) -> np.ndarray:
    """Validate a branch (six values, each +1 or -1); ``None`` -> the home branch."""
    return check_signs(branch, HOME_BRANCH)


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
    """Legs of one pose in plain floats, per carriage: q, n_i (3-tuples), r_k = R p_k
    (3-tuples), n_i . u_k."""

    q: list
    legs: list
    arms: list
    along: list


class HexapodKinematics:
    """The hexapod's kinematics: the component that :class:`~hexapod_pin.hexapod.robot.Hexapod`
    delegates its kinematics methods to.

    Args:
        geometry: the :class:`~hexapod_pin.hexapod.geometry.HexapodGeometry`.
    """

    def __init__(self, geometry):
        self.geometry = geometry

    # -- shared geometry in carriage order -------------------------------------------
    def _carriage_frames(self):
        """Rail midpoints, rail directions and platform points in carriage order, (6, 3) each
        (read-only arrays, computed once per robot)."""
        return self._frames6

    @cached_property
    def _frames6(self):
        g = self.geometry
        out = (g.rail_midpoints[RAIL_OF], g.rail_directions[RAIL_OF], g.platform_points[RAIL_OF])
        for arr in out:
            arr.setflags(write=False)
        return out

    @cached_property
    def _home_list(self) -> list:
        return self.geometry.home_pose.tolist()

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
    def _solve_legs(self, pose: list, signs):
        """IK of one pose (6 floats) in plain floats.

        Returns lists: q (6), disc (6), legs n_i (6 tuples), arms r_k (3 tuples).
        """
        cg = self._circles
        x, y, z, roll, pitch, yaw = pose
        rot = rotation_tuple(roll, pitch, yaw)
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
        pose = _floats6(pose, "pose")
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

        Works per rail: both carriages of rail k share ``d_k = P_k - m_k``, its
        component along the rail ``a_k = u_k . d_k`` and the root
        ``rho_k = sqrt(disc_k)``; ``q_i = a_k + s_i rho_k``. With the perpendicular
        part ``p_k = d_k - a_k u_k``, the leg is ``n_i = p_k - s_i rho_k u_k`` and
        ``n_i . u_k = -s_i rho_k``, so the Jacobian row is

            ``J[i] = [u_k, r_k x u_k] - s_i [p_k, r_k x p_k] / rho_k``

        (the same row as :meth:`jacobian`, algebraically simplified). Relies on
        the hexapod's conventions that rails and platform points lie in the
        planes z = 0 of their frames (``m_k``, ``u_k``, ``p_k`` have no z
        component), which :class:`HexapodGeometry` guarantees.
        """
        g = self.geometry
        mids, dirs, pts = g.rail_midpoints, g.rail_directions, g.platform_points
        # rail-major columns (3, 1): every array below is (3, n) with the long axis last,
        # where numpy's inner loops are fast (a (n, 3) layout is several times slower)
        mx, my = mids[:, 0:1], mids[:, 1:2]
        ux, uy = dirs[:, 0:1], dirs[:, 1:2]
        px, py = pts[:, 0:1], pts[:, 1:2]
        length2 = g.leg_length ** 2
        tol = TYPE_I_TOL * g.leg_length
        n = poses.shape[0]
        q = np.empty((n, 6))
        reachable = np.empty(n, dtype=bool)
        regular = np.empty(n, dtype=bool)
        jac = np.empty((n, 6, 6)) if jacobian else None
        per_row = signs.ndim == 2
        if not per_row:
            parity_signs = (signs[0::2, None], signs[1::2, None])              # (3, 1) each
        for start in range(0, n, BATCH_CHUNK):
            stop = min(start + BATCH_CHUNK, n)
            x, y, z, roll, pitch, yaw = np.ascontiguousarray(poses[start:stop].T)
            if per_row:
                rows = signs[start:stop].T
                parity_signs = (rows[0::2], rows[1::2])                          # (3, n) each
            cr, sr = np.cos(roll), np.sin(roll)
            cp, sp = np.cos(pitch), np.sin(pitch)
            cy, sy = np.cos(yaw), np.sin(yaw)
            spsr = sp * sr
            r00, r10, r20 = cy * cp, sy * cp, -sp
            r01, r11, r21 = cy * spsr - sy * cr, sy * spsr + cy * cr, cp * sr
            rx = px * r00 + py * r01                                   # (3, n): r_k = R p_k
            ry = px * r10 + py * r11
            rz = px * r20 + py * r21
            dx = rx + x - mx                                           # d_k = P_k - m_k
            dy = ry + y - my
            dz = rz + z
            along = dx * ux + dy * uy
            disc = length2 - (dx * dx + dy * dy + dz * dz) + along * along
            root = np.sqrt(np.maximum(disc, 0.0))
            block_q = q[start:stop]
            for parity, sgn in enumerate(parity_signs):
                block_q[:, parity::2] = (along + sgn * root).T
            reachable[start:stop] = np.all(disc >= 0.0, axis=0)
            good = root >= tol
            regular[start:stop] = np.all(good, axis=0)
            if not jacobian:
                continue
            inv = np.divide(1.0, root, out=np.zeros_like(root), where=good)
            perp_x, perp_y = dx - along * ux, dy - along * uy           # p_k (z part: dz)
            scaled = (perp_x * inv, perp_y * inv, dz * inv,
                      (ry * dz - rz * perp_y) * inv, (rz * perp_x - rx * dz) * inv,
                      (rx * perp_y - ry * perp_x) * inv)               # [p, r x p] / rho
            base = (ux, uy, 0.0, -rz * uy, rz * ux, rx * uy - ry * ux)  # [u, r x u]
            # rows i = 2k + parity of J, column-major over the chunk, then one transposed copy
            cols = np.empty((6, 6, stop - start))
            for parity, sgn in enumerate(parity_signs):
                for col in range(6):
                    np.subtract(base[col], sgn * scaled[col], out=cols[parity::2, col])
            jac[start:stop] = cols.transpose(2, 0, 1)
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
        pose = _floats6(pose, "pose")
        _, disc, legs, arms = self._solve_legs(pose, self._signs(branch))
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
        """Legs of a (validated) pose in plain floats; raises on unreachable or type-I poses."""
        q, disc, legs, arms = self._solve_legs(pose, self._signs(branch))
        if min(disc) < 0.0:
            self._raise_unreachable(disc)
        dirs = self._circles.dirs_t
        along = [_dot3(legs[i], dirs[i >> 1]) for i in range(6)]
        worst = min(range(6), key=lambda i: abs(along[i]))
        if not abs(along[worst]) >= TYPE_I_TOL * self.geometry.leg_length:
            raise SingularityError(f"workspace Jacobian: type-I singularity, the leg of carriage "
                                   f"{worst} is perpendicular to its rail (|cos|)",
                                   abs(along[worst]) / self.geometry.leg_length)
        return _LegState(q, legs, [arms[i >> 1] for i in range(6)], along)

    def _rates(self, state: _LegState, twist: list):
        """``qdot`` (6 floats) and ``dn_i/dt`` (6 3-tuples) for a twist (6 floats)."""
        v, w = twist[:3], twist[3:]
        dirs = self._circles.dirs_t
        qdot, dlegs = [], []
        for i in range(6):
            wr = _cross3(w, state.arms[i])
            tip_vel = (v[0] + wr[0], v[1] + wr[1], v[2] + wr[2])     # dP_k/dt
            qd = _dot3(state.legs[i], tip_vel) / state.along[i]       # (J @ twist)_i
            u = dirs[i >> 1]
            qdot.append(qd)
            dlegs.append((tip_vel[0] - qd * u[0], tip_vel[1] - qd * u[1], tip_vel[2] - qd * u[2]))
        return qdot, dlegs

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
        pose = _floats6(pose, "pose")
        twist = _floats6(twist, "twist")
        state = self._leg_state(pose, branch)
        _, dlegs = self._rates(state, twist)
        dirs = self._circles.dirs_t
        w = twist[3:]
        rows = []
        for i in range(6):
            n, r, dn = state.legs[i], state.arms[i], dlegs[i]
            inv = 1.0 / state.along[i]
            rn = _cross3(r, n)
            a = _cross3(_cross3(w, r), n)
            b = _cross3(r, dn)
            rate = _dot3(dn, dirs[i >> 1]) * inv                   # d(n.u)/dt / (n.u)
            rows.append([(dn[0] - n[0] * rate) * inv, (dn[1] - n[1] * rate) * inv,
                         (dn[2] - n[2] * rate) * inv, (a[0] + b[0] - rn[0] * rate) * inv,
                         (a[1] + b[1] - rn[1] * rate) * inv, (a[2] + b[2] - rn[2] * rate) * inv])
        return np.array(rows)

    def qddot(self, pose, twist, twist_dot, branch: Sequence[float] | None = None) -> np.ndarray:
        """Carriage accelerations (6,) (m/s^2): ``qddot = J twist_dot + dJ/dt twist``.

        Evaluated in the equivalent form obtained by differentiating
        ``n_i . dn_i/dt = 0`` once more::

            qddot_i = (|dn_i/dt|^2 + n_i . d2P_k/dt2) / (n_i . u_k),
            d2P_k/dt2 = vdot + wdot x r_k + w x (w x r_k)

        (:meth:`jacobian_derivative` gives the other form; the tests check both).

        Args:
            pose: (6,) (m, rad).
            twist: ``(v, w)`` (6,) world axes (m/s, rad/s).
            twist_dot: plain time derivative of ``twist`` (6,) (m/s^2, rad/s^2).
            branch: IK branch, default the home branch.

        Raises:
            InputError, UnreachablePoseError, SingularityError: as :meth:`jacobian`.
        """
        pose = _floats6(pose, "pose")
        twist = _floats6(twist, "twist")
        twist_dot = _floats6(twist_dot, "twist_dot")
        state = self._leg_state(pose, branch)
        _, dlegs = self._rates(state, twist)
        return np.array(self._qddot_from(state, twist, twist_dot, dlegs)[0])

    @staticmethod
    def _qddot_from(state: _LegState, twist: list, twist_dot: list, dlegs: list):
        """qddot (6 floats) and the platform-point accelerations (6 3-tuples)."""
        w, dw, dv = twist[3:], twist_dot[3:], twist_dot[:3]
        qddot, tip_acc = [], []
        for i in range(6):
            r = state.arms[i]
            a1, a2 = _cross3(dw, r), _cross3(w, _cross3(w, r))
            acc = (dv[0] + a1[0] + a2[0], dv[1] + a1[1] + a2[1], dv[2] + a1[2] + a2[2])
            tip_acc.append(acc)
            qddot.append((_dot3(dlegs[i], dlegs[i]) + _dot3(state.legs[i], acc))
                         / state.along[i])
        return qddot, tip_acc

    def leg_motion(self, pose, twist, twist_dot=None,
                   branch: Sequence[float] | None = None) -> LegMotion:
        """Direction, angular velocity / acceleration and centre-of-mass motion of each leg.

        See :class:`LegMotion` for the definitions (the angular velocity is the
        true one of the rigid leg behind its universal joint). With
        ``e = n / L``: ``de/dt = dn/dt / L``, ``d2e/dt2 = d2n/dt2 / L``,
        ``d2n/dt2 = vdot + wdot x r_k + w x (w x r_k) - qddot_i u_k``; centre of mass
        ``c_i + L/2 e``, velocity ``qdot_i u_k + dn/dt / 2``; the angular
        acceleration differentiates ``w = e x de/dt + lambda e``:
        ``e x d2e/dt2 + dlambda/dt e + lambda de/dt``.

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
        pose = _floats6(pose, "pose")
        twist = _floats6(twist, "twist")
        if twist_dot is not None:
            twist_dot = _floats6(twist_dot, "twist_dot")
        state = self._leg_state(pose, branch)
        cg = self._circles
        inv_len = 1.0 / cg.leg_length
        frac = LEG_COM_FRACTION
        qdot, dlegs = self._rates(state, twist)
        if twist_dot is not None:
            qddot, tip_acc = self._qddot_from(state, twist, twist_dot, dlegs)
        out = {"e": [], "com": [], "omega": [], "vcom": [], "alpha": [], "acom": []}
        for i in range(6):
            u, m = cg.dirs_t[i >> 1], cg.mids_t[i >> 1]
            n, dn, qi = state.legs[i], dlegs[i], state.q[i]
            e = (n[0] * inv_len, n[1] * inv_len, n[2] * inv_len)
            de = (dn[0] * inv_len, dn[1] * inv_len, dn[2] * inv_len)
            cosine = state.along[i] * inv_len                           # u . e
            gimbal = 1.0 - cosine * cosine
            if not gimbal >= GIMBAL_TOL:
                raise SingularityError(f"leg of carriage {i} lies along its rail (universal "
                                       "joint in gimbal lock; 1 - cos^2)", gimbal)
            perp = _cross3(e, de)                                       # e x de
            sigma = _dot3(perp, u)
            spin = cosine * sigma / gimbal
            out["e"].append(e)
            out["com"].append((m[0] + qi * u[0] + frac * n[0], m[1] + qi * u[1] + frac * n[1],
                               m[2] + qi * u[2] + frac * n[2]))
            out["omega"].append((perp[0] + spin * e[0], perp[1] + spin * e[1],
                                 perp[2] + spin * e[2]))
            qd = qdot[i]
            out["vcom"].append((qd * u[0] + frac * dn[0], qd * u[1] + frac * dn[1],
                                qd * u[2] + frac * dn[2]))
            if twist_dot is None:
                continue
            acc, qdd = tip_acc[i], qddot[i]
            ddn = (acc[0] - qdd * u[0], acc[1] - qdd * u[1], acc[2] - qdd * u[2])
            dperp = _cross3(e, (ddn[0] * inv_len, ddn[1] * inv_len, ddn[2] * inv_len))
            dcos = _dot3(de, u)
            dspin = ((dcos * sigma + cosine * _dot3(dperp, u)) / gimbal
                     + 2.0 * cosine * cosine * dcos * sigma / (gimbal * gimbal))
            out["alpha"].append((dperp[0] + dspin * e[0] + spin * de[0],
                                 dperp[1] + dspin * e[1] + spin * de[1],
                                 dperp[2] + dspin * e[2] + spin * de[2]))
            out["acom"].append((qdd * u[0] + frac * ddn[0], qdd * u[1] + frac * ddn[1],
                                qdd * u[2] + frac * ddn[2]))
        arrays = [np.array(out[k]) for k in ("e", "com", "omega", "vcom")]
        if twist_dot is None:
            return LegMotion(*arrays, np.array(qdot))
        return LegMotion(*arrays, np.array(qdot), np.array(out["alpha"]), np.array(out["acom"]),
                         np.array(qddot))

    # -- singularities ----------------------------------------------------------------------
    def singularity(self, pose, branch: Sequence[float] | None = None) -> SingularityMeasures:
        """Measures of the distance to type-I and type-II singularities (see
        :class:`SingularityMeasures`). Does not raise at a singular pose.

        Raises:
            InputError: bad shapes or values.
            UnreachablePoseError: the pose cannot be reached.
        """
        pose = _floats6(pose, "pose")
        _, disc, legs, arms = self._solve_legs(pose, self._signs(branch))
        if min(disc) < 0.0:
            self._raise_unreachable(disc)
        g = self.geometry
        dirs = self._circles.dirs_t
        inv_len, inv_rad = 1.0 / g.leg_length, 1.0 / g.platform_radius
        cosine, a_hat, a_mat = [], [], []
        for i in range(6):
            n, r = legs[i], arms[i >> 1]
            rn = _cross3(r, n)
            cosine.append(abs(_dot3(n, dirs[i >> 1])) * inv_len)
            a_hat.append([n[0] * inv_len, n[1] * inv_len, n[2] * inv_len,
                          rn[0] * inv_len * inv_rad, rn[1] * inv_len * inv_rad,
                          rn[2] * inv_len * inv_rad])
            a_mat.append([n[0], n[1], n[2], rn[0], rn[1], rn[2]])
        worst = min(range(6), key=cosine.__getitem__)
        sv_a = np.linalg.svd(np.array(a_hat), compute_uv=False)
        if cosine[worst] < TYPE_I_TOL:
            sv_j, cond = None, math.inf
        else:
            jac = np.array(a_mat) / (np.array(cosine) * g.leg_length)[:, None]
            sv_j = np.linalg.svd(jac, compute_uv=False)
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
        q = _floats6(q, "q")
        guess = self._home_list if guess is None else _floats6(guess, "guess")
        cg = self._circles
        system = am.circle_system(cg, q)
        if system is None:
            excess = max(abs(q[1] - q[0]), abs(q[3] - q[2]), abs(q[5] - q[4])) - 2 * cg.leg_length
            raise AssemblyError("no assembly: two carriages of a rail are more than "
                                "2 leg_length apart", excess, 0)
        theta = system.angles_of_t(am.platform_points_t(cg, guess))
        scale = max(1.0, cg.leg_length)
        result = am.newton_circles(system, theta, max_iter=max_iter, tol=am.INNER_TOL * scale)
        pose = am.pose_from_points_t(cg, system.points_t(*result.theta))
        err = am.leg_length_error(cg, pose, q)
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
