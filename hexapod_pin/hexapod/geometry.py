"""Design parameters of the rail-driven hexapod (SI units, validated).

The default numbers are documented placeholders: the dimensions of the real
Quanser 6-DoF Hexapod are not public. Every number is a parameter.

Conventions (world frame z up, rails in the plane z = 0):

* rail k (k = 0, 1, 2) has its midpoint at ``m_k = rail_radius (cos a_k, sin a_k, 0)``
  with ``a_k = 90 deg + 120 deg k`` and its direction ``u_k = (-sin a_k, cos a_k, 0)``;
* carriage i rides on rail ``k = i // 2`` at ``c_i = m_k + q_i u_k``;
* the platform point of rail k is ``p_k = platform_radius (cos a_k, sin a_k, 0)``
  in the platform frame, whose origin is the platform's centre of mass.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from ..core import layouts
from ..core.checks import validate_scalars
from ..core.description import expand_xacro, urdf_dir
from ..errors import GeometryError

N_RAILS = 3
N_CARRIAGES = 6


@dataclass(frozen=True)
class HexapodGeometry:
    """Geometry, inertia and limits of the hexapod (SI units).

    Attributes:
        rail_radius: distance from the world origin to each rail midpoint (m).
        platform_radius: distance from the platform origin to each spherical
            joint, in the platform plane (m).
        leg_length: length of each leg, universal joint to spherical joint (m).
        carriage_home: ``abs(q_i)`` at home (m): even carriages at
            ``-carriage_home``, odd ones at ``+carriage_home``.
        rail_half_length: stroke, ``abs(q_i) <= rail_half_length`` (m).
        carriage_min_gap: ``q_{2k+1} - q_{2k} >= carriage_min_gap`` (m).
        carriage_mass: point mass of each carriage (kg).
        leg_mass: mass of each leg, a thin uniform rod (kg).
        platform_mass: mass of the platform (kg).
        platform_inertia: principal moments of inertia of the platform about
            its frame axes at its centre of mass (kg m^2), three values.
        gravity: magnitude of gravity, acting along -z (m/s^2).
        max_actuator_force: bound on ``abs(tau_i)`` (N); ``inf`` for none.

    Raises:
        GeometryError: on a non-finite, non-positive or inconsistent value,
            naming the field and the value.
    """

    rail_radius: float = 0.35
    platform_radius: float = 0.12
    leg_length: float = 0.45
    carriage_home: float = 0.15
    rail_half_length: float = 0.30
    carriage_min_gap: float = 0.02
    carriage_mass: float = 0.5
    leg_mass: float = 0.3
    platform_mass: float = 1.5
    platform_inertia: tuple[float, float, float] = field(default=(0.004, 0.004, 0.008))
    gravity: float = 9.81
    max_actuator_force: float = 100.0

    def __post_init__(self) -> None:
        validate_scalars(self, skip=("platform_inertia",),
                         positive=("rail_radius", "platform_radius", "leg_length",
                                   "carriage_home", "rail_half_length", "carriage_mass",
                                   "leg_mass", "platform_mass", "max_actuator_force"),
                         non_negative=("carriage_min_gap", "gravity"))
        self._validate_inertia()
        self._validate_home()

    def _validate_inertia(self) -> None:
        try:
            inertia = tuple(float(v) for v in self.platform_inertia)
        except (TypeError, ValueError):
            raise GeometryError("platform_inertia", self.platform_inertia,
                                "must be three real numbers") from None
        if len(inertia) != 3 or not all(math.isfinite(v) for v in inertia):
            raise GeometryError("platform_inertia", self.platform_inertia,
                                "must be three finite numbers")
        if min(inertia) <= 0.0:
            raise GeometryError("platform_inertia", inertia,
                                "principal moments must be > 0 (positive definite)")
        a, b, c = inertia
        tol = 1e-12 * (a + b + c)
        if a + b < c - tol or b + c < a - tol or a + c < b - tol:
            raise GeometryError("platform_inertia", inertia,
                                "violates the triangle inequality of a physical body")
        object.__setattr__(self, "platform_inertia", inertia)

    def _validate_home(self) -> None:
        if self.carriage_home > self.rail_half_length:
            raise GeometryError("carriage_home", self.carriage_home,
                                f"outside the stroke rail_half_length={self.rail_half_length}")
        if 2.0 * self.carriage_home < self.carriage_min_gap:
            raise GeometryError("carriage_home", self.carriage_home,
                                f"home gap {2 * self.carriage_home} < carriage_min_gap="
                                f"{self.carriage_min_gap}")
        if self.home_height_squared <= 0.0:
            raise GeometryError(
                "leg_length", self.leg_length,
                "home cannot be assembled: leg_length^2 must exceed "
                "(rail_radius - platform_radius)^2 + carriage_home^2 = "
                f"{self.leg_length ** 2 - self.home_height_squared:.6g}")

    @property
    def home_height_squared(self) -> float:
        """Square of the home platform height (m^2); positive when home assembles."""
        radial = self.rail_radius - self.platform_radius
        return self.leg_length ** 2 - radial ** 2 - self.carriage_home ** 2

    @property
    def home_height(self) -> float:
        """Height z of the platform origin at home (m), about 0.3565 for the defaults."""
        return math.sqrt(self.home_height_squared)

    @property
    def home_q(self) -> np.ndarray:
        """Carriage positions at home (m), shape (6,): ``-h`` even, ``+h`` odd."""
        return np.tile([-self.carriage_home, self.carriage_home], N_RAILS)

    @property
    def home_pose(self) -> np.ndarray:
        """Home pose ``(x, y, z, roll, pitch, yaw)`` (m, rad), shape (6,)."""
        return np.array([0.0, 0.0, self.home_height, 0.0, 0.0, 0.0])

    @property
    def rail_midpoints(self) -> np.ndarray:
        """Rail midpoints ``m_k`` in the world (m), shape (3, 3)."""
        return layouts.points_on_circle(self.rail_radius, 3)

    @property
    def rail_directions(self) -> np.ndarray:
        """Unit rail directions ``u_k`` in the world, shape (3, 3)."""
        return layouts.rail_directions(3)

    @property
    def platform_points(self) -> np.ndarray:
        """Spherical-joint points ``p_k`` in the platform frame (m), shape (3, 3)."""
        return layouts.points_on_circle(self.platform_radius, 3)

    def xacro_args(self) -> dict[str, str]:
        """The xacro arguments of ``urdf/hexapod.urdf.xacro`` for this geometry."""
        ixx, iyy, izz = self.platform_inertia
        values = {
            "rail_radius": self.rail_radius,
            "platform_radius": self.platform_radius,
            "leg_length": self.leg_length,
            "rail_half_length": self.rail_half_length,
            "carriage_mass": self.carriage_mass,
            "leg_mass": self.leg_mass,
            "platform_mass": self.platform_mass,
            "platform_ixx": ixx,
            "platform_iyy": iyy,
            "platform_izz": izz,
            "max_actuator_force": self.max_actuator_force
            if math.isfinite(self.max_actuator_force) else 1e30,
        }
        return {k: repr(float(v)) for k, v in values.items()}

    def replace(self, **changes) -> "HexapodGeometry":
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)


def hexapod_urdf(geometry: HexapodGeometry) -> str:
    """Expanded URDF text of the hexapod tree for a :class:`HexapodGeometry`."""
    return expand_xacro(urdf_dir() / "hexapod.urdf.xacro", geometry.xacro_args())
