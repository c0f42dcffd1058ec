"""The symmetric three-rail layout shared by the rail-driven robots (hexapod, planar 3-PRR).

Rail ``k`` (k = 0, 1, 2) sits at angle ``a_k = 90 deg + 120 deg k`` about the world z axis:
its midpoint is ``radius (cos a_k, sin a_k)`` and its direction ``u_k = (-sin a_k, cos a_k)``
(tangent to the circle, counter-clockwise); the platform's joints sit at the same angles on
a circle of the platform radius. In space the points and directions get ``z = 0``.
"""

from __future__ import annotations

import numpy as np

N_RAILS = 3


def rail_angles() -> np.ndarray:
    """Angles ``a_k = 90 deg + 120 deg k`` of the three rails (rad), shape (3,)."""
    return np.pi / 2 + 2 * np.pi / 3 * np.arange(N_RAILS)


def points_on_circle(radius: float, dim: int) -> np.ndarray:
    """``radius (cos a_k, sin a_k[, 0])`` for the three rail angles (m), shape (3, dim)."""
    a = rail_angles()
    cols = [np.cos(a), np.sin(a)] + [np.zeros(N_RAILS)] * (dim - 2)
    return radius * np.stack(cols, axis=1)


def rail_directions(dim: int) -> np.ndarray:
    """Unit rail directions ``u_k = (-sin a_k, cos a_k[, 0])``, shape (3, dim)."""
    a = rail_angles()
    cols = [-np.sin(a), np.cos(a)] + [np.zeros(N_RAILS)] * (dim - 2)
    return np.stack(cols, axis=1)
