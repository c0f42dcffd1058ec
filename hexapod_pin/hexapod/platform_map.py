"""Closed-form map from the hexapod's platform state to its Pinocchio tree state.

The hexapod's tree (``urdf/hexapod.urdf.xacro``) has, per carriage ``i`` on rail
``k = i // 2``: a prismatic joint along ``u_k`` (coordinate ``q_i``), a universal joint
``u_i_a`` about ``u_k`` then ``u_i_b`` about the rotated ``y`` axis, the leg along the
resulting local ``z``; and a free-flyer platform. With the carriage-frame axes
``(u, l, z) = (u_k, z x u_k, z)``, the unit leg direction ``e = n / L`` is::

    e = sin(b) u - sin(a) cos(b) l + cos(a) cos(b) z
    =>  b = atan2(e.u, rho),  a = atan2(-e.l, e.z),  rho = cos(b) = |(e.l, e.z)|

Time derivatives follow from ``dn/dt = V_k - qdot_i u`` and ``d2n/dt2 = A_k - qddot_i u``
(``V_k``, ``A_k``: velocity and acceleration of the platform point ``P_k``), with
``X = e.z``, ``Y = -e.l``::

    bdot = (de/dt . u) / rho              bddot = (d2e/dt2 . u + (e.u) bdot^2) / rho
    adot = (X dY - Y dX) / rho^2          addot = (X d2Y - Y d2X) / rho^2
                                                  - 2 adot (X dX + Y dY) / rho^2

The free-flyer gets ``(t, quaternion(R))``, the body velocity ``(R^T v, R^T w)`` and
the acceleration ``(R^T (vdot - w x v), R^T wdot)``.

Every tree rate is linear in the twist, ``v_tree = G twist``. Each carriage and
universal-joint rate depends on the twist only through ``V_k = v + w x r_k``, so its row
of ``G`` is ``[g, r_k x g]`` with ``g`` the gradient of the rate with respect to ``V_k``::

    g_carriage = n / (n.u)
    g_b = (u - n / (n.u)) / (L rho)
    g_a = -(X l + Y z) / (L rho^2)

and the free-flyer rows are ``blockdiag(R^T, R^T)``. ``G^T`` maps a generalised force of
the tree to a wrench on the platform (virtual power): :meth:`PlatformMap.project`.

Everything here is written in plain Python floats: for one state (six legs) that is
several times faster than numpy on small arrays. It relies on the hexapod conventions
of :class:`~hexapod_pin.geometry.HexapodGeometry` (horizontal rails, carriage frames with
``z`` up), which the URDF shares.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg.lapack import dgesv

from ..errors import HexapodPinError, SingularityError, UnreachablePoseError
from .kinematics import GIMBAL_TOL, TYPE_I_TOL
from ..core.pose import rotation_tuple

#: LU pivot ratio (smallest / largest) of ``A^T`` below which the platform wrench cannot
#: be distributed on the legs (type-II singularity: the platform moves with the
#: carriages locked)
TYPE_II_PIVOT_RTOL = 1e-12


class Legs:
    """The pose-dependent part of a hexapod state (plain floats, carriage order).

    Attributes:
        rot: ``R`` row-major, 9 floats.
        quat: platform quaternion ``(x, y, z, w)``.
        position: platform origin ``t`` (3 floats).
        arms: ``r_k = R p_k`` per rail (3 tuples).
        q: carriage positions (6 floats, m).
        legs: leg vectors ``n_i`` from the universal joint to the platform point (6 tuples).
        along: ``n_i . u_k`` (6 floats).
        xs, ys, rho2, ex: ``X = e.z``, ``Y = -e.l``, ``rho^2 = X^2 + Y^2`` and ``e.u`` per leg.
        angles_a, angles_b: the universal-joint angles (rad), or None when not asked for.
    """

    __slots__ = (
        "along",
        "angles_a",
        "angles_b",
        "arms",
        "ex",
        "legs",
        "position",
        "q",
        "quat",
        "rho2",
        "rot",
        "xs",
        "ys",
    )


class PlatformMap:
    """Closed-form platform -> tree map of one hexapod (see the module docstring).

    Args:
        geometry: the :class:`~hexapod_pin.geometry.HexapodGeometry`.
        indices: the :class:`~hexapod_pin.hexapod.HexapodIndices` of its tree.
        nq, nv: sizes of the tree's configuration and velocity.
    """

    def __init__(self, geometry, indices, nq: int, nv: int):
        g = geometry
        self.leg_length = float(g.leg_length)
        self.nq, self.nv = int(nq), int(nv)
        mids, dirs, pts = g.rail_midpoints, g.rail_directions, g.platform_points
        self._points = [tuple(float(c) for c in p) for p in pts]
        self._carriages = []
        for i in range(6):
            k = i // 2
            (mx, my, mz), (ux, uy, uz) = mids[k].tolist(), dirs[k].tolist()
            self._carriages.append((k, mx, my, mz, ux, uy, uz, -uy, ux))
        self._type_one = TYPE_I_TOL * self.leg_length
        # the URDF's depth-first joint order: (carriage_i, u_i_a, u_i_b) for i = 0..5, then
        # the platform's free-flyer; the hot paths below build and read q, v in that order
        legs3 = np.arange(18).reshape(6, 3)
        layout = [(indices.carriage_q, legs3[:, 0]), (indices.u_a_q, legs3[:, 1]),
                  (indices.u_b_q, legs3[:, 2]), (indices.carriage_v, legs3[:, 0]),
                  (indices.u_a_v, legs3[:, 1]), (indices.u_b_v, legs3[:, 2])]
        if (any(not np.array_equal(got, want) for got, want in layout)
                or indices.platform_q != slice(18, 25) or indices.platform_v != slice(18, 24)
                or (self.nq, self.nv) != (25, 24)):
            raise HexapodPinError("PlatformMap expects the joint order of "
                                  "urdf/hexapod.urdf.xacro: (carriage_i, u_i_a, u_i_b) for "
                                  f"i = 0..5, then platform_joint; got {indices}")

    # -- pose -> legs -----------------------------------------------------------------
    def legs(self, pose, signs, angles: bool = False, checks: bool = True) -> Legs:
        """Inverse kinematics and leg geometry of a pose (6 floats) on a branch (6 signs).

        Args:
            pose: 6 floats (m, rad).
            signs: the IK branch, 6 floats +1 / -1.
            angles: also compute the universal-joint angles.
            checks: refuse the singular poses below (off: only for building ``q``).

        Raises:
            UnreachablePoseError: a leg cannot reach.
            SingularityError: with ``checks``, a leg perpendicular to its rail (type I)
                or along it (universal joint in gimbal lock).
        """
        x, y, z, roll, pitch, yaw = pose
        cr, sr = math.cos(roll), math.sin(roll)
        cp, sp = math.cos(pitch), math.sin(pitch)
        cy, sy = math.cos(yaw), math.sin(yaw)
        r00, r01, r02 = cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr
        r10, r11, r12 = sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr
        r20, r21, r22 = -sp, cp * sr, cp * cr
        arms = [(r00 * px + r01 * py + r02 * pz, r10 * px + r11 * py + r12 * pz,
                 r20 * px + r21 * py + r22 * pz) for px, py, pz in self._points]
        length = self.leg_length
        length2 = length * length
        qs, legs, along = [], [], []
        short = None
        for (k, mx, my, mz, ux, uy, uz, _, _), s in zip(self._carriages, signs):
            rx, ry, rz = arms[k]
            dx, dy, dz = x + rx - mx, y + ry - my, z + rz - mz
            a = dx * ux + dy * uy + dz * uz
            disc = length2 - (dx * dx + dy * dy + dz * dz - a * a)
            if disc < 0.0:
                short = True
                disc = 0.0
            qi = a + s * math.sqrt(disc)
            nx, ny, nz = dx - qi * ux, dy - qi * uy, dz - qi * uz
            qs.append(qi)
            legs.append((nx, ny, nz))
            along.append(nx * ux + ny * uy + nz * uz)
        if short:
            self._raise_unreachable(pose, signs)
        out = Legs()
        # quaternion of Rz(yaw) Ry(pitch) Rx(roll), w >= 0
        hr, hp, hy = 0.5 * roll, 0.5 * pitch, 0.5 * yaw
        c1, s1 = math.cos(hr), math.sin(hr)
        c2, s2 = math.cos(hp), math.sin(hp)
        c3, s3 = math.cos(hy), math.sin(hy)
        qw = c1 * c2 * c3 + s1 * s2 * s3
        qx = s1 * c2 * c3 - c1 * s2 * s3
        qy = c1 * s2 * c3 + s1 * c2 * s3
        qz = c1 * c2 * s3 - s1 * s2 * c3
        if qw < 0.0:
            qx, qy, qz, qw = -qx, -qy, -qz, -qw
        out.quat = (qx, qy, qz, qw)
        out.rot = (r00, r01, r02, r10, r11, r12, r20, r21, r22)
        out.position = (x, y, z)
        self._finish(out, arms, qs, legs, along, angles, checks)
        return out

    def legs_at(self, q_tree: list, angles: bool = True) -> Legs:
        """Leg geometry read from an assembled tree configuration (list of nq floats).

        The leg vectors come from the universal-joint angles (what the tree itself
        sees), the platform from its free-flyer. Raises SingularityError as :meth:`legs`.
        """
        x, y, z, qx, qy, qz, qw = q_tree[18:25]
        norm = 1.0 / math.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
        qx, qy, qz, qw = qx * norm, qy * norm, qz * norm, qw * norm
        r00, r01, r02 = 1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qz * qw), 2 * (qx * qz + qy * qw)
        r10, r11, r12 = 2 * (qx * qy + qz * qw), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qx * qw)
        r20, r21, r22 = 2 * (qx * qz - qy * qw), 2 * (qy * qz + qx * qw), 1 - 2 * (qx * qx + qy * qy)
        arms = [(r00 * px + r01 * py + r02 * pz, r10 * px + r11 * py + r12 * pz,
                 r20 * px + r21 * py + r22 * pz) for px, py, pz in self._points]
        length = self.leg_length
        qs, legs, along = [], [], []
        for i, (_, _, _, _, ux, uy, uz, lx, ly) in enumerate(self._carriages):
            qc, qa, qb = q_tree[3 * i:3 * i + 3]
            sb, cb = math.sin(qb), math.cos(qb)
            ex, ey, ez = sb, -math.sin(qa) * cb, math.cos(qa) * cb
            nx = length * (ex * ux + ey * lx)
            ny = length * (ex * uy + ey * ly)
            nz = length * (ex * uz + ez)
            qs.append(qc)
            legs.append((nx, ny, nz))
            along.append(nx * ux + ny * uy + nz * uz)
        out = Legs()
        out.quat = (qx, qy, qz, qw)
        out.rot = (r00, r01, r02, r10, r11, r12, r20, r21, r22)
        out.position = (x, y, z)
        self._finish(out, arms, qs, legs, along, angles)
        return out

    def _finish(self, out: Legs, arms, qs, legs, along, angles: bool,
                checks: bool = True) -> None:
        inv_len = 1.0 / self.leg_length
        type_one = self._type_one
        xs, ys, rho2s, exs = [], [], [], []
        for i, (_, _, _, _, _, _, _, lx, ly) in enumerate(self._carriages):
            nx, ny, nz = legs[i]
            if checks and not abs(along[i]) >= type_one:
                raise SingularityError(f"workspace Jacobian: type-I singularity, the leg of "
                                       f"carriage {i} is perpendicular to its rail (|cos|)",
                                       abs(along[i]) * inv_len)
            big_x = nz * inv_len
            big_y = -(nx * lx + ny * ly) * inv_len
            rho2 = big_x * big_x + big_y * big_y
            if checks and not rho2 >= GIMBAL_TOL:
                raise SingularityError(f"leg of carriage {i} lies along its rail (universal "
                                       "joint in gimbal lock; 1 - cos^2)", rho2)
            xs.append(big_x)
            ys.append(big_y)
            rho2s.append(rho2)
            exs.append(along[i] * inv_len)
        out.arms, out.q, out.legs, out.along = arms, qs, legs, along
        out.xs, out.ys, out.rho2, out.ex = xs, ys, rho2s, exs
        if angles:
            out.angles_a = [math.atan2(yv, xv) for xv, yv in zip(xs, ys)]
            out.angles_b = [math.atan2(e, math.sqrt(r)) for e, r in zip(exs, rho2s)]
        else:
            out.angles_a = out.angles_b = None

    def _raise_unreachable(self, pose, signs) -> None:
        x, y, z, roll, pitch, yaw = pose
        length = self.leg_length
        bad, shortfall = [], []
        rot = np.array(rotation_tuple(roll, pitch, yaw))
        for i, (k, mx, my, mz, ux, uy, uz, _, _) in enumerate(self._carriages):
            d = np.array([x, y, z]) + rot @ np.array(self._points[k]) - np.array([mx, my, mz])
            a = d @ np.array([ux, uy, uz])
            disc = length * length - (d @ d - a * a)
            if disc < 0.0:
                bad.append(i)
                shortfall.append(math.sqrt(length * length - disc) - length)
        raise UnreachablePoseError(bad, shortfall)

    # -- tree configuration -------------------------------------------------------------
    def configuration(self, legs: Legs) -> list:
        """Tree configuration (list of nq floats) of legs built with ``angles=True``."""
        q = []
        for values in zip(legs.q, legs.angles_a, legs.angles_b):
            q += values
        q += legs.position
        q += legs.quat
        return q

    def closure_error(self, legs: Legs) -> float:
        """Max-abs gap (m) between each leg tip, rebuilt from the universal-joint angles
        exactly as the tree places it, and its platform point (the closure residual)."""
        length = self.leg_length
        worst = 0.0
        for i, (_, _, _, _, ux, uy, uz, lx, ly) in enumerate(self._carriages):
            qa, qb = legs.angles_a[i], legs.angles_b[i]
            sb, cb = math.sin(qb), math.cos(qb)
            ex, ey, ez = sb, -math.sin(qa) * cb, math.cos(qa) * cb
            nx, ny, nz = legs.legs[i]
            worst = max(worst, abs(length * (ex * ux + ey * lx) - nx),
                        abs(length * (ex * uy + ey * ly) - ny), abs(length * (ex * uz + ez) - nz))
        return worst

    def closure_residual(self, q_tree: list) -> float:
        """Max-abs closure residual (m) of a tree configuration (list of nq floats): the
        gap between each leg tip, placed by the tree's joints, and its platform anchor
        (the same quantity as :meth:`ClosedLoopModel.residual`, in closed form)."""
        x, y, z, qx, qy, qz, qw = q_tree[18:25]
        s = 2.0 / (qx * qx + qy * qy + qz * qz + qw * qw)
        r00, r01, r02 = 1 - s * (qy * qy + qz * qz), s * (qx * qy - qz * qw), s * (qx * qz + qy * qw)
        r10, r11, r12 = s * (qx * qy + qz * qw), 1 - s * (qx * qx + qz * qz), s * (qy * qz - qx * qw)
        r20, r21, r22 = s * (qx * qz - qy * qw), s * (qy * qz + qx * qw), 1 - s * (qx * qx + qy * qy)
        anchors = [(x + r00 * px + r01 * py + r02 * pz, y + r10 * px + r11 * py + r12 * pz,
                    z + r20 * px + r21 * py + r22 * pz) for px, py, pz in self._points]
        length = self.leg_length
        worst = 0.0
        for i, (k, mx, my, mz, ux, uy, uz, lx, ly) in enumerate(self._carriages):
            qc, qa, qb = q_tree[3 * i:3 * i + 3]
            sb, cb = math.sin(qb), math.cos(qb)
            ex, ey, ez = length * sb, -length * math.sin(qa) * cb, length * math.cos(qa) * cb
            ax, ay, az = anchors[k]
            worst = max(worst, abs(mx + qc * ux + ex * ux + ey * lx - ax),
                        abs(my + qc * uy + ex * uy + ey * ly - ay),
                        abs(mz + qc * uz + ex * uz + ez - az))
        return worst

    # -- rates ----------------------------------------------------------------------------
    def velocity(self, legs: Legs, twist) -> tuple[list, list]:
        """Tree velocity (list of nv floats) for a twist (6 floats).

        Returns ``(v, dn)``: ``dn`` holds the leg rates ``dn_i/dt`` (6 tuples) that
        :meth:`acceleration` needs.
        """
        vx, vy, vz, wx, wy, wz = twist
        tips = [(vx + wy * rz - wz * ry, vy + wz * rx - wx * rz, vz + wx * ry - wy * rx)
                for rx, ry, rz in legs.arms]
        inv_len = 1.0 / self.leg_length
        v, dlegs = [], []
        for (k, _, _, _, ux, uy, uz, lx, ly), (nx, ny, nz), nu, big_x, big_y, rho2 in zip(
                self._carriages, legs.legs, legs.along, legs.xs, legs.ys, legs.rho2):
            tx, ty, tz = tips[k]
            qd = (nx * tx + ny * ty + nz * tz) / nu
            dx, dy, dz = tx - qd * ux, ty - qd * uy, tz - qd * uz
            dlegs.append((dx, dy, dz))
            v.append(qd)
            v.append((big_x * -(dx * lx + dy * ly) - big_y * dz) * inv_len / rho2)
            v.append((dx * ux + dy * uy + dz * uz) * inv_len / math.sqrt(rho2))
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = legs.rot
        v += (r00 * vx + r10 * vy + r20 * vz, r01 * vx + r11 * vy + r21 * vz,
              r02 * vx + r12 * vy + r22 * vz, r00 * wx + r10 * wy + r20 * wz,
              r01 * wx + r11 * wy + r21 * wz, r02 * wx + r12 * wy + r22 * wz)
        return v, dlegs

    def acceleration(self, legs: Legs, twist, twist_dot, v: list, dlegs: list) -> list:
        """Tree acceleration (list of nv floats) for ``twist_dot`` (6 floats), given the
        velocity ``v`` and leg rates of :meth:`velocity` at the same twist."""
        vx, vy, vz, wx, wy, wz = twist
        ax, ay, az, bx, by, bz = twist_dot
        accs = []
        for rx, ry, rz in legs.arms:
            # A_k = vdot + wdot x r + w x (w x r)
            cx, cy, cz = wy * rz - wz * ry, wz * rx - wx * rz, wx * ry - wy * rx
            accs.append((ax + by * rz - bz * ry + wy * cz - wz * cy,
                         ay + bz * rx - bx * rz + wz * cx - wx * cz,
                         az + bx * ry - by * rx + wx * cy - wy * cx))
        inv_len = 1.0 / self.leg_length
        a = []
        j = 0
        for (k, _, _, _, ux, uy, uz, lx, ly), (nx, ny, nz), (dx, dy, dz), nu, big_x, big_y, \
                rho2, ex in zip(self._carriages, legs.legs, dlegs, legs.along, legs.xs,
                                legs.ys, legs.rho2, legs.ex):
            tx, ty, tz = accs[k]
            qdd = (dx * dx + dy * dy + dz * dz + nx * tx + ny * ty + nz * tz) / nu
            ddx, ddy, ddz = tx - qdd * ux, ty - qdd * uy, tz - qdd * uz
            adot, bdot = v[j + 1], v[j + 2]
            j += 3
            d_x, d_y = dz * inv_len, -(dx * lx + dy * ly) * inv_len
            a.append(qdd)
            a.append((big_x * -(ddx * lx + ddy * ly) - big_y * ddz) * inv_len / rho2
                     - 2.0 * adot * (big_x * d_x + big_y * d_y) / rho2)
            a.append(((ddx * ux + ddy * uy + ddz * uz) * inv_len + ex * bdot * bdot)
                     / math.sqrt(rho2))
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = legs.rot
        # a_ff = (R^T (vdot - w x v), R^T wdot)
        px = ax - (wy * vz - wz * vy)
        py = ay - (wz * vx - wx * vz)
        pz = az - (wx * vy - wy * vx)
        a += (r00 * px + r10 * py + r20 * pz, r01 * px + r11 * py + r21 * pz,
              r02 * px + r12 * py + r22 * pz, r00 * bx + r10 * by + r20 * bz,
              r01 * bx + r11 * by + r21 * bz, r02 * bx + r12 * by + r22 * bz)
        return a

    # -- forces -------------------------------------------------------------------------------
    def project(self, legs: Legs, force: list) -> list:
        """``G^T force``: the platform wrench ``(f, m)`` (world axes, about the platform
        origin, 6 floats) equivalent by virtual power to a tree generalised force (list
        of nv floats)."""
        inv_len = 1.0 / self.leg_length
        fx = fy = fz = mx = my = mz = 0.0
        arms = legs.arms
        j = 0
        for (k, _, _, _, ux, uy, uz, lx, ly), (nx, ny, nz), nu, big_x, big_y, rho2 in zip(
                self._carriages, legs.legs, legs.along, legs.xs, legs.ys, legs.rho2):
            f_c, f_a, f_b = force[j:j + 3]
            j += 3
            f_b *= inv_len / math.sqrt(rho2)
            f_a *= -inv_len / rho2
            coef = (f_c - f_b) / nu
            f_ax = f_a * big_x
            gx = coef * nx + f_b * ux + f_ax * lx
            gy = coef * ny + f_b * uy + f_ax * ly
            gz = coef * nz + f_b * uz + f_a * big_y
            rx, ry, rz = arms[k]
            fx += gx
            fy += gy
            fz += gz
            mx += ry * gz - rz * gy
            my += rz * gx - rx * gz
            mz += rx * gy - ry * gx
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = legs.rot
        a0, a1, a2, b0, b1, b2 = force[j:j + 6]
        return [fx + r00 * a0 + r01 * a1 + r02 * a2, fy + r10 * a0 + r11 * a1 + r12 * a2,
                fz + r20 * a0 + r21 * a1 + r22 * a2, mx + r00 * b0 + r01 * b1 + r02 * b2,
                my + r10 * b0 + r11 * b1 + r12 * b2, mz + r20 * b0 + r21 * b1 + r22 * b2]

    def force_matrix(self, legs: Legs) -> np.ndarray:
        """``A^T`` (6, 6): column i is ``[n_i, r_k x n_i]`` (so ``J^T = A^T diag(1/(n.u))``)."""
        arms = legs.arms
        cols = []
        for (k, *_), (nx, ny, nz) in zip(self._carriages, legs.legs):
            rx, ry, rz = arms[k]
            cols += (nx, ny, nz, ry * nz - rz * ny, rz * nx - rx * nz, rx * ny - ry * nx)
        return np.array(cols).reshape(6, 6).T

    def solve_forces(self, legs: Legs, wrench) -> list:
        """Actuator forces ``tau`` (6 floats) with ``J^T tau = wrench`` (6 floats).

        ``J^T tau = A^T (tau / (n.u))`` with ``A[i] = [n_i, r_k x n_i]``: one 6x6 LU solve.

        Raises:
            SingularityError: ``A`` numerically singular (type-II singularity).
        """
        lu, _, sol, info = dgesv(self.force_matrix(legs), np.array(wrench))
        diag = lu.diagonal().tolist()
        small, big = min(map(abs, diag)), max(map(abs, diag))
        if info != 0 or not small > TYPE_II_PIVOT_RTOL * big:
            raise SingularityError("leg force matrix A = [n_i, r_k x n_i] (type-II "
                                   "singularity; smallest LU pivot over the largest)",
                                   small / big if big > 0.0 else 0.0)
        return [s * nu for s, nu in zip(sol.tolist(), legs.along)]

    def leg_forces(self, legs: Legs, force: list, tau: list) -> list:
        """The closure multipliers: force (3 floats, world) on each leg tip from the
        platform, from the leg's three tree rows (carriage, u_a, u_b) of
        ``S^T tau + J_c^T lambda = force``.

        Leg i's rows read ``[u, u x n, b x n]^T lambda_i = (force_c - tau_i, force_a,
        force_b)`` with ``b = (X l + Y z) / rho`` the second universal axis; solved by
        Cramer's rule (the determinant vanishes only at the singularities :meth:`legs`
        refuses).
        """
        out = []
        for i, (k, _, _, _, ux, uy, uz, lx, ly) in enumerate(self._carriages):
            nx, ny, nz = legs.legs[i]
            rho = math.sqrt(legs.rho2[i])
            bx, by, bz = legs.xs[i] * lx / rho, legs.xs[i] * ly / rho, legs.ys[i] / rho
            # columns c1 = u, c2 = u x n, c3 = b x n
            c2 = (uy * nz - uz * ny, uz * nx - ux * nz, ux * ny - uy * nx)
            c3 = (by * nz - bz * ny, bz * nx - bx * nz, bx * ny - by * nx)
            y1, y2, y3 = force[3 * i:3 * i + 3]
            y1 -= tau[i]
            # rows of the inverse of C^T are the cross products of the columns / det
            k23 = (c2[1] * c3[2] - c2[2] * c3[1], c2[2] * c3[0] - c2[0] * c3[2],
                   c2[0] * c3[1] - c2[1] * c3[0])
            k31 = (c3[1] * uz - c3[2] * uy, c3[2] * ux - c3[0] * uz, c3[0] * uy - c3[1] * ux)
            k12 = (uy * c2[2] - uz * c2[1], uz * c2[0] - ux * c2[2], ux * c2[1] - uy * c2[0])
            det = ux * k23[0] + uy * k23[1] + uz * k23[2]
            out.append(((y1 * k23[0] + y2 * k31[0] + y3 * k12[0]) / det,
                        (y1 * k23[1] + y2 * k31[1] + y3 * k12[1]) / det,
                        (y1 * k23[2] + y2 * k31[2] + y3 * k12[2]) / det))
        return out

    def velocity_map(self, legs: Legs) -> np.ndarray:
        """``G`` (nv, 6) with ``v_tree = G twist``."""
        out = np.zeros((self.nv, 6))
        inv_len = 1.0 / self.leg_length
        for i, (k, _, _, _, ux, uy, uz, lx, ly) in enumerate(self._carriages):
            nx, ny, nz = legs.legs[i]
            big_x, big_y, rho2 = legs.xs[i], legs.ys[i], legs.rho2[i]
            rx, ry, rz = legs.arms[k]
            inv_nu = 1.0 / legs.along[i]
            cb = inv_len / math.sqrt(rho2)
            ca = -inv_len / rho2
            rows = ((3 * i, (nx * inv_nu, ny * inv_nu, nz * inv_nu)),
                    (3 * i + 2, ((ux - nx * inv_nu) * cb, (uy - ny * inv_nu) * cb,
                                 (uz - nz * inv_nu) * cb)),
                    (3 * i + 1, (ca * big_x * lx, ca * big_x * ly, ca * big_y)))
            for row, (gx, gy, gz) in rows:
                out[row] = (gx, gy, gz, ry * gz - rz * gy, rz * gx - rx * gz, rx * gy - ry * gx)
        rot_t = np.array(legs.rot).reshape(3, 3).T
        out[18:21, :3] = rot_t
        out[21:24, 3:] = rot_t
        return out
