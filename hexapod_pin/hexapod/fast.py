"""Compiled fast path (numba) for the hexapod's single-state dynamics and simulation.

The kernels below are a scalar, one-state port of the closed form of
:mod:`hexapod_pin.batch_dynamics` (see its docstring for the model and the equations):
inverse dynamics, forward dynamics (reduced equation ``M_x twist_dot = J^T tau + wrench -
h_x``, Cholesky) and statics, plus a simulation loop in independent coordinates. They
never call Pinocchio; the tests check them against the Pinocchio routes of
:class:`~hexapod_pin.dynamics.HexapodDynamics` to 1e-10.

Compilation: numba compiles the kernels on first use (``@njit(cache=True)``: the machine
code is cached next to this module, in ``__pycache__``, so later processes only load it:
about 25-30 s to compile on a small 2-core machine, under a second to load). numba is a
dependency of the library (:mod:`hexapod_pin.platform_kernels` needs it too); should this
module fail to import it (the tests simulate that), :func:`available` is False and the same
functions run as plain Python: correct, but slower than the reference routes (ID about
350 µs, simulation about 0.4x real time at 1 kHz). No other module of the library imports
this one. The kernels are compiled with the fast-math flags ``contract,
reassoc, nsz`` only (no ``nnan`` / ``ninf``: the finiteness checks stay exact); results
differ from the reference routes by round-off. The small helpers are inlined by LLVM
(``forceinline``) and compiled, like the simulation loop, without numba's reference
counting (they never allocate): handing arrays to a helper then costs nothing.

Conventions (those of the library): pose ``(x, y, z, roll, pitch, yaw)`` (m, rad) with
``R = Rz(yaw) Ry(pitch) Rx(roll)``; twist ``(v, w)`` of the platform origin, world axes;
``twist_dot`` its plain time derivative; ``tau_i`` the force on carriage i along ``+u_k``
(N), carriage order; wrench ``(f, m)`` applied on the platform by the environment, world
axes, moment about the platform origin (N, N m); home IK branch.

Errors: the kernels return a status code, never NaN. The public functions validate their
inputs once; on any non-zero code they re-run the reference (Pinocchio) route of the same
state, which raises the library's usual exception with its values
(:class:`~hexapod_pin.errors.UnreachablePoseError`,
:class:`~hexapod_pin.errors.SingularityError`, :class:`~hexapod_pin.errors.InputError`);
at the exact border of a tolerance, where that route succeeds, its answer is returned.

Simulation (:func:`simulate_fast`): state ``(p, Q, v, w)`` with ``Q`` the unit quaternion
of ``R`` (no gimbal lock), ``dp/dt = v``, ``dQ/dt = 1/2 (0, w) (x) Q`` (world angular
velocity), ``d(v, w)/dt = a`` from the forward dynamics. Forces are held over a step
(zero-order hold), either constant or a joint PID on carriage set-points (IK and
``J twist`` of a sampled platform reference, computed once per reference sample before
the loop; the law of :class:`~hexapod_pin.simulate.PIDController`). Integrators:

``"rk4"`` (default)
    classical Runge-Kutta, four forward dynamics per step, the quaternion renormalised
    after the step; fourth order (the error falls 16x when ``dt`` halves). Unactuated
    under gravity, the total energy is kept to about 1e-11 of the kinetic energy at
    1 kHz. Caveat of the zero-order hold, not of RK4: a command held over the step lags
    by half a step on average, so an undamped stiff P-law (no ``kd``) gains energy.
``"rk2"``
    explicit midpoint, two forward dynamics per step; second order (error 4x smaller
    when ``dt`` halves); energy error about 1e-6 of the kinetic energy unactuated.
``"semi_implicit_euler"``
    one forward dynamics per step: ``(v, w)+ = (v, w) + dt a``, then ``p+ = p + dt v+``
    and ``Q+ = exp(dt w+) (x) Q`` (the scheme of MuJoCo's default Euler integrator for a
    free joint). First order (error 2x smaller when ``dt`` halves). Energy: unactuated
    under gravity it loses about 1.4 % of the kinetic energy reached at 1 kHz (first
    order in ``dt``); on an oscillation it neither grows nor stays constant but decays
    slowly (about 1.4 % of the kinetic energy per second at 1 kHz; the scheme is not
    symplectic here, the mass matrix depending on the pose), including under the
    undamped P-law where the Runge-Kutta schemes gain energy. The only one of the three
    above 1000x real time at 1 kHz on a small machine (see ``benchmarks/bench_fast.py``).

Independent coordinates keep the closures exactly (the tree is rebuilt from the pose), so
there is no drift to project. The result, :class:`FastTrajectory`, is a smaller
:class:`~hexapod_pin.simulate.Trajectory` (no tree configurations; rebuild one with
``robot.configuration(pose)``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..errors import ActuatorSaturationError, HexapodPinError, InputError, StrokeLimitError
from .kinematics import GIMBAL_TOL, HOME_BRANCH, RAIL_OF, TYPE_I_TOL
from .kernels import GIMBAL, NOT_PD, OK, TYPE_I, TYPE_II, UNREACHABLE, lu_solve6
from .platform_map import TYPE_II_PIVOT_RTOL
from ..core.checks import as_array
from .simulation import check_run_arguments

try:  # a dependency; the plain-Python fallback below is for its absence
    import numba as _numba
except ImportError:  # pragma: no cover - exercised in a subprocess by the tests
    _numba = None

__all__ = ["FastDynamics", "FastTrajectory", "available", "fast_dynamics", "simulate_fast"]


def available() -> bool:
    """Whether numba is importable (the kernels are then compiled, else plain Python:
    correct but slower than the reference routes)."""
    return _numba is not None


_FLAGS = {"cache": True, "error_model": "numpy", "fastmath": {"contract", "reassoc", "nsz"}}


def _jit(func):
    return _numba.njit(**_FLAGS)(func) if _numba is not None else func


def _lean_options() -> dict:
    """Options compiling a kernel without numba's reference-counting runtime, for code
    that never allocates (numba's private jit option ``_nrt``, present in numba 0.68;
    plain options when a numba lacks it: same results, slower)."""
    try:
        from numba.core.options import DefaultOptions
    except ImportError:  # pragma: no cover - another numba layout: plain options
        return {}
    return {"_nrt": False} if hasattr(DefaultOptions, "_nrt") else {}


_LEAN = _lean_options() if _numba is not None else {}
#: the shared 6x6 LU of platform_kernels (its plain-Python body in the fallback)
_lu_solve6 = lu_solve6 if _numba is not None else lu_solve6.py_func


def _jit_lean(func):
    """:func:`_jit` without reference counting (an allocation-free kernel)."""
    return _numba.njit(**_LEAN, **_FLAGS)(func) if _numba is not None else func


def _jit_inline(func):
    """:func:`_jit_lean`, inlined by LLVM into its compiled callers (``forceinline``): a
    small helper then costs its arithmetic only, no call and no reference count of its
    array arguments (together they were about a third of a semi-implicit Euler step)."""
    if _numba is None:
        return func
    return _numba.njit(forceinline=True, **_LEAN, **_FLAGS)(func)


# status codes of the kernels
NONFINITE, STROKE, GAP, SATURATED = range(6, 10)   # OK .. NOT_PD (0-5): platform_kernels'
_STATUS_OF_CODE = {STROKE: "stroke_limit", GAP: "carriage_gap"}

# layout of the packed geometry vector (per-carriage blocks of 6, then scalars)
_MX, _MY, _UX, _UY, _PX, _PY, _SG = (6 * j for j in range(7))
_L, _MC, _ML, _MP, _IA, _IB, _IC, _G, _T1, _GIM, _T2, _BND, _HALF, _GAP = range(42, 56)
# rows of the per-carriage work array (n_rows, 6)
_RX, _RY, _RZ, _NX, _NY, _NZ, _NU, _Q, _QD, _DN2, _A0X, _A0Y, _A0Z, _QDD0, _INV = range(15)
_WORK_ROWS = 15


def pack_geometry(geometry) -> np.ndarray:
    """The geometry as the flat float64 vector the kernels read (56,).

    Raises:
        HexapodPinError: rails or platform points off the planes ``z = 0`` (the closed
            form relies on it, as :mod:`hexapod_pin.batch_dynamics`).
    """
    g = geometry
    mids, dirs, pts = g.rail_midpoints[RAIL_OF], g.rail_directions[RAIL_OF], \
        g.platform_points[RAIL_OF]
    if np.any(mids[:, 2] != 0.0) or np.any(dirs[:, 2] != 0.0) or np.any(pts[:, 2] != 0.0):
        raise HexapodPinError("the compiled dynamics needs rails and platform points in the "
                              "planes z = 0 of their frames")
    out = np.zeros(56)
    for start, values in ((_MX, mids[:, 0]), (_MY, mids[:, 1]), (_UX, dirs[:, 0]),
                          (_UY, dirs[:, 1]), (_PX, pts[:, 0]), (_PY, pts[:, 1]),
                          (_SG, HOME_BRANCH)):
        out[start:start + 6] = values
    ia, ib, ic = g.platform_inertia
    out[_L:_GAP + 1] = (g.leg_length, g.carriage_mass, g.leg_mass, g.platform_mass, ia, ib, ic,
                        g.gravity, TYPE_I_TOL * g.leg_length, GIMBAL_TOL, TYPE_II_PIVOT_RTOL,
                        g.max_actuator_force, g.rail_half_length, g.carriage_min_gap)
    return out


# --------------------------------------------------------------------------------------
# kernels (scalar code; compiled when numba is present)
# --------------------------------------------------------------------------------------
@_jit_inline
def _rotation_rpy(roll, pitch, yaw, rot):
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    rot[0], rot[1], rot[2] = cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr
    rot[3], rot[4], rot[5] = sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr
    rot[6], rot[7], rot[8] = -sp, cp * sr, cp * cr


@_jit_inline
def _rotation_quat(w, x, y, z, rot):
    """``R`` (row-major 9) of a quaternion ``(w, x, y, z)`` (any non-zero norm)."""
    s = 2.0 / (w * w + x * x + y * y + z * z)
    rot[0], rot[1], rot[2] = 1.0 - s * (y * y + z * z), s * (x * y - z * w), s * (x * z + y * w)
    rot[3], rot[4], rot[5] = s * (x * y + z * w), 1.0 - s * (x * x + z * z), s * (y * z - x * w)
    rot[6], rot[7], rot[8] = s * (x * z - y * w), s * (y * z + x * w), 1.0 - s * (x * x + y * y)


@_jit_inline
def _legs(geo, x, y, z, rot, wk):
    """Carriage positions and leg vectors of a pose (home branch); returns a code."""
    length = geo[_L]
    worst = OK
    for i in range(6):
        px, py = geo[_PX + i], geo[_PY + i]
        ux, uy = geo[_UX + i], geo[_UY + i]
        rx = rot[0] * px + rot[1] * py
        ry = rot[3] * px + rot[4] * py
        rz = rot[6] * px + rot[7] * py
        dx, dy, dz = x + rx - geo[_MX + i], y + ry - geo[_MY + i], z + rz
        along = dx * ux + dy * uy
        disc = length * length - (dx * dx + dy * dy + dz * dz) + along * along
        if not disc >= 0.0:
            return UNREACHABLE
        root = math.sqrt(disc)
        q = along + geo[_SG + i] * root
        nx, ny = dx - q * ux, dy - q * uy
        nu = nx * ux + ny * uy
        if not abs(nu) >= geo[_T1]:
            worst = TYPE_I
        else:
            nl = -nx * uy + ny * ux                       # n . l, l = z x u
            if not (dz * dz + nl * nl) / (length * length) >= geo[_GIM]:
                worst = GIMBAL
        wk[_RX, i], wk[_RY, i], wk[_RZ, i] = rx, ry, rz
        wk[_NX, i], wk[_NY, i], wk[_NZ, i] = nx, ny, dz
        wk[_NU, i], wk[_Q, i] = nu, q
    return worst


@_jit_inline
def _rates(geo, twist, wk, drift=True):
    """Carriage rates and (``drift``) ``|dn/dt|^2``, ``w x (w x r)``, ``qddot_0``."""
    vx, vy, vz, wx, wy, wz = twist[0], twist[1], twist[2], twist[3], twist[4], twist[5]
    for i in range(6):
        rx, ry, rz = wk[_RX, i], wk[_RY, i], wk[_RZ, i]
        nx, ny, nz, nu = wk[_NX, i], wk[_NY, i], wk[_NZ, i], wk[_NU, i]
        ux, uy = geo[_UX + i], geo[_UY + i]
        cx, cy, cz = wy * rz - wz * ry, wz * rx - wx * rz, wx * ry - wy * rx
        tx, ty, tz = vx + cx, vy + cy, vz + cz
        inv = 1.0 / nu
        wk[_INV, i] = inv
        qd = (nx * tx + ny * ty + nz * tz) * inv
        wk[_QD, i] = qd
        if drift:
            ex, ey = tx - qd * ux, ty - qd * uy
            dn2 = ex * ex + ey * ey + tz * tz
            ax, ay, az = wy * cz - wz * cy, wz * cx - wx * cz, wx * cy - wy * cx
            wk[_DN2, i] = dn2
            wk[_A0X, i], wk[_A0Y, i], wk[_A0Z, i] = ax, ay, az
            wk[_QDD0, i] = (dn2 + nx * ax + ny * ay + nz * az) * inv


@_jit_inline
def _inertia_world(geo, rot, vx, vy, vz, out, offset):
    """``out[offset:offset+3] += R I R^T v``."""
    b0 = geo[_IA] * (rot[0] * vx + rot[3] * vy + rot[6] * vz)
    b1 = geo[_IB] * (rot[1] * vx + rot[4] * vy + rot[7] * vz)
    b2 = geo[_IC] * (rot[2] * vx + rot[5] * vy + rot[8] * vz)
    out[offset] += rot[0] * b0 + rot[1] * b1 + rot[2] * b2
    out[offset + 1] += rot[3] * b0 + rot[4] * b1 + rot[5] * b2
    out[offset + 2] += rot[6] * b0 + rot[7] * b1 + rot[8] * b2


@_jit_inline
def _gyroscopic(geo, rot, twist, out, sign):
    """``out[3:6] += sign * w x (I_w w)``."""
    wx, wy, wz = twist[3], twist[4], twist[5]
    b0 = geo[_IA] * (rot[0] * wx + rot[3] * wy + rot[6] * wz)
    b1 = geo[_IB] * (rot[1] * wx + rot[4] * wy + rot[7] * wz)
    b2 = geo[_IC] * (rot[2] * wx + rot[5] * wy + rot[8] * wz)
    hx = rot[0] * b0 + rot[1] * b1 + rot[2] * b2
    hy = rot[3] * b0 + rot[4] * b1 + rot[5] * b2
    hz = rot[6] * b0 + rot[7] * b1 + rot[8] * b2
    out[3] += sign * (wy * hz - wz * hy)
    out[4] += sign * (wz * hx - wx * hz)
    out[5] += sign * (wx * hy - wy * hx)


@_jit_inline
def _add_tip_loads(wk, i, fx, fy, fz, out):
    """``out += [F, r x F]`` for the tip load of carriage i."""
    rx, ry, rz = wk[_RX, i], wk[_RY, i], wk[_RZ, i]
    out[0] += fx
    out[1] += fy
    out[2] += fz
    out[3] += ry * fz - rz * fy
    out[4] += rz * fx - rx * fz
    out[5] += rx * fy - ry * fx


@_jit
def _solve_legs(wk, rhs, rtol, mat):
    """Solve ``A^T t = rhs`` in place (``A^T`` columns ``[n_i, r_k x n_i]``) by LU with
    partial pivoting; returns TYPE_II when the smallest pivot is below ``rtol`` times the
    largest (as :meth:`PlatformMap.solve_forces`)."""
    for i in range(6):
        rx, ry, rz = wk[_RX, i], wk[_RY, i], wk[_RZ, i]
        nx, ny, nz = wk[_NX, i], wk[_NY, i], wk[_NZ, i]
        mat[0, i], mat[1, i], mat[2, i] = nx, ny, nz
        mat[3, i], mat[4, i], mat[5, i] = ry * nz - rz * ny, rz * nx - rx * nz, rx * ny - ry * nx
    return _lu_solve6(mat, rhs, rtol, np.arange(6))


@_jit_inline
def _finite(vec):
    for k in range(vec.shape[0]):
        if not math.isfinite(vec[k]):
            return False
    return True


@_jit_inline
def _check_bound(geo, tau, bounded):
    if bounded and math.isfinite(geo[_BND]):
        for i in range(6):
            if abs(tau[i]) > geo[_BND] * (1.0 + 1e-9):
                return SATURATED
    return OK


@_jit
def _state_of(geo, pose, twist, other, wrench, rot, wk):
    """The common start of the single-state kernels: the four input vectors finite, then
    ``R``, the legs and their rates of ``(pose, twist)``; returns a code."""
    if not (_finite(pose) and _finite(twist) and _finite(other) and _finite(wrench)):
        return NONFINITE
    _rotation_rpy(pose[3], pose[4], pose[5], rot)
    code = _legs(geo, pose[0], pose[1], pose[2], rot, wk)
    if code != OK:
        return code
    _rates(geo, twist, wk)
    return OK


@_jit
def inverse_kernel(geo, pose, twist, twist_dot, wrench, bounded, tau):
    """Inverse dynamics: fills ``tau`` (6,) and returns a status code."""
    rot = np.empty(9)
    wk = np.empty((_WORK_ROWS, 6))
    code = _state_of(geo, pose, twist, twist_dot, wrench, rot, wk)
    if code != OK:
        return code
    m_c, m_l, m_p, g = geo[_MC], geo[_ML], geo[_MP], geo[_G]
    ax, ay, az, bx, by, bz = (twist_dot[0], twist_dot[1], twist_dot[2], twist_dot[3],
                              twist_dot[4], twist_dot[5])
    rhs = np.zeros(6)
    for i in range(6):
        rx, ry, rz = wk[_RX, i], wk[_RY, i], wk[_RZ, i]
        cx = wk[_A0X, i] + ax + (by * rz - bz * ry)
        cy = wk[_A0Y, i] + ay + (bz * rx - bx * rz)
        cz = wk[_A0Z, i] + az + (bx * ry - by * rx)
        qdd = (wk[_DN2, i] + wk[_NX, i] * cx + wk[_NY, i] * cy + wk[_NZ, i] * cz) / wk[_NU, i]
        ux, uy = geo[_UX + i], geo[_UY + i]
        tau[i] = (m_c + m_l / 3.0) * qdd + (m_l / 6.0) * (ux * cx + uy * cy)
        side = (m_l / 6.0) * qdd
        _add_tip_loads(wk, i, side * ux + (m_l / 3.0) * cx, side * uy + (m_l / 3.0) * cy,
                       (m_l / 3.0) * cz + 0.5 * m_l * g, rhs)
    rhs[0] += m_p * ax
    rhs[1] += m_p * ay
    rhs[2] += m_p * (az + g)
    _gyroscopic(geo, rot, twist, rhs, 1.0)
    _inertia_world(geo, rot, bx, by, bz, rhs, 3)
    for j in range(6):
        rhs[j] -= wrench[j]
    mat = np.empty((6, 6))
    code = _solve_legs(wk, rhs, geo[_T2], mat)
    if code != OK:
        return code
    for i in range(6):
        tau[i] += wk[_NU, i] * rhs[i]
    return _check_bound(geo, tau, bounded)


@_jit
def _static_at(geo, wk, wrench, rhs, mat, tau):
    """Statics at legs ``wk`` (no rates needed): fills ``tau`` (6,); returns a code."""
    for j in range(6):
        rhs[j] = -wrench[j]
    half_leg = 0.5 * geo[_ML] * geo[_G]
    for i in range(6):
        _add_tip_loads(wk, i, 0.0, 0.0, half_leg, rhs)
    rhs[2] += geo[_MP] * geo[_G]
    code = _solve_legs(wk, rhs, geo[_T2], mat)
    if code != OK:
        return code
    for i in range(6):
        tau[i] = wk[_NU, i] * rhs[i]
    return OK


@_jit
def static_kernel(geo, pose, wrench, bounded, tau):
    """Statics: fills ``tau`` (6,) holding ``pose`` at rest; returns a status code."""
    if not (_finite(pose) and _finite(wrench)):
        return NONFINITE
    rot = np.empty(9)
    wk = np.empty((_WORK_ROWS, 6))
    _rotation_rpy(pose[3], pose[4], pose[5], rot)
    code = _legs(geo, pose[0], pose[1], pose[2], rot, wk)
    if code != OK:
        return code
    code = _static_at(geo, wk, wrench, np.empty(6), np.empty((6, 6)), tau)
    if code != OK:
        return code
    return _check_bound(geo, tau, bounded)


@_jit_inline
def _forward_core(geo, rot, twist, forces, wrench, wk, mats, out):
    """Reduced forward dynamics at legs ``wk`` (rates done): ``out`` = twist_dot (6,);
    ``mats[0]`` gets ``J^T`` (6, 6) (column i: ``J_i = [n_i, r_i x n_i] / (n_i . u_i)``),
    ``mats[1]`` the Cholesky factor of the reduced mass matrix. Returns OK or NOT_PD."""
    jac, mass = mats[0], mats[1]
    m_c, m_l, m_p, g = geo[_MC], geo[_ML], geo[_MP], geo[_G]
    mu = m_l / 3.0
    m_leg, m_side = m_c + m_l / 3.0, m_l / 6.0
    o0, o1, o2 = wrench[0], wrench[1], wrench[2] - m_p * g
    o3, o4, o5 = wrench[3], wrench[4], wrench[5]
    # the 21 entries of the legs' share of the mass matrix (upper triangle), in registers
    m00 = m01 = m02 = m03 = m04 = m05 = m11 = m12 = m13 = m14 = m15 = 0.0
    m22 = m23 = m24 = m25 = m33 = m34 = m35 = m44 = m45 = m55 = 0.0
    sx = sy = sz = 0.0
    pxx = pyy = pzz = pxy = pxz = pyz = 0.0
    for i in range(6):
        rx, ry, rz = wk[_RX, i], wk[_RY, i], wk[_RZ, i]
        nx, ny, nz, inv = wk[_NX, i], wk[_NY, i], wk[_NZ, i], wk[_INV, i]
        ux, uy = geo[_UX + i], geo[_UY + i]
        j0, j1, j2 = nx * inv, ny * inv, nz * inv
        j3, j4, j5 = (ry * nz - rz * ny) * inv, (rz * nx - rx * nz) * inv, \
            (rx * ny - ry * nx) * inv
        jac[0, i], jac[1, i], jac[2, i], jac[3, i], jac[4, i], jac[5, i] = j0, j1, j2, j3, j4, j5
        # U_i = [u, r x u] = (ux, uy, 0, -rz uy, rz ux, rx uy - ry ux); the leg's share of
        # the mass matrix is m_leg J J^T + m_side (J U^T + U J^T) = J W^T + V J^T with
        # W = m_leg J + m_side U, V = m_side U (V_2 = 0)
        v0, v1 = m_side * ux, m_side * uy
        v3, v4, v5 = -rz * v1, rz * v0, rx * v1 - ry * v0
        w0, w1, w2 = m_leg * j0 + v0, m_leg * j1 + v1, m_leg * j2
        w3, w4, w5 = m_leg * j3 + v3, m_leg * j4 + v4, m_leg * j5 + v5
        m00, m01 = m00 + j0 * w0 + v0 * j0, m01 + j0 * w1 + v0 * j1
        m02, m03 = m02 + j0 * w2 + v0 * j2, m03 + j0 * w3 + v0 * j3
        m04, m05 = m04 + j0 * w4 + v0 * j4, m05 + j0 * w5 + v0 * j5
        m11, m12 = m11 + j1 * w1 + v1 * j1, m12 + j1 * w2 + v1 * j2
        m13, m14 = m13 + j1 * w3 + v1 * j3, m14 + j1 * w4 + v1 * j4
        m15 = m15 + j1 * w5 + v1 * j5
        m22, m23 = m22 + j2 * w2, m23 + j2 * w3
        m24, m25 = m24 + j2 * w4, m25 + j2 * w5
        m33, m34 = m33 + j3 * w3 + v3 * j3, m34 + j3 * w4 + v3 * j4
        m35 = m35 + j3 * w5 + v3 * j5
        m44, m45 = m44 + j4 * w4 + v4 * j4, m45 + j4 * w5 + v4 * j5
        m55 = m55 + j5 * w5 + v5 * j5
        sx += rx
        sy += ry
        sz += rz
        pxx += rx * rx
        pyy += ry * ry
        pzz += rz * rz
        pxy += rx * ry
        pxz += rx * rz
        pyz += ry * rz
        # bias: end loads at the drift accelerations (twist_dot = 0), J^T c0 and tip loads
        qdd0 = wk[_QDD0, i]
        a0x, a0y, a0z = wk[_A0X, i], wk[_A0Y, i], wk[_A0Z, i]
        c0 = m_leg * qdd0 + m_side * (ux * a0x + uy * a0y)
        f0 = m_side * qdd0
        fx, fy, fz = f0 * ux + mu * a0x, f0 * uy + mu * a0y, mu * a0z + 0.5 * m_l * g
        load = forces[i] - c0
        o0 += j0 * load - fx
        o1 += j1 * load - fy
        o2 += j2 * load - fz
        o3 += j3 * load - (ry * fz - rz * fy)
        o4 += j4 * load - (rz * fx - rx * fz)
        o5 += j5 * load - (rx * fy - ry * fx)
    mass[0, 0], mass[0, 1], mass[0, 2] = m00, m01, m02
    mass[0, 3], mass[0, 4], mass[0, 5] = m03, m04, m05
    mass[1, 1], mass[1, 2], mass[1, 3], mass[1, 4], mass[1, 5] = m11, m12, m13, m14, m15
    mass[2, 2], mass[2, 3], mass[2, 4], mass[2, 5] = m22, m23, m24, m25
    mass[3, 3], mass[3, 4], mass[3, 5] = m33, m34, m35
    mass[4, 4], mass[4, 5] = m44, m45
    mass[5, 5] = m55
    # platform plus point masses mu at the six tips, as one rigid body (upper triangle)
    sx, sy, sz = mu * sx, mu * sy, mu * sz
    total = m_p + 6.0 * mu
    for j in range(3):
        mass[j, j] += total
    mass[0, 4] += sz
    mass[0, 5] -= sy
    mass[1, 3] -= sz
    mass[1, 5] += sx
    mass[2, 3] += sy
    mass[2, 4] -= sx
    trace = pxx + pyy + pzz
    # world inertia of the platform R diag(I) R^T (upper triangle), its part of the mass
    # matrix, and the gyroscopic moment w x (I_w w)
    ia, ib, ic = geo[_IA], geo[_IB], geo[_IC]
    i00 = rot[0] * rot[0] * ia + rot[1] * rot[1] * ib + rot[2] * rot[2] * ic
    i11 = rot[3] * rot[3] * ia + rot[4] * rot[4] * ib + rot[5] * rot[5] * ic
    i22 = rot[6] * rot[6] * ia + rot[7] * rot[7] * ib + rot[8] * rot[8] * ic
    i01 = rot[0] * rot[3] * ia + rot[1] * rot[4] * ib + rot[2] * rot[5] * ic
    i02 = rot[0] * rot[6] * ia + rot[1] * rot[7] * ib + rot[2] * rot[8] * ic
    i12 = rot[3] * rot[6] * ia + rot[4] * rot[7] * ib + rot[5] * rot[8] * ic
    mass[3, 3] += mu * (trace - pxx) + i00
    mass[4, 4] += mu * (trace - pyy) + i11
    mass[5, 5] += mu * (trace - pzz) + i22
    mass[3, 4] += i01 - mu * pxy
    mass[3, 5] += i02 - mu * pxz
    mass[4, 5] += i12 - mu * pyz
    wx, wy, wz = twist[3], twist[4], twist[5]
    hx = i00 * wx + i01 * wy + i02 * wz
    hy = i01 * wx + i11 * wy + i12 * wz
    hz = i02 * wx + i12 * wy + i22 * wz
    out[0], out[1], out[2] = o0, o1, o2
    out[3] = o3 - (wy * hz - wz * hy)
    out[4] = o4 - (wz * hx - wx * hz)
    out[5] = o5 - (wx * hy - wy * hx)
    # Cholesky M = R^T R (R upper, in place on the upper triangle, 1 / R_jj on the
    # diagonal), then the two triangular solves
    for j in range(6):
        d = mass[j, j]
        for k in range(j):
            d -= mass[k, j] * mass[k, j]
        if not d > 0.0:
            return NOT_PD
        inv_d = 1.0 / math.sqrt(d)
        mass[j, j] = inv_d
        for c in range(j + 1, 6):
            t = mass[j, c]
            for k in range(j):
                t -= mass[k, j] * mass[k, c]
            mass[j, c] = t * inv_d
    for r in range(6):
        t = out[r]
        for k in range(r):
            t -= mass[k, r] * out[k]
        out[r] = t * mass[r, r]
    for r in range(5, -1, -1):
        t = out[r]
        for k in range(r + 1, 6):
            t -= mass[r, k] * out[k]
        out[r] = t * mass[r, r]
    return OK


@_jit
def forward_kernel(geo, pose, twist, forces, wrench, twist_dot, qddot):
    """Forward dynamics: fills ``twist_dot`` (6,), ``qddot`` (6,); returns a code."""
    rot = np.empty(9)
    wk = np.empty((_WORK_ROWS, 6))
    code = _state_of(geo, pose, twist, forces, wrench, rot, wk)
    if code != OK:
        return code
    mats = np.empty((2, 6, 6))
    code = _forward_core(geo, rot, twist, forces, wrench, wk, mats, twist_dot)
    if code != OK:
        return code
    jac = mats[0]
    for i in range(6):
        s = wk[_QDD0, i]
        for a in range(6):
            s += jac[a, i] * twist_dot[a]
        qddot[i] = s
    return OK


# -- simulation -------------------------------------------------------------------------
# integrators (codes of the kernel) and their explicit Runge-Kutta tableaux (diagonal:
# stage s is evaluated at state + _RK_A[s] dt k_{s-1}; the step is sum_s _RK_B[s] dt k_s)
RK4, SEMI_IMPLICIT_EULER, RK2 = range(3)
INTEGRATORS = {"rk4": RK4, "rk2": RK2, "semi_implicit_euler": SEMI_IMPLICIT_EULER}
_RK_A = np.array([[0.0, 0.5, 0.5, 1.0], [0.0, 0.0, 0.0, 0.0], [0.0, 0.5, 0.0, 0.0]])
_RK_B = np.array([[1.0 / 6.0, 1.0 / 3.0, 1.0 / 3.0, 1.0 / 6.0], [1.0, 0.0, 0.0, 0.0],
                  [0.0, 1.0, 0.0, 0.0]])
_RK_STAGES = np.array([4, 1, 2])


@_jit_inline
def _carriages(geo, state, rot, wk, twist):
    """Legs (and rates) of a state ``(p, Q (w, x, y, z), v, w)``; returns a code (stroke
    not checked)."""
    _rotation_quat(state[3], state[4], state[5], state[6], rot)
    code = _legs(geo, state[0], state[1], state[2], rot, wk)
    if code != OK:
        return code
    for j in range(6):
        twist[j] = state[7 + j]
    _rates(geo, twist, wk)
    return OK


@_jit_inline
def _limits(geo, wk):
    for i in range(6):
        if abs(wk[_Q, i]) > geo[_HALF]:
            return STROKE
    for k in range(3):
        if wk[_Q, 2 * k + 1] - wk[_Q, 2 * k] < geo[_GAP]:
            return GAP
    return OK


@_jit
def _set_points(geo, ref_poses, ref_twists, feedforward, setpoints):
    """Carriage set-points of the reference rows into ``setpoints`` (3, m, 6): ``q``
    (IK), ``qdot`` (``J twist``) and, with ``feedforward``, the static forces of the pose
    (zero wrench), else zero. Returns ``(first_bad_row, code)``; ``first_bad_row = m``
    when all succeed."""
    rot = np.empty(9)
    wk = np.empty((_WORK_ROWS, 6))
    rhs, mat = np.empty(6), np.empty((6, 6))
    n_rows = setpoints.shape[1]
    for row in range(n_rows):
        _rotation_rpy(ref_poses[row, 3], ref_poses[row, 4], ref_poses[row, 5], rot)
        code = _legs(geo, ref_poses[row, 0], ref_poses[row, 1], ref_poses[row, 2], rot, wk)
        if code != OK:
            return row, code
        _rates(geo, ref_twists[row], wk, False)
        for i in range(6):
            setpoints[0, row, i], setpoints[1, row, i] = wk[_Q, i], wk[_QD, i]
            setpoints[2, row, i] = 0.0
        if feedforward:
            code = _static_at(geo, wk, _ZERO6, rhs, mat, setpoints[2, row])
            if code != OK:
                return row, code
    return n_rows, OK


@_jit_inline
def _command(geo, wk, k, mode, forces_in, ref_q, ref_qd, ref_ff, bad_row, bad_code, gains,
             integral, dt, saturation, forces):
    """Actuator forces of step ``k`` into ``forces``; returns (code, saturated)."""
    if mode == 0:
        for i in range(6):
            forces[i] = forces_in[i]
    else:
        row = min(k, ref_q.shape[0] - 1)
        if row >= bad_row:
            return bad_code, False
        kp, ki, kd = gains[0], gains[1], gains[2]
        for i in range(6):
            err = ref_q[row, i] - wk[_Q, i]
            forces[i] = kp * err + ki * integral[i] + kd * (ref_qd[row, i] - wk[_QD, i])
            integral[i] += err * dt
            forces[i] += ref_ff[row, i]
    sat = False
    bound = geo[_BND]
    if saturation != 2 and math.isfinite(bound):
        for i in range(6):
            if saturation == 1 and abs(forces[i]) > bound:
                return SATURATED, False
        for i in range(6):
            if abs(forces[i]) > bound:
                forces[i] = max(-bound, min(bound, forces[i]))
                sat = True
    return OK, sat


@_jit_inline
def _record(rec_state, rec_q, rec_qd, rec_f, rec_sat, n, state, wk, forces, sat):
    for j in range(13):
        rec_state[n, j] = state[j]
    for i in range(6):
        rec_q[n, i], rec_qd[n, i], rec_f[n, i] = wk[_Q, i], wk[_QD, i], forces[i]
    rec_sat[n] = sat


@_jit_inline
def _euler_update(state, acc, dt):
    """Semi-implicit Euler on ``state`` in place: ``(v, w) += dt acc``, then ``p += dt v``
    and ``Q <- exp(dt w) (x) Q`` with the new ``(v, w)``; ``Q`` renormalised."""
    for j in range(6):
        state[7 + j] += dt * acc[j]
    for j in range(3):
        state[j] += dt * state[7 + j]
    wx, wy, wz = state[10], state[11], state[12]
    norm = math.sqrt(wx * wx + wy * wy + wz * wz)
    half = 0.5 * dt * norm
    if half < 1e-4:          # Taylor series: relative errors below half^4 / 120 < 1e-18
        h2 = half * half
        ew, s = 1.0 - h2 * (0.5 - h2 / 24.0), 0.5 * dt * (1.0 - h2 / 6.0)
    else:
        ew, s = math.cos(half), math.sin(half) / norm
    ex, ey, ez = s * wx, s * wy, s * wz
    qw, qx, qy, qz = state[3], state[4], state[5], state[6]
    qw, qx, qy, qz = (ew * qw - ex * qx - ey * qy - ez * qz, ew * qx + ex * qw + ey * qz - ez * qy,
                      ew * qy - ex * qz + ey * qw + ez * qx, ew * qz + ex * qy - ey * qx + ez * qw)
    inv = 1.0 / math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
    state[3], state[4], state[5], state[6] = qw * inv, qx * inv, qy * inv, qz * inv


@_jit_lean
def simulate_kernel(geo, n_steps, dt, record_every, integrator, mode, forces_in, wrench,
                    setpoints, bad_row, bad_code, gains, saturation, check_limits, work,
                    record, last_forces):
    """Integration loop; returns ``(code, step, n_recorded)``.

    ``integrator``: RK4, SEMI_IMPLICIT_EULER or RK2. ``mode`` 0: constant forces, 1: PID
    on ``setpoints`` (3, m, 6) (carriage ``q``, ``qdot`` and feedforward forces of each
    reference row, from :func:`_set_points`; rows ``>= bad_row`` failed with
    ``bad_code``). ``saturation`` 0: clip, 1: raise (code SATURATED), 2: ignore.
    ``work``: scratch ``(vecs (4, 13), rot (9,), wk, mats (2, 6, 6), small (3, 6))``,
    ``vecs[0]`` the initial state. ``record``: ``(state, q, qdot, forces, saturated)``
    arrays of the samples. ``last_forces`` gets the last command computed (before
    clipping when it raised). One loop, one evaluation of the dynamics per pass (a step
    boundary or a Runge-Kutta stage), so that each helper is inlined once; no
    allocation (compiled without the reference-counting runtime).
    """
    vecs, rot, wk, mats, small = work
    state, point, incr, deriv = vecs[0], vecs[1], vecs[2], vecs[3]
    twist, acc, integral = small[0], small[1], small[2]
    rec_state, rec_q, rec_qd, rec_f, rec_sat = record
    ref_q, ref_qd, ref_ff = setpoints[0], setpoints[1], setpoints[2]
    forces = last_forces
    for j in range(13):
        point[j] = state[j]
    for i in range(6):
        integral[i] = 0.0
    n_stages = _RK_STAGES[integrator]
    step, stage, n_rec = 0, 0, 0
    while True:
        code = _carriages(geo, point, rot, wk, twist)
        if code != OK:
            if stage == 0:
                return code, step, (n_rec + 1 if step > 0 else 0)
            return code, step + 1, n_rec + 1
        if stage == 0:
            # a step boundary: limits, command, recording
            stop = _limits(geo, wk) if (check_limits and step > 0) else OK
            sat = False
            if stop == OK:
                code, sat = _command(geo, wk, step, mode, forces_in, ref_q, ref_qd, ref_ff,
                                     bad_row, bad_code, gains, integral, dt, saturation,
                                     forces)
                if code != OK:
                    if step == 0:
                        _record(rec_state, rec_q, rec_qd, rec_f, rec_sat, 0, state, wk,
                                _ZERO6, False)
                    return code, step, n_rec + 1
            if step == 0:
                _record(rec_state, rec_q, rec_qd, rec_f, rec_sat, 0, state, wk, forces, sat)
            elif step % record_every == 0 or stop != OK:
                n_rec += 1
                if stop == OK:
                    _record(rec_state, rec_q, rec_qd, rec_f, rec_sat, n_rec, state, wk,
                            forces, sat)
                else:                     # the stop state, with the previous command
                    _record(rec_state, rec_q, rec_qd, rec_f, rec_sat, n_rec, state, wk,
                            rec_f[n_rec - 1], False)
            if stop != OK:
                return stop, step, n_rec + 1
            if step == n_steps:
                return OK, n_steps, n_rec + 1
        code = _forward_core(geo, rot, twist, forces, wrench, wk, mats, acc)
        if code != OK:
            return code, step + 1, n_rec + 1
        if integrator == SEMI_IMPLICIT_EULER:
            _euler_update(state, acc, dt)
            stage = n_stages
        else:
            b = _RK_B[integrator, stage]
            qw, qx, qy, qz = point[3], point[4], point[5], point[6]
            wx, wy, wz = twist[3], twist[4], twist[5]
            deriv[0], deriv[1], deriv[2] = twist[0], twist[1], twist[2]
            deriv[3] = -0.5 * (wx * qx + wy * qy + wz * qz)
            deriv[4] = 0.5 * (qw * wx + wy * qz - wz * qy)
            deriv[5] = 0.5 * (qw * wy + wz * qx - wx * qz)
            deriv[6] = 0.5 * (qw * wz + wx * qy - wy * qx)
            for j in range(6):
                deriv[7 + j] = acc[j]
            stage += 1
            if stage < n_stages:
                a = _RK_A[integrator, stage] * dt
                for j in range(13):
                    incr[j] = (incr[j] if stage > 1 else 0.0) + b * deriv[j]
                    point[j] = state[j] + a * deriv[j]
            else:
                for j in range(13):
                    state[j] += dt * ((incr[j] if stage > 1 else 0.0) + b * deriv[j])
                inv = 1.0 / math.sqrt(state[3] ** 2 + state[4] ** 2 + state[5] ** 2
                                      + state[6] ** 2)
                for j in range(3, 7):
                    state[j] *= inv
        if stage == n_stages:
            if not _finite(state):
                return NONFINITE, step + 1, n_rec + 1
            for j in range(13):
                point[j] = state[j]
            step += 1
            stage = 0


# --------------------------------------------------------------------------------------
# Python boundary
# --------------------------------------------------------------------------------------
_ZERO6 = np.zeros(6)


def _vec6(value, name: str) -> np.ndarray:
    """A float64 (6,) array (finiteness is checked inside the kernels)."""
    if type(value) is np.ndarray and value.dtype == np.float64 and value.shape == (6,):
        return value
    return as_array(value, (6,), name)


class FastDynamics:
    """Compiled single-state dynamics of one hexapod (get it with :func:`fast_dynamics`).

    Same conventions and results as the reference routes of
    :class:`~hexapod_pin.dynamics.HexapodDynamics` (to round-off), leaner answers:
    plain (6,) arrays, no tree state.

    Args:
        robot: the :class:`~hexapod_pin.Hexapod`.
    """

    def __init__(self, robot):
        self.robot = robot
        self.geo = pack_geometry(robot.geometry)
        bound = float(robot.geometry.max_actuator_force)
        self._bounds = np.full(6, bound) if math.isfinite(bound) else None

    def _fail(self, code: int, reference: Callable[[], np.ndarray], tau=None):
        if code == SATURATED:
            raise ActuatorSaturationError(tau, self._bounds)
        # the reference route raises the precise exception (InputError, unreachable,
        # singular); at a tolerance border where it succeeds, its answer stands
        return reference()

    def inverse_dynamics(self, pose, twist, twist_dot, wrench=None,
                         bounded: bool = True) -> np.ndarray:
        """Actuator forces producing a platform motion (closed-loop inverse dynamics).

        As :meth:`Hexapod.inverse_dynamics` with ``method="kkt"`` (the 6x6 solve).

        Args:
            pose: (6,) (m, rad). twist: ``(v, w)`` world axes (m/s, rad/s), (6,).
            twist_dot: its time derivative (m/s^2, rad/s^2), (6,).
            wrench: ``(f, m)`` on the platform, world axes, about its origin (N, N m);
                default zero.
            bounded: raise when ``abs(tau) > geometry.max_actuator_force``.

        Returns:
            tau (6,) (N), force on carriage i along ``+u_k``.

        Raises:
            ActuatorSaturationError, UnreachablePoseError, SingularityError, InputError.
        """
        pose, twist, twist_dot = _vec6(pose, "pose"), _vec6(twist, "twist"), \
            _vec6(twist_dot, "twist_dot")
        wrench = _ZERO6 if wrench is None else _vec6(wrench, "wrench")
        tau = np.empty(6)
        code = inverse_kernel(self.geo, pose, twist, twist_dot, wrench, bounded, tau)
        if code:
            return self._fail(code, lambda: self.robot.inverse_dynamics(
                pose, twist, twist_dot, None if wrench is _ZERO6 else wrench, method="kkt",
                bounded=bounded, joint_wrenches=False).actuator_forces, tau)
        return tau

    def forward_dynamics(self, pose, twist, actuator_forces, wrench=None) -> np.ndarray:
        """Platform acceleration produced by actuator forces (constrained forward dynamics).

        As :meth:`Hexapod.forward_dynamics` (``twist_dot`` only; for the carriage
        accelerations too, see :meth:`forward_dynamics_full`).

        Args:
            pose: (6,) (m, rad). twist: ``(v, w)`` world axes, (6,).
            actuator_forces: tau (6,) (N). wrench: (6,) or None.

        Returns:
            twist_dot (6,) (m/s^2, rad/s^2), world axes.

        Raises:
            UnreachablePoseError, SingularityError, InputError.
        """
        return self.forward_dynamics_full(pose, twist, actuator_forces, wrench)[0]

    def forward_dynamics_full(self, pose, twist, actuator_forces, wrench=None):
        """:meth:`forward_dynamics` returning ``(twist_dot, qddot)``, each (6,)."""
        pose, twist = _vec6(pose, "pose"), _vec6(twist, "twist")
        forces = _vec6(actuator_forces, "actuator_forces")
        wrench = _ZERO6 if wrench is None else _vec6(wrench, "wrench")
        twist_dot, qddot = np.empty(6), np.empty(6)
        code = forward_kernel(self.geo, pose, twist, forces, wrench, twist_dot, qddot)
        if code:
            def reference():
                res = self.robot.forward_dynamics(pose, twist, forces,
                                                  None if wrench is _ZERO6 else wrench)
                return res.twist_dot, res.actuator_accelerations
            return self._fail(code, reference)
        return twist_dot, qddot

    def static_forces(self, pose, wrench=None, bounded: bool = True) -> np.ndarray:
        """Actuator forces (6,) (N) holding the platform at rest at ``pose``.

        As :meth:`Hexapod.static_forces`. Raises the same exceptions.
        """
        pose = _vec6(pose, "pose")
        wrench = _ZERO6 if wrench is None else _vec6(wrench, "wrench")
        tau = np.empty(6)
        code = static_kernel(self.geo, pose, wrench, bounded, tau)
        if code:
            return self._fail(code, lambda: self.robot.static_forces(
                pose, None if wrench is _ZERO6 else wrench, bounded=bounded), tau)
        return tau


def fast_dynamics(robot) -> FastDynamics:
    """The :class:`FastDynamics` of a hexapod (built once, cached on the robot)."""
    fd = robot.__dict__.get("_fast_dynamics")
    if fd is None:
        fd = robot.__dict__["_fast_dynamics"] = FastDynamics(robot)
    return fd


@dataclass(frozen=True)
class FastTrajectory:
    """Result of :func:`simulate_fast` (a smaller :class:`~hexapod_pin.simulate.Trajectory`).

    Attributes:
        times: (n,) (s).
        poses: (n, 6) platform poses (m, rad).
        quaternions: (n, 4) platform orientation ``(x, y, z, w)``, Pinocchio's order.
        twists: (n, 6) platform twists ``(v, w)``, world axes (m/s, rad/s).
        q: (n, 6) carriage positions (m). qdot: (n, 6) carriage velocities (m/s).
        actuator_forces: (n, 6) forces applied from each sample to the next (N) (last
            row: the command at the final state, or the previous one after a stop).
        saturated: (n,) True where the command was clipped to the bound.
        status: "completed", "stroke_limit", "carriage_gap" or "failed".
        message: details of a stop.
        dt: the step (s).
        wall_time: seconds spent in the compiled code (set-points of the reference, then
            the loop; the first call of a process also compiles it or loads it from the
            cache, see the benchmark).
        integrator: "rk4", "rk2" or "semi_implicit_euler".
    """

    times: np.ndarray
    poses: np.ndarray
    quaternions: np.ndarray
    twists: np.ndarray
    q: np.ndarray
    qdot: np.ndarray
    actuator_forces: np.ndarray
    saturated: np.ndarray
    status: str
    message: str
    dt: float
    wall_time: float
    integrator: str = "rk4"

    @property
    def real_time_factor(self) -> float:
        """Simulated time divided by wall time (that of
        :attr:`hexapod_pin.simulate.Trajectory.real_time_factor`, shared)."""
        from .simulation import Trajectory  # lazily: simulate may come to import us
        return Trajectory.real_time_factor.fget(self)


def _sample_reference(reference, n_steps: int, dt: float):
    """Reference poses and twists (n_steps + 1, 6) from a callable or a pair of arrays."""
    if callable(reference):
        refs = [reference(k * dt) for k in range(n_steps + 1)]
        poses = np.array([as_array(r.pose, (6,), "reference pose") for r in refs])
        twists = np.array([as_array(r.twist, (6,), "reference twist") for r in refs])
        return poses, twists
    try:
        poses, twists = reference
    except (TypeError, ValueError):
        raise InputError("reference", reference, "expected a callable t -> "
                         "PlatformReference or a pair (poses, twists)") from None
    poses = as_array(poses, (6,), "reference poses", batch=True)
    twists = as_array(twists, (6,), "reference twists", batch=True)
    if poses.shape != twists.shape or poses.shape[0] < 1:
        raise InputError("reference", (poses.shape, twists.shape),
                         "poses and twists must have the same number (>= 1) of rows")
    return np.ascontiguousarray(poses), np.ascontiguousarray(twists)


def simulate_fast(robot, duration: float, dt: float = 1e-3, *, pose0=None, twist0=None,
                  actuator_forces=None, wrench=None, reference=None, kp: float = 30000.0,
                  ki: float = 40000.0, kd: float = 3000.0, feedforward: bool = False,
                  check_limits: bool = True, on_limit: str = "stop",
                  saturation: str = "clip", record_every: int = 1,
                  integrator: str = "rk4") -> FastTrajectory:
    """Integrate the hexapod's dynamics in compiled code (in platform coordinates).

    Args:
        robot: the :class:`~hexapod_pin.Hexapod`.
        duration: simulated time (s). dt: step and control period (s).
        pose0, twist0: initial platform state (default: home at rest; with a
            ``reference``, its first sample).
        actuator_forces: constant (6,) forces (N) without a reference; default zero.
        wrench: constant ``(f, m)`` on the platform (world axes, about its origin), held
            in world axes (:func:`~hexapod_pin.simulate.simulate` holds it in platform
            axes over a step: the two differ by O(dt)).
        reference: enables the joint PID of :class:`~hexapod_pin.simulate.PIDController`
            (``tau = kp e + ki sum(e dt) + kd (qdot_ref - qdot)``, ``e = q_ref - q``,
            ``q_ref`` = IK of the reference pose, ``qdot_ref = J`` reference twist, both
            computed in compiled code for each sample before the loop): a callable
            ``t -> PlatformReference`` (sampled at ``k dt`` before the loop, in Python)
            or a pair of arrays ``(poses, twists)``, each (m, 6), sampled at ``k dt``
            (the last row is held when m < steps + 1).
        kp: N/m. ki: N/(m s). kd: N s/m. feedforward: add the static forces of the
            reference pose.
        check_limits: stop at the stroke limits / carriage gap (checked after each step).
        on_limit: "stop" (status "stroke_limit" / "carriage_gap") or "raise".
        saturation: "clip", "raise" or "ignore" (commands beyond the bound).
        record_every: record one sample every this many steps.
        integrator: "rk4" (default; 4 forward dynamics per step, fourth order), "rk2"
            (explicit midpoint; 2, second order) or "semi_implicit_euler" (1, first
            order; velocities first, then ``p += dt v``, ``Q = exp(dt w) Q``, as MuJoCo's
            Euler). Accuracy and energy behaviour: see the module docstring.

    Returns:
        :class:`FastTrajectory`. A singular or unreachable state stops the run with
        status "failed" and the reference route's message.

    Raises:
        InputError, StrokeLimitError (``on_limit="raise"``), ActuatorSaturationError
        (``saturation="raise"``).
    """
    record_every = check_run_arguments(duration, dt, on_limit, saturation, record_every)
    modes = {"clip": 0, "raise": 1, "ignore": 2}
    if not isinstance(integrator, str) or integrator not in INTEGRATORS:
        raise InputError("integrator", integrator, f"expected one of {tuple(INTEGRATORS)}")
    if reference is not None and actuator_forces is not None:
        raise InputError("actuator_forces", actuator_forces, "give forces or a reference")
    n_steps = max(1, round(duration / dt))
    if reference is not None:
        ref_poses, ref_twists = _sample_reference(reference, n_steps, dt)
        mode, forces_in = 1, _ZERO6
    else:
        ref_poses = ref_twists = np.zeros((1, 6))
        mode = 0
        forces_in = _ZERO6 if actuator_forces is None else as_array(actuator_forces, (6,),
                                                                    "actuator_forces")
    if pose0 is None:
        pose0 = ref_poses[0] if reference is not None else robot.home_pose
    if twist0 is None:
        twist0 = ref_twists[0] if reference is not None else np.zeros(6)
    pose0, twist0 = as_array(pose0, (6,), "pose0"), as_array(twist0, (6,), "twist0")
    wrench = _ZERO6 if wrench is None else as_array(wrench, (6,), "wrench")
    gains = np.array([kp, ki, kd], dtype=float)
    if not np.all(np.isfinite(gains)):
        raise InputError("gains", gains, "must be finite")
    feedforward = bool(feedforward)
    geo = fast_dynamics(robot).geo
    robot.static_forces(pose0, bounded=False)    # raises for an unreachable / singular pose0
    vecs = np.zeros((4, 13))
    vecs[0, :3] = pose0[:3]
    vecs[0, 3:7] = _quaternion_wxyz(pose0[3:])
    vecs[0, 7:] = twist0
    work = (vecs, np.empty(9), np.empty((_WORK_ROWS, 6)), np.empty((2, 6, 6)),
            np.zeros((3, 6)))
    n_rec = n_steps // record_every + 2
    record = (np.empty((n_rec, 13)), np.empty((n_rec, 6)), np.empty((n_rec, 6)),
              np.empty((n_rec, 6)), np.zeros(n_rec, dtype=np.bool_))
    last_forces = np.zeros(6)
    setpoints = np.zeros((3, min(len(ref_poses), n_steps + 1) if mode else 1, 6))
    start = time.perf_counter()
    bad_row, bad_code = _set_points(geo, ref_poses, ref_twists, feedforward, setpoints) \
        if mode else (setpoints.shape[1], OK)
    code, step, n = simulate_kernel(geo, n_steps, float(dt), record_every,
                                    INTEGRATORS[integrator], mode, forces_in, wrench,
                                    setpoints, bad_row, bad_code, gains, modes[saturation],
                                    bool(check_limits), work, record, last_forces)
    wall = time.perf_counter() - start
    rec_state, rec_q, rec_qd, rec_f, rec_sat = record
    if code == SATURATED:
        raise ActuatorSaturationError(last_forces, np.full(6, robot.geometry.max_actuator_force))
    if n == 0:              # the initial state itself failed (checked above: not expected)
        raise HexapodPinError(f"simulate_fast: initial state rejected (status {code})")
    steps = np.arange(n) * record_every
    if code in (STROKE, GAP):                       # the stop state is recorded
        steps[-1] = step
    times = steps * float(dt)
    rec_state = rec_state[:n]
    quat = rec_state[:, [4, 5, 6, 3]]
    poses = np.empty((n, 6))
    _poses_of(rec_state, poses)
    status, message = "completed", ""
    t_stop = float(step * dt)
    if code in (STROKE, GAP):
        violations = robot.stroke_violations(rec_q[n - 1])
        if on_limit == "raise":
            raise StrokeLimitError(rec_q[n - 1], violations)
        status, message = _STATUS_OF_CODE[code], f"at t = {t_stop:.6g} s: " + "; ".join(
            violations)
    elif code != OK:
        status, message = "failed", f"at t = {t_stop:.6g} s: {_describe(robot, code, poses[-1])}"
    return FastTrajectory(times, poses, quat.copy(), rec_state[:, 7:].copy(), rec_q[:n].copy(),
                          rec_qd[:n].copy(), rec_f[:n].copy(), rec_sat[:n].copy(), status,
                          message, float(dt), wall, integrator)


class FastStepper:
    """Step the hexapod's dynamics one ``dt`` at a time from Python (a controller in the
    loop): the compiled loop of :func:`simulate_fast` run for one step per call, from a
    state it keeps, without the per-call set-up of :func:`simulate_fast`.

    Args:
        robot: the :class:`~hexapod_pin.Hexapod`.
        dt: the step (s).
        pose0, twist0: initial platform state (default: home at rest).
        integrator: "semi_implicit_euler" (default, one evaluation per step), "rk2" or
            "rk4" (see :func:`simulate_fast`).
        check_limits: stop at the stroke limits / carriage gap (checked after each step).

    Raises:
        InputError: bad ``dt``, ``integrator`` or initial state; UnreachablePoseError,
            SingularityError: the initial pose (as the reference routes raise them).

    Not thread-safe (the state and scratch arrays are reused).
    """

    def __init__(self, robot, dt: float = 1e-3, *, pose0=None, twist0=None,
                 integrator: str = "semi_implicit_euler", check_limits: bool = True):
        if not (np.isfinite(dt) and dt > 0):
            raise InputError("dt", dt, "must be a positive number")
        if integrator not in INTEGRATORS:
            raise InputError("integrator", integrator, f"expected one of {tuple(INTEGRATORS)}")
        self.robot, self.dt, self.integrator = robot, float(dt), integrator
        self.check_limits = bool(check_limits)
        self._geo = fast_dynamics(robot).geo
        self._work = (np.zeros((4, 13)), np.empty(9), np.empty((_WORK_ROWS, 6)),
                      np.empty((2, 6, 6)), np.zeros((3, 6)))
        self._record = (np.empty((3, 13)), np.empty((3, 6)), np.empty((3, 6)),
                        np.empty((3, 6)), np.zeros(3, dtype=np.bool_))
        self._setpoints = np.zeros((3, 1, 6))
        self._gains = np.zeros(3)
        self._last = np.zeros(6)
        self.time = 0.0
        self.reset(robot.home_pose if pose0 is None else pose0,
                   np.zeros(6) if twist0 is None else twist0)

    def reset(self, pose, twist) -> None:
        """Set the platform state (pose (6,), m and rad; twist (6,), world axes) and the
        time to 0. Raises as the constructor."""
        pose, twist = as_array(pose, (6,), "pose"), as_array(twist, (6,), "twist")
        self.robot.static_forces(pose, bounded=False)   # raises for an unreachable / singular pose
        state = self._work[0][0]
        state[:3] = pose[:3]
        state[3:7] = _quaternion_wxyz(pose[3:])
        state[7:] = twist
        self.time = 0.0

    def step(self, actuator_forces, wrench=None) -> None:
        """Advance one ``dt`` with the forces (6,) (N) and the wrench (6,) on the platform
        (world axes, about its origin; default zero) held over the step.

        Raises:
            InputError: non-finite or badly shaped forces / wrench.
            StrokeLimitError: the step ends beyond a stroke limit or the carriage gap
                (with ``check_limits``); the state is that end state.
            SingularityError, UnreachablePoseError, HexapodPinError: the step failed (the
                state is left at the start of the step).
        """
        forces = _vec6(actuator_forces, "actuator_forces")
        wrench = _ZERO6 if wrench is None else _vec6(wrench, "wrench")
        if not (_finite(forces) and _finite(wrench)):
            as_array(forces, (6,), "actuator_forces")
            as_array(wrench, (6,), "wrench")
        state = self._work[0][0]
        start = state.copy()
        code, _, n = simulate_kernel(self._geo, 1, self.dt, 1, INTEGRATORS[self.integrator],
                                     0, forces, wrench, self._setpoints, 1, OK, self._gains, 2,
                                     self.check_limits, self._work, self._record, self._last)
        if code == OK:
            self.time += self.dt
            return
        if code in (STROKE, GAP):
            self.time += self.dt
            q = self._record[1][n - 1]
            raise StrokeLimitError(q.copy(), self.robot.stroke_violations(q))
        state[:] = start
        raise HexapodPinError(f"FastStepper.step at t = {self.time:.6g} s: "
                              + _describe(self.robot, code, self.pose))

    @property
    def pose(self) -> np.ndarray:
        """Platform pose (6,) (m, rad)."""
        out = np.empty((1, 6))
        _poses_of(self._work[0][:1], out)
        return out[0]

    @property
    def twist(self) -> np.ndarray:
        """Platform twist ``(v, w)`` (6,), world axes (m/s, rad/s)."""
        return self._work[0][0, 7:].copy()


def _describe(robot, code: int, pose) -> str:
    """The reference route's message for the last state (its exception, if it raises),
    else the kernel's reason (the failure was at a Runge-Kutta stage of the next step)."""
    names = {UNREACHABLE: "pose unreachable", TYPE_I: "type-I singularity",
             GIMBAL: "universal joint in gimbal lock", TYPE_II: "type-II singularity",
             NOT_PD: "reduced mass matrix not positive definite", NONFINITE: "non-finite state"}
    try:
        robot.static_forces(pose, bounded=False)
    except HexapodPinError as exc:
        return str(exc)
    return f"{names.get(code, f'status {code}')} within the step from the last recorded state"


def _quaternion_wxyz(rpy) -> np.ndarray:
    roll, pitch, yaw = (0.5 * float(a) for a in rpy)
    c1, s1, c2, s2 = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
    c3, s3 = math.cos(yaw), math.sin(yaw)
    return np.array([c1 * c2 * c3 + s1 * s2 * s3, s1 * c2 * c3 - c1 * s2 * s3,
                     c1 * s2 * c3 + s1 * c2 * s3, c1 * c2 * s3 - s1 * s2 * c3])


@_jit
def _poses_of(states, out):
    """Poses ``(x, y, z, roll, pitch, yaw)`` (n, 6) of recorded states ``(p, Q (w, x, y, z),
    ...)``: :func:`hexapod_pin.pose.rpy_from_rotation` of ``R(Q)`` (pitch in [-pi/2,
    pi/2]; at gimbal lock roll = 0 and yaw takes the rest)."""
    rot = np.empty(9)
    for k in range(out.shape[0]):
        _rotation_quat(states[k, 3], states[k, 4], states[k, 5], states[k, 6], rot)
        out[k, 0], out[k, 1], out[k, 2] = states[k, 0], states[k, 1], states[k, 2]
        horizontal = math.hypot(rot[0], rot[3])
        out[k, 4] = math.atan2(-rot[6], horizontal)
        if horizontal < 1e-12:
            out[k, 3], out[k, 5] = 0.0, math.atan2(-rot[1], rot[4])
        else:
            out[k, 3], out[k, 5] = math.atan2(rot[7], rot[8]), math.atan2(rot[3], rot[0])
