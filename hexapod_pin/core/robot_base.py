"""The implementation every robot facade shares: :class:`RobotBase`.

The robots (:class:`~hexapod_pin.Hexapod`, :class:`~hexapod_pin.Planar3PRR`,
:class:`~hexapod_pin.core.robot.ClosedLoopRobot`) are facades over components that hold
their mechanics; what is the same for all of them lives here once: the lock their calls
take turns on, the home configuration, the URDF text, the pose layout, and the
configuration-level maps that need no closed form (the platform twist of a tree state,
read from Pinocchio's frame Jacobian). A robot supplies ``model`` (its
:class:`~hexapod_pin.core.closed_loop.ClosedLoopModel`), ``geometry``,
``configuration(pose)``, ``home_pose``, and its pose axes and platform frame.
"""

from __future__ import annotations

import threading
from functools import cached_property
from typing import Any

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..errors import DescriptionError, InputError
from .checks import as_array, check_finite_result
from .closed_loop import ClosedLoopModel
from .effects import JointEffects
from .closed_form import ClosedFormDynamics
from .results import InverseDynamicsDerivatives
from .robot_api import PoseLayout, delegate, pose_layout, takes_placement


class RobotBase:
    """The shared part of every robot facade (see the module docstring).

    Attributes:
        POSE_AXES: the pose components (a subset of ``("x", "y", "z", "roll", "pitch",
            "yaw")`` in that order) of a robot class with a fixed pose (class attribute).
        PLATFORM_FRAME: the platform frame's name in the tree (class attribute).
        model: the :class:`ClosedLoopModel` (set by :meth:`_init_facade`).
        lock: serialises the robot's calls (a ``threading.RLock``: its components share
            scratch buffers and Pinocchio data).
    """

    POSE_AXES: tuple[str, ...] = ("x", "y", "z", "roll", "pitch", "yaw")
    PLATFORM_FRAME = "platform"
    model: ClosedLoopModel
    geometry: Any

    def _init_facade(self, model: ClosedLoopModel) -> None:
        """Set the model and the lock (the first thing a robot's constructor does)."""
        self.model = model
        #: serialises the robot's calls (its components share scratch and Pinocchio data)
        self.lock = threading.RLock()
        self._base_data = model.model.createData()

    # -- what every robot has ------------------------------------------------------------
    @property
    def pose_axes(self) -> tuple[str, ...]:
        """The pose components, a subset of ``("x", "y", "z", "roll", "pitch", "yaw")`` in
        that order (m, rad); the twist and the wrench are the same selection of ``(v, w)``
        and ``(f, m)``, world axes."""
        return self.POSE_AXES

    @property
    def pinocchio_model(self) -> pin.Model:
        """The robot's Pinocchio model, ``robot.model.model``: the kinematic tree (the
        loops cut open) with the frames ``<closure>/anchor1`` / ``anchor2`` of each loop
        closure added; the closures themselves, the actuation and the joint effects are
        in ``robot.model`` (:class:`~hexapod_pin.core.closed_loop.ClosedLoopModel`).

        Pinocchio's conventions: ``q`` (nq,), ``v`` (nv,), joint order of the tree, SI
        units, gravity ``model.gravity`` (world axes). Use it with any Pinocchio
        algorithm, e.g. ``pin.framesForwardKinematics(robot.pinocchio_model, data,
        robot.configuration(pose))``; a configuration from ``robot.configuration`` closes
        every loop. Modify a copy (``pin.Model(robot.pinocchio_model)``), not the model
        itself: the robot's routes use it.
        """
        return self.model.model

    @property
    def platform_frame(self) -> str:
        """The name of the platform frame in the tree."""
        return self.PLATFORM_FRAME

    @cached_property
    def pose_layout(self) -> PoseLayout:
        """The :class:`~hexapod_pin.core.robot_api.PoseLayout` of :attr:`pose_axes`."""
        return pose_layout(self.pose_axes)

    @cached_property
    def home_configuration(self) -> npt.NDArray[np.float64]:
        """Pinocchio configuration at home (nq,), every closure satisfied."""
        return self.configuration(self.home_pose)     # type: ignore[attr-defined]

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.geometry!r})"

    def urdf(self) -> str:
        """The URDF text of the tree (``robot.model.urdf_xml``).

        Raises:
            DescriptionError: the model was not built from URDF text.
        """
        text = self.model.urdf_xml
        if text is None:
            raise DescriptionError(self.model.name, "the model was not built from URDF text")
        return str(text)

    # -- joint and drive effects (core.effects) ----------------------------------------------
    @property
    def effects(self) -> JointEffects:
        """The joint and drive effects of the robot's model
        (:class:`~hexapod_pin.core.effects.JointEffects`, ``robot.model.effects``)."""
        return self.model.effects

    def with_effects(self, effects: JointEffects | None = None, **values: Any) -> Any:
        """The same robot with other joint and drive effects (armature, damping, Coulomb
        friction, springs, gears, effort limits): a new robot of the same class, geometry,
        pose axes and home; this one is unchanged. Every route of the new robot (closed
        forms, tree routes, batches, simulation) includes them.

        Args:
            effects: a complete record to start from (default: this robot's).
            **values: fields to change, as
                :meth:`ClosedLoopModel.with_effects
                <hexapod_pin.core.closed_loop.ClosedLoopModel.with_effects>` takes them
                (arrays in the tree's order or ``{joint name: value}``).

        Raises:
            InputError: a bad field (see :func:`~hexapod_pin.core.effects.resolve_effects`).
        """
        return self._with_model(self.model.with_effects(effects, **values))

    # -- gravity ------------------------------------------------------------------------------
    @property
    def gravity(self) -> npt.NDArray[np.float64]:
        """The gravity vector (3,) in world axes (m/s^2), ``robot.model.gravity``."""
        return self.model.gravity

    def with_gravity(self, gravity: npt.ArrayLike) -> Any:
        """The same mechanism under another gravity vector (this robot is unchanged).

        A robot loaded from a description returns a robot of its class on
        ``model.with_gravity(gravity)``. The hexapod's and the planar robot's closed forms
        take gravity along their own vertical only (the hexapod: ``-z``; the planar robot:
        ``-y``): with such a vector they return a robot of their class with that magnitude
        (``geometry.gravity``); with any other direction (a wall-mounted hexapod, a tilted
        plane) a :class:`~hexapod_pin.core.robot.ClosedLoopRobot` over the same tree, the
        same platform frame, pose axes, home, force bounds and effects, whose every route
        is derived from the tree (the generic routes: slower, never a closed form that
        would ignore the direction).

        Args:
            gravity: (3,) the gravitational acceleration in world axes (m/s^2), e.g. ``(0,
                0, -9.81)``; any direction and magnitude (zero: no gravity).

        Raises:
            InputError: not 3 finite real numbers.
        """
        g = as_array(gravity, (3,), "gravity")
        return self._with_gravity(self.model.with_gravity(g), g)

    def _with_gravity(self, model: ClosedLoopModel, gravity: np.ndarray) -> Any:
        """A robot like this one on ``model`` (this one's tree under ``gravity``, (3,));
        a robot whose closed form takes one direction only overrides this."""
        return self._with_model(model)

    def _with_model(self, model: ClosedLoopModel) -> Any:
        """A robot like this one on ``model`` (the same tree with other effects); each
        robot class supplies it."""
        raise NotImplementedError(f"{type(self).__name__} cannot be rebuilt on another model")

    # -- the dynamics component's shared routes (core.closed_form; a robot may override) ----
    energies = delegate("dynamics", ClosedFormDynamics.energies)
    inverse_dynamics_batch = delegate("dynamics", ClosedFormDynamics.inverse_dynamics_batch)
    forward_dynamics_batch = delegate("dynamics", ClosedFormDynamics.forward_dynamics_batch)
    static_forces_batch = delegate("dynamics", ClosedFormDynamics.static_forces_batch)
    reduced_dynamics_batch = delegate("dynamics", ClosedFormDynamics.reduced_dynamics_batch)

    # -- configuration-level maps ----------------------------------------------------------
    @cached_property
    def platform_frame_id(self) -> int:
        """The Pinocchio id of the platform frame (a robot that resolved its frame itself
        overrides this, so that a name shared by two frames cannot pick another)."""
        return self.model.frame_id(self.platform_frame)

    def twist_from_configuration(self, q: npt.ArrayLike,
                                 v: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """The platform twist (dim,) of a tree state: the selected components of the
        platform frame's velocity ``(v, w)`` (origin velocity and angular velocity, world
        axes; Pinocchio's ``LOCAL_WORLD_ALIGNED``), ``T(q) v``. Needs no inverse
        kinematics, so it is the twist of ``q``'s own working and assembly mode.

        The frame velocity is defined for any tree state: ``q`` need not close the loops
        nor ``v`` keep them (the twist is then that of the platform body in the tree).

        Args:
            q: tree configuration (nq,), its quaternions (free-flyer, ball joints) unit to
                1e-10.
            v: tree velocity (nv,) (Pinocchio conventions).

        Raises:
            InputError: bad shapes, NaN / inf, a quaternion that is not unit (the rotation
                Pinocchio would use is not the one ``q`` means).
        """
        q, v = self.model.check_q(q), self.model.check_v(v)
        model = self.model.model
        if not pin.isNormalized(model, q, 1e-10):
            raise InputError("q", q, "its quaternions are not unit (to 1e-10): normalise "
                             "them (pin.normalize)")
        with self.lock:
            data = self._base_data
            pin.forwardKinematics(model, data, q, v)
            vel = pin.getFrameVelocity(model, data, self.platform_frame_id,
                                       pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
            return np.asarray(vel.vector, dtype=float)[self.pose_layout.components].copy()

    # -- derivatives, linearisation, stiffness (core.platform_derivatives, core.stiffness) --
    @takes_placement
    def inverse_dynamics_derivatives(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
                                     twist_dot: npt.ArrayLike,
                                     wrench: npt.ArrayLike | None = None
                                     ) -> InverseDynamicsDerivatives:
        """Analytic derivatives of the (unbounded) inverse-dynamics actuator forces with
        respect to the pose, the twist, the twist_dot and the wrench (home working mode;
        twist, twist_dot and wrench held in world axes): a
        :class:`~hexapod_pin.core.results.InverseDynamicsDerivatives`, from the one chain
        rule of every robot
        (:func:`~hexapod_pin.core.platform_derivatives.robot_inverse_dynamics_derivatives`:
        the closed form's compiled partials where the robot has them, else the tree's
        forward-dynamics derivatives by the implicit-function theorem; the joint effects
        included).

        Args:
            pose: (dim,) (m, rad).
            twist: (dim,) world axes (m/s, rad/s).
            twist_dot: (dim,) world axes (m/s^2, rad/s^2).
            wrench: (dim,) on the platform, world axes, moment about its origin; None: 0.

        Raises:
            InputError: bad shapes, NaN / inf, redundant actuation, a coordinate with
                Coulomb friction at rest (not differentiable).
            UnreachablePoseError: the pose is out of reach.
            SingularityError: a singular pose.
            SolverError: a solve misses its equations.
        """
        from .platform_derivatives import robot_inverse_dynamics_derivatives
        with self.lock:                     # the route checks its numbers finite itself
            return robot_inverse_dynamics_derivatives(self, pose, twist, twist_dot, wrench)

    @takes_placement
    def forward_dynamics_derivatives(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
                                     actuator_forces: npt.ArrayLike,
                                     wrench: npt.ArrayLike | None = None, *,
                                     branch: Any = None) -> Any:
        """Analytic derivatives of the platform acceleration with respect to the pose, the
        twist, the actuator forces and the wrench (world axes; twist and wrench held in
        world axes): a :class:`~hexapod_pin.core.platform_derivatives.ForwardDynamicsDerivatives`
        from the tree's KKT derivatives
        (:func:`~hexapod_pin.core.platform_derivatives.forward_dynamics_derivatives`, the
        same implementation for every robot; the joint effects included).

        Args:
            pose: (dim,) (m, rad).
            twist: (dim,) world axes (m/s, rad/s).
            actuator_forces: (n_act,) (N, N m).
            wrench: (dim,) on the platform, world axes, moment about its origin; None: 0.
            branch: the working mode (as :meth:`configuration` takes it).

        Raises:
            InputError: bad shapes, NaN / inf, a coordinate with Coulomb friction at rest.
            UnreachablePoseError: the pose is out of reach.
            SingularityError: a singular pose.
            SolverError: a solve misses its equations.
        """
        from .platform_derivatives import forward_dynamics_derivatives
        with self.lock:                     # the route checks its numbers finite itself
            return forward_dynamics_derivatives(self, pose,  # type: ignore[arg-type]
                                                twist, actuator_forces, wrench, branch)

    def forward_dynamics_derivatives_batch(self, poses: npt.ArrayLike, twists: npt.ArrayLike,
                                           actuator_forces: npt.ArrayLike,
                                           wrenches: npt.ArrayLike | None = None, *,
                                           branch: Any = None) -> Any:
        """:meth:`forward_dynamics_derivatives` of N states (rows of (N, dim) and (N, n_act)
        arrays): one :class:`~hexapod_pin.core.platform_derivatives.ForwardDynamicsDerivatives`
        whose arrays carry a leading axis N
        (:func:`~hexapod_pin.core.platform_derivatives.forward_dynamics_derivatives_batch`).

        Raises:
            InputError: bad shapes, NaN / inf, Coulomb friction at rest.
            BatchUnreachablePoseError: a pose out of reach (``index``: its row).
            BatchSingularityError: a singular state (``index``).
            SolverError: a solve misses its equations.
        """
        from .platform_derivatives import forward_dynamics_derivatives_batch
        return self._checked("forward_dynamics_derivatives_batch",
                             forward_dynamics_derivatives_batch, poses, twists,
                             actuator_forces, wrenches, branch)

    @takes_placement
    def linearize(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
                  actuator_forces: npt.ArrayLike, wrench: npt.ArrayLike | None = None, *,
                  branch: Any = None, dt: float | None = None,
                  integrator: str = "rk4") -> Any:
        """The continuous-time linearised model ``dx/dt = A x + B du`` in ``x = (dp,
        dtheta, twist)`` (world axes): a
        :class:`~hexapod_pin.core.platform_derivatives.StateSpaceModel` (``A = [[0, I],
        [d_world, d_twist]]`` at rest, ``B = [[0], [d_actuator_forces]]``). Arguments and
        errors as :meth:`forward_dynamics_derivatives`; with a step ``dt`` (s) it also
        holds the discrete-time ``Ad``, ``Bd`` of one simulation step of ``integrator``
        (:meth:`step_jacobians`; no wrench then: ``simulate`` applies none).

        Raises:
            InputError: see :meth:`forward_dynamics_derivatives` and :meth:`step_jacobians`;
                a ``dt`` with a wrench.
            UnreachablePoseError: see :meth:`forward_dynamics_derivatives`.
            SingularityError: see :meth:`forward_dynamics_derivatives`.
            SolverError: see :meth:`forward_dynamics_derivatives`.
        """
        import dataclasses

        from .platform_derivatives import linearize
        out = self._checked("linearize", linearize, pose, twist, actuator_forces, wrench,
                            branch)
        if dt is None:
            return out
        if wrench is not None:
            raise InputError("wrench", wrench, "the step Jacobians (dt given) are those of "
                             "simulate, which applies no wrench")
        step = self.step_jacobians(pose, twist, actuator_forces, dt, integrator=integrator,
                                   branch=branch)
        return dataclasses.replace(out, ad=step.ad, bd=step.bd, dt=step.dt,
                                   integrator=step.integrator)

    @takes_placement
    def step_jacobians(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
                       actuator_forces: npt.ArrayLike, dt: float, *,
                       integrator: str = "rk4", branch: Any = None) -> Any:
        """The Jacobians ``Ad = d x_{k+1} / d x_k``, ``Bd = d x_{k+1} / d u_k`` of one
        ``simulate`` step (``x = (dp, dtheta, twist)``, world axes; the projection onto
        the closures included), analytic, by the chain rule through the integrator's
        stages: a :class:`~hexapod_pin.core.step_jacobians.StepJacobians`
        (:func:`~hexapod_pin.core.step_jacobians.step_jacobians`).

        Args:
            pose: (dim,) (m, rad).
            twist: (dim,) world axes (m/s, rad/s).
            actuator_forces: (n_act,) held over the step (N, N m).
            dt: the step (s), > 0.
            integrator: "rk4" (default) or "semi_implicit_euler".
            branch: the working mode.

        Raises:
            InputError: bad shapes, NaN / inf, a bad ``dt`` or integrator, Coulomb
                friction (not differentiable).
            UnreachablePoseError: the pose is out of reach.
            SingularityError: a singular pose.
            SolverError: a solve misses its equations.
            AssemblyError: the step's projection does not converge.
        """
        from .step_jacobians import step_jacobians
        return self._checked("step_jacobians", step_jacobians, pose, twist, actuator_forces,
                             dt, integrator, branch)

    @takes_placement
    def cartesian_stiffness(self, pose: npt.ArrayLike, actuator_stiffness: npt.ArrayLike,
                            wrench: npt.ArrayLike | None = None, *, branch: Any = None) -> Any:
        """The Cartesian stiffness ``K_x = J^T K_a J + K_g`` at a static pose (the
        geometric part from the static forces holding gravity and ``wrench``): a
        :class:`~hexapod_pin.core.stiffness.CartesianStiffness` (world tangent ``(dp,
        dtheta)``; :func:`~hexapod_pin.core.stiffness.cartesian_stiffness`).

        Args:
            pose: (dim,) (m, rad).
            actuator_stiffness: scalar or (n_act,) (N/m, N m/rad), >= 0.
            wrench: (dim,) held on the platform; None: gravity only.
            branch: the working mode.

        Raises:
            InputError: bad shapes, NaN / inf, a negative stiffness, Coulomb friction.
            UnreachablePoseError: the pose is out of reach.
            SingularityError: a singular pose.
            SolverError: the routes disagree.
        """
        from .stiffness import cartesian_stiffness
        return self._checked("cartesian_stiffness", cartesian_stiffness, pose,
                             actuator_stiffness, wrench, branch)

    @takes_placement
    def vibration_modes(self, pose: npt.ArrayLike, actuator_stiffness: npt.ArrayLike, *,
                        branch: Any = None) -> Any:
        """Natural frequencies (Hz, ascending) and mode shapes of ``M_x`` and ``K_x`` about
        a static pose under gravity: a :class:`~hexapod_pin.core.stiffness.VibrationModes`
        (:func:`~hexapod_pin.core.stiffness.vibration_modes`).

        Args:
            pose: (dim,) (m, rad).
            actuator_stiffness: scalar or (n_act,) (N/m, N m/rad), >= 0.
            branch: the working mode.

        Raises:
            InputError: see :meth:`cartesian_stiffness`.
            UnreachablePoseError: the pose is out of reach.
            SingularityError: a singular pose or a statically unstable preload.
            SolverError: see :meth:`cartesian_stiffness`.
        """
        from .stiffness import vibration_modes
        return self._checked("vibration_modes", vibration_modes, pose, actuator_stiffness,
                             branch)

    @takes_placement
    def holding_forces(self, pose: npt.ArrayLike, wrench: npt.ArrayLike | None = None, *,
                       branch: Any = None) -> Any:
        """The band of actuator forces (N or N m, joint side) that hold ``pose`` at rest
        when Coulomb friction helps: a :class:`~hexapod_pin.core.holding.HoldingBand`
        (per actuator ``lower`` / ``upper``, the others free, and the frictionless
        ``static`` forces; :func:`~hexapod_pin.core.holding.holding_band`, exact LPs,
        verified).

        Args:
            pose: (dim,) (m, rad).
            wrench: (dim,) ON the platform, world axes, moment about its origin; None:
                gravity only.
            branch: the working mode.

        Raises:
            InputError: bad shapes, NaN / inf.
            UnreachablePoseError: the pose is out of reach.
            SingularityError: a singular pose.
            SolverError: an LP or its verification fails.
        """
        from .holding import holding_band
        with self.lock:
            return holding_band(self, pose, wrench, branch=branch)

    def _checked(self, name: str, function: Any, *args: Any) -> Any:
        """``function(self, *args)`` under the robot's lock, every number checked finite."""
        with self.lock:
            out = function(self, *args)
        return check_finite_result(f"{type(self).__name__}.{name}", out)


def gravity_along(gravity: np.ndarray, axis: int) -> float | None:
    """The magnitude ``g >= 0`` (m/s^2) of a gravity vector (3,) pointing along ``-e_axis``
    (the other components zero to 1e-12 relative), or None for any other direction (the
    closed form of a robot whose vertical is ``axis`` cannot take it)."""
    others = np.delete(gravity, axis)
    if np.abs(others).max() > 1e-12 * max(1.0, float(np.abs(gravity).max())) \
            or gravity[axis] > 0.0:
        return None
    return float(-gravity[axis])
