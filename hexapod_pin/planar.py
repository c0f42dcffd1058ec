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
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import pinocchio as pin

from .closed_loop import ClosedLoopModel
from .description import build_model, expand_xacro, load_loops, urdf_dir
from .dynamics import (TreeForwardDynamics, TreeInverseDynamics, forward_dynamics_tree,
                       inverse_dynamics_tree)
from .errors import (AssemblyError, GeometryError, SingularityError,
                     StrokeLimitError, UnreachablePoseError)
from .geometry import validate_scalars
from .pose import as_array, check_signs

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


def rail_angles() -> np.ndarray:
    """Angles ``a_k = 90 deg + 120 deg k`` of the three rails (rad), shape (3,)."""
    return np.pi / 2 + 2 * np.pi / 3 * np.arange(N_SLIDERS)


def _rot2(theta) -> np.ndarray:
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s], [s, c]])


def _cross2(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """z component of ``a x b`` for arrays of 2-vectors (..., 2)."""
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


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
        tree = build_model(planar_urdf(self.geometry), source="planar_3prr.urdf.xacro")
        self.model = ClosedLoopModel(tree, load_loops(urdf_dir() / "planar_3prr.loops.yaml"),
                                     name="planar_3prr")
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
        pose = as_array(pose, (3,), "pose")
        branch = check_branch(branch)
        g = self.geometry
        d = self.platform_points_world(pose) - self._mids
        along = np.einsum("ki,ki->k", d, self._dirs)
        disc = g.link_length ** 2 - (np.einsum("ki,ki->k", d, d) - along ** 2)
        if np.any(disc < 0.0):
            bad = np.flatnonzero(disc < 0.0)
            dist = np.sqrt(g.link_length ** 2 - disc[bad])
            raise UnreachablePoseError(bad, dist - g.link_length)
        s = along + branch * np.sqrt(disc)
        if check_limits:
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
        pose = as_array(pose, (3,), "pose")
        s = self.inverse_kinematics(pose, branch=branch, check_limits=False)
        return self._jacobian(pose, s)

    def _jacobian(self, pose: np.ndarray, s: np.ndarray) -> np.ndarray:
        links = self.link_vectors(pose, s)
        dots = self._link_dots(links)
        r = self.platform_points_world(pose) - pose[:2]
        out = np.empty((N_SLIDERS, 3))
        out[:, :2] = links
        out[:, 2] = _cross2(r, links)
        return out / dots[:, None]

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
        the pose.

        Args:
            pose: ``(x, y, theta)``, shape (3,).
            branch: IK branch, default all ``+1``.

        Returns:
            q (nq = 9,) satisfying the 9 closure rows to 1e-12 m.

        Raises:
            UnreachablePoseError: a link cannot reach.
            AssemblyError: the closed form misses the closures by more than 1e-12 m.
        """
        pose = as_array(pose, (3,), "pose")
        s = self.inverse_kinematics(pose, branch=branch, check_limits=False)
        return self._configuration(pose, s)

    def _configuration(self, pose: np.ndarray, s: np.ndarray) -> np.ndarray:
        links = self.link_vectors(pose, s)
        idx = self.indices
        q = np.zeros(self.model.nq)
        q[idx.slider] = s
        q[idx.link] = _wrap(np.arctan2(links[:, 1], links[:, 0]) - rail_angles() - np.pi / 2)
        q[idx.platform] = pose
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
        pose = as_array(pose, (3,), "pose")
        twist = as_array(twist, (3,), "twist")
        s = self.inverse_kinematics(pose, branch=branch, check_limits=False)
        return self._velocity(pose, s, twist)

    def _velocity(self, pose: np.ndarray, s: np.ndarray, twist: np.ndarray) -> np.ndarray:
        sdot = self._jacobian(pose, s) @ twist
        links = self.link_vectors(pose, s)
        r = self.platform_points_world(pose) - pose[:2]
        point_vel = twist[:2] + twist[2] * np.stack([-r[:, 1], r[:, 0]], axis=1)
        link_vel = point_vel - sdot[:, None] * self._dirs
        idx = self.indices
        v = np.zeros(self.model.nv)
        v[idx.slider] = sdot
        v[idx.link] = _cross2(links, link_vel) / self.geometry.link_length ** 2
        v[idx.platform] = twist
        return v

    def acceleration(self, pose, twist, twist_dot, branch=None) -> np.ndarray:
        """Tree acceleration ``a`` (nv = 9,) of a platform motion, every closure kept.

        The platform chain's acceleration is ``twist_dot``; the others solve
        ``J_c a = -gamma(q, v)`` (:meth:`ClosedLoopModel.complete_acceleration`, which
        tolerates the redundant out-of-plane rows).

        Raises:
            UnreachablePoseError, SingularityError: see :meth:`jacobian`.
        """
        pose = as_array(pose, (3,), "pose")
        twist = as_array(twist, (3,), "twist")
        twist_dot = as_array(twist_dot, (3,), "twist_dot")
        s = self.inverse_kinematics(pose, branch=branch, check_limits=False)
        q = self._configuration(pose, s)
        v = self._velocity(pose, s, twist)
        return self.model.complete_acceleration(q, v, self.indices.platform, twist_dot)

    # -- dynamics ------------------------------------------------------------------------
    def _state(self, pose, twist, branch):
        pose = as_array(pose, (3,), "pose")
        twist = as_array(twist, (3,), "twist")
        s = self.inverse_kinematics(pose, branch=branch, check_limits=False)
        return self._configuration(pose, s), self._velocity(pose, s, twist)

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
        ``M a + h - tau_ext = S^T tau + J_c^T lambda`` on the tree
        (:func:`hexapod_pin.dynamics.inverse_dynamics_tree`; the redundant
        out-of-plane rows are handled there), gravity ``-g`` along y included.

        Args:
            pose: ``(x, y, theta)`` (m, m, rad), shape (3,).
            twist: ``(vx, vy, omega)`` (m/s, rad/s), world axes, shape (3,).
            twist_dot: its time derivative (m/s^2, rad/s^2), shape (3,).
            wrench: ``(fx, fy, mz)`` applied ON the platform by the environment (N, N m),
                moment about the platform origin; default zero.
            branch: IK branch, default all ``+1``.
            bounds: ``abs(tau_k) <= bounds`` (N); default ``geometry.max_actuator_force``.
            method: "kkt" (linear solve) or "qp" (ProxSuite), see
                :func:`~hexapod_pin.dynamics.inverse_dynamics_tree`.

        Returns:
            :class:`PlanarInverseDynamics` (forces along ``+u_k``, N).

        Raises:
            InputError: a malformed input.
            UnreachablePoseError: the pose cannot be reached.
            SingularityError: a link perpendicular to its rail.
            ActuatorSaturationError: the motion needs more than ``bounds``.
        """
        q, v = self._state(pose, twist, branch)
        twist_dot = as_array(twist_dot, (3,), "twist_dot")
        a = self.model.complete_acceleration(q, v, self.indices.platform, twist_dot)
        res = inverse_dynamics_tree(self.model, q, v, a, self._external(wrench),
                                    bounds=self._bounds(bounds), method=method)
        return PlanarInverseDynamics(res.actuator_forces.copy(),
                                     self._link_forces(res.multipliers), res)

    def static_forces(self, pose, wrench=None, branch=None) -> np.ndarray:
        """Actuator forces (3,) (N, along ``+u_k``) holding the platform at rest.

        Balances gravity (``-g`` along y, every body) and the external ``wrench``
        ``(fx, fy, mz)`` applied ON the platform (N, N m, moment about its origin):
        :meth:`inverse_dynamics` at zero twist and acceleration, without bounds.

        Raises:
            InputError, UnreachablePoseError, SingularityError: see
            :meth:`inverse_dynamics`.
        """
        zero = np.zeros(3)
        return self.inverse_dynamics(pose, zero, zero, wrench, branch,
                                     bounds=np.inf).forces

    def forward_dynamics(self, pose, twist, forces, wrench=None, branch=None,
                         method: str = "kkt") -> PlanarForwardDynamics:
        """Platform acceleration for given actuator forces (closed-loop forward dynamics).

        Solves ``M a + h = S^T tau + tau_ext + J_c^T lambda``, ``J_c a = -gamma`` on the
        tree (:func:`hexapod_pin.dynamics.forward_dynamics_tree`, redundant rows
        handled there); the platform chain's acceleration is ``twist_dot``.

        Args:
            pose: ``(x, y, theta)``, shape (3,).
            twist: ``(vx, vy, omega)`` (m/s, rad/s), world axes, shape (3,).
            forces: actuator forces (3,) (N), on slider k along ``+u_k``.
            wrench: ``(fx, fy, mz)`` on the platform (N, N m); default zero.
            branch: IK branch, default all ``+1``.
            method: "kkt", "qp" or "pinocchio" (slow here: the redundant rows need
                Pinocchio's proximal iterations).

        Returns:
            :class:`PlanarForwardDynamics`.

        Raises:
            InputError, UnreachablePoseError, SingularityError: see
            :meth:`inverse_dynamics`.
        """
        q, v = self._state(pose, twist, branch)
        tau = self._external(wrench)
        tau[self.indices.slider] += as_array(forces, (3,), "forces")
        res = forward_dynamics_tree(self.model, q, v, tau, method=method)
        return PlanarForwardDynamics(res.a[self.indices.platform].copy(),
                                     res.a[self.indices.slider].copy(),
                                     self._link_forces(res.multipliers), res)

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
