"""Forward kinematics of the rail-driven hexapod: the three-circle formulation.

With the six carriages held, the two legs of rail k are two spheres of radius
``L = leg_length`` centred at the carriages ``c_2k`` and ``c_2k+1`` on the rail
line. Their intersection, where the platform point ``P_k`` must lie, is a circle

    ``P_k(theta_k) = M_k + rho_k (cos theta_k b1_k + sin theta_k b2_k)``

in the plane perpendicular to the rail through the carriages' midpoint
``M_k = m_k + (q_2k + q_2k+1)/2 u_k``, of radius ``rho_k = sqrt(L^2 - h_k^2)``,
``h_k = (q_2k+1 - q_2k)/2``. The in-plane axes are fixed per rail:
``b2_k`` is world z made perpendicular to the rail (world z for horizontal
rails) and ``b1_k = b2_k x u_k`` (horizontal, pointing from the rail towards the
world z axis). On these circles both leg-length equations of rail k hold
identically, so the 18 closure equations reduce to the three triangle equations

    ``E_jk = |P_j(theta_j) - P_k(theta_k)|^2 - s_jk^2 = 0``,  (j, k) in (0,1), (1,2), (2,0),

``s_jk = |p_j - p_k|`` the sides of the platform triangle. Each ``E_jk`` is
bilinear in ``x_j = (cos theta_j, sin theta_j)`` and ``x_k``::

    E_jk = K + a . x_j + b . x_k + x_j^T Q x_k.

A solution ``theta`` gives three points congruent to the platform triangle, and
exactly one pose maps ``p_k`` to ``P_k`` (:func:`pose_from_points`). This module
holds the Newton solver on ``theta`` used by ``forward_kinematics`` and the
complete enumeration used by ``assembly_modes`` (see :func:`enumerate_assemblies`).

An as-built robot (per-chain lines, lengths and platform joints,
:class:`~hexapod_pin.hexapod.geometry.ChainGeometry`) has no such reduction: the two
legs of a rail need not meet at one point. Its forward kinematics is Newton's method on
the six closure equations (:func:`forward_as_built`) and its assembly modes are those of
its ideal drawing followed to the as-built geometry by continuation
(:func:`modes_as_built`).

All lengths are in metres, angles in radians, world axes throughout.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from ..core.pose import rotation_rpy, rpy_of
from ..errors import AssemblyError
from .geometry import (ChainGeometry, HexapodGeometry, closure_pose, continue_pose,
                       leg_residuals)

#: the three triangle equations, as (j, k) pairs of rails
PAIRS = ((0, 1), (1, 2), (2, 0))
#: Newton stops when the triangle-side errors are below this (m)
INNER_TOL = 1e-14
#: accepted leg-length error of a returned pose (m)
POSE_TOL = 1e-12
#: circle radius / leg length below which a rail's circle is degenerate
DEGENERATE_RADIUS = 1e-9
#: number of theta_0 samples of the resultant (>= 17; the surplus checks aliasing)
N_SAMPLES = 32
#: eliminant coefficients below this fraction of the Hadamard bound of its Sylvester
#: matrices count as an identically vanishing eliminant (random configurations: >= 2e-5)
DEGENERATE_ELIMINANT = 1e-12
#: a back-substituted candidate is polished when its side errors are below this
#: fraction of the longest platform side (roots of multiplicity m are only
#: accurate to about eps^(1/m), so candidates are first only roughly right)
CANDIDATE_TOL = 1e-2


@dataclass(frozen=True)
class CircleGeometry:
    """Per-geometry constants of the three-circle formulation (world axes, m).

    Attributes:
        mids: rail midpoints ``m_k``, shape (3, 3).
        dirs: rail unit directions ``u_k``, shape (3, 3).
        axis1: the first in-plane unit axis ``b1_k`` of each rail's circle, (3, 3).
        axis2: the second in-plane unit axis ``b2_k`` of each rail's circle, (3, 3).
        leg_length: ``L`` (m).
        sides: ``s_jk`` for the pairs of :data:`PAIRS`, shape (3,).
        platform_points: ``p_k`` in the platform frame, shape (3, 3).
        platform_frame: orthonormal frame of the platform triangle in platform
            axes (columns), shape (3, 3); see :func:`pose_from_points`.
        platform_centroid: mean of ``p_k`` in the platform frame, shape (3,).
    """

    mids: np.ndarray
    dirs: np.ndarray
    axis1: np.ndarray
    axis2: np.ndarray
    leg_length: float
    sides: np.ndarray
    platform_points: np.ndarray
    platform_frame: np.ndarray
    platform_centroid: np.ndarray

    mids_t: tuple = field(init=False, repr=False, compare=False)
    dirs_t: tuple = field(init=False, repr=False, compare=False)
    axis1_t: tuple = field(init=False, repr=False, compare=False)
    axis2_t: tuple = field(init=False, repr=False, compare=False)
    sides_t: tuple = field(init=False, repr=False, compare=False)
    gram_t: tuple = field(init=False, repr=False, compare=False)
    points_t: tuple = field(init=False, repr=False, compare=False)
    frame_t: tuple = field(init=False, repr=False, compare=False)
    centroid_t: tuple = field(init=False, repr=False, compare=False)
    half_inverse_sides_t: tuple = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        # plain-float copies for the scalar hot paths
        tup = lambda arr: tuple(tuple(float(v) for v in row) for row in arr)
        gram = tuple((float(self.axis1[j] @ self.axis1[k]), float(self.axis1[j] @ self.axis2[k]),
                      float(self.axis2[j] @ self.axis1[k]), float(self.axis2[j] @ self.axis2[k]))
                     for j, k in PAIRS)
        for name, value in (("mids_t", tup(self.mids)), ("dirs_t", tup(self.dirs)),
                            ("axis1_t", tup(self.axis1)), ("axis2_t", tup(self.axis2)),
                            ("sides_t", tuple(float(v) for v in self.sides)), ("gram_t", gram),
                            ("half_inverse_sides_t", tuple(0.5 / float(v) for v in self.sides)),
                            ("points_t", tup(self.platform_points)),
                            ("frame_t", tup(self.platform_frame)),
                            ("centroid_t", tuple(float(v) for v in self.platform_centroid))):
            object.__setattr__(self, name, value)

    @classmethod
    def from_geometry(cls, geometry: HexapodGeometry) -> CircleGeometry:
        """Build the constants of a :class:`HexapodGeometry`."""
        dirs = geometry.rail_directions
        up = np.array([0.0, 0.0, 1.0])
        axis2 = up - (dirs @ up)[:, None] * dirs
        axis2 /= np.linalg.norm(axis2, axis=1)[:, None]
        axis1 = np.cross(axis2, dirs)
        pts = geometry.platform_points
        sides = np.array([np.linalg.norm(pts[j] - pts[k]) for j, k in PAIRS])
        return cls(geometry.rail_midpoints, dirs, axis1, axis2, float(geometry.leg_length),
                   sides, pts, triangle_frame(pts), pts.mean(axis=0))


class CircleSystem(NamedTuple):
    """The three circles and triangle equations for one set of carriage positions.

    (An immutable named tuple rather than a dataclass: it is built on every
    forward-kinematics call.)

    Attributes:
        centres_t: ``M_k`` as three 3-tuples (m).
        radii_t: ``rho_k`` as three floats (m).
        circle_geometry: the per-geometry constants (axes ``b1_k``, ``b2_k``, sides).
        coeffs: per pair of :data:`PAIRS` the nine floats
            ``(K, a0, a1, b0, b1, Q00, Q01, Q10, Q11)`` of
            ``E_jk = K + a . x_j + b . x_k + x_j^T Q x_k`` (m^2).
    """

    centres_t: tuple
    radii_t: tuple
    circle_geometry: CircleGeometry
    coeffs: tuple

    @property
    def centres(self) -> np.ndarray:
        """``M_k`` (3, 3) (m)."""
        return np.array(self.centres_t)

    @property
    def radii(self) -> np.ndarray:
        """``rho_k`` (3,) (m)."""
        return np.array(self.radii_t)

    @property
    def sides(self) -> np.ndarray:
        """Platform triangle sides ``s_jk`` (3,) (m), in the order of :data:`PAIRS`."""
        return self.circle_geometry.sides

    def coefficient_arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``K`` (3,), ``a`` (3, 2), ``b`` (3, 2), ``Q`` (3, 2, 2) as numpy arrays."""
        c = np.array(self.coeffs)
        return c[:, 0], c[:, 1:3], c[:, 3:5], c[:, 5:].reshape(3, 2, 2)

    def points(self, theta: Sequence[float]) -> np.ndarray:
        """Platform points ``P_k(theta_k)`` (3, 3) (m) for angles ``theta`` (3,) (rad)."""
        return np.array(self.points_t(*(float(t) for t in theta)))

    def points_t(self, t0: float, t1: float, t2: float) -> list[tuple[float, float, float]]:
        """:meth:`points` in plain floats: three 3-tuples."""
        cg = self.circle_geometry
        out = []
        for (cx, cy, cz), rho, b1, b2, t in zip(self.centres_t, self.radii_t, cg.axis1_t,
                                                cg.axis2_t, (t0, t1, t2)):
            c, s = rho * math.cos(t), rho * math.sin(t)
            out.append((cx + c * b1[0] + s * b2[0], cy + c * b1[1] + s * b2[1],
                        cz + c * b1[2] + s * b2[2]))
        return out

    def angles_of(self, points: npt.ArrayLike) -> np.ndarray:
        """Circle angles (3,) of the points nearest to ``points`` (3, 3) on each circle."""
        return np.array(self.angles_of_t(np.asarray(points, dtype=float).tolist()))

    def angles_of_t(self, points: Sequence[Sequence[float]]) -> list[float]:
        """:meth:`angles_of` in plain floats (a list of three angles)."""
        cg = self.circle_geometry
        out = []
        for (px, py, pz), (cx, cy, cz), b1, b2 in zip(points, self.centres_t, cg.axis1_t,
                                                      cg.axis2_t):
            dx, dy, dz = px - cx, py - cy, pz - cz
            out.append(math.atan2(dx * b2[0] + dy * b2[1] + dz * b2[2],
                                  dx * b1[0] + dy * b1[1] + dz * b1[2]))
        return out

    def residual(self, theta: Sequence[float]) -> np.ndarray:
        """The three triangle equations ``E_jk`` (m^2) at ``theta`` (3,)."""
        return np.array(_residual_and_jacobian(self.coeffs, *(float(t) for t in theta))[0])


def triangle_frame(points: np.ndarray) -> np.ndarray:
    """Orthonormal frame (columns e1, e2, e3) of a triangle ``points`` (3, 3).

    ``e1`` along ``p1 - p0``, ``e3`` along ``(p1 - p0) x (p2 - p0)``, ``e2 = e3 x e1``.
    """
    e1 = points[1] - points[0]
    e3 = np.cross(e1, points[2] - points[0])
    e1 = e1 / np.linalg.norm(e1)
    e3 = e3 / np.linalg.norm(e3)
    return np.stack([e1, np.cross(e3, e1), e3], axis=1)


def circle_system(cg: CircleGeometry, q: Sequence[float] | np.ndarray) -> CircleSystem | None:
    """The circles of the platform points for carriage positions ``q`` (6,) (m).

    Plain-float arithmetic (this is on the forward-kinematics hot path).

    Returns:
        the :class:`CircleSystem`, or ``None`` when the two carriages of some rail
        are farther apart than ``2 L`` (no assembly exists).

    Raises:
        AssemblyError: degenerate rails: two carriages of a rail coincide (the
            legs' spheres coincide, the platform point may move on a sphere) or
            stand exactly ``2 L`` apart (the circle shrinks to a point and its
            angle is undefined).
    """
    L = cg.leg_length
    q0, q1, q2, q3, q4, q5 = q.tolist() if isinstance(q, np.ndarray) else map(float, q)
    halves = (0.5 * (q1 - q0), 0.5 * (q3 - q2), 0.5 * (q5 - q4))
    means = (0.5 * (q0 + q1), 0.5 * (q2 + q3), 0.5 * (q4 + q5))
    small = DEGENERATE_RADIUS * L
    radii = []
    for k in range(3):
        rho2 = L * L - halves[k] * halves[k]
        if rho2 < 0.0:
            return None
        if not abs(halves[k]) > small:
            raise AssemblyError(f"degenerate: carriages {2 * k} and {2 * k + 1} coincide "
                                f"(q = {means[k]:.6g}); platform point {k} may move on a sphere",
                                0.0, 0)
        if not rho2 > small * small:
            raise AssemblyError(f"degenerate: the legs of rail {k} are stretched along the rail "
                                f"(|q_{2 * k + 1} - q_{2 * k}| = 2 leg_length)", 0.0, 0)
        radii.append(math.sqrt(rho2))
    (m0x, m0y, m0z), (m1x, m1y, m1z), (m2x, m2y, m2z) = cg.mids_t
    (u0x, u0y, u0z), (u1x, u1y, u1z), (u2x, u2y, u2z) = cg.dirs_t
    a, b, c = means
    centres = ((m0x + a * u0x, m0y + a * u0y, m0z + a * u0z),
               (m1x + b * u1x, m1y + b * u1y, m1z + b * u1z),
               (m2x + c * u2x, m2y + c * u2y, m2z + c * u2z))
    a1, a2 = cg.axis1_t, cg.axis2_t
    coeffs = []
    for (j, k), side, (g00, g01, g10, g11) in zip(PAIRS, cg.sides_t, cg.gram_t):
        (xj, yj, zj), (xk, yk, zk) = centres[j], centres[k]
        dx, dy, dz = xj - xk, yj - yk, zj - zk
        rj, rk = radii[j], radii[k]
        w = -2.0 * rj * rk
        (p0, p1, p2), (p3, p4, p5) = a1[j], a2[j]
        (p6, p7, p8), (p9, p10, p11) = a1[k], a2[k]
        coeffs.append((dx * dx + dy * dy + dz * dz + rj * rj + rk * rk - side * side,
                       2.0 * rj * (dx * p0 + dy * p1 + dz * p2),
                       2.0 * rj * (dx * p3 + dy * p4 + dz * p5),
                       -2.0 * rk * (dx * p6 + dy * p7 + dz * p8),
                       -2.0 * rk * (dx * p9 + dy * p10 + dz * p11),
                       w * g00, w * g01, w * g10, w * g11))
    return CircleSystem(centres, tuple(radii), cg, tuple(coeffs))


def _residual_and_jacobian(coeffs, t0: float, t1: float, t2: float):
    """Triangle equations and their Jacobian in plain floats (the Newton hot path).

    Returns ``(E_01, E_12, E_20)`` and the six non-zero Jacobian entries
    ``(A0, B0, A1, B1, A2, B2)``: row p of the 3x3 Jacobian has ``A_p`` in the
    column of its first rail j and ``B_p`` in that of its second rail k
    (pairs (0,1), (1,2), (2,0): a cyclic pattern).
    """
    c0, c1, c2 = math.cos(t0), math.cos(t1), math.cos(t2)
    s0, s1, s2 = math.sin(t0), math.sin(t1), math.sin(t2)
    (K0, a00, a01, b00, b01, q000, q001, q010, q011), \
        (K1, a10, a11, b10, b11, q100, q101, q110, q111), \
        (K2, a20, a21, b20, b21, q200, q201, q210, q211) = coeffs
    # pair (0, 1): x_j = x0, x_k = x1
    g0 = a00 + q000 * c1 + q001 * s1
    g1 = a01 + q010 * c1 + q011 * s1
    e01 = K0 + g0 * c0 + g1 * s0 + b00 * c1 + b01 * s1
    A0 = g1 * c0 - g0 * s0
    B0 = (b01 + q001 * c0 + q011 * s0) * c1 - (b00 + q000 * c0 + q010 * s0) * s1
    # pair (1, 2)
    g0 = a10 + q100 * c2 + q101 * s2
    g1 = a11 + q110 * c2 + q111 * s2
    e12 = K1 + g0 * c1 + g1 * s1 + b10 * c2 + b11 * s2
    A1 = g1 * c1 - g0 * s1
    B1 = (b11 + q101 * c1 + q111 * s1) * c2 - (b10 + q100 * c1 + q110 * s1) * s2
    # pair (2, 0)
    g0 = a20 + q200 * c0 + q201 * s0
    g1 = a21 + q210 * c0 + q211 * s0
    e20 = K2 + g0 * c2 + g1 * s2 + b20 * c0 + b21 * s0
    A2 = g1 * c2 - g0 * s2
    B2 = (b21 + q201 * c2 + q211 * s2) * c0 - (b20 + q200 * c2 + q210 * s2) * s0
    return (e01, e12, e20), (A0, B0, A1, B1, A2, B2)


def _newton_step(res, jac):
    """Solve the cyclic 3x3 system ``J x = res``; ``None`` when (numerically) singular."""
    r0, r1, r2 = res
    A0, B0, A1, B1, A2, B2 = jac
    det = A0 * A1 * A2 + B0 * B1 * B2
    scale = math.sqrt((A0 * A0 + B0 * B0) * (A1 * A1 + B1 * B1) * (A2 * A2 + B2 * B2))
    if not abs(det) > 1e-13 * scale:
        return None
    return ((r0 * A1 * A2 - B0 * r1 * A2 + B0 * B1 * r2) / det,
            (A0 * r1 * A2 - A0 * B1 * r2 + r0 * B1 * B2) / det,
            (A0 * A1 * r2 + B0 * r1 * B2 - r0 * A1 * B2) / det)


@dataclass(frozen=True)
class CircleNewtonResult:
    """Outcome of :func:`newton_circles`.

    Attributes:
        theta: circle angles, three floats (rad).
        side_error: max over the three sides of ``|E_jk| / (2 s_jk)`` (m), the
            first-order error of the side lengths.
        iterations: Newton steps taken.
    """

    theta: tuple
    side_error: float
    iterations: int


def newton_circles(system: CircleSystem, theta0: Sequence[float], max_iter: int = 50,
                   tol: float = INNER_TOL) -> CircleNewtonResult:
    """Newton's method on the three triangle equations, from ``theta0`` (3 floats).

    Full Newton steps (quadratic convergence), halved while they do not reduce
    the largest side error.

    Raises:
        AssemblyError: a singular 3x3 Jacobian (type-II singularity) or no
            convergence to ``tol`` in ``max_iter`` steps. The last iterate is
            never returned as a solution.
    """
    coeffs = system.coeffs
    w0, w1, w2 = system.circle_geometry.half_inverse_sides_t
    t0, t1, t2 = theta0
    res, jac = _residual_and_jacobian(coeffs, t0, t1, t2)
    err = max(abs(res[0]) * w0, abs(res[1]) * w1, abs(res[2]) * w2)
    for iteration in range(max_iter + 1):
        if err <= tol:
            return CircleNewtonResult((t0, t1, t2), err, iteration)
        if iteration == max_iter:
            break
        step = _newton_step(res, jac)
        if step is None:
            raise AssemblyError("singular closure Jacobian (type-II singularity)", err, iteration)
        d0, d1, d2 = step
        alpha = 1.0
        for _ in range(12):
            n0, n1, n2 = t0 - alpha * d0, t1 - alpha * d1, t2 - alpha * d2
            t_res, t_jac = _residual_and_jacobian(coeffs, n0, n1, n2)
            t_err = max(abs(t_res[0]) * w0, abs(t_res[1]) * w1, abs(t_res[2]) * w2)
            if t_err < err or t_err <= tol:
                break
            alpha *= 0.5
        else:
            raise AssemblyError("no Newton step reduces the closure residual", err, iteration)
        t0, t1, t2, res, jac, err = n0, n1, n2, t_res, t_jac, t_err
    raise AssemblyError(f"no convergence to {tol:g} m in {max_iter} iterations", err, max_iter)


def pose_from_points(cg: CircleGeometry,
                     points: np.ndarray) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Platform position ``t`` (3,) and rotation ``R`` (3, 3) mapping ``p_k`` to ``points``.

    ``R = F_world F_platform^T`` with the triangle frames of :func:`triangle_frame`,
    ``t = mean(P) - R mean(p)``. Exact when the world triangle is congruent to
    the platform triangle (a proper rotation always exists: the frames are
    right-handed by construction).
    """
    rot = triangle_frame(points) @ cg.platform_frame.T
    return points.mean(axis=0) - rot @ cg.platform_centroid, rot


def pose_from_points_t(cg: CircleGeometry, points: Sequence[Sequence[float]]) -> list[float]:
    """:func:`pose_from_points` in plain floats, returning the pose (6 floats, m and rad).

    The rotation is converted with the same formulas as
    :func:`hexapod_pin.core.pose.rpy_from_rotation` (pitch in [-pi/2, pi/2]).
    """
    (x0, y0, z0), (x1, y1, z1), (x2, y2, z2) = points
    ax, ay, az = x1 - x0, y1 - y0, z1 - z0
    bx, by, bz = x2 - x0, y2 - y0, z2 - z0
    nx, ny, nz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    inv_a = 1.0 / math.sqrt(ax * ax + ay * ay + az * az)
    inv_n = 1.0 / math.sqrt(nx * nx + ny * ny + nz * nz)
    ax, ay, az = ax * inv_a, ay * inv_a, az * inv_a
    nx, ny, nz = nx * inv_n, ny * inv_n, nz * inv_n
    world = ((ax, ny * az - nz * ay, nx),            # rows of [e1, n x e1, n]
             (ay, nz * ax - nx * az, ny),
             (az, nx * ay - ny * ax, nz))
    fp = cg.frame_t
    rot = [[w[0] * f[0] + w[1] * f[1] + w[2] * f[2] for f in fp] for w in world]
    cx, cy, cz = cg.centroid_t
    mean = ((x0 + x1 + x2) / 3.0, (y0 + y1 + y2) / 3.0, (z0 + z1 + z2) / 3.0)
    t = [mean[i] - (rot[i][0] * cx + rot[i][1] * cy + rot[i][2] * cz) for i in range(3)]
    return t + list(rpy_of(np.array(rot).reshape(9)))


def platform_points_t(cg: CircleGeometry,
                      pose: Sequence[float]) -> list[tuple[float, float, float]]:
    """World platform points ``t + R p_k`` (three 3-tuples) of a pose (6 floats)."""
    x, y, z, roll, pitch, yaw = pose
    buf = np.empty(9)
    rotation_rpy(roll, pitch, yaw, buf)
    r = buf.tolist()
    return [(x + r[0] * px + r[1] * py + r[2] * pz,
             y + r[3] * px + r[4] * py + r[5] * pz,
             z + r[6] * px + r[7] * py + r[8] * pz) for px, py, pz in cg.points_t]


def leg_length_error(cg: CircleGeometry, pose: Sequence[float], q: Sequence[float]) -> float:
    """Largest ``| |P_k - c_i| - L |`` over the six legs (m) for a pose and ``q`` (floats)."""
    pts = platform_points_t(cg, pose)
    worst = 0.0
    for i, qi in enumerate(q):
        k = i // 2
        (px, py, pz), (mx, my, mz), (ux, uy, uz) = pts[k], cg.mids_t[k], cg.dirs_t[k]
        dx, dy, dz = px - mx - qi * ux, py - my - qi * uy, pz - mz - qi * uz
        worst = max(worst, abs(math.sqrt(dx * dx + dy * dy + dz * dz) - cg.leg_length))
    return worst


# -- the complete enumeration -------------------------------------------------------------
def _trig_to_poly(c0, c1, c2):
    """``z (c0 + c1 cos t + c2 sin t)`` with ``z = exp(i t)``: ascending coefficients (..., 3)."""
    c0, c1, c2 = np.broadcast_arrays(np.asarray(c0, complex), np.asarray(c1, complex),
                                     np.asarray(c2, complex))
    return np.stack([(c1 + 1j * c2) / 2, c0, (c1 - 1j * c2) / 2], axis=-1)


def _polymul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Product of ascending-coefficient polynomials, batched over leading axes."""
    a, b = np.broadcast_arrays(a[..., :, None], b[..., None, :])
    out = np.zeros(a.shape[:-2] + (a.shape[-2] + b.shape[-1] - 1,), dtype=complex)
    for i in range(a.shape[-2]):
        out[..., i:i + b.shape[-1]] += a[..., i, :] * b[..., i, :]
    return out


def resultant_samples(system: CircleSystem, theta0: np.ndarray) -> np.ndarray:
    """The eliminant ``D(theta_0)`` at the given angles (N,) -> complex (N,).

    ``D`` is the determinant of the Sylvester matrices of :func:`sylvester_matrices`.
    """
    return np.linalg.det(sylvester_matrices(system, theta0))


def sylvester_matrices(system: CircleSystem, theta0: np.ndarray) -> np.ndarray:
    """The 6x6 Sylvester matrices (N, 6, 6) whose determinants are ``D(theta_0)``.

    With ``z_k = exp(i theta_k)``, ``z_j z_k E_jk`` is a polynomial of degree 2 in
    each of ``z_j``, ``z_k``. For each ``theta_0``:

    1. ``f(z1) = z1 E_01(theta_0, .)`` and ``g(z1; z2) = z1 z2 E_12`` are quadratics in
       ``z1`` (the coefficients of ``g`` quadratics in ``z2``); their Sylvester
       resultant ``R(z2) = (f2 g0 - f0 g2)^2 - (f2 g1 - f1 g2)(f1 g0 - f0 g1)`` has
       degree 4 in ``z2``;
    2. ``h(z2) = z2 E_20(., theta_0)`` is quadratic in ``z2``; ``D`` is the 6x6
       Sylvester determinant of ``R`` and ``h`` (formal degrees 4 and 2).

    ``D`` is a trigonometric polynomial of degree 8 in ``theta_0``: degree 2 in the
    coefficients of ``R`` (each of trigonometric degree 2) and 4 in those of
    ``h`` (degree 1).
    """
    K, a, b, Q = system.coefficient_arrays()
    x0 = np.stack([np.cos(theta0), np.sin(theta0)], axis=-1)               # (N, 2)
    # f(z1): E_01 as a function of x1 at fixed theta_0
    f_cs = b[0] + x0 @ Q[0]                                                # (N, 2)
    f = _trig_to_poly(K[0] + x0 @ a[0], f_cs[:, 0], f_cs[:, 1])            # (N, 3) in z1
    # g(z1; z2): E_12 = K + a.x1 + b.x2 + x1^T Q x2; coefficients in z1 are polys in z2
    alpha = _trig_to_poly(K[1], b[1][0], b[1][1])                          # (3,) in z2
    beta = _trig_to_poly(a[1][0], Q[1][0, 0], Q[1][0, 1])
    gamma = _trig_to_poly(a[1][1], Q[1][1, 0], Q[1][1, 1])
    g = np.stack([(beta + 1j * gamma) / 2, alpha, (beta - 1j * gamma) / 2])  # (3 in z1, 3 in z2)
    f0, f1, f2 = (f[:, i, None] for i in range(3))                           # (N, 1)
    g0, g1, g2 = (g[i][None, :] for i in range(3))                           # (1, 3)
    res_z2 = (_polymul(f2 * g0 - f0 * g2, f2 * g0 - f0 * g2)
              - _polymul(f2 * g1 - f1 * g2, f1 * g0 - f0 * g1))             # (N, 5) in z2
    # h(z2): E_20 = K + a.x2 + b.x0 + x2^T Q x0 as a function of x2
    h_cs = a[2] + x0 @ Q[2].T                                              # (N, 2)
    h = _trig_to_poly(K[2] + x0 @ b[2], h_cs[:, 0], h_cs[:, 1])            # (N, 3) in z2
    syl = np.zeros((theta0.shape[0], 6, 6), dtype=complex)
    for row in range(2):
        syl[:, row, row:row + 5] = res_z2[:, ::-1]
    for row in range(4):
        syl[:, 2 + row, row:row + 3] = h[:, ::-1]
    return syl


def eliminant_roots(system: CircleSystem) -> tuple[np.ndarray, np.ndarray, float]:
    """Fourier coefficients of ``D`` and the roots of ``z^8 D`` (degree-16 polynomial).

    Returns:
        (coefficients c_-8..c_8 (17,), roots (<= 16,) complex, aliasing) where
        ``aliasing`` is the largest ``|c_m|``, ``|m| > 8``, relative to the
        largest coefficient (a consistency check: ~1e-15).

    Raises:
        AssemblyError: ``D`` vanishes identically (degenerate carriage positions
            with a continuum of assemblies).
    """
    n = N_SAMPLES
    syl = sylvester_matrices(system, 2 * np.pi * np.arange(n) / n)
    samples = np.linalg.det(syl)
    spectrum = np.fft.fft(samples) / n            # D(t) = sum_m c_m exp(i m t)
    coeffs = np.concatenate([spectrum[-8:], spectrum[:9]])       # c_-8 .. c_8
    top = float(np.max(np.abs(coeffs)))
    aliasing = float(np.max(np.abs(spectrum[9:n - 8]))) / top if top > 0 else math.inf
    # Hadamard's bound on |det| (product of the row norms): an identically vanishing D
    # leaves only rounding, ~1e-16 of it; genuine configurations sit above ~1e-5
    bound = float(np.max(np.prod(np.linalg.norm(syl, axis=-1), axis=-1)))
    if not top > DEGENERATE_ELIMINANT * bound:
        raise AssemblyError("degenerate: the eliminant vanishes identically (a continuum of "
                            "assemblies or coincident circles)", 0.0, 0)
    roots = np.roots(coeffs[::-1])
    return coeffs, roots, aliasing


def _solve_trig(alpha: float, beta: float, gamma: float, slack: float = 1e-3) -> list[float]:
    """Real ``t`` with ``alpha + beta cos t + gamma sin t = 0`` (0, 1 or 2 of them).

    A tangency missed by rounding (``|alpha|`` up to ``1 + slack`` times
    ``hypot(beta, gamma)``) counts as a double root.
    """
    amp = math.hypot(beta, gamma)
    if amp == 0.0:
        return []
    ratio = -alpha / amp
    if abs(ratio) > 1.0 + slack:
        return []
    phase = math.atan2(gamma, beta)
    spread = math.acos(max(-1.0, min(1.0, ratio)))
    return [phase + spread, phase - spread] if spread > 0.0 else [phase]


def _candidates(system: CircleSystem, t0: float) -> list[tuple[float, float, float]]:
    """All (theta0, theta1, theta2) compatible with ``theta0`` along both elimination paths."""
    K, a, b, Q = system.coefficient_arrays()
    x0 = np.array([math.cos(t0), math.sin(t0)])
    out = []
    # E_01(theta0, theta1) = 0 -> theta1 ; E_20(theta2, theta0) = 0 -> theta2
    cs01 = b[0] + x0 @ Q[0]
    th1 = _solve_trig(K[0] + a[0] @ x0, cs01[0], cs01[1])
    cs20 = a[2] + Q[2] @ x0
    th2 = _solve_trig(K[2] + b[2] @ x0, cs20[0], cs20[1])
    for t1 in th1:
        for t2 in th2:
            out.append((t0, t1, t2))
    # path B: theta1 from E_01, theta2 from E_12 (covers E_20 vanishing identically)
    for t1 in th1:
        x1 = np.array([math.cos(t1), math.sin(t1)])
        cs12 = b[1] + x1 @ Q[1]
        for t2 in _solve_trig(K[1] + a[1] @ x1, cs12[0], cs12[1]):
            out.append((t0, t1, t2))
    # path C: theta2 from E_20, theta1 from E_12 (covers E_01 vanishing identically)
    for t2 in th2:
        x2 = np.array([math.cos(t2), math.sin(t2)])
        cs12 = a[1] + Q[1] @ x2
        for t1 in _solve_trig(K[1] + b[1] @ x2, cs12[0], cs12[1]):
            out.append((t0, t1, t2))
    return out


def enumerate_assemblies(system: CircleSystem) -> list[np.ndarray]:
    """Every real solution ``theta`` (3,) of the triangle equations, each once.

    Method and completeness argument:

    1. Elimination. Put ``z_k = exp(i theta_k)``; real angles are the points of
       the unit circle. ``z_j z_k E_jk`` is a polynomial of bidegree (2, 2). The
       Sylvester resultant of two polynomials with *formal* degrees vanishes
       exactly when they share a root in the projective line (a common root at
       infinity included), so eliminating ``z1`` from ``E_01, E_12`` and then
       ``z2`` against ``E_20`` (:func:`resultant_samples`) gives a function
       ``D(theta_0)`` that vanishes at the ``theta_0`` of *every* solution, real or
       complex. ``D`` is a trigonometric polynomial of degree 8, so
       ``z^8 D = sum_m c_m z^(m+8)`` is a polynomial of degree 16 (the classic
       bound of 16 assemblies of a 6-3 Stewart platform).
    2. Its coefficients are computed exactly (up to rounding) by sampling ``D``
       at 32 equispaced angles and a discrete Fourier transform (unitary, so
       well conditioned; the unused frequencies 9..16 must vanish and are checked
       in the tests). All 16 roots come from the companion-matrix eigenvalues
       (``numpy.roots``, backward stable). The argument of *every* root is a
       candidate ``theta_0`` (no test of ``|z| = 1``, which rounding can break
       for multiple roots: the next steps sort real from complex).
    3. Back substitution is exhaustive: for each candidate ``theta_0`` every
       ``theta_1`` with ``E_01 = 0`` and ``theta_2`` with ``E_20 = 0`` (each a
       circle-sphere intersection, at most two closed-form roots; a tangency
       missed by up to 1e-3 relative counts as a double root), and the
       completions through ``E_12`` along the two other orders, are tried. So two
       solutions sharing ``theta_0`` are both found.
    4. Candidates whose side errors exceed ``CANDIDATE_TOL`` times the platform
       side are dropped (they belong to complex or spurious roots; a genuine
       candidate is off only by the root's error, at most about ``eps^(1/m)``
       for a root of multiplicity ``m``, e.g. ~1e-4 for the triple roots of the
       symmetric home configuration). The others are polished by Newton on the
       three equations (:func:`newton_circles`, quadratic convergence to
       1e-14 m); failures are dropped, survivors are deduplicated.

    Hence every real solution is found whose ``theta_0`` the eigenvalue solver
    returns within the Newton basin of that solution (always, unless two
    solutions nearly coincide). What is not covered, and what happens:

    * ``D`` identically zero (a continuum of assemblies): :class:`AssemblyError`.
    * Two real solutions closer than about ``sqrt(eps)`` (at a type-II
      singularity, where two assembly modes merge): they may be returned as one.
    """
    _, roots, _ = eliminant_roots(system)
    cands = np.array([c for t0 in np.angle(roots) for c in _candidates(system, float(t0))])
    if cands.size == 0:
        return []
    err = np.max(np.abs(_residuals(system, cands)) * (0.5 / system.sides), axis=1)
    keep = err <= CANDIDATE_TOL * float(np.max(system.sides))
    cands = cands[keep][np.argsort(err[keep])]
    found: list[np.ndarray] = []
    for index in _distinct(cands, 1e-9):
        try:
            sol = np.array(newton_circles(system, cands[index], max_iter=30).theta)
        except AssemblyError:
            continue
        sol = _wrap(sol)
        if not found or np.min(_angle_distances(np.array(found), sol)) > 1e-8:
            found.append(sol)
    return found


def _residuals(system: CircleSystem, theta: np.ndarray) -> np.ndarray:
    """Triangle equations for many angle triples (n, 3) -> (n, 3) (m^2)."""
    K, a, b, Q = system.coefficient_arrays()
    x = np.stack([np.cos(theta), np.sin(theta)], axis=-1)                  # (n, 3, 2)
    out = np.empty(theta.shape)
    for row, (j, k) in enumerate(PAIRS):
        xj, xk = x[:, j], x[:, k]
        out[:, row] = (K[row] + xj @ a[row] + xk @ b[row]
                       + np.einsum("ni,ij,nj->n", xj, Q[row], xk))
    return out


def _wrap(theta: np.ndarray) -> np.ndarray:
    """Angles wrapped to (-pi, pi]."""
    return np.angle(np.exp(1j * np.asarray(theta)))


def _angle_distances(many: np.ndarray, one: np.ndarray) -> np.ndarray:
    """Largest wrapped difference of each row of ``many`` (n, 3) to ``one`` (3,)."""
    return np.max(np.abs(_wrap(many - one)), axis=-1)


def _distinct(points: np.ndarray, tol: float) -> list[int]:
    """Indices of a greedy selection of rows at least ``tol`` apart (in order)."""
    dist = np.max(np.abs(_wrap(points[:, None, :] - points[None, :, :])), axis=-1)
    chosen: list[int] = []
    for i in range(points.shape[0]):
        if not chosen or np.min(dist[i, chosen]) > tol:
            chosen.append(i)
    return chosen


# --------------------------------------------------------------------------------------
# as-built robots: Newton on the six closure equations, continuation from the drawing
# --------------------------------------------------------------------------------------
def forward_as_built(chains: ChainGeometry, q: npt.ArrayLike, guess: npt.ArrayLike,
                     max_iter: int = 50) -> np.ndarray:
    """Forward kinematics of an as-built robot: Newton's method on the six closure
    equations ``|t + R p_i - c_i(q)| = L_i`` (:func:`~hexapod_pin.hexapod.geometry.
    closure_pose`) from ``guess`` (6,), converging to the assembly mode whose basin holds
    it; every leg within ``CLOSURE_TOL max(1, L_i)`` m of its length.

    Raises:
        AssemblyError: no convergence within ``max_iter`` iterations or a singular
            closure Jacobian (type II) on the way.
    """
    pose = closure_pose(chains, q, guess, max_iter=max_iter)
    if pose is None:
        start = float(np.max(np.abs(leg_residuals(chains, q, guess))))
        raise AssemblyError("Newton's method on the six closure equations did not converge "
                            "from the guess (no assembly nearby, or a type-II singularity); "
                            f"leg-length residual at the guess {start:.3e} m",
                            start, max_iter)
    return pose


def modes_as_built(geometry: HexapodGeometry, q: npt.ArrayLike) -> list[np.ndarray]:
    """The assembly modes of an as-built robot at readings ``q`` (6,), by continuation
    from those of its ideal drawing.

    The ideal robot's modes at the same readings come from the complete enumeration
    (:func:`enumerate_assemblies`); each is followed along the straight line from the
    drawing's :class:`~hexapod_pin.hexapod.geometry.ChainGeometry` vector to the as-built
    one (:func:`~hexapod_pin.hexapod.geometry.continue_pose`: Newton's method on the six
    closure equations at each step, adaptive steps); the modes that arrive are verified
    by :func:`~hexapod_pin.hexapod.geometry.closure_pose`'s tolerance and deduplicated.
    A mode that meets a fold on the way (two real assemblies merge and cease to exist)
    or a type-II singularity is lost, never replaced by a wrong pose. Completeness is
    not guaranteed: an as-built robot may have assemblies with no ideal counterpart
    (the drawing is a special, symmetric case); for millimetre deviations the tests find
    every mode of the drawing.

    Returns:
        the distinct poses (6,) found, in no particular order.

    Raises:
        AssemblyError: the ideal readings are degenerate (see :func:`enumerate_assemblies`).
    """
    q = np.asarray(q, dtype=float)
    cg = CircleGeometry.from_geometry(geometry)
    system = circle_system(cg, q)
    if system is None:
        return []
    start, stop = ChainGeometry.ideal(geometry), geometry.chain_geometry
    found: list[np.ndarray] = []
    for theta in enumerate_assemblies(system):
        pose = np.array(pose_from_points_t(cg, system.points_t(*theta.tolist())))
        pose = continue_pose(start, stop, q, pose)
        if pose is not None and not any(
                np.max(np.abs(pose - other)) <= 1e-9 for other in found):
            found.append(pose)
    return found
