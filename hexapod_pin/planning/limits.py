"""Limits and payload of a motion, and their coefficients along a path.

Along a path ``x(s)`` with tangent ``xi(s)`` and its derivative ``xi'(s)``
(:mod:`hexapod_pin.planning.path`), the robot's closed-loop inverse dynamics is affine in
``s_ddot`` and ``s_dot^2`` (it is affine in ``twist_dot`` and the wrench, and its velocity
terms are quadratic in the twist)::

    tau(s, s_dot, s_ddot) = a(s) s_ddot + b(s) s_dot^2 + c(s)
    c = ID(x, 0, 0, w_0),  a = ID(x, 0, xi, w_0 - m [xi_v, 0]) - c,
    b = ID(x, xi, xi', w_0 - m [xi'_v, 0]) - c

with ``w_0`` the constant payload wrench plus the weight of the payload mass ``m`` (a
point mass at the platform origin: its inertial force ``-m dv/dt`` is affine in
``s_ddot`` and ``s_dot^2`` too). One call of the robot's ``inverse_dynamics_batch`` over
the 3 N states gives ``a, b, c``. The actuator velocities are ``q' s_dot`` with
``q' = J xi`` (``jacobian_batch``); the actuator accelerations ``q' s_ddot + q'' s_dot^2``
with ``q'' = J xi' + dJ/ds xi`` read from ``forward_dynamics_batch`` driven by the forces
of the state ``(x, xi, xi')``.

Drive effects (``robot.effects``, :mod:`hexapod_pin.core.effects`): the armature is
inertia and the springs depend on the pose only, so both stay inside ``a`` and ``c``
(computed on the robot without damping and Coulomb friction). Viscous damping gives
``D q' s_dot``, linear in ``s_dot`` (not of the ``s_ddot`` / ``s_dot^2`` form), and
Coulomb friction ``-coulomb sign(q' s_dot) = -coulomb sign(q')`` for ``s_dot > 0``, a
constant; so with effects::

    tau = a s_ddot + b s_dot^2 + d(s) s_dot + f(s) + c

``d`` the robot with damping minus the one without at ``(x, xi, xi')`` (exact: the
damping force is linear in the velocity), ``f`` the robot with friction minus the one
without there. With ``x = s_dot^2`` the term ``d sqrt(x)`` is not affine: each row
``alpha u + beta x + delta sqrt(x) + gamma <= 0`` is replaced by a conservative one
linearised at a speed ``r_0`` per grid point (:func:`constraint_rows`): for ``delta > 0``
the tangent ``sqrt(x) <= r_0 / 2 + x / (2 r_0)``, for ``delta < 0`` the two rows of
``sqrt(x) >= min(x / r_0, r_0)``; both are exact at ``x = r_0^2``, and every profile that
meets the linearised rows meets the true ones (the planner iterates ``r_0`` and verifies,
:func:`~hexapod_pin.planning.trajectory.time_optimal`). At a grid point where the path is
at rest (``s_dot = 0``: the ends) the friction of inverse dynamics is ``-coulomb
sign(q' s_ddot)``, either sign: the rows there hold for both.

Units: forces N (or N m), actuator velocities m/s (or rad/s), accelerations m/s^2 (or
rad/s^2), platform linear speed m/s, angular speed rad/s; every limit is a bound on the
absolute value, ``inf`` for none.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.robot_api import ParallelRobot, pose_layout
from ..core.workspace_maps import actuator_force_bounds
from ..core.checks import as_array, bounds, flag, real_array, real_number, within_magnitude
from ..errors import HexapodPinError, InfeasiblePathError, InputError
from .path import PathSamples


@dataclass(frozen=True)
class Limits:
    """Bounds on the motion (absolute values; ``inf``: none).

    Attributes:
        actuator_force: N (or N m), a scalar or one value per actuator; None: the robot's
            ``geometry.max_actuator_force``, and where the drive effects give a smaller
            ``effort_limit`` (``robot.effects``, joint side) that one.
        actuator_velocity: m/s (or rad/s), scalar or per actuator.
        actuator_acceleration: m/s^2 (or rad/s^2), scalar or per actuator.
        linear_speed: speed of the platform origin (m/s): the norm of the linear
            components of the twist (ignored by a robot with none in its pose).
        angular_speed: norm of the angular components of the twist (rad/s; ignored by a
            robot with no angle in its pose).
        strokes: reject a path that leaves the actuators' strokes (else only reachability
            is required).
        margin: the planner keeps every bound times ``1 - margin`` (0 <= margin < 1), so
            that the motion between its grid points, which may exceed the bounds it was
            planned for by a fraction of a percent that shrinks with the grid step, stays
            within the full bounds; :func:`check_feasibility` checks the full bounds.
    """

    actuator_force: float | tuple | None = None
    actuator_velocity: float | tuple = np.inf
    actuator_acceleration: float | tuple = np.inf
    linear_speed: float = np.inf
    angular_speed: float = np.inf
    strokes: bool = True
    margin: float = 0.0

    def __post_init__(self) -> None:
        """Check every field by name (:class:`InputError`): bounds as in
        :func:`~hexapod_pin.core.checks.bounds` (a finite bound beyond
        :data:`~hexapod_pin.core.checks.MAX_MAGNITUDE` cannot be certified: use inf for
        none), ``strokes`` a bool, ``0 <= margin < 1``."""
        for name in ("actuator_force", "actuator_velocity", "actuator_acceleration"):
            value = getattr(self, name)
            if value is not None or name != "actuator_force":
                sized = isinstance(value, (list, tuple)) or getattr(value, "ndim", 0) > 0
                bounds(value, len(value) if sized else 1, name)
        for name in ("linear_speed", "angular_speed"):
            bounds(getattr(self, name), 1, name)
        flag(self.strokes, "strokes")
        margin = real_number(self.margin, "margin", minimum=0.0, strict=False)
        if not margin < 1.0:
            raise InputError("margin", self.margin, "expected 0 <= margin < 1")

    def per_actuator(self, robot: ParallelRobot, planning: bool = False) -> dict[str, np.ndarray]:
        """``{"force", "velocity", "acceleration", "linear_speed", "angular_speed"}`` ->
        bounds for ``robot``: (n_act,) for the actuators, (1,) for the platform speeds;
        with ``planning``, each times ``1 - margin``.

        Raises:
            InputError: a bound of the wrong length for ``robot``.
        """
        scale = 1.0 - float(self.margin) if planning else 1.0
        n = robot.n_actuators
        force = actuator_force_bounds(robot) if self.actuator_force is None \
            else self.actuator_force
        out = {}
        for name, value in (("force", force), ("velocity", self.actuator_velocity),
                            ("acceleration", self.actuator_acceleration)):
            out[name] = bounds(value, n, f"actuator_{name}") * scale
        for name in ("linear_speed", "angular_speed"):
            out[name] = bounds(getattr(self, name), 1, name) * scale
        return out


@dataclass(frozen=True)
class Payload:
    """What the platform carries.

    Attributes:
        mass: a point mass at the platform origin (kg), >= 0: its weight and inertial
            force act on the platform (their components along the robot's linear pose
            axes).
        wrench: a constant wrench ON the platform, the selection ``pose_axes`` of ``(f,
            m)`` (world axes, moment about the platform origin; N, N m), shape (dim,), or
            None.
    """

    mass: float = 0.0
    wrench: tuple | None = None

    def __post_init__(self) -> None:
        """Check the fields by name (:class:`InputError`): ``mass`` a real number >= 0
        (kg), ``wrench`` None or real, finite numbers of one dimension."""
        real_number(self.mass, "mass", minimum=0.0, strict=False)
        if self.wrench is not None:
            wrench = within_magnitude(real_array(self.wrench, "wrench"), self.wrench, "wrench")
            if wrench.ndim != 1:
                raise InputError("wrench", self.wrench, f"expected shape (dim,), got "
                                 f"{wrench.shape}")

    def check(self, dim: int) -> None:
        """Raise :class:`InputError` on a wrench whose size is not ``dim``."""
        if self.wrench is not None:
            as_array(self.wrench, (dim,), "wrench")

    @property
    def is_zero(self) -> bool:
        return self.mass == 0.0 and (self.wrench is None or not np.any(self.wrench))

    def wrenches(self, robot: ParallelRobot, twist_dots: np.ndarray) -> np.ndarray | None:
        """The payload's wrench on the platform (N, dim) for platform accelerations
        ``twist_dots`` (N, dim): ``wrench + m (g - dv/dt)`` on the linear components (the
        world axes of the robot's linear pose axes, e.g. ``g[[0, 2]]`` for ``("x",
        "z")``; no moment: the mass sits at the platform origin); None for no payload."""
        if self.is_zero:
            return None
        layout = pose_layout(robot)
        lin = layout.linear
        out = np.zeros((len(twist_dots), layout.dim))
        if self.wrench is not None:
            out += np.asarray(self.wrench, dtype=float)
        gravity = np.asarray(robot.model.model.gravity.linear,
                             dtype=float)[layout.components[lin]]
        out[:, lin] += self.mass * (gravity - np.asarray(twist_dots)[:, lin])
        return out


@dataclass(frozen=True)
class PathCoefficients:
    """The limits along a sampled path as affine functions of ``(s_ddot, s_dot^2)``.

    Attributes:
        samples: the :class:`PathSamples` (N points).
        force_a: (N, n_act) ``a`` of ``tau = a s_ddot + b s_dot^2 + c`` (N).
        force_b: (N, n_act) ``b`` (N).
        force_c: (N, n_act) ``c`` (N).
        velocity_ratio: (N, n_act) ``q' = J xi``: actuator velocities per unit path speed.
        acceleration_b: (N, n_act) ``q''`` (None unless accelerations are limited).
        actuator_positions: (N, n_act) (m or rad).
        speed_bound: (N,) the largest ``s_dot^2`` the velocity limits allow (``inf``: none).
        force_d: (N, n_act) ``d``: the damping force per unit path speed (N s/m, or
            N m s/m); zeros without damping.
        force_f: (N, n_act) ``f``: the Coulomb friction force while the path moves
            forward (N); zeros without friction.
    """

    samples: PathSamples
    force_a: np.ndarray
    force_b: np.ndarray
    force_c: np.ndarray
    velocity_ratio: np.ndarray
    acceleration_b: np.ndarray | None
    actuator_positions: np.ndarray
    speed_bound: np.ndarray
    force_d: np.ndarray
    force_f: np.ndarray

    @property
    def damped(self) -> bool:
        """Whether a force depends on the path speed linearly (damping)."""
        return bool(np.any(self.force_d))

    def forces(self, s_ddot: np.ndarray, s_dot: np.ndarray) -> np.ndarray:
        """``a s_ddot + b s_dot^2 + d s_dot + f + c`` (N, n_act) at the grid points, the
        friction ``f sign(s_ddot)`` where the path is at rest (``s_dot = 0``: the sign
        inverse dynamics gives a joint at rest that accelerates)."""
        friction = np.where((s_dot > 0)[:, None], 1.0, np.sign(s_ddot)[:, None]) * self.force_f
        return (self.force_a * s_ddot[:, None] + self.force_b * (s_dot ** 2)[:, None]
                + self.force_d * s_dot[:, None] + friction + self.force_c)


def effect_variants(robot: ParallelRobot) -> tuple[ParallelRobot, ParallelRobot | None,
                                                   ParallelRobot | None]:
    """``(base, damped, full)``: the robot without damping and Coulomb friction (armature
    and springs kept: they fit ``a``, ``c``), the robot with its damping but no friction
    (None without damping), the robot itself (None without friction)."""
    effects = getattr(robot, "effects", None)
    if effects is None or not (effects.damping.any() or effects.coulomb.any()):
        return robot, None, None
    zero = np.zeros(effects.damping.size)
    rebuild = getattr(robot, "with_effects")          # every robot with effects has it
    base = rebuild(damping=zero, coulomb=zero)
    damped = None
    if effects.damping.any():
        damped = rebuild(coulomb=zero) if effects.coulomb.any() else robot
    return base, damped, robot if effects.coulomb.any() else None


def _fail_at(samples: PathSamples, index: int, reason: str, **kw) -> InfeasiblePathError:
    return InfeasiblePathError(index, samples.s[index], samples.poses[index], reason, **kw)


def path_coefficients(robot: ParallelRobot, samples: PathSamples, limits: Limits,
                      payload: Payload) -> PathCoefficients:
    """:class:`PathCoefficients` of ``robot`` along ``samples`` (see the module docstring).

    Raises:
        InfeasiblePathError: a grid pose out of reach, out of its strokes (with
            ``limits.strokes``) or singular (it names the grid point).
    """
    n, dim = len(samples.s), robot.pose_dim
    bounds = limits.per_actuator(robot, planning=True)
    ik = robot.inverse_kinematics_batch(samples.poses)
    bad = ~(ik.ok if limits.strokes else ik.reachable)
    if np.any(bad):
        k = int(np.argmax(bad))
        reason = "the actuators leave their strokes" if ik.reachable[k] else \
            "the pose is out of reach"
        raise _fail_at(samples, k, reason)
    jac = robot.jacobian_batch(samples.poses)
    if not np.all(jac.ok):
        raise _fail_at(samples, int(np.argmax(~jac.ok)), "type-I singularity")
    zero = np.zeros((n, dim))
    xi, dxi = samples.tangents, samples.curvatures
    wrenches = None
    if not payload.is_zero:
        wrenches = np.vstack([payload.wrenches(robot, x)      # type: ignore[misc]
                              for x in (zero, xi, dxi)])   # not None: a payload is given
    poses3 = np.vstack([samples.poses] * 3)
    base, damped, full = effect_variants(robot)
    forces = _inverse(base, samples, poses3, np.vstack([zero, zero, xi]),
                      np.vstack([zero, xi, dxi]), wrenches)
    moving = forces[2 * n:]
    w_moving = None if wrenches is None else wrenches[2 * n:]
    force_d, force_f = np.zeros_like(moving), np.zeros_like(moving)
    if damped is not None:
        force_d = _inverse(damped, samples, samples.poses, xi, dxi, w_moving) - moving
        moving = moving + force_d
    if full is not None:
        force_f = _inverse(full, samples, samples.poses, xi, dxi, w_moving) - moving
    c = forces[:n]
    velocity_ratio = np.einsum("nij,nj->ni", jac.jacobian, xi)
    acc_b = None
    if np.any(np.isfinite(bounds["acceleration"])):
        acc_b = base.forward_dynamics_batch(
            samples.poses, xi, forces[2 * n:],
            None if wrenches is None else wrenches[2 * n:]).actuator_accelerations
    layout = pose_layout(robot)
    with np.errstate(divide="ignore"):
        ratios = [np.abs(velocity_ratio) / bounds["velocity"],
                  np.linalg.norm(xi[:, layout.linear], axis=1)[:, None]
                  / bounds["linear_speed"],
                  np.linalg.norm(xi[:, layout.angular], axis=1)[:, None]
                  / bounds["angular_speed"]]
        worst = np.max(np.hstack(ratios), axis=1)
        speed_bound = np.where(worst > 0, 1.0 / worst ** 2, np.inf)
    return PathCoefficients(samples, forces[n:2 * n] - c, forces[2 * n:] - c, c,
                            velocity_ratio, acc_b, ik.actuator_positions, speed_bound,
                            force_d, force_f)


def _inverse(robot: ParallelRobot, samples: PathSamples, poses: np.ndarray,
             twists: np.ndarray, twist_dots: np.ndarray,
             wrenches: np.ndarray | None) -> np.ndarray:
    """The robot's batch inverse dynamics (unbounded), a failure named at its grid point."""
    try:
        return robot.inverse_dynamics_batch(poses, twists, twist_dots, wrenches,
                                            bounded=False).actuator_forces
    except HexapodPinError as exc:
        k = getattr(exc, "index", None)
        if k is None:
            raise
        raise _fail_at(samples, k % len(samples.s),
                       f"inverse dynamics failed: {exc}") from exc


def constraint_rows(coeffs: PathCoefficients, robot: ParallelRobot, limits: Limits,
                    speed: np.ndarray | None = None, force_scale: float = 1.0,
                    at_rest: np.ndarray | None = None) -> np.ndarray:
    """The limits as rows ``alpha s_ddot + beta s_dot^2 + gamma <= 0``, (N, m, 3), each
    divided by its bound (dimensionless; the bounds times ``1 - limits.margin``).

    Args:
        coeffs: the :class:`PathCoefficients`.
        robot: the robot (its default bounds).
        limits: the :class:`Limits`.
        speed: (N,) the path speed ``r_0`` (m/s, > 0) at which the damping term ``d
            s_dot`` is linearised conservatively (module docstring); None: the damping
            term is left out (not conservative: a first guess only).
        force_scale: the force bounds are multiplied by it (0 < force_scale <= 1).
        at_rest: (N,) bool, the grid points where the path speed is zero (the friction
            rows there hold for both signs); default none.

    Raises:
        InfeasiblePathError: a grid point where the robot cannot hold the path's pose
            statically, or move through it slowly against its friction, within its force
            limits (it names the point and the actuator).
    """
    bounds = limits.per_actuator(robot, planning=True)
    blocks = []
    force = bounds["force"] * force_scale
    finite = np.flatnonzero(np.isfinite(force))
    if finite.size:
        slow = coeffs.force_c + coeffs.force_f
        over = np.abs(slow[:, finite]) > force[finite]
        if np.any(over):
            k, j = np.unravel_index(int(np.argmax(over)), over.shape)
            i = int(finite[j])
            what = "hold this pose statically" if not np.any(coeffs.force_f) else \
                "move slowly through this pose against its friction (statically)"
            raise _fail_at(coeffs.samples, int(k), f"the robot cannot {what} within its "
                           "force limits", actuator=i, value=slow[k, i], limit=force[i])
        a, b = coeffs.force_a[:, finite], coeffs.force_b[:, finite]
        c, f = coeffs.force_c[:, finite], coeffs.force_f[:, finite]
        d = coeffs.force_d[:, finite] if speed is not None else np.zeros_like(a)
        blocks.append(_force_rows(a, b, c + f, d, force[finite], speed))
        if at_rest is not None and np.any(at_rest) and np.any(f):
            # at rest the friction of an accelerating joint takes the sign of s_ddot
            flipped = np.where(at_rest[:, None], c - f, c + f)
            blocks.append(_force_rows(a, b, flipped, d, force[finite], speed))
    acc = bounds["acceleration"]
    finite = np.flatnonzero(np.isfinite(acc))
    if finite.size:
        blocks.append(_two_sided(coeffs.velocity_ratio[:, finite],
                                 coeffs.acceleration_b[:, finite],  # type: ignore[index]
                                 np.zeros((len(coeffs.force_c), finite.size)), acc[finite]))
    if not blocks:
        return np.zeros((len(coeffs.force_c), 1, 3))
    return np.ascontiguousarray(np.concatenate(blocks, axis=1))


def _force_rows(a, b, c, d, bound, speed) -> np.ndarray:
    """Rows of ``-bound <= a u + b x + d sqrt(x) + c <= bound`` (N, 4 n, 3), ``d
    sqrt(x)`` linearised conservatively at ``sqrt(x) = speed`` (module docstring): for a
    positive coefficient the tangent (twice, to keep the shape), for a negative one the
    rows of ``x / speed`` and of ``speed``. Without damping: :func:`_two_sided`."""
    if not np.any(d):
        return _two_sided(a, b, c, bound)
    r0 = np.asarray(speed, dtype=float)[:, None]
    blocks = []
    for sign in (1.0, -1.0):
        alpha, beta = sign * a / bound, sign * b / bound
        gamma, delta = sign * c / bound - 1.0, sign * d / bound
        pos, neg = np.maximum(delta, 0.0), np.minimum(delta, 0.0)
        tangent_beta, tangent_gamma = beta + pos / (2.0 * r0), gamma + pos * r0 / 2.0
        blocks.append(np.stack([alpha, tangent_beta + neg / r0, tangent_gamma], axis=-1))
        blocks.append(np.stack([alpha, tangent_beta, tangent_gamma + neg * r0], axis=-1))
    return np.concatenate(blocks, axis=1)


def _two_sided(a, b, c, bound) -> np.ndarray:
    """Rows of ``-bound <= a u + b x + c <= bound``, divided by ``bound``: (N, 2 n, 3)."""
    upper = np.stack([a / bound, b / bound, c / bound - 1.0], axis=-1)
    lower = np.stack([-a / bound, -b / bound, -c / bound - 1.0], axis=-1)
    return np.concatenate([upper, lower], axis=1)
