"""The planar 3-PRR robot: geometry + tree model + loop closures + closed forms.

:class:`Planar3PRR` implements the API shared by every parallel robot
(:mod:`hexapod_pin.core.robot_api`) by composition: a :class:`PlanarKinematics`, a
:class:`PlanarAssembly` (forward kinematics, assembly modes) and a
:class:`PlanarDynamics`, over one :class:`PlanarWorkspace` (the compiled closed form's
constants and buffers). Conventions: :mod:`hexapod_pin.planar.geometry`.

The tree (``urdf/planar_3prr.urdf.xacro``) is built in 3-D: world -> slider_k
(prismatic) -> link_k_joint (revolute about z) -> link_k, and world -> platform_x
(prismatic, world x) -> platform_y (prismatic, world y) -> platform_theta (revolute about
z) -> platform, so that the platform chain's q and v ARE the pose ``(x, y, theta)`` and
the twist ``(vx, vy, omega)`` (world axes). The loops are closed by 3-D point closures
(``urdf/planar_3prr.loops.yaml``): 9 rows of which the 3 out-of-plane rows are
identically zero; the generic :class:`~hexapod_pin.core.closed_loop.ClosedLoopModel`
reports them (rank 6 of 9, mobility 3) and every tree route tolerates them
(minimum-norm multipliers, zero on the redundant rows).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import numpy.typing as npt

from ..core.closed_loop import ClosedLoopModel
from ..core.effects import JointEffects
from ..core.robot_api import delegate
from ..core.robot import tree_robot
from ..core.robot_base import RobotBase, gravity_along
from ..errors import ArgumentTypeError
from .assembly_modes import PlanarAssembly
from .dynamics import PlanarDynamics
from .geometry import N_ACTUATORS, PlanarGeometry, planar_model, set_gravity
from .kinematics import PlanarKinematics, PlanarWorkspace


class Planar3PRR(RobotBase):
    """The planar 3-PRR robot (see the module docstring).

    Args:
        geometry: design parameters; default :class:`PlanarGeometry` ().
        effects: a :class:`~hexapod_pin.core.effects.JointEffects` record of this tree
            (``other.effects``), or None: rigid. Every route includes it, the sliders'
            drives in the compiled kernels (:mod:`hexapod_pin.core.effects_projection`);
            ``robot.with_effects(...)`` gives the robot with other effects.

    Raises:
        ArgumentTypeError: the geometry is not a :class:`PlanarGeometry`.
        InputError: the effects are a record of another tree.

    Attributes:
        geometry: the :class:`PlanarGeometry`.
        model: the :class:`ClosedLoopModel`.
        indices: where the sliders, links and platform chain sit in ``q`` and ``v``.
        kinematics: the :class:`PlanarKinematics` component.
        assembly: the :class:`PlanarAssembly` component.
        dynamics: the :class:`PlanarDynamics` component.

    Example:
        >>> robot = Planar3PRR.default()
        >>> robot.inverse_kinematics([0.01, -0.02, 0.05])   # slider positions (m)
    """

    pose_dim = 3
    n_actuators = N_ACTUATORS
    #: the pose ``(x, y, theta)`` (m, m, rad), ``theta`` the rotation about the world z axis
    POSE_AXES = ("x", "y", "yaw")

    def __init__(self, geometry: PlanarGeometry | None = None,
                 effects: JointEffects | None = None) -> None:
        self.geometry = PlanarGeometry() if geometry is None else geometry
        if not isinstance(self.geometry, PlanarGeometry):
            raise ArgumentTypeError("geometry", geometry,
                                    f"expected a PlanarGeometry, got {type(geometry).__name__}")
        clm = planar_model(self.geometry)
        if effects is not None:
            clm = clm.with_effects(effects)
            set_gravity(clm, self.geometry)           # the rebuilt model's gravity
        self._init_facade(clm)
        self.workspace = PlanarWorkspace(self.geometry, self.model)
        self.indices = self.workspace.indices
        self.kinematics = PlanarKinematics(self.geometry, self.model, self.workspace)
        self.assembly = PlanarAssembly(self.geometry)
        self.dynamics = PlanarDynamics(self.geometry, self.model, self.workspace, self.lock,
                                       self.kinematics.singularity)

    def _with_model(self, model: ClosedLoopModel) -> "Planar3PRR":
        """This robot rebuilt from its geometry with the effects of ``model`` (the same
        tree; a planar robot builds in milliseconds)."""
        return Planar3PRR(self.geometry, effects=model.effects)

    def _with_gravity(self, model: ClosedLoopModel, gravity: np.ndarray) -> Any:
        """The planar robot with ``geometry.gravity`` = g for a gravity ``(0, -g, 0)``; for
        any other direction (its closed form takes -y only) the tree routes' robot
        (:func:`~hexapod_pin.core.robot.tree_robot`)."""
        magnitude = gravity_along(gravity, 1)
        if magnitude is None:
            return tree_robot(self, model)
        return Planar3PRR(dataclasses.replace(self.geometry, gravity=magnitude),
                          effects=model.effects)

    @classmethod
    def default(cls) -> "Planar3PRR":
        """The planar robot with the default geometry."""
        return cls(PlanarGeometry())

    # -- home ---------------------------------------------------------------------------------
    @property
    def home_pose(self) -> npt.NDArray[np.float64]:
        """Home pose (0, 0, 0) (m, m, rad), shape (3,)."""
        return self.geometry.home_pose

    @property
    def home_actuators(self) -> npt.NDArray[np.float64]:
        """Slider positions at home (m), shape (3,)."""
        return self.geometry.home_actuators

    # -- configurations (PlanarKinematics) --------------------------------------------------
    configuration = delegate("kinematics", PlanarKinematics.configuration)
    pose_from_configuration = delegate("kinematics", PlanarKinematics.pose_from_configuration)
    actuator_positions = delegate("kinematics", PlanarKinematics.actuator_positions)
    velocity = delegate("kinematics", PlanarKinematics.velocity)
    acceleration = delegate("kinematics", PlanarKinematics.acceleration)
    platform_points_world = delegate("kinematics", PlanarKinematics.platform_points_world)
    slider_points = delegate("kinematics", PlanarKinematics.slider_points)
    link_vectors = delegate("kinematics", PlanarKinematics.link_vectors)
    branch_of = delegate("kinematics", PlanarKinematics.branch_of)
    stroke_violations = delegate("kinematics", PlanarKinematics.stroke_violations)
    check_stroke = delegate("kinematics", PlanarKinematics.check_stroke)

    # -- kinematics (PlanarKinematics, PlanarAssembly) -----------------------------------------
    inverse_kinematics = delegate("kinematics", PlanarKinematics.inverse_kinematics)
    forward_kinematics = delegate("assembly", PlanarAssembly.forward_kinematics)
    assembly_modes = delegate("assembly", PlanarAssembly.assembly_modes)
    assembly_polynomial = delegate("assembly", PlanarAssembly.assembly_polynomial)
    jacobian = delegate("kinematics", PlanarKinematics.jacobian)
    twist_from_actuator_velocities = delegate("kinematics",
                                              PlanarKinematics.twist_from_actuator_velocities)
    jacobian_derivative = delegate("kinematics", PlanarKinematics.jacobian_derivative)
    singularity = delegate("kinematics", PlanarKinematics.singularity)
    inverse_kinematics_batch = delegate("kinematics", PlanarKinematics.inverse_kinematics_batch)
    jacobian_batch = delegate("kinematics", PlanarKinematics.jacobian_batch)

    # -- dynamics (PlanarDynamics; energies and batches: RobotBase) ------------------------------
    inverse_dynamics = delegate("dynamics", PlanarDynamics.inverse_dynamics)
    forward_dynamics = delegate("dynamics", PlanarDynamics.forward_dynamics)
    static_forces = delegate("dynamics", PlanarDynamics.static_forces)
    reduced_dynamics = delegate("dynamics", PlanarDynamics.reduced_dynamics)
