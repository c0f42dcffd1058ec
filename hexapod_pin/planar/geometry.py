"""Geometry, inertia and limits of the planar 3-PRR robot, its URDF and its tree model.

Conventions (fixed; see also ``urdf/planar_3prr.urdf.xacro``):

* plane x-y, gravity ``-g`` along y;
* rail k (k = 0, 1, 2) has its midpoint at ``m_k = rail_radius (cos a_k, sin a_k)``,
  ``a_k = 90 deg + 120 deg k``, and its direction ``u_k = (-sin a_k, cos a_k)``;
* slider k sits at ``c_k = m_k + s_k u_k``; ``s_k`` (m) is actuator k's position and
  the actuator force ``tau_k`` (N) acts on slider k along ``+u_k``;
* the platform pose is ``(x, y, theta)`` (m, m, rad): its origin, which is its centre of
  mass, and its rotation about z; platform point k is
  ``P_k = (x, y) + platform_radius (cos(a_k + theta), sin(a_k + theta))``;
* a link of length ``link_length`` joins ``c_k`` to ``P_k`` (``|P_k - c_k| = L`` closes
  loop k); its vector ``n_k = P_k - c_k``;
* inertia: sliders are point masses, links thin uniform rods (``m L^2 / 12`` about their
  centre), the platform a rigid body with ``platform_inertia`` about its origin.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..core import layouts
from ..core.checks import check_signs, validate_scalars
from ..core.closed_loop import ClosedLoopModel
from ..core.description import (build_model, expand_xacro, load_loops, register_xacro_rules,
                                urdf_dir)
from ..errors import GeometryError

#: number of actuators (sliders), chains and loops
N_ACTUATORS = 3
#: the home branch: every slider on the larger root of its quadratic
HOME_BRANCH = np.ones(N_ACTUATORS)
#: every inverse-kinematics branch, home first
ALL_BRANCHES = tuple(np.array(b, dtype=float)
                     for b in itertools.product((1.0, -1.0), repeat=N_ACTUATORS))


def check_branch(branch: npt.ArrayLike) -> np.ndarray:
    """Validate a branch (three values, each +1 or -1); ``None`` -> the home branch.

    Raises:
        InputError: wrong length, or a value other than +1 / -1.
    """
    return check_signs(branch, HOME_BRANCH)


@dataclass(frozen=True)
class PlanarGeometry:
    """Geometry, inertia and limits of the planar 3-PRR robot (SI units).

    Attributes:
        rail_radius: distance from the world origin to each rail midpoint (m).
        platform_radius: distance from the platform origin to each platform joint (m);
            also the characteristic length of the singularity measures.
        link_length: length of each link, slider joint to platform joint (m).
        slider_mass: point mass of each slider (kg).
        link_mass: mass of each link, a thin uniform rod (kg).
        platform_mass: mass of the platform (kg).
        platform_inertia: moment of inertia of the platform about z at its origin
            (its centre of mass) (kg m^2).
        gravity: magnitude of gravity, acting along -y (m/s^2).
        rail_half_length: stroke, ``abs(s_k) <= rail_half_length`` (m).
        max_actuator_force: bound on ``abs(tau_k)`` (N) enforced by every method called
            with ``bounded=True``; ``inf`` (the default: the seed gives no actuator
            rating for the planar model) for none.

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
    def home_actuators(self) -> np.ndarray:
        """Actuator (slider) positions at home (m), shape (3,): all ``+home_slider``."""
        return np.full(N_ACTUATORS, self.home_slider)

    @property
    def home_pose(self) -> np.ndarray:
        """Home pose ``(x, y, theta) = 0`` (m, m, rad), shape (3,)."""
        return np.zeros(3)

    @property
    def rail_midpoints(self) -> np.ndarray:
        """Rail midpoints ``m_k`` in the world (m), shape (3, 2)."""
        return layouts.points_on_circle(self.rail_radius, 2)

    @property
    def rail_directions(self) -> np.ndarray:
        """Unit rail directions ``u_k``, shape (3, 2)."""
        return layouts.rail_directions(2)

    @property
    def platform_points(self) -> np.ndarray:
        """Platform joint points ``p_k`` in the platform frame (m), shape (3, 2)."""
        return layouts.points_on_circle(self.platform_radius, 2)

    def xacro_args(self) -> dict[str, str]:
        """The xacro arguments of ``urdf/planar_3prr.urdf.xacro`` for this geometry
        (an infinite ``max_actuator_force`` is written as 1e30: a URDF effort is finite)."""
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

    def replace(self, **changes: Any) -> "PlanarGeometry":
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)


#: the arguments of urdf/planar_3prr.urdf.xacro checked by the geometry's own rules when
#: the file is expanded with them (core.description.register_xacro_rules)
register_xacro_rules("planar_3prr.urdf.xacro", PlanarGeometry, {
    name: name for name in ("rail_radius", "platform_radius", "link_length",
                            "rail_half_length", "slider_mass", "link_mass", "platform_mass",
                            "platform_inertia", "max_actuator_force")})


def planar_urdf(geometry: PlanarGeometry) -> str:
    """Expanded URDF text of the planar 3-PRR tree for a :class:`PlanarGeometry`."""
    return expand_xacro(urdf_dir() / "planar_3prr.urdf.xacro", geometry.xacro_args())


@dataclass(frozen=True)
class PlanarIndices:
    """Where the planar robot's coordinates sit in Pinocchio's ``q`` and ``v``.

    ``q`` and ``v`` coincide index for index (every joint of the tree is 1-DoF).

    Attributes:
        slider: slider k's prismatic coordinate (actuator k), shape (3,).
        link: link k's revolute angle, measured from ``u_k`` (rad), shape (3,).
        platform: the platform chain ``(x, y, theta)``, shape (3,).
    """

    slider: np.ndarray
    link: np.ndarray
    platform: np.ndarray


def planar_model(geometry: PlanarGeometry) -> ClosedLoopModel:
    """The :class:`ClosedLoopModel` of a geometry: the tree of
    ``urdf/planar_3prr.urdf.xacro``, the closures of ``urdf/planar_3prr.loops.yaml``,
    Pinocchio's gravity set to ``-g`` along y."""
    xml = planar_urdf(geometry)
    tree = build_model(xml, source="planar_3prr.urdf.xacro")
    model = ClosedLoopModel(tree, load_loops(urdf_dir() / "planar_3prr.loops.yaml"),
                            name="planar_3prr", urdf_xml=xml)
    set_gravity(model, geometry)
    return model


def set_gravity(model: ClosedLoopModel, geometry: PlanarGeometry) -> None:
    """Set Pinocchio's gravity of ``model`` to ``-geometry.gravity`` along y (the URDF carries
    none; a model rebuilt with other effects gets it again)."""
    model.model.gravity = pin.Motion(np.array([0.0, -geometry.gravity, 0.0, 0.0, 0.0, 0.0]))
