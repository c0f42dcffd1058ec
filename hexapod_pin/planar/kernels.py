"""The planar 3-PRR's closed form, compiled: the one source of its mechanics.

Every single-state route of :class:`~hexapod_pin.planar.robot.Planar3PRR` calls one of
these kernels once, and every batch route runs the same kernels over N states
(:mod:`hexapod_pin.core.batching`: ``numba.prange`` over chunks of states, on the calling
thread for small batches). The Pinocchio tree routes (:mod:`hexapod_pin.core.dynamics`) stay the
independent reference the tests compare them with.

The equations (conventions of :mod:`hexapod_pin.planar.geometry`; ``z x w = (-w_y, w_x)``,
``a x b = a_x b_y - a_y b_x``):

* leg k (:func:`legs`): ``r_k = R(theta) p_k``, ``d_k = (x, y) + r_k - m_k``,
  ``s_k = u_k . d_k + branch_k sqrt(L^2 - |d_k|^2 + (u_k . d_k)^2)``, the link vector
  ``n_k = d_k - s_k u_k``, ``nu_k = n_k . u_k`` and the Jacobian row
  ``J_k = (n_k, r_k x n_k) / nu_k`` (``actuator velocities = J twist``);
* velocity map ``v = G twist`` (keeps every closure): platform rows the identity, slider
  k the row ``J_k``, link k the row ``(-u_ky, u_kx, u_k . r_k) / nu_k``; link rate
  ``phi'_k = n_k x (v + omega z x r_k - s'_k u_k) / L^2``;
* accelerations (:func:`accelerations`): with ``b_k = a_xy + alpha z x r_k +
  phi'_k^2 n_k - omega^2 r_k``, ``u_k s''_k + (z x n_k) phi''_k = b_k``, so
  ``s''_k = (b_k . n_k) / nu_k`` and ``phi''_k = (u_k x b_k) / nu_k``;
* Newton-Euler (:func:`tree_forces`): the generalised force ``M a + h`` of the tree
  (Pinocchio's ``rnea``) in closed form. Link centre ``c_k + n_k / 2`` with acceleration
  ``a_G = s'' u + (phi'' z x n - phi'^2 n) / 2``: slider row ``m_s (s'' + g u_y) +
  m_l (a_G + g y) . u``, link row ``m_l L^2 / 12 phi'' + (n / 2) x m_l (a_G + g y)``,
  platform rows ``(m_p a_x, m_p (a_y + g), I_p alpha)``;
* closures: ``lambda_k`` (world x, y) the force of the platform ON link k, so the link
  pushes the platform with ``closure_k = -lambda_k``. Tree rows: slider
  ``f_s = tau + u . lambda``, link ``f_phi = (z x n) . lambda``, platform
  ``f_p - wrench = -(sum lambda, sum r x lambda)``;
* inverse dynamics (:func:`solve_inverse`): ``lambda_k = mu_k n_k + (f_phi / L^2) z x n_k``
  from the link rows, a 3x3 in ``mu`` on the platform rows (columns
  ``(n_k, r_k x n_k)``: singular at a type-II singularity), ``tau`` from the slider rows;
* reduced dynamics (:func:`reduced`): ``M_x = G^T M G`` (columns: Newton-Euler of the
  unit accelerations ``G e_j`` at rest, no gravity), ``h_x = G^T (M a_0 + h)``;
  ``J^T tau + wrench = M_x twist_dot + h_x``;
* forward dynamics (:func:`forward`): that 3x3 solved, ``a = a_0 + G twist_dot``, the
  multipliers per loop from its slider and link rows (determinant ``nu_k``), the
  platform rows and the closures at acceleration level as the checks;
* drives (:mod:`hexapod_pin.core.effects_projection`): the effects of the sliders'
  coordinates (``robot.effects``: armature, damping, Coulomb friction, springs), packed
  after the geometry (:data:`DRIVES`), add ``a s'' + d s' + K (s - r) + c sign(s')`` to
  ``tau`` (the closure forces do not change), ``J^T diag(a) J`` to ``M_x`` and ``J^T (a
  s''_0 - drive force)`` to ``h_x`` (inertia only, never weight), and forward dynamics
  solves the friction of the sliders at rest
  (:func:`~hexapod_pin.core.effects_projection.stick_slip`); the slider rows of the
  closure forces then read ``f_s = tau + drive force + friction``. A rigid robot skips it
  all (the rigid kernels' numbers, bit for bit).

Layouts: ``geo`` (:func:`pack_geometry`), the leg buffer ``legs`` (3, LEG_COLS) (one row
per leg: s, n, r, nu, J row, s', phi', s'', phi'', the friction of a slider at rest), the
tree forces ``f`` (9,) in local order (sliders, links, platform x, y, theta), ``idx`` (12,)
the tree indices (platform chain, sliders, links) and the first multiplier row of each
closure. Kernels never
raise: they return a status (below) and leave the values the caller's exception needs
in ``info``.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from ..core import effects_projection as drv
from ..core.batching import CHUNK, n_chunks, prange_jit
from ..core.compiled import all_finite, jit
from ..core.kernel_status import (NONFINITE, OK, RESIDUAL,  # one numbering: every robot
                                  RESIDUAL_RTOL, TYPE_I, TYPE_II, UNREACHABLE)
from ..core.layouts import rail_angles
from ..core.measures import TYPE_I_TOL, TYPE_II_TOL
from .geometry import N_ACTUATORS, PlanarGeometry


# geometry vector: per leg k, 7 values from 7 k: m (2), u (2), p (2), a_k; then scalars
# (the singularity thresholds are packed, not read as globals: compiled code caches globals)
G_LEN, G_TOL, G_MS, G_ML, G_MP, G_IP, G_G, G_RP, G_TOL2 = range(21, 30)
#: 1.0 when passive coordinates (links, the platform's joints) carry effects, which the
#: kernels do not model: the Python routes then answer on the tree
PASSIVE = 30
#: where the sliders' drive vector starts (:func:`~hexapod_pin.core.effects_projection.pack_drives`)
DRIVES = 31
GEO_SIZE = DRIVES + drv.drive_size(N_ACTUATORS)
# leg buffer columns
S, NX, NY, RX, RY, NU, J0, J1, J2, SD, PD, SDD, PDD, FR = range(14)
LEG_COLS = 14
# info vector: shortfalls (3), unreachable flags (3), worst |n.u| / L, max |s|, residual,
# sigma_min(A_hat) of the type-II test
INFO_SIZE = 10
X_WORST, X_SMAX, X_RES, X_TYPE_TWO = 6, 7, 8, 9
# index vector: platform chain (3), sliders (3), links (3), first closure row of each loop
I_PLAT, I_SLIDER, I_LINK, I_ROW = 0, 3, 6, 9
IDX_SIZE = 12


def pack_geometry(geometry: PlanarGeometry, drives: np.ndarray | None = None,
                  passive: bool = False) -> np.ndarray:
    """The constants of a :class:`PlanarGeometry` as the kernels' flat ``geo`` vector, the
    :data:`PASSIVE` flag (``passive``: effects on passive coordinates) and the sliders'
    drive vector ``drives`` (default none: a rigid robot)."""
    geo = np.zeros(GEO_SIZE)
    for k, (mid, dirn, pt, angle) in enumerate(zip(
            geometry.rail_midpoints, geometry.rail_directions, geometry.platform_points,
            rail_angles())):
        geo[7 * k:7 * k + 7] = (*mid, *dirn, *pt, angle)
    geo[G_LEN], geo[G_TOL] = geometry.link_length, TYPE_I_TOL
    geo[G_MS], geo[G_ML] = geometry.slider_mass, geometry.link_mass
    geo[G_MP], geo[G_IP] = geometry.platform_mass, geometry.platform_inertia
    geo[G_G], geo[G_RP] = geometry.gravity, geometry.platform_radius
    geo[G_TOL2] = TYPE_II_TOL
    geo[PASSIVE] = float(passive)
    if drives is not None:
        geo[DRIVES:] = drives
    return geo


# ---------------------------------------------------------------------------------------
# kinematics
# ---------------------------------------------------------------------------------------
@jit
def legs(geo, pose, signs, buf, info):
    """Inverse kinematics, link vectors and Jacobian rows of a pose (leg buffer ``buf``).

    Returns OK or UNREACHABLE (``info[0:3]`` the shortfalls (m), ``info[3:6]`` 1.0 for
    each leg that cannot reach; such a leg's ``s`` is the foot of the perpendicular from
    its platform point, the nearest to reaching). ``info[X_WORST]`` gets the smallest
    ``|nu_k| / L`` of the reaching legs, ``info[X_SMAX]`` the largest ``|s_k|``.
    """
    x, y, theta = pose[0], pose[1], pose[2]
    cos_t, sin_t = math.cos(theta), math.sin(theta)
    length = geo[G_LEN]
    length2 = length * length
    status = OK
    worst, s_max = math.inf, 0.0
    for k in range(N_ACTUATORS):
        g = 7 * k
        mx, my, ux, uy = geo[g], geo[g + 1], geo[g + 2], geo[g + 3]
        px, py = geo[g + 4], geo[g + 5]
        rx, ry = px * cos_t - py * sin_t, px * sin_t + py * cos_t
        dx, dy = x + rx - mx, y + ry - my
        along = dx * ux + dy * uy
        disc = length2 - ((dx * dx + dy * dy) - along * along)
        leg = buf[k]
        info[k], info[3 + k] = 0.0, 0.0
        if not disc >= 0.0:
            info[k], info[3 + k] = math.sqrt(length2 - disc) - length, 1.0
            leg[S] = along
            s_max = max(s_max, abs(along))
            status = UNREACHABLE
            continue
        s = along + signs[k] * math.sqrt(disc)
        nx, ny = dx - s * ux, dy - s * uy
        nu = nx * ux + ny * uy
        leg[S], leg[NX], leg[NY], leg[RX], leg[RY], leg[NU] = s, nx, ny, rx, ry, nu
        leg[J0], leg[J1], leg[J2] = nx / nu, ny / nu, (rx * ny - ry * nx) / nu
        worst = min(worst, abs(nu) / length)
        s_max = max(s_max, abs(s))
    info[X_WORST], info[X_SMAX] = worst, s_max
    return status


@jit
def link_row(geo, buf, k):
    """Row of link k in the velocity map ``G``: ``(-u_y, u_x, u . r) / nu`` (rad per
    unit twist)."""
    leg = buf[k]
    ux, uy, nu = geo[7 * k + 2], geo[7 * k + 3], leg[NU]
    return -uy / nu, ux / nu, (ux * leg[RX] + uy * leg[RY]) / nu


@jit
def velocity_map(geo, idx, buf, out):
    """The velocity map ``G`` (nv, 3), model order: ``v = G twist`` keeps every closure."""
    out[:, :] = 0.0
    for j in range(3):
        out[idx[I_PLAT + j], j] = 1.0
    for k in range(N_ACTUATORS):
        l0, l1, l2 = link_row(geo, buf, k)
        i_s, i_l = idx[I_SLIDER + k], idx[I_LINK + k]
        out[i_s, 0], out[i_s, 1], out[i_s, 2] = buf[k, J0], buf[k, J1], buf[k, J2]
        out[i_l, 0], out[i_l, 1], out[i_l, 2] = l0, l1, l2


@jit
def rates(geo, buf, twist):
    """Slider velocities ``s'`` and link rates ``phi'`` of a twist (leg buffer)."""
    vx, vy, omega = twist[0], twist[1], twist[2]
    length2 = geo[G_LEN] * geo[G_LEN]
    for k in range(N_ACTUATORS):
        leg = buf[k]
        sdot = leg[J0] * vx + leg[J1] * vy + leg[J2] * omega
        lvx = vx - omega * leg[RY] - sdot * geo[7 * k + 2]
        lvy = vy + omega * leg[RX] - sdot * geo[7 * k + 3]
        leg[SD], leg[PD] = sdot, (leg[NX] * lvy - leg[NY] * lvx) / length2


@jit
def accelerations(geo, buf, twist, twist_dot):
    """Slider and link accelerations ``s''``, ``phi''`` of a motion (after :func:`rates`)."""
    ax, ay, alpha = twist_dot[0], twist_dot[1], twist_dot[2]
    omega2 = twist[2] * twist[2]
    for k in range(N_ACTUATORS):
        leg = buf[k]
        nx, ny, rx, ry, nu = leg[NX], leg[NY], leg[RX], leg[RY], leg[NU]
        phid2 = leg[PD] * leg[PD]
        bx = ax - alpha * ry + phid2 * nx - omega2 * rx
        by = ay + alpha * rx + phid2 * ny - omega2 * ry
        leg[SDD] = (bx * nx + by * ny) / nu
        leg[PDD] = (geo[7 * k + 2] * by - geo[7 * k + 3] * bx) / nu


@jit
def leg_state(geo, pose, twist, twist_dot, signs, level, singular, buf, info):
    """:func:`legs`, then (``level`` >= 1) :func:`rates`, (``level`` 2)
    :func:`accelerations`. With ``singular``, a link perpendicular to its rail (smallest
    ``|nu| / L`` below TYPE_I_TOL) returns TYPE_I. Returns OK, NONFINITE, UNREACHABLE or
    TYPE_I."""
    if not all_finite(pose) or (level >= 1 and not all_finite(twist)) \
            or (level >= 2 and not all_finite(twist_dot)):
        return NONFINITE
    status = legs(geo, pose, signs, buf, info)
    if status != OK:
        return status
    if singular and info[X_WORST] < geo[G_TOL]:
        return TYPE_I
    if level >= 1:
        rates(geo, buf, twist)
    if level >= 2:
        accelerations(geo, buf, twist, twist_dot)
    return OK


@jit
def write_tree(geo, idx, pose, twist, twist_dot, level, buf, q, v, a):
    """The tree state ``q`` (and ``v`` from ``level`` 1, ``a`` from ``level`` 2), model
    order, from the leg buffer; link angles ``atan2(n) - a_k - pi / 2`` in (-pi, pi]."""
    for j in range(3):
        q[idx[I_PLAT + j]] = pose[j]
    for k in range(N_ACTUATORS):
        leg = buf[k]
        q[idx[I_SLIDER + k]] = leg[S]
        angle = math.atan2(leg[NY], leg[NX]) - geo[7 * k + 6] - math.pi / 2
        q[idx[I_LINK + k]] = math.pi - (math.pi - angle) % (2.0 * math.pi)
        if level >= 1:
            v[idx[I_SLIDER + k]], v[idx[I_LINK + k]] = leg[SD], leg[PD]
        if level >= 2:
            a[idx[I_SLIDER + k]], a[idx[I_LINK + k]] = leg[SDD], leg[PDD]
    for j in range(3):
        if level >= 1:
            v[idx[I_PLAT + j]] = twist[j]
        if level >= 2:
            a[idx[I_PLAT + j]] = twist_dot[j]


@jit
def tree_state(geo, idx, pose, twist, twist_dot, signs, level, singular, q, v, a, buf,
               info):
    """:func:`leg_state` then :func:`write_tree`: the closed-form tree state."""
    status = leg_state(geo, pose, twist, twist_dot, signs, level, singular, buf, info)
    if status == OK:
        write_tree(geo, idx, pose, twist, twist_dot, level, buf, q, v, a)
    return status


@jit
def jacobian_derivative(geo, buf, twist, out):
    """``dJ/dt`` (3, 3) along a twist (after :func:`rates`): with ``n' = v + omega z x r
    - s' u``, ``r' = omega z x r`` and ``nu' = n' . u``, ``dJ_k/dt = (n', r' x n + r x n')
    / nu - J_k nu' / nu``."""
    vx, vy, omega = twist[0], twist[1], twist[2]
    for k in range(N_ACTUATORS):
        leg = buf[k]
        ux, uy = geo[7 * k + 2], geo[7 * k + 3]
        nx, ny, rx, ry, nu = leg[NX], leg[NY], leg[RX], leg[RY], leg[NU]
        dnx = vx - omega * ry - leg[SD] * ux
        dny = vy + omega * rx - leg[SD] * uy
        dnu = (dnx * ux + dny * uy) / nu
        dmom = -omega * (rx * nx + ry * ny) + rx * dny - ry * dnx
        out[k, 0] = dnx / nu - leg[J0] * dnu
        out[k, 1] = dny / nu - leg[J1] * dnu
        out[k, 2] = dmom / nu - leg[J2] * dnu


@jit
def singularity_parts(geo, buf, cosines, a_hat):
    """``|cos|`` between each link and its rail (``|nu| / L``) and the dimensionless
    closure matrix rows ``(n / L, (r x n) / (L r_p))`` (characteristic length: the
    platform radius ``r_p``), for :func:`hexapod_pin.core.measures.singularity_measures`."""
    length, radius = geo[G_LEN], geo[G_RP]
    for k in range(N_ACTUATORS):
        leg = buf[k]
        cosines[k] = abs(leg[NU]) / length
        a_hat[k, 0], a_hat[k, 1] = leg[NX] / length, leg[NY] / length
        a_hat[k, 2] = (leg[RX] * leg[NY] - leg[RY] * leg[NX]) / (length * radius)


# ---------------------------------------------------------------------------------------
# dynamics
# ---------------------------------------------------------------------------------------
@jit
def tree_forces(geo, buf, pd, sdd, pdd, twist_dot, gravity, out):
    """Newton-Euler ``M a + h`` of the tree (Pinocchio's ``rnea``), local order (9,).

    ``pd``, ``sdd``, ``pdd`` (3,) the link rates and the slider and link accelerations,
    ``twist_dot`` the platform's, ``gravity`` 1.0 (with gravity) or 0.0 (without).
    """
    g = geo[G_G] * gravity
    length = geo[G_LEN]
    m_s, m_l = geo[G_MS], geo[G_ML]
    i_l = m_l * length * length / 12.0
    for k in range(N_ACTUATORS):
        leg = buf[k]
        ux, uy, nx, ny = geo[7 * k + 2], geo[7 * k + 3], leg[NX], leg[NY]
        phid2 = pd[k] * pd[k]
        ax = sdd[k] * ux - 0.5 * (pdd[k] * ny + phid2 * nx)
        ay = sdd[k] * uy + 0.5 * (pdd[k] * nx - phid2 * ny) + g
        out[k] = m_s * (sdd[k] + g * uy) + m_l * (ax * ux + ay * uy)
        out[3 + k] = i_l * pdd[k] + 0.5 * m_l * (nx * ay - ny * ax)
    m_p = geo[G_MP]
    out[6] = m_p * twist_dot[0]
    out[7] = m_p * (twist_dot[1] + g)
    out[8] = geo[G_IP] * twist_dot[2]


@jit
def motion_forces(geo, buf, twist_dot, gravity, out):
    """:func:`tree_forces` of the motion held in the leg buffer."""
    tree_forces(geo, buf, buf[:, PD], buf[:, SDD], buf[:, PDD], twist_dot, gravity, out)


@jit
def project(geo, buf, force, out):
    """``G^T f`` (3,): the platform wrench equivalent, by virtual power, to the tree
    generalised force ``f`` (local order)."""
    out[0], out[1], out[2] = force[6], force[7], force[8]
    for k in range(N_ACTUATORS):
        leg = buf[k]
        l0, l1, l2 = link_row(geo, buf, k)
        out[0] += leg[J0] * force[k] + l0 * force[3 + k]
        out[1] += leg[J1] * force[k] + l1 * force[3 + k]
        out[2] += leg[J2] * force[k] + l2 * force[3 + k]


@jit
def solve3(m00, m01, m02, m10, m11, m12, m20, m21, m22, f0, f1, f2, out):
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


@jit
def type_two_sigma(geo, buf):
    """The type-II test's value for the legs in ``buf``: ``sigma_min(A_hat)``, ``A_hat`` rows
    ``[e_k, (r_k x e_k) / R]`` (:func:`hexapod_pin.core.measures.closure_matrix_hat`, ``R``
    the platform radius). The lower bound ``|det| / (|A_hat|_F^2 / 2) <= sigma_min`` is
    returned when it clears :data:`TYPE_II_TOL` (the state is then certainly regular);
    below it, the exact ``sigma_min`` from the SVD."""
    inv_len, inv_rad = 1.0 / geo[G_LEN], 1.0 / geo[G_RP]
    a = np.empty((N_ACTUATORS, 3))
    for k in range(N_ACTUATORS):
        leg = buf[k]
        a[k, 0], a[k, 1] = leg[NX] * inv_len, leg[NY] * inv_len
        a[k, 2] = (leg[RX] * leg[NY] - leg[RY] * leg[NX]) * inv_len * inv_rad
    det = (a[0, 0] * (a[1, 1] * a[2, 2] - a[1, 2] * a[2, 1])
           - a[0, 1] * (a[1, 0] * a[2, 2] - a[1, 2] * a[2, 0])
           + a[0, 2] * (a[1, 0] * a[2, 1] - a[1, 1] * a[2, 0]))
    frob2 = 0.0
    for k in range(N_ACTUATORS):
        for c in range(3):
            frob2 += a[k, c] * a[k, c]
    if frob2 > 0.0 and abs(det) / (0.5 * frob2) >= geo[G_TOL2]:
        return abs(det) / (0.5 * frob2)
    return np.linalg.svd(a)[1][-1]


@jit
def solve_inverse(geo, buf, force, wrench, has_wrench, tau, closure, info):
    """Actuator forces ``tau`` (3,) and closure forces (3, 2) from the tree rows
    ``f = S^T tau + J_c^T lambda + tau_ext`` (module docstring; ``closure = -lambda``).

    Returns OK, NONFINITE (the wrench), TYPE_II (``sigma_min(A_hat)`` below
    :data:`~hexapod_pin.core.measures.TYPE_II_TOL`, in ``info[X_TYPE_TWO]``: the one
    type-II test of every robot) or RESIDUAL (a row misses by more
    than RESIDUAL_RTOL relative; the max-abs residual in ``info[X_RES]``).
    """
    if has_wrench and not all_finite(wrench):
        return NONFINITE
    fx, fy, fth = force[6], force[7], force[8]
    if has_wrench:
        fx, fy, fth = fx - wrench[0], fy - wrench[1], fth - wrench[2]
    length2 = geo[G_LEN] * geo[G_LEN]
    px, py, pth = -fx, -fy, -fth            # right-hand side of the 3x3 in mu
    for k in range(N_ACTUATORS):
        leg = buf[k]
        c = force[3 + k] / length2
        px, py = px + c * leg[NY], py - c * leg[NX]
        pth -= c * (leg[RX] * leg[NX] + leg[RY] * leg[NY])
    l0, l1, l2 = buf[0], buf[1], buf[2]
    mu = np.empty(3)
    hadamard = solve3(l0[NX], l1[NX], l2[NX], l0[NY], l1[NY], l2[NY],
                      l0[RX] * l0[NY] - l0[RY] * l0[NX],
                      l1[RX] * l1[NY] - l1[RY] * l1[NX],
                      l2[RX] * l2[NY] - l2[RY] * l2[NX], px, py, pth, mu)
    sigma = type_two_sigma(geo, buf) if hadamard > 0.0 else 0.0
    info[X_TYPE_TWO] = sigma
    if not sigma >= geo[G_TOL2]:
        return TYPE_II
    res, sum_x, sum_y, sum_m = 0.0, 0.0, 0.0, 0.0
    scale = max(1.0, abs(fx), abs(fy), abs(fth))
    for k in range(N_ACTUATORS):
        leg = buf[k]
        nx, ny = leg[NX], leg[NY]
        c = force[3 + k] / length2
        lx, ly = mu[k] * nx - c * ny, mu[k] * ny + c * nx
        ux, uy = geo[7 * k + 2], geo[7 * k + 3]
        fs, fl = force[k], force[3 + k]
        tau[k] = fs - (ux * lx + uy * ly)
        closure[k, 0], closure[k, 1] = -lx, -ly
        res = max(res, abs(tau[k] + ux * lx + uy * ly - fs), abs(nx * ly - ny * lx - fl))
        scale = max(scale, abs(fs), abs(fl))
        sum_x, sum_y = sum_x + lx, sum_y + ly
        sum_m += leg[RX] * ly - leg[RY] * lx
    res = max(res, abs(sum_x + fx), abs(sum_y + fy), abs(sum_m + fth))
    info[X_RES] = res
    if not (res <= RESIDUAL_RTOL * scale and all_finite(tau)):
        return RESIDUAL
    return OK


@jit
def reduced(geo, buf, m_x, h_x):
    """``M_x = G^T M G`` (3, 3) and ``h_x = G^T (M a_0 + h)`` (3,) of the motion in the leg
    buffer (its accelerations must be ``a_0``, those of ``twist_dot = 0``)."""
    force = np.empty(9)
    col = np.empty(3)
    zero3 = np.zeros(3)
    motion_forces(geo, buf, zero3, 1.0, force)
    project(geo, buf, force, h_x)
    sdd, pdd, unit = np.empty(3), np.empty(3), np.zeros(3)
    for j in range(3):
        unit[:] = 0.0
        unit[j] = 1.0
        for k in range(N_ACTUATORS):
            sdd[k] = buf[k, J0 + j]
            pdd[k] = link_row(geo, buf, k)[j]
        tree_forces(geo, buf, zero3, sdd, pdd, unit, 0.0, force)
        project(geo, buf, force, col)
        for i in range(3):
            m_x[i, j] = col[i]
    for i in range(3):                    # symmetric by construction: remove round-off
        for j in range(i + 1, 3):
            m = 0.5 * (m_x[i, j] + m_x[j, i])
            m_x[i, j], m_x[j, i] = m, m
    if geo[DRIVES + drv.FLAG] != 0.0:
        drv.add_reduced(geo, DRIVES, N_ACTUATORS, 3, jacobian_t(buf), buf[:, S], buf[:, SD],
                        buf[:, SDD], m_x, h_x)


@jit
def jacobian_t(buf):
    """``J^T`` (3, N_ACTUATORS) of the legs in the buffer."""
    out = np.empty((3, N_ACTUATORS))
    for k in range(N_ACTUATORS):
        for j in range(3):
            out[j, k] = buf[k, J0 + j]
    return out


@jit
def forward(geo, buf, twist, forces, wrench, has_wrench, twist_dot, closure, info):
    """Forward dynamics by the null-space method (module docstring); the leg buffer holds
    ``a_0`` on entry and the solved accelerations on return.

    Returns OK, NONFINITE (forces or wrench) or RESIDUAL (``M_x`` not positive definite,
    or a platform row or a closure at acceleration level missed by more than
    RESIDUAL_RTOL relative; the closure miss in ``info[X_RES]``).
    """
    if not all_finite(forces) or (has_wrench and not all_finite(wrench)):
        return NONFINITE
    m_x, h_x = np.empty((3, 3)), np.empty(3)
    reduced(geo, buf, m_x, h_x)
    rhs = np.empty(3)
    for j in range(3):
        rhs[j] = -h_x[j] + (wrench[j] if has_wrench else 0.0)
        for k in range(N_ACTUATORS):
            rhs[j] += buf[k, J0 + j] * forces[k]
    if not (m_x[0, 0] > 0.0 and m_x[1, 1] > 0.0 and m_x[2, 2] > 0.0):
        return RESIDUAL
    drives = geo[DRIVES + drv.FLAG] != 0.0
    if drives and drv.any_at_rest(geo, DRIVES, N_ACTUATORS, buf[:, SD], buf[:, FR]):
        if drv.stick_slip(geo, DRIVES, N_ACTUATORS, 3, m_x, jacobian_t(buf), buf[:, SD],
                          buf[:, SDD], rhs, twist_dot, buf[:, FR], np.empty((4, 3, 3)),
                          np.empty((8, 3))) != OK:
            return RESIDUAL
    elif solve3(m_x[0, 0], m_x[0, 1], m_x[0, 2], m_x[1, 0], m_x[1, 1], m_x[1, 2],
                m_x[2, 0], m_x[2, 1], m_x[2, 2], rhs[0], rhs[1], rhs[2], twist_dot) == 0.0:
        return RESIDUAL
    ax, ay, alpha = twist_dot[0], twist_dot[1], twist_dot[2]
    for k in range(N_ACTUATORS):
        leg = buf[k]
        l0, l1, l2 = link_row(geo, buf, k)
        leg[SDD] += leg[J0] * ax + leg[J1] * ay + leg[J2] * alpha
        leg[PDD] += l0 * ax + l1 * ay + l2 * alpha
    force = np.empty(9)
    motion_forces(geo, buf, twist_dot, 1.0, force)
    omega2 = twist[2] * twist[2]
    cres, sum_x, sum_y, sum_m, scale = 0.0, 0.0, 0.0, 0.0, 1.0
    acc_scale = max(1.0, abs(ax), abs(ay), abs(alpha))
    for k in range(N_ACTUATORS):
        leg = buf[k]
        nx, ny, rx, ry, nu = leg[NX], leg[NY], leg[RX], leg[RY], leg[NU]
        ux, uy = geo[7 * k + 2], geo[7 * k + 3]
        fs, fl = force[k] - forces[k], force[3 + k]
        if drives:                    # the slider's drive: a s'' - drive force - friction
            fs += (geo[DRIVES + drv.HEAD + drv.BLOCK * k + drv.ARM] * leg[SDD]
                   - drv.drive_force(geo, DRIVES, k, leg[S], leg[SD]) - leg[FR])
        lx, ly = (fs * nx - uy * fl) / nu, (ux * fl + ny * fs) / nu
        closure[k, 0], closure[k, 1] = -lx, -ly
        sum_x, sum_y, sum_m = sum_x + lx, sum_y + ly, sum_m + rx * ly - ry * lx
        scale = max(scale, abs(force[k]), abs(fl), abs(forces[k]), abs(lx), abs(ly),
                    abs(rx * ly), abs(ry * lx))
        # the loop's in-plane closure rows at acceleration level, J_c a + gamma
        phid2 = leg[PD] * leg[PD]
        sdd, pdd = leg[SDD], leg[PDD]
        # relative to the terms' magnitudes (round-off of their sum)
        acc_scale = max(acc_scale, abs(sdd), abs(pdd) * geo[G_LEN], phid2 * geo[G_LEN],
                        omega2 * geo[G_RP], abs(alpha) * geo[G_RP])
        cres = max(cres,
                   abs(ux * sdd - ny * pdd - (ax - alpha * ry) - phid2 * nx + omega2 * rx),
                   abs(uy * sdd + nx * pdd - (ay + alpha * rx) - phid2 * ny + omega2 * ry))
    fx, fy, fth = force[6], force[7], force[8]
    if has_wrench:
        fx, fy, fth = fx - wrench[0], fy - wrench[1], fth - wrench[2]
    scale = max(scale, abs(fx), abs(fy), abs(fth))
    worst = max(abs(sum_x + fx), abs(sum_y + fy), abs(sum_m + fth))
    info[X_RES] = cres
    if not (worst <= RESIDUAL_RTOL * scale and cres <= RESIDUAL_RTOL * acc_scale
            and all_finite(twist_dot)):
        return RESIDUAL
    return OK


# ---------------------------------------------------------------------------------------
# single states: one kernel call per route
# ---------------------------------------------------------------------------------------
@jit
def inverse_dynamics(geo, idx, pose, twist, twist_dot, wrench, has_wrench, signs, q, v, a,
                     tau, closure, buf, info):
    """Tree state, Newton-Euler and :func:`solve_inverse`: the closed-form inverse
    dynamics (statics with zero twist and twist_dot). Returns a status of
    :func:`leg_state` or :func:`solve_inverse`; ``q``, ``v``, ``a`` are written once the
    tree state is known."""
    status = tree_state(geo, idx, pose, twist, twist_dot, signs, 2, True, q, v, a, buf, info)
    if status != OK:
        return status
    force = np.empty(9)
    motion_forces(geo, buf, twist_dot, 1.0, force)
    status = solve_inverse(geo, buf, force, wrench, has_wrench, tau, closure, info)
    if status == OK and geo[DRIVES + drv.FLAG] != 0.0:
        for k in range(N_ACTUATORS):
            leg = buf[k]
            tau[k] += drv.inverse_load(geo, DRIVES, k, leg[S], leg[SD], leg[SDD])
    return status


@jit
def forward_dynamics(geo, idx, pose, twist, forces, wrench, has_wrench, signs, q, v, a,
                     twist_dot, closure, buf, info):
    """Tree state at ``twist_dot = 0`` and :func:`forward`; writes ``q``, ``v`` and, on
    success, the tree acceleration ``a``."""
    zero3 = np.zeros(3)
    status = tree_state(geo, idx, pose, twist, zero3, signs, 2, True, q, v, a, buf, info)
    if status != OK:
        return status
    status = forward(geo, buf, twist, forces, wrench, has_wrench, twist_dot, closure, info)
    if status == OK:
        write_tree(geo, idx, pose, twist, twist_dot, 2, buf, q, v, a)
    return status


@jit
def reduced_dynamics(geo, pose, twist, signs, m_x, h_x, jac, buf, info):
    """:func:`reduced` of a platform state, and its Jacobian ``jac`` (3, 3)."""
    zero3 = np.zeros(3)
    status = leg_state(geo, pose, twist, zero3, signs, 2, True, buf, info)
    if status != OK:
        return status
    reduced(geo, buf, m_x, h_x)
    for k in range(N_ACTUATORS):
        for j in range(3):
            jac[k, j] = buf[k, J0 + j]
    return OK


# ---------------------------------------------------------------------------------------
# batches: the same kernels over N states (chunks of CHUNK states, one scratch per chunk)
# ---------------------------------------------------------------------------------------
@prange_jit(2)
def inverse_kinematics_batch(geo, signs, poses, positions, reachable, regular, infos):
    """:func:`legs` of N poses: positions (N, 3), reachable and regular (no type I) flags,
    each state's ``info``."""
    n = poses.shape[0]
    for c in numba.prange(n_chunks(n)):
        buf = np.empty((N_ACTUATORS, LEG_COLS))
        for i in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            status = legs(geo, poses[i], signs, buf, infos[i])
            for k in range(N_ACTUATORS):
                positions[i, k] = buf[k, S]
            reachable[i] = status == OK
            regular[i] = status == OK and infos[i, X_WORST] >= geo[G_TOL]


@prange_jit(2)
def jacobian_batch(geo, signs, poses, jacobians, positions, reachable, regular, infos):
    """:func:`inverse_kinematics_batch` and the Jacobians (N, 3, 3); zero where a state is
    unreachable or type-I singular."""
    n = poses.shape[0]
    for c in numba.prange(n_chunks(n)):
        buf = np.empty((N_ACTUATORS, LEG_COLS))
        for i in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            status = legs(geo, poses[i], signs, buf, infos[i])
            ok = status == OK and infos[i, X_WORST] >= geo[G_TOL]
            for k in range(N_ACTUATORS):
                positions[i, k] = buf[k, S]
                for j in range(3):
                    jacobians[i, k, j] = buf[k, J0 + j] if ok else 0.0
            reachable[i] = status == OK
            regular[i] = ok


@prange_jit(3)
def inverse_dynamics_batch(geo, idx, signs, poses, twists, twist_dots, wrenches, has_wrench,
                           tau, closure, status, infos):
    """:func:`inverse_dynamics` of N states (statics: zero twists and twist_dots)."""
    n = poses.shape[0]
    for c in numba.prange(n_chunks(n)):
        buf = np.empty((N_ACTUATORS, LEG_COLS))
        q, v, a = np.empty(9), np.empty(9), np.empty(9)
        for i in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            status[i] = inverse_dynamics(geo, idx, poses[i], twists[i], twist_dots[i],
                                         wrenches[i], has_wrench, signs, q, v, a, tau[i],
                                         closure[i], buf, infos[i])


@prange_jit(3)
def forward_dynamics_batch(geo, idx, signs, poses, twists, forces, wrenches, has_wrench,
                           twist_dots, accelerations_out, closure, status, infos):
    """:func:`forward_dynamics` of N states; actuator accelerations (N, 3)."""
    n = poses.shape[0]
    for c in numba.prange(n_chunks(n)):
        buf = np.empty((N_ACTUATORS, LEG_COLS))
        q, v, a = np.empty(9), np.empty(9), np.empty(9)
        for i in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            status[i] = forward_dynamics(geo, idx, poses[i], twists[i], forces[i],
                                         wrenches[i], has_wrench, signs, q, v, a,
                                         twist_dots[i], closure[i], buf, infos[i])
            for k in range(N_ACTUATORS):
                accelerations_out[i, k] = buf[k, SDD]


@prange_jit(2)
def reduced_dynamics_batch(geo, signs, poses, twists, m_x, h_x, jac, status, infos):
    """:func:`reduced_dynamics` of N states."""
    n = poses.shape[0]
    for c in numba.prange(n_chunks(n)):
        buf = np.empty((N_ACTUATORS, LEG_COLS))
        for i in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            status[i] = reduced_dynamics(geo, poses[i], twists[i], signs, m_x[i], h_x[i],
                                         jac[i], buf, infos[i])
