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

from functools import cached_property

import numpy as np

from ..core.results import (BatchForwardDynamics, BatchInverseDynamics, BatchReducedDynamics,
                            Energies, ForwardDynamicsResult, InverseDynamicsDerivatives,
                            InverseDynamicsResult,
                            InverseKinematicsBatch, JacobianBatch, ReducedDynamics,
                            SingularityMeasures)
from .assembly_modes import AssemblyPolynomial, PlanarAssembly
from .derivatives import inverse_dynamics_derivatives
from .dynamics import PlanarDynamics
from .geometry import N_ACTUATORS, PlanarGeometry, planar_model
from .kinematics import PlanarKinematics, PlanarWorkspace


class Planar3PRR:
    """The planar 3-PRR robot (see the module docstring).

    Args:
        geometry: design parameters; default :class:`PlanarGeometry` ().

    Attributes:
        geometry, model (the :class:`ClosedLoopModel`), indices (where the sliders, links
        and platform chain sit in ``q`` and ``v``), kinematics, assembly, dynamics (the
        components the methods delegate to).

    Example:
        >>> robot = Planar3PRR.default()
        >>> robot.inverse_kinematics([0.01, -0.02, 0.05])   # slider positions (m)
    """

    pose_dim = 3
    n_actuators = N_ACTUATORS

    def __init__(self, geometry: PlanarGeometry | None = None):
        self.geometry = PlanarGeometry() if geometry is None else geometry
        if not isinstance(self.geometry, PlanarGeometry):
            raise TypeError(f"geometry must be a PlanarGeometry, got {type(geometry).__name__}")
        self.model = planar_model(self.geometry)
        self.workspace = PlanarWorkspace(self.geometry, self.model)
        self.indices = self.workspace.indices
        self.kinematics = PlanarKinematics(self.geometry, self.model, self.workspace)
        self.assembly = PlanarAssembly(self.geometry)
        self.dynamics = PlanarDynamics(self.geometry, self.model, self.workspace)

    @classmethod
    def default(cls) -> "Planar3PRR":
        """The planar robot with the default geometry."""
        return cls(PlanarGeometry())

    def __repr__(self) -> str:
        return f"Planar3PRR({self.geometry!r})"

    def urdf(self) -> str:
        """The URDF text of the tree (the xacro expanded with this geometry; the loops are
        in ``urdf/planar_3prr.loops.yaml``): ``robot.model.urdf_xml``."""
        return self.model.urdf_xml

    # -- home ---------------------------------------------------------------------------------
    @property
    def home_pose(self) -> np.ndarray:
        """Home pose (0, 0, 0) (m, m, rad), shape (3,)."""
        return self.geometry.home_pose

    @property
    def home_actuators(self) -> np.ndarray:
        """Slider positions at home (m), shape (3,)."""
        return self.geometry.home_actuators

    @cached_property
    def home_configuration(self) -> np.ndarray:
        """Pinocchio configuration at home (nq,), every closure satisfied."""
        return self.configuration(self.home_pose)

    # -- configurations -----------------------------------------------------------------------
    def configuration(self, pose, branch=None) -> np.ndarray:
        """Pinocchio ``q`` (nq = 9,) of the tree for a pose, every closure held to 1e-12 m.
        See :meth:`PlanarKinematics.configuration`."""
        return self.kinematics.configuration(pose, branch)

    def pose_from_configuration(self, q) -> np.ndarray:
        """Platform pose (3,) read from a Pinocchio configuration (nq,)."""
        return self.kinematics.pose_from_configuration(q)

    def actuator_positions(self, q) -> np.ndarray:
        """Slider positions (3,) (m) read from a Pinocchio configuration (nq,)."""
        return self.kinematics.actuator_positions(q)

    def velocity(self, pose, twist, branch=None) -> np.ndarray:
        """Tree velocity ``v`` (nv,) of a platform motion; see
        :meth:`PlanarKinematics.velocity`."""
        return self.kinematics.velocity(pose, twist, branch)

    def acceleration(self, pose, twist, twist_dot, branch=None) -> np.ndarray:
        """Tree acceleration ``a`` (nv,) of a platform motion; see
        :meth:`PlanarKinematics.acceleration`."""
        return self.kinematics.acceleration(pose, twist, twist_dot, branch)

    # -- points --------------------------------------------------------------------------------
    def platform_points_world(self, pose) -> np.ndarray:
        """World positions ``P_k`` of the three platform joints (m), shape (3, 2)."""
        return self.kinematics.platform_points_world(pose)

    def slider_points(self, actuators) -> np.ndarray:
        """World positions ``c_k`` of the slider joints (m), shape (3, 2)."""
        return self.kinematics.slider_points(actuators)

    def link_vectors(self, pose, actuators) -> np.ndarray:
        """Link vectors ``n_k = P_k - c_k`` (m), shape (3, 2)."""
        return self.kinematics.link_vectors(pose, actuators)

    def branch_of(self, pose, actuators) -> np.ndarray:
        """The IK branch (3 signs) that maps ``pose`` to ``actuators``."""
        return self.kinematics.branch_of(pose, actuators)

    def stroke_violations(self, actuators) -> list[str]:
        """Human-readable stroke violations of slider positions (3,)."""
        return self.kinematics.stroke_violations(actuators)

    def check_stroke(self, actuators) -> None:
        """Raise :class:`StrokeLimitError` when slider positions leave the stroke."""
        self.kinematics.check_stroke(actuators)

    # -- kinematics ----------------------------------------------------------------------------
    def inverse_kinematics(self, pose, branch=None, check_limits: bool = True) -> np.ndarray:
        """Slider positions (3,) (m) of a pose (closed form); see
        :meth:`PlanarKinematics.inverse_kinematics`."""
        return self.kinematics.inverse_kinematics(pose, branch, check_limits)

    def forward_kinematics(self, actuators, guess=None) -> np.ndarray:
        """The pose (3,) of the assembly mode that Newton reaches from ``guess`` (default:
        home); see :meth:`PlanarAssembly.forward_kinematics`.

        Raises:
            InputError, AssemblyError.
        """
        return self.assembly.forward_kinematics(
            actuators, self.home_pose if guess is None else guess)

    def assembly_modes(self, actuators) -> np.ndarray:
        """Every real assembly mode, shape (n_modes, 3), ``0 <= n_modes <= 6``, sorted by
        theta; see :meth:`PlanarAssembly.assembly_modes`."""
        return self.assembly.assembly_modes(actuators)

    def assembly_polynomial(self, actuators) -> AssemblyPolynomial:
        """The sextic whose real roots give every assembly mode; see
        :meth:`PlanarAssembly.assembly_polynomial`."""
        return self.assembly.assembly_polynomial(actuators)

    def jacobian(self, pose, branch=None) -> np.ndarray:
        """``J`` (3, 3) with ``actuator velocities = J @ twist``; see
        :meth:`PlanarKinematics.jacobian`."""
        return self.kinematics.jacobian(pose, branch)

    def twist_from_actuator_velocities(self, pose, actuator_velocities,
                                       branch=None) -> np.ndarray:
        """The twist (3,) that gives the slider velocities (``J^-1``)."""
        return self.kinematics.twist_from_actuator_velocities(pose, actuator_velocities,
                                                              branch)

    def jacobian_derivative(self, pose, twist, branch=None) -> np.ndarray:
        """``dJ/dt`` (3, 3) along the motion; see :meth:`PlanarKinematics.jacobian_derivative`."""
        return self.kinematics.jacobian_derivative(pose, twist, branch)

    def singularity(self, pose, branch=None) -> SingularityMeasures:
        """Distances to type-I and type-II singularities (never raises at one);
        characteristic length: the platform radius."""
        return self.kinematics.singularity(pose, branch)

    # -- dynamics ------------------------------------------------------------------------------
    def inverse_dynamics(self, pose, twist, twist_dot, wrench=None, *, branch=None,
                         method: str = "kkt", bounded: bool = True,
                         joint_wrenches: bool = True) -> InverseDynamicsResult:
        """Actuator forces that produce a platform motion; see
        :meth:`PlanarDynamics.inverse_dynamics`."""
        return self.dynamics.inverse_dynamics(pose, twist, twist_dot, wrench, branch=branch,
                                              method=method, bounded=bounded,
                                              joint_wrenches=joint_wrenches)

    def forward_dynamics(self, pose, twist, actuator_forces, wrench=None, *, branch=None,
                         method: str = "nullspace") -> ForwardDynamicsResult:
        """Platform acceleration produced by actuator forces; see
        :meth:`PlanarDynamics.forward_dynamics`."""
        return self.dynamics.forward_dynamics(pose, twist, actuator_forces, wrench,
                                              branch=branch, method=method)

    def static_forces(self, pose, wrench=None, *, branch=None,
                      bounded: bool = True) -> np.ndarray:
        """Actuator forces (3,) holding the platform at rest against gravity + wrench; see
        :meth:`PlanarDynamics.static_forces`."""
        return self.dynamics.static_forces(pose, wrench, branch=branch, bounded=bounded)

    def reduced_dynamics(self, pose, twist, branch=None) -> ReducedDynamics:
        """``J^T tau + wrench = M_x twist_dot + h_x``; see
        :meth:`PlanarDynamics.reduced_dynamics`."""
        return self.dynamics.reduced_dynamics(pose, twist, branch)

    def energies(self, pose, twist, branch=None) -> Energies:
        """Kinetic, potential and total energy of every body (J)."""
        return self.dynamics.energies(pose, twist, branch)

    def inverse_dynamics_derivatives(self, pose, twist, twist_dot,
                                     wrench=None) -> InverseDynamicsDerivatives:
        """Derivatives of the actuator forces w.r.t. pose, twist, twist_dot and wrench
        (analytic); see :mod:`hexapod_pin.planar.derivatives`."""
        return inverse_dynamics_derivatives(self.dynamics, pose, twist, twist_dot, wrench)

    # -- batches -------------------------------------------------------------------------------
    def inverse_kinematics_batch(self, poses, branch=None) -> InverseKinematicsBatch:
        """:meth:`inverse_kinematics` of N poses (N, 3); never raises for a state."""
        return self.kinematics.inverse_kinematics_batch(poses, branch)

    def jacobian_batch(self, poses, branch=None) -> JacobianBatch:
        """:meth:`jacobian` of N poses (N, 3); never raises for a state."""
        return self.kinematics.jacobian_batch(poses, branch)

    def inverse_dynamics_batch(self, poses, twists, twist_dots, wrenches=None, *,
                               bounded: bool = True) -> BatchInverseDynamics:
        """:meth:`inverse_dynamics` of N states; see
        :meth:`PlanarDynamics.inverse_dynamics_batch`."""
        return self.dynamics.inverse_dynamics_batch(poses, twists, twist_dots, wrenches,
                                                    bounded=bounded)

    def forward_dynamics_batch(self, poses, twists, actuator_forces,
                               wrenches=None) -> BatchForwardDynamics:
        """:meth:`forward_dynamics` of N states; see
        :meth:`PlanarDynamics.forward_dynamics_batch`."""
        return self.dynamics.forward_dynamics_batch(poses, twists, actuator_forces, wrenches)

    def static_forces_batch(self, poses, wrenches=None, *,
                            bounded: bool = True) -> np.ndarray:
        """:meth:`static_forces` of N poses: (N, 3) forces (N)."""
        return self.dynamics.static_forces_batch(poses, wrenches, bounded=bounded)

    def reduced_dynamics_batch(self, poses, twists) -> BatchReducedDynamics:
        """:meth:`reduced_dynamics` of N states."""
        return self.dynamics.reduced_dynamics_batch(poses, twists)
