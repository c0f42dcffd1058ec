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
from .closed_loop import ClosedLoopModel
from .effects import JointEffects
from .robot_api import PoseLayout, pose_layout


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

    def _with_model(self, model: ClosedLoopModel) -> Any:
        """A robot like this one on ``model`` (the same tree with other effects); each
        robot class supplies it."""
        raise NotImplementedError(f"{type(self).__name__} cannot be rebuilt on another model")

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
