"""Closed-form dynamics of the hexapod for many states at once (vectorised numpy).

An independent route from the Pinocchio tree (:mod:`hexapod_pin.dynamics`): Newton-Euler
of the platform plus a closed form of each leg and carriage, written for N states as
structure-of-arrays numpy (every array ``(6, N)`` or ``(N,)``: the long axis last).

Model (the same bodies as ``urdf/hexapod.urdf.xacro``, numbers from the geometry):

* carriage ``i``: a point mass ``m_c`` at ``c_i = m_k + q_i u_k`` (moves along ``u_k``);
* leg ``i``: a uniform rod of mass ``m_l`` from ``c_i`` to the platform point ``P_k``
  with no inertia about its own axis (the URDF's ``izz = 0``). It is dynamically
  equivalent (same mass, centre of mass and inertia tensor) to point masses
  ``m_l/6, 2 m_l/3, m_l/6`` at ``c_i``, the middle and ``P_k``; its inertia forces and
  weight are therefore statically equivalent to end loads ``m_l (a_c/3 + a_P/6) - m_l g/2``
  at ``c_i`` and ``F_i = m_l (a_c/6 + a_P/3) - m_l g/2`` at ``P_k`` (``g = (0, 0, -g)``,
  ``a_c = qddot_i u_k``, ``a_P = A_k``);
* platform: mass ``m_p`` and principal inertia ``I`` at its origin.

The leg is a two-force member once those end loads are taken off: its universal joint
(free about ``u_k`` and about an axis perpendicular to the leg) and its spherical joint
(free) transmit no moment about the leg's free axes, so the moment of the remaining tip
force about ``c_i`` must vanish on them; the remaining force is axial, ``t_i n_i``.
Hence, per leg and for the platform (world axes, moments about the platform origin)::

    force of leg tip i on the platform   Phi_i = t_i n_i - F_i
    carriage i along its rail            tau_i = c_i + t_i (n_i . u_k),
                                         c_i = (m_c + m_l/3) qddot_i + (m_l/6) u_k . A_k
    platform                             sum_i [Phi_i, r_k x Phi_i] + [m_p g, 0] + wrench
                                           = [m_p vdot, I_w wdot + w x I_w w]

(``r_k = R p_k``, ``I_w = R I R^T``; the rails are horizontal so gravity does no work on
the carriages). Inverse dynamics solves the platform equation ``A^T t = b`` (``A`` rows
``[n_i, r_k x n_i]``) for the six axial forces ``t``; forward dynamics uses the same
relations as the reduced (null-space) equation ``J^T tau + wrench = M_x twist_dot + h_x``
with ``qddot = J twist_dot + qddot_0``::

    M_x = J^T diag(m_c + m_l/3) J + (m_l/6) (J^T U + U^T J) + M_p
    h_x = the same expression as the right-hand side at twist_dot = 0

(``U`` rows ``[u_k, r_k x u_k]``; ``M_p`` the platform plus point masses ``m_l/3`` at the
six ``P_k`` as a rigid body). Kinematics as in :mod:`hexapod_pin.kinematics`
(home branch; ``qddot_i = (|dn_i/dt|^2 + n_i . A_k) / (n_i . u_k)``).

Relies on the hexapod conventions that :class:`~hexapod_pin.geometry.HexapodGeometry`
guarantees: rails and platform points in the planes ``z = 0`` of their frames.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import (BatchActuatorSaturationError, BatchSingularityError,
                      BatchUnreachablePoseError)
from .kinematics import HOME_BRANCH, RAIL_OF, TYPE_I_TOL
from ..core.checks import as_array

#: states per chunk (keeps the temporaries in cache)
CHUNK = 4096
#: Hadamard ratio ``|det A| / prod |columns of A|`` below which a state counts as
#: type-II singular (the platform moves with the carriages locked)
TYPE_II_HADAMARD_TOL = 1e-12
#: relative slack of the actuator bounds (as the single-state routes)
_BOUND_RTOL = 1e-9


# --------------------------------------------------------------------------------------
# results and errors
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class BatchInverseDynamics:
    """Result of :meth:`HexapodDynamics.inverse_dynamics_batch` for N states.

    Attributes:
        actuator_forces: (N, 6), force on carriage i along ``+u_k`` (N).
        closure_forces: (N, 6, 3) force each leg tip exerts on the platform, world (N).
        residual: (N,) max-abs residual of the platform's Newton-Euler equation with
            those forces (N, N m): round-off only.
    """

    actuator_forces: np.ndarray
    closure_forces: np.ndarray
    residual: np.ndarray


@dataclass(frozen=True)
class BatchForwardDynamics:
    """Result of :meth:`HexapodDynamics.forward_dynamics_batch` for N states.

    Attributes:
        twist_dot: (N, 6) time derivative of the world-axes twist (m/s^2, rad/s^2).
        qddot: (N, 6) carriage accelerations (m/s^2).
        closure_forces: (N, 6, 3) force each leg tip exerts on the platform, world (N).
    """

    twist_dot: np.ndarray
    qddot: np.ndarray
    closure_forces: np.ndarray


@dataclass(frozen=True)
class BatchReducedDynamics:
    """Reduced dynamics ``J^T tau + wrench = M_x twist_dot + h_x`` of N states.

    Attributes:
        mass_matrix: ``M_x`` (N, 6, 6), symmetric positive definite.
        bias: ``h_x`` (N, 6) (N, N m): velocity-product and gravity terms.
        jacobian: ``J`` (N, 6, 6), ``qdot = J twist``.
    """

    mass_matrix: np.ndarray
    bias: np.ndarray
    jacobian: np.ndarray

    def __iter__(self):
        return iter((self.mass_matrix, self.bias))


# --------------------------------------------------------------------------------------
# kernel
# --------------------------------------------------------------------------------------
class _Kin:
    """Kinematics of a chunk: every attribute (6, n) per carriage or (n,) per state."""

    __slots__ = ("a0", "dn2", "inertia_w", "n", "nu", "q", "qd", "qdd0", "r", "rot", "w")


class BatchDynamics:
    """Closed-form hexapod dynamics over N states (see the module docstring).

    Args:
        geometry: the :class:`~hexapod_pin.geometry.HexapodGeometry`.
    """

    def __init__(self, geometry):
        g = geometry
        mids = g.rail_midpoints[RAIL_OF]
        dirs = g.rail_directions[RAIL_OF]
        pts = g.platform_points[RAIL_OF]
        col = lambda arr, j: np.ascontiguousarray(arr[:, j:j + 1])
        self._m = (col(mids, 0), col(mids, 1))
        self._u = (col(dirs, 0), col(dirs, 1))
        self._p = (col(pts, 0), col(pts, 1))
        self._signs = HOME_BRANCH[:, None].copy()
        self.leg_length = float(g.leg_length)
        self._type_one = TYPE_I_TOL * self.leg_length
        self.m_c, self.m_l, self.m_p = float(g.carriage_mass), float(g.leg_mass), \
            float(g.platform_mass)
        self.inertia = tuple(float(v) for v in g.platform_inertia)
        self.gravity = float(g.gravity)
        bound = float(g.max_actuator_force)
        self.bounds = np.full(6, bound) if np.isfinite(bound) else None

    # -- kinematics --------------------------------------------------------------------
    def _kinematics(self, poses: np.ndarray, twists: np.ndarray | None, start: int) -> _Kin:
        x, y, z, roll, pitch, yaw = np.ascontiguousarray(poses.T)
        cr, sr, cp, sp = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch)
        cy, sy = np.cos(yaw), np.sin(yaw)
        spsr, spcr = sp * sr, sp * cr
        rot = ((cy * cp, cy * spsr - sy * cr, cy * spcr + sy * sr),
               (sy * cp, sy * spsr + cy * cr, sy * spcr - cy * sr),
               (-sp, cp * sr, cp * cr))
        (px, py), (mx, my), (ux, uy) = self._p, self._m, self._u
        rx = px * rot[0][0] + py * rot[0][1]                    # r = R p_k, (6, n)
        ry = px * rot[1][0] + py * rot[1][1]
        rz = px * rot[2][0] + py * rot[2][1]
        dx, dy, dz = rx + (x - mx), ry + (y - my), rz + z         # P_k - m_k
        along = dx * ux + dy * uy
        disc = self.leg_length ** 2 - (dx * dx + dy * dy + dz * dz) + along * along
        bad = disc < 0.0
        if bad.any():
            state = int(np.flatnonzero(bad.any(axis=0))[0])
            carriages = np.flatnonzero(bad[:, state])
            length = self.leg_length
            raise BatchUnreachablePoseError(
                start + state, carriages,
                np.sqrt(length ** 2 - disc[carriages, state]) - length)
        root = np.sqrt(disc)
        near = root < self._type_one
        if near.any():
            state = int(np.flatnonzero(near.any(axis=0))[0])
            i = int(np.argmin(root[:, state]))
            raise BatchSingularityError(
                start + state, f"workspace Jacobian: type-I singularity, the leg of carriage "
                f"{i} is perpendicular to its rail (|cos|)", root[i, state] / self.leg_length)
        q = along + self._signs * root
        nx, ny = dx - q * ux, dy - q * uy
        kin = _Kin()
        kin.r, kin.n, kin.nu, kin.q, kin.rot = (rx, ry, rz), (nx, ny, dz), -self._signs * root, \
            q, rot
        ia, ib, ic = self.inertia
        if twists is None:
            kin.w = None
            return kin
        vx, vy, vz, wx, wy, wz = np.ascontiguousarray(twists.T)
        # tip velocity V = v + w x r, carriage rate, leg rate dn = V - qdot u
        tx, ty, tz = vx + (wy * rz - wz * ry), vy + (wz * rx - wx * rz), vz + (wx * ry - wy * rx)
        qd = (nx * tx + ny * ty + dz * tz) / kin.nu
        ex, ey = tx - qd * ux, ty - qd * uy
        kin.qd = qd
        kin.dn2 = ex * ex + ey * ey + tz * tz
        # velocity-product tip acceleration w x (w x r)
        cx, cy_, cz = wy * rz - wz * ry, wz * rx - wx * rz, wx * ry - wy * rx
        a0 = (wy * cz - wz * cy_, wz * cx - wx * cz, wx * cy_ - wy * cx)
        kin.a0 = a0
        kin.qdd0 = (kin.dn2 + nx * a0[0] + ny * a0[1] + dz * a0[2]) / kin.nu
        kin.w = (wx, wy, wz)
        # I_w w = R (I (R^T w))
        bw = [rot[0][j] * wx + rot[1][j] * wy + rot[2][j] * wz for j in range(3)]
        bw = (ia * bw[0], ib * bw[1], ic * bw[2])
        kin.inertia_w = tuple(rot[j][0] * bw[0] + rot[j][1] * bw[1] + rot[j][2] * bw[2]
                              for j in range(3))
        return kin

    def _inertia_world(self, rot, vec):
        """``R I R^T vec`` for (n,) component triples."""
        ia, ib, ic = self.inertia
        b = [rot[0][j] * vec[0] + rot[1][j] * vec[1] + rot[2][j] * vec[2] for j in range(3)]
        b = (ia * b[0], ib * b[1], ic * b[2])
        return tuple(rot[j][0] * b[0] + rot[j][1] * b[1] + rot[j][2] * b[2] for j in range(3))

    @staticmethod
    def _leg_matrix(kin: _Kin) -> np.ndarray:
        """``A^T`` (n, 6, 6): column i is ``[n_i, r_k x n_i]``."""
        (rx, ry, rz), (nx, ny, nz) = kin.r, kin.n
        rows = np.stack([nx, ny, nz, ry * nz - rz * ny, rz * nx - rx * nz, rx * ny - ry * nx])
        return np.ascontiguousarray(rows.transpose(2, 0, 1))

    def _check_type_two(self, mat: np.ndarray, start: int) -> None:
        sign, logdet = np.linalg.slogdet(mat)
        lognorms = np.log(np.linalg.norm(mat, axis=1)).sum(axis=1)
        ratio = np.where(sign != 0.0, np.exp(logdet - lognorms), 0.0)
        bad = ~(ratio >= TYPE_II_HADAMARD_TOL)
        if bad.any():
            state = int(np.flatnonzero(bad)[0])
            raise BatchSingularityError(
                start + state, "leg force matrix A = [n_i, r_k x n_i] (type-II singularity; "
                "Hadamard ratio |det| / prod |columns|)", float(ratio[state]))

    def _end_loads(self, kin: _Kin, qdd, acc):
        """``c_i`` (6, n) and the tip loads ``F_i`` (three (6, n)) for carriage
        accelerations ``qdd`` and tip accelerations ``acc``."""
        ux, uy = self._u
        m_c, m_l = self.m_c, self.m_l
        c = (m_c + m_l / 3.0) * qdd + (m_l / 6.0) * (ux * acc[0] + uy * acc[1])
        side = (m_l / 6.0) * qdd
        loads = (side * ux + (m_l / 3.0) * acc[0], side * uy + (m_l / 3.0) * acc[1],
                 (m_l / 3.0) * acc[2] + 0.5 * m_l * self.gravity)
        return c, loads

    def _platform_rhs(self, kin: _Kin, loads, vdot, wdot, wrench) -> np.ndarray:
        """``sum_i [F_i, r x F_i] + [m_p (vdot - g), I_w wdot + w x I_w w] - wrench``
        (6, n)."""
        (rx, ry, rz), (fx, fy, fz) = kin.r, loads
        out = np.empty((6, rx.shape[1]))
        out[0] = fx.sum(axis=0)
        out[1] = fy.sum(axis=0)
        out[2] = fz.sum(axis=0)
        out[3] = (ry * fz - rz * fy).sum(axis=0)
        out[4] = (rz * fx - rx * fz).sum(axis=0)
        out[5] = (rx * fy - ry * fx).sum(axis=0)
        m_p = self.m_p
        out[2] += m_p * self.gravity
        if vdot is not None:
            out[0] += m_p * vdot[0]
            out[1] += m_p * vdot[1]
            out[2] += m_p * vdot[2]
        if kin.w is not None:
            (wx, wy, wz), (hx, hy, hz) = kin.w, kin.inertia_w
            out[3] += wy * hz - wz * hy
            out[4] += wz * hx - wx * hz
            out[5] += wx * hy - wy * hx
        if wdot is not None:
            iw = self._inertia_world(kin.rot, wdot)
            out[3] += iw[0]
            out[4] += iw[1]
            out[5] += iw[2]
        if wrench is not None:
            out -= wrench
        return out

    # -- inverse dynamics ------------------------------------------------------------------
    def inverse(self, poses, twists, twist_dots, wrenches=None,
                bounded: bool = True) -> BatchInverseDynamics:
        """Actuator and closure forces of N motions (arrays validated by the caller)."""
        n = poses.shape[0]
        forces = np.empty((n, 6))
        closure = np.empty((n, 6, 3))
        residual = np.empty(n)
        for start in range(0, n, CHUNK):
            stop = min(start + CHUNK, n)
            kin = self._kinematics(poses[start:stop], twists[start:stop], start)
            ax, ay, az, bx, by, bz = np.ascontiguousarray(twist_dots[start:stop].T)
            rx, ry, rz = kin.r
            acc = (kin.a0[0] + ax + (by * rz - bz * ry), kin.a0[1] + ay + (bz * rx - bx * rz),
                   kin.a0[2] + az + (bx * ry - by * rx))
            nx, ny, nz = kin.n
            qdd = (kin.dn2 + nx * acc[0] + ny * acc[1] + nz * acc[2]) / kin.nu
            c, loads = self._end_loads(kin, qdd, acc)
            wrench = None if wrenches is None else wrenches[start:stop].T
            rhs = self._platform_rhs(kin, loads, (ax, ay, az), (bx, by, bz), wrench)
            mat = self._leg_matrix(kin)
            self._check_type_two(mat, start)
            axial = np.linalg.solve(mat, rhs.T[:, :, None])[:, :, 0]          # t (n, 6)
            residual[start:stop] = np.abs(np.einsum("nij,nj->ni", mat, axial)
                                          - rhs.T).max(axis=1)
            forces[start:stop] = (c + kin.nu * axial.T).T
            t = axial.T
            block = closure[start:stop]
            block[:, :, 0] = (t * nx - loads[0]).T
            block[:, :, 1] = (t * ny - loads[1]).T
            block[:, :, 2] = (t * nz - loads[2]).T
        self._check_bounds(forces, bounded)
        return BatchInverseDynamics(forces, closure, residual)

    def _check_bounds(self, forces: np.ndarray, bounded: bool) -> None:
        if bounded and self.bounds is not None:
            over = np.flatnonzero(np.any(np.abs(forces) > self.bounds * (1 + _BOUND_RTOL),
                                         axis=1))
            if over.size:
                raise BatchActuatorSaturationError(over[0], forces[over[0]], self.bounds)

    def static(self, poses, wrenches=None, bounded: bool = True) -> np.ndarray:
        """Actuator forces (N, 6) holding N poses at rest."""
        n = poses.shape[0]
        forces = np.empty((n, 6))
        for start in range(0, n, CHUNK):
            stop = min(start + CHUNK, n)
            kin = self._kinematics(poses[start:stop], None, start)
            zero = np.zeros((6, stop - start))
            _, loads = self._end_loads(kin, zero, (zero, zero, zero))
            wrench = None if wrenches is None else wrenches[start:stop].T
            rhs = self._platform_rhs(kin, loads, None, None, wrench)
            mat = self._leg_matrix(kin)
            self._check_type_two(mat, start)
            axial = np.linalg.solve(mat, rhs.T[:, :, None])[:, :, 0]
            forces[start:stop] = (kin.nu * axial.T).T
        self._check_bounds(forces, bounded)
        return forces

    # -- reduced dynamics / forward dynamics ------------------------------------------------------
    def _reduced(self, kin: _Kin):
        """``J`` rows (6 components of (6, n)), ``M_x`` (n, 6, 6), ``h_x`` (6, n)."""
        (rx, ry, rz), (nx, ny, nz), nu = kin.r, kin.n, kin.nu
        ux, uy = self._u
        inv = 1.0 / nu
        jac = np.stack([nx * inv, ny * inv, nz * inv, (ry * nz - rz * ny) * inv,
                        (rz * nx - rx * nz) * inv, (rx * ny - ry * nx) * inv])   # (6, 6, n)
        zero = np.zeros_like(rx)
        side = np.stack([ux + zero, uy + zero, zero, -rz * uy, rz * ux, rx * uy - ry * ux])
        m_c, m_l = self.m_c, self.m_l
        mass = np.einsum("aik,bik->kab", (m_c + m_l / 3.0) * jac, jac)
        cross = np.einsum("aik,bik->kab", (m_l / 6.0) * jac, side)
        mass += cross + cross.transpose(0, 2, 1)
        # platform + point masses m_l/3 at each of the six tips, as one rigid body
        mu = m_l / 3.0
        total = self.m_p + 6.0 * mu
        sx, sy, sz = mu * rx.sum(axis=0), mu * ry.sum(axis=0), mu * rz.sum(axis=0)
        for j in range(3):
            mass[:, j, j] += total
        mass[:, 0, 4] += sz
        mass[:, 0, 5] -= sy
        mass[:, 1, 3] -= sz
        mass[:, 1, 5] += sx
        mass[:, 2, 3] += sy
        mass[:, 2, 4] -= sx
        mass[:, 4, 0] += sz
        mass[:, 5, 0] -= sy
        mass[:, 3, 1] -= sz
        mass[:, 5, 1] += sx
        mass[:, 3, 2] += sy
        mass[:, 4, 2] -= sx
        r2 = rx * rx + ry * ry + rz * rz
        comps = (rx, ry, rz)
        rot = kin.rot
        ia, ib, ic = self.inertia
        for a in range(3):
            for b in range(3):
                point = -mu * (comps[a] * comps[b]).sum(axis=0)
                if a == b:
                    point += mu * r2.sum(axis=0)
                body = (rot[a][0] * rot[b][0] * ia + rot[a][1] * rot[b][1] * ib
                        + rot[a][2] * rot[b][2] * ic)
                mass[:, 3 + a, 3 + b] += point + body
        c0, loads0 = self._end_loads(kin, kin.qdd0, kin.a0)
        bias = self._platform_rhs(kin, loads0, None, None, None)
        bias += np.einsum("aik,ik->ak", jac, c0)
        return jac, mass, bias

    def reduced(self, poses, twists) -> BatchReducedDynamics:
        """``M_x``, ``h_x`` and ``J`` of N states."""
        n = poses.shape[0]
        mass = np.empty((n, 6, 6))
        bias = np.empty((n, 6))
        jac = np.empty((n, 6, 6))
        for start in range(0, n, CHUNK):
            stop = min(start + CHUNK, n)
            kin = self._kinematics(poses[start:stop], twists[start:stop], start)
            j, m, h = self._reduced(kin)
            mass[start:stop], bias[start:stop] = m, h.T
            jac[start:stop] = j.transpose(2, 1, 0)
        return BatchReducedDynamics(mass, bias, jac)

    def forward(self, poses, twists, forces, wrenches=None) -> BatchForwardDynamics:
        """Platform and carriage accelerations and closure forces of N states."""
        n = poses.shape[0]
        twist_dot = np.empty((n, 6))
        qddot = np.empty((n, 6))
        closure = np.empty((n, 6, 3))
        for start in range(0, n, CHUNK):
            stop = min(start + CHUNK, n)
            kin = self._kinematics(poses[start:stop], twists[start:stop], start)
            self._check_type_two(self._leg_matrix(kin), start)
            jac, mass, bias = self._reduced(kin)
            tau = forces[start:stop].T                                          # (6, n)
            rhs = np.einsum("aik,ik->ka", jac, tau) - bias.T
            if wrenches is not None:
                rhs += wrenches[start:stop]
            tdd = np.linalg.solve(mass, rhs[:, :, None])[:, :, 0]               # (n, 6)
            twist_dot[start:stop] = tdd
            qdd = np.einsum("aik,ka->ik", jac, tdd) + kin.qdd0                  # (6, n)
            qddot[start:stop] = qdd.T
            ax, ay, az, bx, by, bz = tdd.T
            rx, ry, rz = kin.r
            acc = (kin.a0[0] + ax + (by * rz - bz * ry), kin.a0[1] + ay + (bz * rx - bx * rz),
                   kin.a0[2] + az + (bx * ry - by * rx))
            c, loads = self._end_loads(kin, qdd, acc)
            t = (tau - c) / kin.nu
            nx, ny, nz = kin.n
            block = closure[start:stop]
            block[:, :, 0] = (t * nx - loads[0]).T
            block[:, :, 1] = (t * ny - loads[1]).T
            block[:, :, 2] = (t * nz - loads[2]).T
        return BatchForwardDynamics(twist_dot, qddot, closure)


def check_batch(poses, twists=None, twist_dots=None, wrenches=None, forces=None):
    """Validate batch inputs: (N, 6) each, same N; None passes through."""
    poses = as_array(poses, (6,), "poses", batch=True)
    n = poses.shape[0]
    out = [poses]
    for name, arr in (("twists", twists), ("twist_dots", twist_dots), ("wrenches", wrenches),
                      ("actuator_forces", forces)):
        if arr is None:
            out.append(None)
            continue
        arr = as_array(arr, (6,), name, batch=True)
        if arr.shape[0] != n:
            from ..errors import InputError

            raise InputError(name, arr, f"expected {n} rows like poses, got {arr.shape[0]}")
        out.append(arr)
    return out
