"""The rail-driven hexapod: geometry + tree model + loop closures + closed forms.

``Hexapod`` ties a :class:`HexapodGeometry` to the generic
:class:`ClosedLoopModel` built from ``urdf/hexapod.urdf.xacro`` and
``urdf/hexapod.loops.yaml``, and adds the hexapod's closed forms (kinematics,
dynamics) as methods. Conventions: see :mod:`hexapod_pin.hexapod.geometry` and
:mod:`hexapod_pin.core.pose`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..core.checks import as_array
from ..core.closed_loop import ClosedLoopModel
from ..core.description import build_model, load_loops, urdf_dir
from ..core.effects import JointEffects
from ..core.robot_api import delegate, takes_placement
from ..core.robot import tree_robot
from ..core.robot_base import RobotBase, gravity_along
from .dynamics import HexapodDynamics
from ..errors import ArgumentTypeError, AssemblyError
from .geometry import HexapodGeometry, hexapod_urdf
from . import kernels
from .kinematics import HexapodKinematics, check_branch
from ..core.pose import rpy_from_rotation

#: closure residual accepted for a closed-form configuration (m), for robots up to 1 m;
#: scaled by the robot's size above (round-off grows with the coordinates)
CLOSED_FORM_TOL = 1e-12


@dataclass(frozen=True)
class HexapodIndices:
    """Where the hexapod's coordinates sit in Pinocchio's ``q`` and ``v``.

    Attributes:
        carriage_q: carriage i's prismatic coordinate in q, shape (6,).
        carriage_v: the same in v, shape (6,).
        u_a_q: first universal-joint angle (about the rail) in q, shape (6,).
        u_a_v: the same in v, shape (6,).
        u_b_q: second universal-joint angle in q, shape (6,).
        u_b_v: the same in v, shape (6,).
        platform_q: slice of the free-flyer (position, quaternion x y z w) in q.
        platform_v: slice of the free-flyer velocity (body frame) in v.
    """

    carriage_q: np.ndarray
    carriage_v: np.ndarray
    u_a_q: np.ndarray
    u_a_v: np.ndarray
    u_b_q: np.ndarray
    u_b_v: np.ndarray
    platform_q: slice
    platform_v: slice


class Hexapod(RobotBase):
    """The rail-driven 6-DoF hexapod: a facade over its components (composition).

    It implements the shared API of every parallel robot
    (:class:`~hexapod_pin.core.robot_api.ParallelRobot`). The kinematics methods are those of
    :class:`~hexapod_pin.hexapod.kinematics.HexapodKinematics` (``robot.kinematics``),
    the dynamics methods those of :class:`~hexapod_pin.hexapod.dynamics.HexapodDynamics`
    (``robot.dynamics``); configurations of the tree are computed here.

    Args:
        geometry: design parameters; default :class:`HexapodGeometry` ().
        effects: the joint and drive effects of the tree
            (:class:`~hexapod_pin.core.effects.JointEffects` of this robot's tree, e.g.
            ``other.effects``); default none (rigid). ``robot.with_effects(armature=...,
            damping=..., ...)`` returns a robot with others; every route includes them (the
            carriages' drives inside the compiled closed form, see
            :mod:`hexapod_pin.core.effects_projection`).

    Raises:
        ArgumentTypeError: ``geometry`` is not a :class:`HexapodGeometry`.
        InputError: ``effects`` is not a record of this tree.

    Attributes:
        geometry: the :class:`HexapodGeometry`.
        model: the :class:`ClosedLoopModel` (tree + closures) built from the geometry.
        indices: where the hexapod's coordinates sit in the tree (:class:`HexapodIndices`).
        pose_dim: 6.
        pose_axes: ``("x", "y", "z", "roll", "pitch", "yaw")``.
        n_actuators: 6.

    Example:
        >>> robot = Hexapod.default()
        >>> q = robot.configuration(robot.home_pose)   # Pinocchio q, closures hold
    """

    pose_dim = 6
    n_actuators = 6
    POSE_AXES = ("x", "y", "z", "roll", "pitch", "yaw")
    #: the module that registers this class's ``simulate(..., backend="compiled")``,
    #: imported by :func:`~hexapod_pin.core.simulate.simulate` on first use
    COMPILED_SIMULATOR = "hexapod_pin.hexapod.compiled_backend"

    def __init__(self, geometry: HexapodGeometry | None = None,
                 effects: JointEffects | None = None) -> None:
        self.geometry = HexapodGeometry() if geometry is None else geometry
        if not isinstance(self.geometry, HexapodGeometry):
            raise ArgumentTypeError("geometry", geometry,
                                    f"expected a HexapodGeometry, got {type(geometry).__name__}")
        xml = hexapod_urdf(self.geometry)
        tree = build_model(xml, source="hexapod.urdf.xacro")
        clm = ClosedLoopModel(tree, load_loops(urdf_dir() / "hexapod.loops.yaml"),
                              name="hexapod", urdf_xml=xml)
        self._assemble(clm if effects is None else clm.with_effects(effects))

    def _with_model(self, model: ClosedLoopModel) -> "Hexapod":
        """This robot (geometry) on ``model``, the same tree with other effects."""
        robot = Hexapod.__new__(Hexapod)
        robot.geometry = self.geometry
        robot._assemble(model)
        return robot

    def _with_gravity(self, model: ClosedLoopModel, gravity: np.ndarray) -> Any:
        """The hexapod with ``geometry.gravity`` = g for a gravity ``(0, 0, -g)``; for any
        other direction (its closed form takes -z only) the tree routes' robot
        (:func:`~hexapod_pin.core.robot.tree_robot`)."""
        magnitude = gravity_along(gravity, 2)
        if magnitude is None:
            return tree_robot(self, model)
        robot = Hexapod.__new__(Hexapod)
        robot.geometry = dataclasses.replace(self.geometry, gravity=magnitude)
        robot._assemble(model)
        return robot

    def _assemble(self, clm: ClosedLoopModel) -> None:
        """The facade and its components on the hexapod's model ``clm``."""
        self._init_facade(clm)
        # the URDF carries no gravity: gravity along -z with the geometry's magnitude
        self.model.model.gravity = pin.Motion(np.array([0.0, 0.0, -self.geometry.gravity,
                                                        0.0, 0.0, 0.0]))
        self.indices = self._indices()
        self.closed_form = kernels.ClosedForm(self.geometry, self.indices, self.model)
        self.kinematics = HexapodKinematics(self.geometry, self.closed_form)
        self.dynamics = HexapodDynamics(self.geometry, self.model, self.indices,
                                        self.closed_form, self.lock,
                                        self.kinematics.singularity)

    # -- kinematics (HexapodKinematics) ----------------------------------------------------
    platform_points_world = delegate("kinematics", HexapodKinematics.platform_points_world)
    platform_joints_world = delegate("kinematics", HexapodKinematics.platform_joints_world)
    inverse_kinematics = delegate("kinematics", HexapodKinematics.inverse_kinematics)
    stroke_violations = delegate("kinematics", HexapodKinematics.stroke_violations)
    check_stroke = delegate("kinematics", HexapodKinematics.check_stroke)
    branch_of = delegate("kinematics", HexapodKinematics.branch_of)
    inverse_kinematics_batch = delegate("kinematics",
                                        HexapodKinematics.inverse_kinematics_batch)
    jacobian_batch = delegate("kinematics", HexapodKinematics.jacobian_batch)
    jacobian = delegate("kinematics", HexapodKinematics.jacobian)
    twist_from_qdot = delegate("kinematics", HexapodKinematics.twist_from_qdot)
    twist_from_actuator_velocities = delegate("kinematics",
                                              HexapodKinematics.twist_from_actuator_velocities)
    jacobian_derivative = delegate("kinematics", HexapodKinematics.jacobian_derivative)
    qddot = delegate("kinematics", HexapodKinematics.qddot)
    leg_motion = delegate("kinematics", HexapodKinematics.leg_motion)
    singularity = delegate("kinematics", HexapodKinematics.singularity)
    forward_kinematics = delegate("kinematics", HexapodKinematics.forward_kinematics)
    assembly_modes = delegate("kinematics", HexapodKinematics.assembly_modes)

    # -- dynamics (HexapodDynamics; energies and batches: RobotBase) -----------------------
    inverse_dynamics = delegate("dynamics", HexapodDynamics.inverse_dynamics)
    forward_dynamics = delegate("dynamics", HexapodDynamics.forward_dynamics)
    static_forces = delegate("dynamics", HexapodDynamics.static_forces)
    reduced_dynamics = delegate("dynamics", HexapodDynamics.reduced_dynamics)
    tree_energies = delegate("dynamics", HexapodDynamics.tree_energies)

    @classmethod
    def default(cls) -> "Hexapod":
        """The hexapod with the default (placeholder) geometry."""
        return cls(HexapodGeometry())

    def _indices(self) -> HexapodIndices:
        m = self.model
        names = [f"carriage_{i}" for i in range(6)]
        ua = [f"u_{i}_a" for i in range(6)]
        ub = [f"u_{i}_b" for i in range(6)]
        qi = lambda js: np.array([m.joint_q_index(j) for j in js])
        vi = lambda js: np.array([m.joint_v_index(j) for j in js])
        pq, pv = m.joint_q_index("platform_joint"), m.joint_v_index("platform_joint")
        return HexapodIndices(qi(names), vi(names), qi(ua), vi(ua), qi(ub), vi(ub),
                              slice(pq, pq + 7), slice(pv, pv + 6))

    # -- home ------------------------------------------------------------------------
    @property
    def home_q(self) -> np.ndarray:
        """Carriage positions at home (m), shape (6,) (the same as :attr:`home_actuators`)."""
        return self.geometry.home_q

    @property
    def home_actuators(self) -> npt.NDArray[np.float64]:
        """Actuator (carriage) positions at home (m), shape (6,)."""
        return self.geometry.home_q

    @property
    def home_pose(self) -> npt.NDArray[np.float64]:
        """Home pose (m, rad), shape (6,): ``geometry.home_pose`` (the level platform at
        ``home_height``; as built, the forward kinematics of ``home_q``)."""
        return self.geometry.home_pose

    # -- pose <-> tree configuration -----------------------------------------------------
    @takes_placement
    def configuration(self, pose: npt.ArrayLike,
                      branch: npt.ArrayLike | None = None) -> npt.NDArray[np.float64]:
        """Pinocchio configuration of the tree for a platform pose (closed form).

        Carriages from the inverse kinematics (stroke limits not checked),
        universal-joint angles from the leg directions (see
        :mod:`hexapod_pin.hexapod.kernels`), the free-flyer from the pose. The second
        universal angle lies in [-pi/2, pi/2].

        Args:
            pose: ``(x, y, z, roll, pitch, yaw)`` (m, rad), shape (6,).
            branch: root choice per carriage, see :meth:`inverse_kinematics`.

        Returns:
            q (nq,) satisfying all 18 closure equations to 1e-12 m (times the robot's size
            in m above 1 m: the largest of leg length, rail and platform radii): checked
            by rebuilding each leg tip from the universal-joint angles, as the tree places
            it.

        Raises:
            InputError: bad shape, NaN / inf, malformed branch.
            UnreachablePoseError: a leg cannot reach.
            AssemblyError: the closed form misses the closures by more than that
                (a leg along its first universal axis).
        """
        cf = self.closed_form
        signs = cf.signs if branch is None else check_branch(branch)
        q = np.empty(self.model.nq)
        with self.lock:
            code = kernels.tree_configuration_unchecked(cf.geo, signs,
                                                        as_array(pose, (6,), "pose"), q,
                                                        cf.scratch.rot, cf.scratch.wk)
            if code != kernels.OK:
                raise cf.error(code)
        err = cf.closure_residual(q)
        g = self.geometry
        if not err <= CLOSED_FORM_TOL * max(1.0, g.leg_length, g.rail_radius, g.platform_radius):
            raise AssemblyError("closed-form configuration misses the closures", err, 0, q)
        return q

    def pose_from_configuration(self, q: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """Platform pose (6,) read from a Pinocchio configuration (nq,)."""
        q = self.model.check_q(q)
        ff = q[self.indices.platform_q]
        rot = pin.Quaternion(ff[6], ff[3], ff[4], ff[5]).normalized().toRotationMatrix()
        return np.concatenate([ff[:3], rpy_from_rotation(rot)])

    def carriage_positions(self, q: npt.ArrayLike) -> np.ndarray:
        """Carriage positions (6,) read from a Pinocchio configuration (nq,)."""
        return self.model.check_q(q)[self.indices.carriage_q].copy()

    def actuator_positions(self, q: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """Actuator (carriage) positions (6,) (m) read from a Pinocchio configuration (nq,)."""
        return self.carriage_positions(q)
