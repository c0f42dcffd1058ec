"""The planar 3-PRR robot of the seed: a second closed-loop robot on the generic core.

The simplified planar model of the hexapod (the seed's section 1.3.1, figure 2): three
straight rails in the x-y plane, one actuated slider per rail, a link of fixed length
from a revolute joint on each slider to a revolute joint on a triangular platform.

Conventions (fixed; see also ``urdf/planar_3prr.urdf.xacro``):

* plane x-y, gravity ``-g`` along y;
* rail k (k = 0, 1, 2) has its midpoint at ``m_k = rail_radius (cos a_k, sin a_k)``,
  ``a_k = 90 deg + 120 deg k``, and its direction ``u_k = (-sin a_k, cos a_k)``;
* slider k sits at ``c_k = m_k + s_k u_k``; ``s_k`` (m) is its coordinate, actuated,
  and ``tau_k`` (N) is the force on slider k along ``+u_k``;
* the platform pose is ``(x, y, theta)`` (m, m, rad): its origin, which is its centre of
  mass, and its rotation about z; platform point k is
  ``P_k = (x, y) + platform_radius (cos(a_k + theta), sin(a_k + theta))``;
* a link joins ``c_k`` to ``P_k``: ``|P_k - c_k| = link_length`` closes loop k;
* twist ``(vx, vy, omega)``: velocity of the platform origin and angular rate (world
  axes); ``twist_dot`` its plain time derivative; wrench ``(fx, fy, mz)``: force and
  moment about the platform origin applied ON the platform by the environment;
* Jacobian: ``sdot = J @ twist``, J of shape (3, 3);
* inertia: sliders are point masses, links thin uniform rods (``m L^2 / 12`` about
  their centre), the platform a rigid body with ``platform_inertia`` about its origin.

The tree (``urdf/planar_3prr.urdf.xacro``) is built in 3-D: world -> slider_k
(prismatic) -> link_k_joint (revolute about z) -> link_k, and world -> platform_x
(prismatic, world x) -> platform_y (prismatic, world y) -> platform_theta (revolute
about z) -> platform. The platform hangs on that chain rather than on a URDF ``planar``
joint because the tools disagree on what ``planar`` means: Pinocchio 4.1 loads it as a
3-DoF ``JointModelPlanar`` (q = (x, y, cos, sin), velocity in body axes), yourdfpy
counts it as 2 DoF and leaves it out of its forward kinematics (checked). The chain
means the same everywhere, and its q and v ARE the pose ``(x, y, theta)`` and the twist
``(vx, vy, omega)`` (world axes), so no conversion is needed.

The loops are closed by 3-D point closures (``urdf/planar_3prr.loops.yaml``; a revolute
joint about z between two bodies moving in the plane is a point closure): 9 rows of which
the 3 out-of-plane rows are identically zero. The generic
:class:`~hexapod_pin.closed_loop.ClosedLoopModel` reports them (rank 6 of 9, mobility 3)
and every route below tolerates them (assembly, velocity and acceleration completion,
forward and inverse dynamics; minimum-norm multipliers, zero on the redundant rows).

Inverse kinematics is the quadratic along each rail (8 branches); forward kinematics is
Newton from a guess, and :meth:`Planar3PRR.assembly_modes` finds every real assembly
mode from a univariate sextic (see :meth:`Planar3PRR.assembly_polynomial`).

Single-state speed: with three loops, numpy's per-call cost (1-5 us) dominates, so the
per-state routes (inverse kinematics, Jacobian, tree velocity and acceleration, inverse
and forward dynamics, statics) validate their inputs once, compute the tree state in
closed form in a compiled kernel (numba, ``cache=True``), call Pinocchio once or twice
(``rnea``, ``crba``, the gravity vector) and solve the closure equations with their
planar structure in a second kernel: per loop a 2x2, plus one 3x3 on the platform rows
for inverse dynamics (:func:`_inverse_kernel`, :func:`_forward_kernel`). Where that
structure is (nearly) singular (type II for inverse dynamics) the state goes to the
generic dense routes of :mod:`hexapod_pin.dynamics`, so the answers are the generic
ones everywhere, to round-off (the tests compare both).
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from dataclasses import dataclass
from functools import cached_property

import numba
import numpy as np
import pinocchio as pin

from ..core.closed_loop import ClosedLoopModel
from ..core.description import build_model, expand_xacro, load_loops, urdf_dir
from ..core.dynamics import (
    TreeForwardDynamics,
    TreeInverseDynamics,
    forward_dynamics_tree,
    inverse_dynamics_tree,
)
from ..errors import (
    ActuatorSaturationError,
    AssemblyError,
    DescriptionError,
    GeometryError,
    InputError,
    SingularityError,
    StrokeLimitError,
    UnreachablePoseError,
)
from ..core.checks import validate_scalars
from ..core.compiled import all_finite
from ..core.checks import as_array, check_signs

N_SLIDERS = 3
#: the home branch: every slider on the larger root of its quadratic
HOME_BRANCH = np.ones(N_SLIDERS)
#: every IK branch, home first
ALL_BRANCHES = tuple(np.array(b, dtype=float)
                     for b in itertools.product((1.0, -1.0), repeat=N_SLIDERS))
#: closure residual accepted for a closed-form configuration (m)
CLOSED_FORM_TOL = 1e-12
#: a link closer than this to perpendicular to its rail (``|n.u| / L``) is singular
_PERPENDICULAR_TOL = 1e-9
#: the closed-form inverse dynamics hands a state to the generic dense route when its 3x3
#: platform system (columns ``(n_k, r_k x n_k)``, type II) has a Hadamard ratio
#: ``|det| / prod |column|`` below this (the generic route returns least squares there)
_TYPE_II_HADAMARD = 1e-6
#: relative equation residual above which a closed-form solve is handed to the generic route
_CLOSED_FORM_RTOL = 1e-9
#: rank of the closure rows: the 2 in-plane rows of each of the 3 point closures
_IN_PLANE_RANK = 2 * N_SLIDERS
_STATUS_ID = "solved (closed form; out-of-plane multipliers zero: minimum norm)"
_STATUS_FD = "solved (closed form, null-space; out-of-plane multipliers zero: minimum norm)"


def rail_angles() -> np.ndarray:
    """Angles ``a_k = 90 deg + 120 deg k`` of the three rails (rad), shape (3,)."""
    return np.pi / 2 + 2 * np.pi / 3 * np.arange(N_SLIDERS)


def _rot2(theta) -> np.ndarray:
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s], [s, c]])


def _cross2(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """z component of ``a x b`` for arrays of 2-vectors (..., 2)."""
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _vec3(value, name: str) -> np.ndarray:
    """A float64 (3,) array from an input, for the compiled kernels (fast path).

    A contiguous, writeable float64 ndarray of shape (3,) is passed through; anything
    else is copied to one and its shape checked, or sent to :func:`as_array`, which
    raises the :class:`InputError`. Finiteness is checked by the kernels; when they
    report a non-finite value the caller re-validates with :func:`as_array` (which
    raises with the offending value).
    """
    if (type(value) is np.ndarray and value.dtype == np.float64 and value.shape == (3,)
            and value.flags.c_contiguous and value.flags.writeable):
        return value            # (one array layout: one compiled specialisation)
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        arr = None
    if arr is None or arr.shape != (3,):
        return as_array(value, (3,), name)
    return arr


def _check_bounds(bounds) -> np.ndarray | None:
    """Actuator bounds (N) as a (3,) array, or None for none (None / inf).

    The rules of :func:`hexapod_pin.dynamics.inverse_dynamics_tree`: a positive scalar or
    three positive values (inf allowed); anything else raises :class:`InputError`.
    """
    if bounds is None:
        return None
    if isinstance(bounds, (int, float)) and not isinstance(bounds, bool):
        if not bounds > 0.0:
            raise InputError("bounds", bounds, "must be positive")
        return None if bounds == math.inf else np.full(N_SLIDERS, float(bounds))
    arr = np.asarray(bounds, dtype=float)
    if arr.ndim == 0:
        arr = np.full(N_SLIDERS, float(arr))
    if arr.shape != (N_SLIDERS,) or np.any(np.isnan(arr)) or np.any(arr <= 0.0):
        raise InputError("bounds", bounds,
                         f"expected a positive scalar or ({N_SLIDERS},) positive values")
    return None if np.all(np.isinf(arr)) else arr


# ---------------------------------------------------------------------------------------
# compiled single-state kernels
# ---------------------------------------------------------------------------------------
# Three loops are too few for numpy to pay (a numpy call costs 1-5 us here): the
# single-state routes validate their inputs once, run one kernel for the closed-form tree
# state, call Pinocchio (rnea, crba or the gravity vector) on its arrays, and run one
# kernel for the structured solve. Kernels return a status and never raise: the caller
# raises the library's exception with the values the kernel left in ``info``, or hands
# the state to the generic dense route (_FALLBACK). Compiled with ``cache=True`` (the
# machine code is cached next to this file, so only the first call after an install
# compiles).
_jit = numba.njit(cache=True, error_model="numpy")

#: kernel status codes
_OK, _NONFINITE, _UNREACHABLE, _SINGULAR, _FALLBACK = 0, -1, 1, 2, 3
# geometry vector: per slider k, 7 values from 7 k: m_x, m_y, u_x, u_y, p_x, p_y, a_k;
# then the link length and the perpendicularity tolerance
_G_LEN, _G_TOL = 7 * N_SLIDERS, 7 * N_SLIDERS + 1
# index vector: platform (x, y, theta), sliders, links (tree v indices), first closure row
# of each loop
_I_PLAT, _I_SLIDER, _I_LINK, _I_ROW = 0, 3, 6, 9
# leg buffer columns, one row per slider: s, n (2), r (2), n.u, J row (3), s', phi',
# s'', phi''
_S, _NX, _NY, _RX, _RY, _NU, _J0, _J1, _J2, _SD, _PD, _SDD, _PDD = range(13)
_LEG_COLS = 13
# info vector: shortfall (3), unreachable flags (3), worst |n.u| / L, max |s|, residual
_INFO_SIZE = 9
_X_WORST, _X_SMAX, _X_RES = 6, 7, 8


@_jit
def _state_kernel(geo, idx, pose, twist, twist_dot, signs, level, singular,
                  q, v, a, legs, info):
    """Closed-form tree state of a platform state (model order, every closure kept).

    ``level`` 0: ``q`` (and the leg buffer: IK, link vectors, Jacobian rows); 1: also
    ``v``; 2: also ``a``. ``singular``: check that no link is perpendicular to its rail.
    Returns _OK, _NONFINITE, _UNREACHABLE (``info[0:3]`` shortfalls, ``info[3:6]``
    flags) or _SINGULAR (``info[_X_WORST]``).
    """
    if not all_finite(pose):
        return _NONFINITE
    if level >= 1 and not all_finite(twist):
        return _NONFINITE
    if level >= 2 and not all_finite(twist_dot):
        return _NONFINITE
    x, y, theta = pose[0], pose[1], pose[2]
    cos_t, sin_t = math.cos(theta), math.sin(theta)
    length = geo[_G_LEN]
    length2 = length * length
    status = _OK
    worst, s_max = math.inf, 0.0
    for k in range(N_SLIDERS):
        g = 7 * k
        mx, my, ux, uy = geo[g], geo[g + 1], geo[g + 2], geo[g + 3]
        px, py = geo[g + 4], geo[g + 5]
        rx, ry = px * cos_t - py * sin_t, px * sin_t + py * cos_t
        wx, wy = x + rx, y + ry                         # platform point P_k
        dx, dy = wx - mx, wy - my
        along = dx * ux + dy * uy
        disc = length2 - ((dx * dx + dy * dy) - along * along)
        info[k], info[3 + k] = 0.0, 0.0
        if not disc >= 0.0:
            info[k], info[3 + k] = math.sqrt(length2 - disc) - length, 1.0
            status = _UNREACHABLE
            continue
        s = along + signs[k] * math.sqrt(disc)
        nx, ny = wx - (mx + s * ux), wy - (my + s * uy)  # link vector n_k = P_k - c_k
        nu = nx * ux + ny * uy
        leg = legs[k]
        leg[_S], leg[_NX], leg[_NY], leg[_RX], leg[_RY], leg[_NU] = s, nx, ny, rx, ry, nu
        leg[_J0], leg[_J1], leg[_J2] = nx / nu, ny / nu, (rx * ny - ry * nx) / nu
        worst = min(worst, abs(nu) / length)
        s_max = max(s_max, abs(s))
    info[_X_WORST], info[_X_SMAX] = worst, s_max
    if status != _OK:
        return status
    if singular and worst < geo[_G_TOL]:
        return _SINGULAR
    for j in range(3):
        q[idx[_I_PLAT + j]] = pose[j]
    for k in range(N_SLIDERS):
        leg = legs[k]
        q[idx[_I_SLIDER + k]] = leg[_S]
        angle = math.atan2(leg[_NY], leg[_NX]) - geo[7 * k + 6] - math.pi / 2
        q[idx[_I_LINK + k]] = math.pi - (math.pi - angle) % (2.0 * math.pi)
    if level < 1:
        return _OK
    vx, vy, omega = twist[0], twist[1], twist[2]
    for j in range(3):
        v[idx[_I_PLAT + j]] = twist[j]
    for k in range(N_SLIDERS):
        leg = legs[k]
        nx, ny, rx, ry = leg[_NX], leg[_NY], leg[_RX], leg[_RY]
        sdot = leg[_J0] * vx + leg[_J1] * vy + leg[_J2] * omega
        lvx = vx - omega * ry - sdot * geo[7 * k + 2]  # P_k velocity less the slider's
        lvy = vy + omega * rx - sdot * geo[7 * k + 3]
        leg[_SD], leg[_PD] = sdot, (nx * lvy - ny * lvx) / length2
        v[idx[_I_SLIDER + k]], v[idx[_I_LINK + k]] = leg[_SD], leg[_PD]
    if level < 2:
        return _OK
    ax, ay, alpha = twist_dot[0], twist_dot[1], twist_dot[2]
    omega2 = omega * omega
    for j in range(3):
        a[idx[_I_PLAT + j]] = twist_dot[j]
    for k in range(N_SLIDERS):
        # loop k: u_k s'' + (z x n_k) phi'' = b_k (Cramer, determinant n_k . u_k)
        leg = legs[k]
        nx, ny, rx, ry, nu = leg[_NX], leg[_NY], leg[_RX], leg[_RY], leg[_NU]
        phid2 = leg[_PD] * leg[_PD]
        bx = ax - alpha * ry + phid2 * nx - omega2 * rx
        by = ay + alpha * rx + phid2 * ny - omega2 * ry
        leg[_SDD] = (bx * nx + by * ny) / nu
        leg[_PDD] = (geo[7 * k + 2] * by - geo[7 * k + 3] * bx) / nu
        a[idx[_I_SLIDER + k]], a[idx[_I_LINK + k]] = leg[_SDD], leg[_PDD]
    return _OK


@_jit
def _solve3(m00, m01, m02, m10, m11, m12, m20, m21, m22, f0, f1, f2, out):
    """Cramer's rule for a 3x3 system (rows ``m_i.``); returns the Hadamard ratio
    ``|det| / prod |column|`` (0: singular; ``out`` then untouched)."""
    c0, c1, c2 = m11 * m22 - m12 * m21, m12 * m20 - m10 * m22, m10 * m21 - m11 * m20
    det = m00 * c0 + m01 * c1 + m02 * c2
    scale = (math.sqrt(m00 * m00 + m10 * m10 + m20 * m20)
             * math.sqrt(m01 * m01 + m11 * m11 + m21 * m21)
             * math.sqrt(m02 * m02 + m12 * m12 + m22 * m22))
    if det == 0.0 or not scale > 0.0:
        return 0.0
    out[0] = (f0 * c0 + m01 * (m12 * f2 - f1 * m22) + m02 * (f1 * m21 - m11 * f2)) / det
    out[1] = (m00 * (f1 * m22 - m12 * f2) + f0 * c1 + m02 * (m10 * f2 - f1 * m20)) / det
    out[2] = (m00 * (m11 * f2 - f1 * m21) + m01 * (f1 * m20 - m10 * f2) + f0 * c2) / det
    return abs(det) / scale


@_jit
def _inverse_kernel(geo, idx, legs, force, wrench, has_wrench, tau, lam, info):
    """Actuator forces and closure forces from ``S^T tau + J_c^T lambda = force - ext``.

    ``force`` (nv,): ``M a + h`` (or ``g(q)`` for statics), model order; ``ext`` the
    wrench on the platform chain. The rows (``lambda_k``, the force of the platform on
    link k, world x-y; the out-of-plane multipliers are zero, the minimum-norm choice on
    the identically-zero rows):

    * link k: ``(z x n_k) . lambda_k = f_phi_k``, so ``lambda_k = mu_k n_k + c_k z x n_k``
      with ``c_k = f_phi_k / |n_k|^2``;
    * platform: ``-sum lambda_k = f_xy`` and ``-sum r_k x lambda_k = f_theta``: 3x3 in
      ``mu`` with columns ``(n_k, r_k x n_k)`` (the Jacobian rows times ``n_k . u_k``,
      singular at type II singularities);
    * slider k: ``tau_k = f_s_k - u_k . lambda_k``.

    Writes ``tau`` (3,), ``lam`` (n_rows,) and the max-abs residual of every row in
    ``info[_X_RES]``. Returns _OK, _NONFINITE (the wrench), or _FALLBACK (Hadamard ratio
    of the 3x3 below _TYPE_II_HADAMARD, or a residual above round-off).
    """
    if has_wrench and not all_finite(wrench):
        return _NONFINITE
    ix, iy, ith = idx[_I_PLAT], idx[_I_PLAT + 1], idx[_I_PLAT + 2]
    fx, fy, fth = force[ix], force[iy], force[ith]
    if has_wrench:
        fx, fy, fth = fx - wrench[0], fy - wrench[1], fth - wrench[2]
    px, py, pth = -fx, -fy, -fth            # right-hand side of the 3x3 in mu
    coef = np.empty(N_SLIDERS)
    for k in range(N_SLIDERS):
        leg = legs[k]
        nx, ny = leg[_NX], leg[_NY]
        c = force[idx[_I_LINK + k]] / (nx * nx + ny * ny)
        coef[k] = c
        px, py = px + c * ny, py - c * nx
        pth -= c * (leg[_RX] * nx + leg[_RY] * ny)
    l0, l1, l2 = legs[0], legs[1], legs[2]
    mu = np.empty(3)
    hadamard = _solve3(l0[_NX], l1[_NX], l2[_NX], l0[_NY], l1[_NY], l2[_NY],
                       l0[_RX] * l0[_NY] - l0[_RY] * l0[_NX],
                       l1[_RX] * l1[_NY] - l1[_RY] * l1[_NX],
                       l2[_RX] * l2[_NY] - l2[_RY] * l2[_NX], px, py, pth, mu)
    if not hadamard >= _TYPE_II_HADAMARD:
        return _FALLBACK
    res, sum_x, sum_y, sum_m = 0.0, 0.0, 0.0, 0.0
    scale = max(1.0, abs(fx), abs(fy), abs(fth))
    lam[:] = 0.0
    for k in range(N_SLIDERS):
        leg = legs[k]
        nx, ny, c = leg[_NX], leg[_NY], coef[k]
        lx, ly = mu[k] * nx - c * ny, mu[k] * ny + c * nx
        ux, uy = geo[7 * k + 2], geo[7 * k + 3]
        fs, fl = force[idx[_I_SLIDER + k]], force[idx[_I_LINK + k]]
        tau[k] = fs - (ux * lx + uy * ly)
        row = idx[_I_ROW + k]
        lam[row], lam[row + 1] = lx, ly
        res = max(res, abs(tau[k] + ux * lx + uy * ly - fs), abs(nx * ly - ny * lx - fl))
        scale = max(scale, abs(fs), abs(fl))
        sum_x, sum_y = sum_x + lx, sum_y + ly
        sum_m += leg[_RX] * ly - leg[_RY] * lx
    res = max(res, abs(sum_x + fx), abs(sum_y + fy), abs(sum_m + fth))
    info[_X_RES] = res
    if not res <= _CLOSED_FORM_RTOL * scale:
        return _FALLBACK
    return _OK


@_jit
def _forward_kernel(geo, idx, legs, twist, bias, mass, forces, wrench, has_wrench,
                    acc, lam, twist_dot, info):
    """Constrained forward dynamics by the null-space method, in closed form.

    ``a = G twist_dot + a_0`` keeps the closures for any ``twist_dot`` (``G`` (nv, 3):
    platform rows the identity, slider rows the Jacobian rows, link rows
    ``(-u_y, u_x, u_k . r_k) / (n_k . u_k)``; ``a_0`` in the leg buffer, from
    :func:`_state_kernel` at zero ``twist_dot``), so ``G^T M G twist_dot = -G^T f`` with
    ``f = M a_0 + h - S^T tau - ext`` (``bias = M a_0 + h`` from Pinocchio's rnea,
    ``mass`` the upper triangle from crba). The multipliers then follow per loop from
    the slider and link rows (a 2x2 with determinant ``n_k . u_k``); the platform rows
    are the check. Writes ``acc`` (nv,), ``lam`` (n_rows,), ``twist_dot`` (3,) and
    ``max |J_c a + gamma|`` in ``info[_X_RES]``. Returns _OK, _NONFINITE (forces or
    wrench) or _FALLBACK (a residual above round-off).
    """
    if not all_finite(forces) or (has_wrench and not all_finite(wrench)):
        return _NONFINITE
    nv = bias.shape[0]
    f = bias.copy()
    if has_wrench:
        for j in range(3):
            f[idx[_I_PLAT + j]] -= wrench[j]
    gmap = np.zeros((nv, 3))
    for j in range(3):
        gmap[idx[_I_PLAT + j], j] = 1.0
    for k in range(N_SLIDERS):
        leg = legs[k]
        i_s, i_l = idx[_I_SLIDER + k], idx[_I_LINK + k]
        f[i_s] -= forces[k]
        ux, uy, nu = geo[7 * k + 2], geo[7 * k + 3], leg[_NU]
        gmap[i_s, 0], gmap[i_s, 1], gmap[i_s, 2] = leg[_J0], leg[_J1], leg[_J2]
        gmap[i_l, 0], gmap[i_l, 1] = -uy / nu, ux / nu
        gmap[i_l, 2] = (ux * leg[_RX] + uy * leg[_RY]) / nu
    mass_g = np.zeros((nv, 3))           # M G, M symmetric from its upper triangle
    for i in range(nv):
        for m in range(nv):
            mim = mass[i, m] if i <= m else mass[m, i]
            if mim != 0.0:
                for j in range(3):
                    mass_g[i, j] += mim * gmap[m, j]
    red = np.zeros((3, 3))
    rhs = np.zeros(3)
    for i in range(nv):
        for j in range(3):
            rhs[j] -= gmap[i, j] * f[i]
            for m in range(3):
                red[j, m] += gmap[i, j] * mass_g[i, m]
    if _solve3(red[0, 0], red[0, 1], red[0, 2], red[1, 0], red[1, 1], red[1, 2],
               red[2, 0], red[2, 1], red[2, 2], rhs[0], rhs[1], rhs[2], twist_dot) == 0.0:
        return _FALLBACK
    # a = a_0 + G twist_dot; the residual force M a + h - S^T tau - ext = J_c^T lambda
    for i in range(nv):
        acc[i] = 0.0
        for j in range(3):
            f[i] += mass_g[i, j] * twist_dot[j]
    for j in range(3):
        acc[idx[_I_PLAT + j]] = twist_dot[j]
    ax, ay, alpha = twist_dot[0], twist_dot[1], twist_dot[2]
    omega2 = twist[2] * twist[2]
    lam[:] = 0.0
    cres, sum_x, sum_y, sum_m, scale = 0.0, 0.0, 0.0, 0.0, 1.0
    for k in range(N_SLIDERS):
        leg = legs[k]
        i_s, i_l = idx[_I_SLIDER + k], idx[_I_LINK + k]
        nx, ny, rx, ry, nu = leg[_NX], leg[_NY], leg[_RX], leg[_RY], leg[_NU]
        ux, uy = geo[7 * k + 2], geo[7 * k + 3]
        sdd = leg[_SDD] + leg[_J0] * ax + leg[_J1] * ay + leg[_J2] * alpha
        pdd = leg[_PDD] + (-uy * ax + ux * ay + (ux * rx + uy * ry) * alpha) / nu
        acc[i_s], acc[i_l] = sdd, pdd
        fs, fl = f[i_s], f[i_l]
        lx, ly = (fs * nx - uy * fl) / nu, (ux * fl + ny * fs) / nu
        row = idx[_I_ROW + k]
        lam[row], lam[row + 1] = lx, ly
        sum_x, sum_y, sum_m = sum_x + lx, sum_y + ly, sum_m + rx * ly - ry * lx
        scale = max(scale, abs(fs), abs(fl), abs(forces[k]))
        # the loop's in-plane closure rows at acceleration level, J_c a + gamma
        phid2 = leg[_PD] * leg[_PD]
        cres = max(cres,
                   abs(ux * sdd - ny * pdd - (ax - alpha * ry) - phid2 * nx + omega2 * rx),
                   abs(uy * sdd + nx * pdd - (ay + alpha * rx) - phid2 * ny + omega2 * ry))
    ix, iy, ith = idx[_I_PLAT], idx[_I_PLAT + 1], idx[_I_PLAT + 2]
    scale = max(scale, abs(f[ix]), abs(f[iy]), abs(f[ith]))
    worst = max(abs(sum_x + f[ix]), abs(sum_y + f[iy]), abs(sum_m + f[ith]))
    info[_X_RES] = cres
    if not worst <= _CLOSED_FORM_RTOL * scale:
        return _FALLBACK
    return _OK


# ---------------------------------------------------------------------------------------
# geometry
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class PlanarGeometry:
    """Geometry, inertia and limits of the planar 3-PRR robot (SI units).

    Attributes:
        rail_radius: distance from the world origin to each rail midpoint (m).
        platform_radius: distance from the platform origin to each platform joint (m).
        link_length: length of each link, slider joint to platform joint (m).
        slider_mass: point mass of each slider (kg).
        link_mass: mass of each link, a thin uniform rod (kg).
        platform_mass: mass of the platform (kg).
        platform_inertia: moment of inertia of the platform about z at its origin
            (its centre of mass) (kg m^2).
        gravity: magnitude of gravity, acting along -y (m/s^2).
        rail_half_length: stroke, ``abs(s_k) <= rail_half_length`` (m).
        max_actuator_force: bound on ``abs(tau_k)`` (N); ``inf`` (default) for none.

    Raises:
        GeometryError: on a non-finite, non-positive or inconsistent value (a home
            that cannot be assembled or lies outside the stroke), naming the field
            and the value.
    """

    rail_radius: float = 0.35
    platform_radius: float = 0.12
    link_length: float = 0.30
    slider_mass: float = 0.5
    link_mass: float = 0.2
    platform_mass: float = 1.0
    platform_inertia: float = 0.002
    gravity: float = 9.81
    rail_half_length: float = 0.30
    max_actuator_force: float = math.inf

    def __post_init__(self) -> None:
        validate_scalars(self, positive=("rail_radius", "platform_radius", "link_length",
                                         "slider_mass", "link_mass", "platform_mass",
                                         "platform_inertia", "rail_half_length",
                                         "max_actuator_force"),
                         non_negative=("gravity",))
        if self.platform_radius >= self.rail_radius:
            raise GeometryError("platform_radius", self.platform_radius,
                                f"must be < rail_radius={self.rail_radius}")
        gap = self.rail_radius - self.platform_radius
        if self.link_length <= gap:
            raise GeometryError("link_length", self.link_length,
                                "home cannot be assembled: link_length must exceed "
                                f"rail_radius - platform_radius = {gap:.6g}")
        if self.home_slider > self.rail_half_length:
            raise GeometryError("rail_half_length", self.rail_half_length,
                                f"home slider position {self.home_slider:.6g} is outside "
                                "the stroke")

    @property
    def home_slider(self) -> float:
        """Slider coordinate at home, ``sqrt(L^2 - (R - r)^2)`` (m), 0.1926 by default."""
        gap = self.rail_radius - self.platform_radius
        return math.sqrt(self.link_length ** 2 - gap ** 2)

    @property
    def home_s(self) -> np.ndarray:
        """Slider coordinates at home (m), shape (3,): all ``+home_slider``."""
        return np.full(N_SLIDERS, self.home_slider)

    @property
    def home_pose(self) -> np.ndarray:
        """Home pose ``(x, y, theta) = 0`` (m, m, rad), shape (3,)."""
        return np.zeros(3)

    @property
    def rail_midpoints(self) -> np.ndarray:
        """Rail midpoints ``m_k`` in the world (m), shape (3, 2)."""
        a = rail_angles()
        return self.rail_radius * np.stack([np.cos(a), np.sin(a)], axis=1)

    @property
    def rail_directions(self) -> np.ndarray:
        """Unit rail directions ``u_k``, shape (3, 2)."""
        a = rail_angles()
        return np.stack([-np.sin(a), np.cos(a)], axis=1)

    @property
    def platform_points(self) -> np.ndarray:
        """Platform joint points ``p_k`` in the platform frame (m), shape (3, 2)."""
        a = rail_angles()
        return self.platform_radius * np.stack([np.cos(a), np.sin(a)], axis=1)

    def xacro_args(self) -> dict[str, str]:
        """The xacro arguments of ``urdf/planar_3prr.urdf.xacro`` for this geometry."""
        values = {
            "rail_radius": self.rail_radius,
            "platform_radius": self.platform_radius,
            "link_length": self.link_length,
            "rail_half_length": self.rail_half_length,
            "slider_mass": self.slider_mass,
            "link_mass": self.link_mass,
            "platform_mass": self.platform_mass,
            "platform_inertia": self.platform_inertia,
            "max_actuator_force": self.max_actuator_force
            if math.isfinite(self.max_actuator_force) else 1e30,
        }
        return {k: repr(float(v)) for k, v in values.items()}

    def replace(self, **changes) -> "PlanarGeometry":
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)


def planar_urdf(geometry: PlanarGeometry) -> str:
    """Expanded URDF text of the planar 3-PRR tree for a :class:`PlanarGeometry`."""
    return expand_xacro(urdf_dir() / "planar_3prr.urdf.xacro", geometry.xacro_args())


def check_branch(branch) -> np.ndarray:
    """Validate a branch (three values, each +1 or -1); ``None`` -> the home branch."""
    return check_signs(branch, HOME_BRANCH)


# ---------------------------------------------------------------------------------------
# results
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class PlanarIndices:
    """Where the planar robot's coordinates sit in Pinocchio's ``q`` and ``v``.

    ``q`` and ``v`` coincide index for index (every joint of the tree is 1-DoF).

    Attributes:
        slider: slider k's prismatic coordinate, shape (3,).
        link: link k's revolute angle, measured from ``u_k`` (rad), shape (3,).
        platform: the platform chain ``(x, y, theta)``, shape (3,).
    """

    slider: np.ndarray
    link: np.ndarray
    platform: np.ndarray


@dataclass(frozen=True)
class AssemblyPolynomial:
    """The univariate polynomial whose real roots give every assembly mode.

    With ``theta = theta_offset + 2 atan(T)``, a pose with slider coordinates ``s``
    closes all three loops only if ``sum_i coefficients[i] T^i = 0`` (see
    :meth:`Planar3PRR.assembly_polynomial`).

    Attributes:
        coefficients: the sextic's coefficients, lowest degree first, shape (7,)
            (scaled so that the largest magnitude is 1).
        theta_offset: the angle ``theta_offset`` of the substitution (rad).
        removed_factor_residual: relative remainder of the exact division by
            ``(1 + T^2)^3`` that turns the degree-12 numerator into the sextic
            (round-off level, about 1e-15).
    """

    coefficients: np.ndarray
    theta_offset: float
    removed_factor_residual: float


@dataclass(frozen=True)
class PlanarInverseDynamics:
    """Result of :meth:`Planar3PRR.inverse_dynamics`.

    Attributes:
        forces: actuator forces ``tau`` (3,) (N), the force on slider k along ``+u_k``.
        link_forces: force (N, world x and y) that the platform exerts on link k at
            platform joint k, shape (3, 2); the link exerts the opposite on the platform.
        tree: the generic result (:class:`~hexapod_pin.dynamics.TreeInverseDynamics`),
            multipliers of all 9 closure rows (the out-of-plane ones are zero:
            minimum-norm multipliers of the redundant rows).
    """

    forces: np.ndarray
    link_forces: np.ndarray
    tree: TreeInverseDynamics


@dataclass(frozen=True)
class PlanarForwardDynamics:
    """Result of :meth:`Planar3PRR.forward_dynamics`.

    Attributes:
        twist_dot: ``(dvx/dt, dvy/dt, domega/dt)`` (m/s^2, rad/s^2), shape (3,).
        slider_accelerations: ``d2 s_k / dt2`` (m/s^2), shape (3,).
        link_forces: force (N, world x and y) of the platform on link k, shape (3, 2).
        tree: the generic result (:class:`~hexapod_pin.dynamics.TreeForwardDynamics`).
    """

    twist_dot: np.ndarray
    slider_accelerations: np.ndarray
    link_forces: np.ndarray
    tree: TreeForwardDynamics


# ---------------------------------------------------------------------------------------
# the robot
# ---------------------------------------------------------------------------------------
class Planar3PRR:
    """The planar 3-PRR robot on the generic closed-loop core.

    ``model`` is the :class:`ClosedLoopModel` loaded from
    ``urdf/planar_3prr.urdf.xacro`` and ``urdf/planar_3prr.loops.yaml`` through the
    same generic loader as the hexapod, with Pinocchio's gravity set to ``-g`` along y.

    Args:
        geometry: design parameters; default :class:`PlanarGeometry` ().

    Example:
        >>> robot = Planar3PRR.default()
        >>> robot.inverse_kinematics([0.01, -0.02, 0.05])   # slider coordinates (m)
    """

    def __init__(self, geometry: PlanarGeometry | None = None):
        self.geometry = PlanarGeometry() if geometry is None else geometry
        if not isinstance(self.geometry, PlanarGeometry):
            raise TypeError(f"geometry must be a PlanarGeometry, got {type(geometry).__name__}")
        xml = planar_urdf(self.geometry)
        tree = build_model(xml, source="planar_3prr.urdf.xacro")
        self.model = ClosedLoopModel(tree, load_loops(urdf_dir() / "planar_3prr.loops.yaml"),
                                     name="planar_3prr", urdf_xml=xml)
        self.model.model.gravity = pin.Motion(
            np.array([0.0, -self.geometry.gravity, 0.0, 0.0, 0.0, 0.0]))
        m = self.model
        self.indices = PlanarIndices(
            np.array([m.joint_v_index(f"slider_{k}") for k in range(N_SLIDERS)]),
            np.array([m.joint_v_index(f"link_{k}_joint") for k in range(N_SLIDERS)]),
            np.array([m.joint_v_index(j) for j in ("platform_x", "platform_y",
                                                   "platform_theta")]))
        self._data = self.model.model.createData()
        # the geometry's derived arrays, computed once (read-only)
        self._mids = _frozen(self.geometry.rail_midpoints)
        self._dirs = _frozen(self.geometry.rail_directions)
        self._pts = _frozen(self.geometry.platform_points)
        # the compiled single-state kernels: geometry and tree indices as flat arrays,
        # scratch buffers and Pinocchio data of their own
        geo = np.empty(_G_TOL + 1)
        for k, (mid, dirn, pt, angle) in enumerate(zip(self._mids, self._dirs, self._pts,
                                                      rail_angles())):
            geo[7 * k:7 * k + 7] = (*mid, *dirn, *pt, angle)
        geo[_G_LEN], geo[_G_TOL] = self.geometry.link_length, _PERPENDICULAR_TOL
        self._geo = geo
        # the kernels read closure k's rows as loop k's (link k on platform point k)
        rows = [r.start for r in self.model.row_slices]
        expected = [("point", f"link_{k}_tip", f"platform_anchor_{k}") for k in range(N_SLIDERS)]
        if [(c.type, c.frame1, c.frame2) for c in self.model.closures] != expected:
            raise DescriptionError("planar_3prr.loops.yaml", "expected the point closures "
                                   f"{expected}, in that order")
        self._idx = np.concatenate([self.indices.platform, self.indices.slider,
                                    self.indices.link, rows]).astype(np.int64)
        #: multiplier rows of the in-plane closure forces, shape (3, 2)
        self._link_rows = np.array([[r, r + 1] for r in rows])
        self._nv = self.model.nv
        self._home_signs = np.ones(N_SLIDERS)
        self._zero3 = np.zeros(3)
        self._legs_buf = np.zeros((N_SLIDERS, _LEG_COLS))
        self._info = np.zeros(_INFO_SIZE)
        self._pin_data = self.model.model.createData()

    @classmethod
    def default(cls) -> "Planar3PRR":
        """The planar robot with the default geometry."""
        return cls(PlanarGeometry())

    def __repr__(self) -> str:
        return f"Planar3PRR({self.geometry!r})"

    # -- home ------------------------------------------------------------------------
    @property
    def home_s(self) -> np.ndarray:
        """Slider coordinates at home (m), shape (3,)."""
        return self.geometry.home_s

    @property
    def home_pose(self) -> np.ndarray:
        """Home pose (0, 0, 0), shape (3,)."""
        return self.geometry.home_pose

    @cached_property
    def home_configuration(self) -> np.ndarray:
        """Pinocchio configuration at home (nq,), every closure satisfied."""
        return self.configuration(self.home_pose)

    # -- geometry helpers ----------------------------------------------------------------
    def platform_points_world(self, pose) -> np.ndarray:
        """World positions ``P_k`` of the three platform joints (m), shape (3, 2)."""
        pose = as_array(pose, (3,), "pose")
        return pose[:2] + self._pts @ _rot2(pose[2]).T

    def slider_points(self, s) -> np.ndarray:
        """World positions ``c_k = m_k + s_k u_k`` of the slider joints (m), shape (3, 2)."""
        s = as_array(s, (N_SLIDERS,), "s")
        return self._mids + s[:, None] * self._dirs

    def link_vectors(self, pose, s) -> np.ndarray:
        """Link vectors ``n_k = P_k - c_k`` (m), shape (3, 2); ``|n_k| = L`` when closed."""
        return self.platform_points_world(pose) - self.slider_points(s)

    # -- the single-state closed form (compiled kernels) -------------------------------
    def _signs(self, branch) -> np.ndarray:
        """A validated branch (3,) (``None``: the home branch), a float64 copy."""
        return self._home_signs if branch is None else np.array(check_branch(branch))

    def _kernel_state(self, level: int, singular: bool, branch, inputs, pose,
                      twist=None, twist_dot=None):
        """Tree ``q``, ``v``, ``a`` (fresh (nv,) arrays, model order) of a platform state.

        Runs :func:`_state_kernel` on arrays from :func:`_vec3` (``v`` is filled from
        ``level`` 1, ``a`` from ``level`` 2; the others are left uninitialised); the leg
        buffer then holds the IK, link vectors, Jacobian rows and leg rates. ``inputs``:
        the ``(value, name)`` pairs as given, for the error messages.

        Raises:
            InputError: a NaN / inf input (named, with its value).
            UnreachablePoseError: a link cannot reach its rail.
            SingularityError: with ``singular``, a link perpendicular to its rail.
        """
        nv = self._nv
        q, v, a = np.empty(nv), np.empty(nv), np.empty(nv)
        status = _state_kernel(self._geo, self._idx, pose,
                               self._zero3 if twist is None else twist,
                               self._zero3 if twist_dot is None else twist_dot,
                               self._signs(branch), level, singular, q, v, a,
                               self._legs_buf, self._info)
        if status != _OK:
            self._raise_for(status, inputs)
        return q, v, a

    def _raise_for(self, status: int, inputs) -> None:
        """Raise the library's exception for a kernel status (values from ``_info``)."""
        info = self._info
        if status == _NONFINITE:
            for value, name in inputs:
                if value is not None:
                    as_array(value, (3,), name)          # raises, naming the value
            raise InputError(inputs[0][1], inputs[0][0], "contains NaN or inf")
        if status == _UNREACHABLE:
            bad = [k for k in range(N_SLIDERS) if info[3 + k] > 0.0]
            raise UnreachablePoseError(bad, [info[k] for k in bad])
        raise SingularityError("inverse kinematic Jacobian (a link perpendicular to its "
                               "rail)", info[_X_WORST])

    # -- inverse kinematics ----------------------------------------------------------------
    def inverse_kinematics(self, pose, branch=None, check_limits: bool = True) -> np.ndarray:
        """Slider coordinates for a platform pose (closed form).

        With ``d_k = P_k - m_k``, slider k solves ``|d_k - s_k u_k| = L``:
        ``s_k = u_k . d_k + branch_k sqrt(L^2 - |d_k|^2 + (u_k . d_k)^2)``.

        Args:
            pose: ``(x, y, theta)`` (m, m, rad), shape (3,).
            branch: three signs ``+1`` / ``-1`` choosing the root of each slider's
                quadratic (``+1``: the larger ``s_k``, the home branch); default all ``+1``.
                The 8 branches are in :data:`ALL_BRANCHES`.
            check_limits: check ``abs(s_k) <= rail_half_length``.

        Returns:
            s, shape (3,) (m along ``u_k`` from the rail midpoint).

        Raises:
            InputError: wrong shape, NaN / inf, or a malformed branch.
            UnreachablePoseError: a link cannot reach its rail (its ``carriages``
                attribute holds the slider indices, ``shortfall`` how much too short).
            StrokeLimitError: with ``check_limits``, a slider outside its stroke.
        """
        self._kernel_state(0, False, branch, ((pose, "pose"),), _vec3(pose, "pose"))
        s = self._legs_buf[:, _S].copy()
        if check_limits and self._info[_X_SMAX] > self.geometry.rail_half_length:
            self.check_stroke(s)
        return s

    def stroke_violations(self, s) -> list[str]:
        """Human-readable stroke violations of slider coordinates ``s`` (3,)."""
        s = as_array(s, (N_SLIDERS,), "s")
        h = self.geometry.rail_half_length
        return [f"slider {k}: |s|={abs(s[k]):.6g} > rail_half_length={h:g}"
                for k in range(N_SLIDERS) if abs(s[k]) > h]

    def check_stroke(self, s) -> None:
        """Raise :class:`StrokeLimitError` when ``s`` leaves the stroke."""
        violations = self.stroke_violations(s)
        if violations:
            raise StrokeLimitError(s, violations)

    def branch_of(self, pose, s) -> np.ndarray:
        """The IK branch (3 signs) that maps ``pose`` to ``s``: ``-sign(n_k . u_k)``.

        Raises:
            SingularityError: a link perpendicular to its rail (both branches meet).
        """
        dots = self._link_dots(self.link_vectors(pose, s))
        return -np.sign(dots)

    def _link_dots(self, links: np.ndarray) -> np.ndarray:
        dots = np.einsum("ki,ki->k", links, self._dirs)
        worst = float(np.min(np.abs(dots))) / self.geometry.link_length
        if worst < _PERPENDICULAR_TOL:
            raise SingularityError("inverse kinematic Jacobian (a link perpendicular to its "
                                   "rail)", worst)
        return dots

    # -- Jacobian -----------------------------------------------------------------------
    def jacobian(self, pose, branch=None) -> np.ndarray:
        """Workspace Jacobian ``J`` (3, 3) with ``sdot = J @ twist``.

        From ``d/dt |n_k|^2 = 0`` with ``dP_k/dt = v + omega z x r_k``, ``r_k = R p_k``::

            J[k] = [n_k, r_k x n_k] / (n_k . u_k)

        Rows in slider order, columns ``(vx, vy, omega)`` (world axes).

        Args:
            pose: ``(x, y, theta)``, shape (3,).
            branch: IK branch, default all ``+1``.

        Raises:
            UnreachablePoseError: the pose cannot be reached.
            SingularityError: a link perpendicular to its rail (type I singularity).
        """
        self._kernel_state(0, True, branch, ((pose, "pose"),), _vec3(pose, "pose"))
        return self._legs_buf[:, _J0:_J2 + 1].copy()

    def twist_from_sdot(self, pose, sdot, branch=None) -> np.ndarray:
        """Platform twist (3,) from slider velocities (m/s): solves ``J @ twist = sdot``.

        Raises:
            SingularityError: where ``J`` is singular (type II, or type I).
        """
        jac = self.jacobian(pose, branch=branch)
        sdot = as_array(sdot, (N_SLIDERS,), "sdot")
        sv = np.linalg.svd(jac, compute_uv=False)
        if sv[-1] <= 1e-12 * sv[0]:
            raise SingularityError("workspace Jacobian", sv[-1])
        return np.linalg.solve(jac, sdot)

    # -- forward kinematics ----------------------------------------------------------------
    def _closure(self, pose: np.ndarray, s: np.ndarray):
        """Residual ``(|n_k|^2 - L^2) / 2`` (m^2) and its pose Jacobian (3, 3)."""
        links = self.link_vectors(pose, s)
        r = self.platform_points_world(pose) - pose[:2]
        res = 0.5 * (np.einsum("ki,ki->k", links, links) - self.geometry.link_length ** 2)
        jac = np.column_stack([links, _cross2(r, links)])
        return res, jac

    def forward_kinematics(self, s, guess=None, tol: float = 1e-12,
                           max_iter: int = 50) -> np.ndarray:
        """Platform pose for slider coordinates, by Newton from a guess.

        Solves ``|P_k(pose) - c_k(s)| = L`` (k = 0, 1, 2) with damped Newton steps; the
        result is the assembly mode the iteration reaches from ``guess`` (use
        :meth:`assembly_modes` for all of them).

        Args:
            s: slider coordinates (m), shape (3,). Stroke limits are not checked.
            guess: starting pose ``(x, y, theta)``; default the home pose.
            tol: convergence threshold on ``max_k | |n_k| - L |`` (m).
            max_iter: maximum Newton iterations.

        Returns:
            pose (3,), theta in (-pi, pi].

        Raises:
            InputError: wrong shape or non-finite values.
            AssemblyError: no convergence (unreachable coordinates, a singular
                configuration); ``q`` holds the last pose.
        """
        s = as_array(s, (N_SLIDERS,), "s")
        pose = self.home_pose.copy() if guess is None else as_array(guess, (3,), "guess").copy()
        pose, err, iterations = self._newton(pose, s, tol, max_iter)
        if err > tol:
            raise AssemblyError("forward kinematics did not converge", err, iterations, pose)
        pose[2] = _wrap(pose[2])
        return pose

    def _newton(self, pose: np.ndarray, s: np.ndarray, tol: float, max_iter: int):
        length = self.geometry.link_length
        res, jac = self._closure(pose, s)
        err = _length_error(res, length)
        for iteration in range(max_iter + 1):
            if err <= tol or iteration == max_iter:
                return pose, err, iteration
            step, *_ = np.linalg.lstsq(jac, -res, rcond=None)
            alpha = 1.0
            for _ in range(30):
                trial = pose + alpha * step
                trial_res, trial_jac = self._closure(trial, s)
                trial_err = _length_error(trial_res, length)
                if trial_err < err:
                    break
                alpha *= 0.5
            else:
                return pose, err, iteration
            pose, res, jac, err = trial, trial_res, trial_jac, trial_err
        return pose, err, max_iter

    def assembly_polynomial(self, s) -> AssemblyPolynomial:
        """The sextic in ``T = tan((theta - theta_offset) / 2)`` of the assembly modes.

        Elimination (the classical route for 3-RPR-like chains: each platform point
        lies on the circle of radius L around its slider joint). With
        ``e_k(theta) = R(theta) p_k - c_k`` the closures read ``|t + e_k|^2 = L^2``,
        ``t = (x, y)``. Subtracting closure 0 from closures 1 and 2 leaves two
        equations LINEAR in t, ``A(theta) t = b(theta)``; Cramer's rule,
        ``t = adj(A) b / det A``, put into closure 0 gives

            F(theta) = |adj(A) b|^2 + 2 det(A) (adj(A) b) . e_0
                       + det(A)^2 (|e_0|^2 - L^2) = 0.

        ``cos`` and ``sin`` are rational in ``T`` with denominator ``W = 1 + T^2``;
        computed exactly in polynomial arithmetic, ``W^6 F`` is a polynomial of degree
        12 divisible by ``W^3`` (the factor from the circular points, which carry no
        real solution); the quotient is the sextic returned here, so there are at most
        6 real assembly modes. ``theta_offset`` is chosen where ``F(theta_offset + pi)``
        is largest, so that no root sits at ``T = infinity``.

        Args:
            s: slider coordinates (m), shape (3,).
        """
        s = as_array(s, (N_SLIDERS,), "s")
        centres = self.slider_points(s)
        candidates = np.linspace(-np.pi, np.pi, 24, endpoint=False)
        values = [abs(self._eliminant(theta, centres)) for theta in candidates + np.pi]
        offset = float(candidates[int(np.argmax(values))])
        numerator = self._eliminant_numerator(offset, centres)
        weight = np.polynomial.Polynomial([1.0, 0.0, 1.0]) ** 3
        quotient, remainder = divmod(numerator, weight)
        scale = float(np.max(np.abs(numerator.coef)))
        rem = float(np.max(np.abs(remainder.coef))) / scale if scale > 0 else 0.0
        coef = np.zeros(7)
        coef[:quotient.coef.size] = quotient.coef[:7]
        top = float(np.max(np.abs(coef)))
        return AssemblyPolynomial(coef / top if top > 0 else coef, offset, rem)

    def _eliminant(self, theta: float, centres: np.ndarray) -> float:
        """``F(theta)`` of :meth:`assembly_polynomial`, evaluated directly."""
        e = self._pts @ _rot2(theta).T - centres
        a = 2.0 * (e[1:] - e[0])
        b = -(np.einsum("ki,ki->k", e[1:], e[1:]) - e[0] @ e[0])
        det = a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]
        adj_b = np.array([a[1, 1] * b[0] - a[0, 1] * b[1], -a[1, 0] * b[0] + a[0, 0] * b[1]])
        length = self.geometry.link_length
        return float(adj_b @ adj_b + 2.0 * det * adj_b @ e[0]
                     + det ** 2 * (e[0] @ e[0] - length ** 2))

    def _eliminant_numerator(self, offset: float, centres: np.ndarray):
        """``W^6 F`` as a polynomial in T (degree <= 12), theta = offset + 2 atan(T)."""
        poly = np.polynomial.Polynomial
        w = poly([1.0, 0.0, 1.0])
        cos_phi, sin_phi = poly([1.0, 0.0, -1.0]), poly([0.0, 2.0])
        c0, s0 = math.cos(offset), math.sin(offset)
        cos_t = c0 * cos_phi - s0 * sin_phi   # numerators over W
        sin_t = s0 * cos_phi + c0 * sin_phi
        pts = self._pts
        # e_k components, numerators over W
        e = [[pts[k, 0] * cos_t - pts[k, 1] * sin_t - centres[k, 0] * w,
              pts[k, 0] * sin_t + pts[k, 1] * cos_t - centres[k, 1] * w] for k in range(3)]
        a = [[2.0 * (e[k][i] - e[0][i]) for i in range(2)] for k in (1, 2)]       # over W
        norm2 = [e[k][0] ** 2 + e[k][1] ** 2 for k in range(3)]                     # over W^2
        b = [-(norm2[k] - norm2[0]) for k in (1, 2)]                                # over W^2
        det = a[0][0] * a[1][1] - a[0][1] * a[1][0]                                 # over W^2
        adj_b = [a[1][1] * b[0] - a[0][1] * b[1], -a[1][0] * b[0] + a[0][0] * b[1]]  # over W^3
        length2 = self.geometry.link_length ** 2
        return (adj_b[0] ** 2 + adj_b[1] ** 2
                + 2.0 * det * (adj_b[0] * e[0][0] + adj_b[1] * e[0][1])
                + det ** 2 * (norm2[0] - length2 * w ** 2))                          # over W^6

    def assembly_modes(self, s, tol: float = 1e-12) -> np.ndarray:
        """Every real assembly mode (platform pose) for slider coordinates ``s``.

        The real roots of the sextic of :meth:`assembly_polynomial` are every
        ``theta`` at which the closures can hold; for each, ``t = (x, y)`` follows from
        the linear equations ``A(theta) t = b(theta)`` (or, where ``det A`` vanishes,
        from the line ``A t = b`` intersected with closure 0), and a few Newton steps
        polish the pose to ``tol``. A pose that does not close to ``1e-9`` m is dropped
        (a spurious root of the eliminant), duplicates are merged. Since every real
        assembly mode is a real root of a polynomial of degree 6, none is missed and
        there are at most 6. Near-real roots (imaginary part below ``1e-6 (1 + |T|)``)
        are tried too, so that double roots at singular configurations are kept.

        Args:
            s: slider coordinates (m), shape (3,). Stroke limits are not checked.
            tol: Newton polishing threshold on ``| |n_k| - L |`` (m).

        Returns:
            poses, shape (n_modes, 3), ``0 <= n_modes <= 6``, sorted by theta in
            (-pi, pi].

        Raises:
            InputError: wrong shape or non-finite values.
            SingularityError: the eliminant vanishes identically (an architecture
                singularity: a continuum of assembly modes).
        """
        s = as_array(s, (N_SLIDERS,), "s")
        poly = self.assembly_polynomial(s)
        centres = self.slider_points(s)
        coef = np.trim_zeros(poly.coefficients, "b")
        if coef.size == 0 or np.max(np.abs(coef)) == 0.0:
            raise SingularityError("assembly polynomial (identically zero)", 0.0)
        roots = np.polynomial.polynomial.polyroots(coef) if coef.size > 1 else np.zeros(0)
        real = roots[np.abs(roots.imag) <= 1e-6 * (1.0 + np.abs(roots))].real
        found: list[np.ndarray] = []
        for root in real:
            theta = poly.theta_offset + 2.0 * math.atan(root)
            for t in self._translations(theta, centres):
                pose, err, _ = self._newton(np.array([t[0], t[1], theta]), s, tol, 20)
                if err > 1e-9:
                    continue
                pose[2] = _wrap(pose[2])
                if not any(_same_pose(pose, other) for other in found):
                    found.append(pose)
        found.sort(key=lambda p: p[2])
        return np.array(found).reshape(-1, 3)

    def _translations(self, theta: float, centres: np.ndarray) -> list[np.ndarray]:
        """Candidate platform origins ``t`` at a given theta (see :meth:`assembly_modes`)."""
        e = self._pts @ _rot2(theta).T - centres
        a = 2.0 * (e[1:] - e[0])
        b = -(np.einsum("ki,ki->k", e[1:], e[1:]) - e[0] @ e[0])
        sv = np.linalg.svd(a, compute_uv=False)
        if sv[-1] > 1e-8 * max(sv[0], 1e-300):
            return [np.linalg.solve(a, b)]
        # rank-deficient: t = t_p + lam * n on the line, then |t + e_0|^2 = L^2
        t_p, *_ = np.linalg.lstsq(a, b, rcond=None)
        _, _, vt = np.linalg.svd(a)
        n = vt[-1]
        w = t_p + e[0]
        qb, qc = 2.0 * n @ w, w @ w - self.geometry.link_length ** 2
        disc = qb * qb - 4.0 * qc
        if disc < 0.0:
            return []
        root = math.sqrt(disc)
        return [t_p + lam * n for lam in ((-qb + root) / 2.0, (-qb - root) / 2.0)]

    # -- tree configuration, velocity, acceleration ------------------------------------------
    def configuration(self, pose, branch=None) -> np.ndarray:
        """Pinocchio configuration of the tree for a platform pose (closed form).

        Sliders from :meth:`inverse_kinematics` (stroke not checked), link angles
        ``atan2(n_k) - (a_k + 90 deg)`` wrapped to (-pi, pi], the platform chain from
        the pose. The closures are then evaluated on the Pinocchio model.

        Args:
            pose: ``(x, y, theta)``, shape (3,).
            branch: IK branch, default all ``+1``.

        Returns:
            q (nq = 9,) satisfying the 9 closure rows to 1e-12 m.

        Raises:
            UnreachablePoseError: a link cannot reach.
            AssemblyError: the closed form misses the closures by more than 1e-12 m.
        """
        q, _, _ = self._kernel_state(0, False, branch, ((pose, "pose"),), _vec3(pose, "pose"))
        err = float(np.max(np.abs(self.model.residual(q))))
        if err > CLOSED_FORM_TOL:
            raise AssemblyError("closed-form configuration misses the closures", err, 0, q)
        return q

    def velocity(self, pose, twist, branch=None) -> np.ndarray:
        """Tree velocity ``v`` (nv = 9,) of a platform motion, every closure kept.

        Sliders ``J @ twist``, link rates ``(n_k x dn_k/dt) / L^2``, the platform chain
        the twist itself (its joints are world x, world y and z).

        Raises:
            UnreachablePoseError, SingularityError: see :meth:`jacobian`.
        """
        return self._state(pose, twist, branch)[1]

    def acceleration(self, pose, twist, twist_dot, branch=None) -> np.ndarray:
        """Tree acceleration ``a`` (nv = 9,) of a platform motion, every closure kept.

        The platform chain's acceleration is ``twist_dot``; the sliders and links solve
        the in-plane rows of ``J_c a = -gamma(q, v)`` (the out-of-plane ones are
        identically zero), two per loop, in closed form: with ``b_k = a_xy +
        omega_dot z x r_k + phi_dot_k^2 n_k - omega^2 r_k`` (the platform point's
        acceleration less the link's centripetal term), ``u_k s''_k + (z x n_k) phi''_k
        = b_k``, so ``s''_k = (b_k . n_k) / (n_k . u_k)`` and ``phi''_k = (u_k x b_k) /
        (n_k . u_k)``.

        Raises:
            UnreachablePoseError, SingularityError: see :meth:`jacobian`.
        """
        inputs = ((pose, "pose"), (twist, "twist"), (twist_dot, "twist_dot"))
        return self._kernel_state(2, True, branch, inputs, _vec3(pose, "pose"),
                                  _vec3(twist, "twist"), _vec3(twist_dot, "twist_dot"))[2]

    # -- dynamics ------------------------------------------------------------------------
    # Single-state routes, "kkt" (the default): the tree state in closed form
    # (_state_kernel), Pinocchio for the generalised forces (rnea; the gravity vector for
    # statics; rnea and crba for forward dynamics), then the planar structure of the
    # closure rows (_inverse_kernel, _forward_kernel) instead of a dense least-squares KKT
    # solve. A state where that structure is (nearly) singular, or whose solve does not
    # check to round-off, goes to the generic dense route: the answers are the generic
    # ones everywhere (to round-off). "qp" / "pinocchio" always take the generic route.
    def _state(self, pose, twist, branch):
        q, v, _ = self._kernel_state(1, True, branch, ((pose, "pose"), (twist, "twist")),
                                     _vec3(pose, "pose"), _vec3(twist, "twist"))
        return q, v

    def _external(self, wrench) -> np.ndarray:
        tau = np.zeros(self.model.nv)
        if wrench is not None:
            tau[self.indices.platform] = as_array(wrench, (3,), "wrench")
        return tau

    def _bounds(self, bounds):
        if bounds is None and math.isfinite(self.geometry.max_actuator_force):
            return self.geometry.max_actuator_force
        return bounds

    def _link_forces(self, multipliers: np.ndarray) -> np.ndarray:
        return np.stack([multipliers[rows][:2] for rows in self.model.row_slices])

    def inverse_dynamics(self, pose, twist, twist_dot, wrench=None, branch=None,
                         bounds=None, method: str = "kkt") -> PlanarInverseDynamics:
        """Actuator forces that produce a platform motion (closed-loop inverse dynamics).

        The tree state follows in closed form (:meth:`configuration`, :meth:`velocity`,
        :meth:`acceleration`); the forces then solve
        ``M a + h - tau_ext = S^T tau + J_c^T lambda`` on the tree, gravity ``-g`` along
        y included; ``M a + h`` is Pinocchio's ``rnea``.

        Args:
            pose: ``(x, y, theta)`` (m, m, rad), shape (3,).
            twist: ``(vx, vy, omega)`` (m/s, rad/s), world axes, shape (3,).
            twist_dot: its time derivative (m/s^2, rad/s^2), shape (3,).
            wrench: ``(fx, fy, mz)`` applied ON the platform by the environment (N, N m),
                moment about the platform origin; default zero.
            branch: IK branch, default all ``+1``.
            bounds: ``abs(tau_k) <= bounds`` (N); default ``geometry.max_actuator_force``.
            method: "kkt" (default): that square linear system solved with its planar
                structure in closed form (:func:`_inverse_kernel`: per loop, the link
                row fixes the closure force across the link, a 3x3 on the platform rows
                its component along the link, the slider row the actuator force; the
                out-of-plane multipliers are zero); near a type II singularity, where
                the 3x3 is singular, the dense least-squares solve of
                :func:`~hexapod_pin.dynamics.inverse_dynamics_tree`. "qp": ProxSuite
                through :func:`~hexapod_pin.dynamics.inverse_dynamics_tree`. Both agree
                to round-off when no bound is active.

        Returns:
            :class:`PlanarInverseDynamics` (forces along ``+u_k``, N).

        Raises:
            InputError: a malformed input (or bounds).
            UnreachablePoseError: the pose cannot be reached.
            SingularityError: a link perpendicular to its rail.
            ActuatorSaturationError: the motion needs more than ``bounds``.
        """
        inputs = ((pose, "pose"), (twist, "twist"), (twist_dot, "twist_dot"))
        pose_a, twist_a = _vec3(pose, "pose"), _vec3(twist, "twist")
        twist_dot_a = _vec3(twist_dot, "twist_dot")
        wrench_a = None if wrench is None else _vec3(wrench, "wrench")
        bounds = self._bounds(bounds)
        limits = _check_bounds(bounds) if method == "kkt" else None
        q, v, a = self._kernel_state(2, True, branch, inputs, pose_a, twist_a, twist_dot_a)
        if method == "kkt":
            force = pin.rnea(self.model.model, self._pin_data, q, v, a)
            res = self._inverse_closed_form(force, wrench, wrench_a, limits)
            if res is not None:
                return res
        res = inverse_dynamics_tree(self.model, q, v, a, self._external(wrench),
                                    bounds=bounds, method=method)
        return PlanarInverseDynamics(res.actuator_forces.copy(),
                                     self._link_forces(res.multipliers), res)

    def _inverse_closed_form(self, force, wrench, wrench_a, limits):
        """:func:`_inverse_kernel` on a generalised force; None: take the generic route."""
        tau, lam = np.empty(N_SLIDERS), np.empty(self.model.n_rows)
        status = _inverse_kernel(self._geo, self._idx, self._legs_buf, force,
                                 self._zero3 if wrench_a is None else wrench_a,
                                 wrench_a is not None, tau, lam, self._info)
        if status == _NONFINITE:
            self._raise_for(status, ((wrench, "wrench"),))
        if status != _OK:
            return None
        if limits is not None and np.any(np.abs(tau) > limits * (1.0 + _CLOSED_FORM_RTOL)):
            raise ActuatorSaturationError(tau, limits)
        tree = TreeInverseDynamics(tau, lam, float(self._info[_X_RES]), "kkt", _STATUS_ID, 0)
        return PlanarInverseDynamics(tau.copy(), lam[self._link_rows], tree)

    def static_forces(self, pose, wrench=None, branch=None) -> np.ndarray:
        """Actuator forces (3,) (N, along ``+u_k``) holding the platform at rest.

        Balances gravity (``-g`` along y, every body) and the external ``wrench``
        ``(fx, fy, mz)`` applied ON the platform (N, N m, moment about its origin):
        :meth:`inverse_dynamics` at zero twist and acceleration, without bounds (the
        generalised gravity ``g(q)`` from Pinocchio, then the same structured solve).

        Raises:
            InputError, UnreachablePoseError, SingularityError: see
            :meth:`inverse_dynamics`.
        """
        pose_a = _vec3(pose, "pose")
        wrench_a = None if wrench is None else _vec3(wrench, "wrench")
        q, _, _ = self._kernel_state(0, True, branch, ((pose, "pose"),), pose_a)
        force = pin.computeGeneralizedGravity(self.model.model, self._pin_data, q)
        res = self._inverse_closed_form(force, wrench, wrench_a, None)
        if res is not None:
            return res.forces
        zero = np.zeros(self.model.nv)
        return inverse_dynamics_tree(self.model, q, zero, zero, self._external(wrench),
                                     bounds=np.inf, method="kkt").actuator_forces.copy()

    def forward_dynamics(self, pose, twist, forces, wrench=None, branch=None,
                         method: str = "kkt") -> PlanarForwardDynamics:
        """Platform acceleration for given actuator forces (closed-loop forward dynamics).

        Solves ``M a + h = S^T tau + tau_ext + J_c^T lambda``, ``J_c a = -gamma`` on the
        tree; the platform chain's acceleration is ``twist_dot``.

        Args:
            pose: ``(x, y, theta)``, shape (3,).
            twist: ``(vx, vy, omega)`` (m/s, rad/s), world axes, shape (3,).
            forces: actuator forces (3,) (N), on slider k along ``+u_k``.
            wrench: ``(fx, fy, mz)`` on the platform (N, N m); default zero.
            branch: IK branch, default all ``+1``.
            method: "kkt" (default): that KKT system solved by the null-space method in
                closed form (:func:`_forward_kernel`: ``a = G twist_dot + a_0`` keeps the
                closures, ``G^T M G twist_dot = G^T (S^T tau + tau_ext - M a_0 - h)``
                with Pinocchio's ``crba`` and ``rnea``, the multipliers per loop from
                its slider and link rows); "qp" or "pinocchio" (slow here: the
                redundant rows need Pinocchio's proximal iterations) through
                :func:`~hexapod_pin.dynamics.forward_dynamics_tree` (redundant rows
                handled there).

        Returns:
            :class:`PlanarForwardDynamics`.

        Raises:
            InputError, UnreachablePoseError, SingularityError: see
            :meth:`inverse_dynamics`.
        """
        inputs = ((pose, "pose"), (twist, "twist"))
        pose_a, twist_a = _vec3(pose, "pose"), _vec3(twist, "twist")
        forces_a = _vec3(forces, "forces")
        wrench_a = None if wrench is None else _vec3(wrench, "wrench")
        # a = a_0: the acceleration at zero twist_dot (the null-space route's offset)
        q, v, acc0 = self._kernel_state(2, True, branch, inputs, pose_a, twist_a)
        if method == "kkt":
            res = self._forward_closed_form(q, v, acc0, twist_a, forces, forces_a, wrench,
                                            wrench_a)
            if res is not None:
                return res
        tau = self._external(wrench)
        tau[self.indices.slider] += as_array(forces, (3,), "forces")
        res = forward_dynamics_tree(self.model, q, v, tau, method=method)
        return PlanarForwardDynamics(res.a[self.indices.platform].copy(),
                                     res.a[self.indices.slider].copy(),
                                     self._link_forces(res.multipliers), res)

    def _forward_closed_form(self, q, v, acc0, twist_a, forces, forces_a, wrench, wrench_a):
        """:func:`_forward_kernel` at a state; None: take the generic route."""
        model, data = self.model.model, self._pin_data
        bias = pin.rnea(model, data, q, v, acc0)          # M a_0 + h (Pinocchio's buffer)
        mass = pin.crba(model, data, q)                    # upper triangle
        acc, lam, twist_dot = np.empty(self._nv), np.empty(self.model.n_rows), np.empty(3)
        status = _forward_kernel(self._geo, self._idx, self._legs_buf, twist_a, bias, mass,
                                 forces_a, self._zero3 if wrench_a is None else wrench_a,
                                 wrench_a is not None, acc, lam, twist_dot, self._info)
        if status == _NONFINITE:
            self._raise_for(status, ((forces, "forces"), (wrench, "wrench")))
        if status != _OK:
            return None
        tree = TreeForwardDynamics(acc, lam, "kkt", _STATUS_FD, 0, _IN_PLANE_RANK,
                                   float(self._info[_X_RES]))
        return PlanarForwardDynamics(twist_dot, acc[self.indices.slider],
                                     lam[self._link_rows], tree)

    def kinetic_energy(self, pose, twist, branch=None) -> float:
        """Kinetic energy of every body (J) for a platform motion (Pinocchio)."""
        q, v = self._state(pose, twist, branch)
        return float(pin.computeKineticEnergy(self.model.model, self._data, q, v))

    def potential_energy(self, pose, branch=None) -> float:
        """Gravity potential energy (J), zero at y = 0 for every body (Pinocchio)."""
        q, _ = self._state(pose, np.zeros(3), branch)
        return float(pin.computePotentialEnergy(self.model.model, self._data, q))

    def energy(self, pose, twist, branch=None) -> float:
        """Total mechanical energy ``T + V`` (J)."""
        return self.kinetic_energy(pose, twist, branch) + self.potential_energy(pose, branch)

    def pose_from_configuration(self, q) -> np.ndarray:
        """Platform pose (3,) read from a Pinocchio configuration (nq,)."""
        return self.model.check_q(q)[self.indices.platform].copy()

    def slider_positions(self, q) -> np.ndarray:
        """Slider coordinates (3,) read from a Pinocchio configuration (nq,)."""
        return self.model.check_q(q)[self.indices.slider].copy()


def _frozen(array: np.ndarray) -> np.ndarray:
    array = np.array(array, dtype=float)
    array.setflags(write=False)
    return array


def _wrap(angle):
    """Angle(s) wrapped to (-pi, pi]."""
    return np.pi - np.mod(np.pi - np.asarray(angle, dtype=float), 2.0 * np.pi)


def _length_error(res: np.ndarray, length: float) -> float:
    """``max_k | |n_k| - L |`` from ``res_k = (|n_k|^2 - L^2) / 2``."""
    norms = np.sqrt(np.maximum(length ** 2 + 2.0 * res, 0.0))
    return float(np.max(np.abs(norms - length)))


def _same_pose(a: np.ndarray, b: np.ndarray, tol: float = 1e-8) -> bool:
    return (np.max(np.abs(a[:2] - b[:2])) <= tol
            and abs(_wrap(a[2] - b[2])) <= tol)
