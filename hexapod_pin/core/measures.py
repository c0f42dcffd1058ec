"""The singularity measures of every parallel robot: one definition, used everywhere.

Every route, CLI command and plot that reports a condition number or a distance to a
singularity calls these functions (see :class:`~hexapod_pin.core.results.SingularityMeasures`
for the definitions and their units).
"""

from __future__ import annotations

import math

import numpy as np

from .results import SingularityMeasures

#: the relative accuracy every answer of the dynamics and kinematics routes keeps: near a
#: singularity the round trips (inverse dynamics -> forward dynamics, forward -> inverse,
#: ``J twist`` -> twist) lose accuracy with the conditioning of the pose, and the routes
#: raise :class:`~hexapod_pin.errors.SingularityError` before they lose more than this
#: (the thresholds below are set from measured walks toward singular poses of both robots;
#: docs/conventions.md, "Accuracy near singularities")
ACCURACY = 1e-6
#: a pose is type-I singular for every route of every robot when the smallest ``|cos|``
#: between a chain's last link and its actuator direction is below this. The round-trip
#: error grows like ``u |twist|^2 / |cos|^4`` at a moving platform (``u`` the unit
#: round-off): measured 1.2e-7 at ``|cos|`` = 2e-3 on the hexapod (0.1 m/s, 0.5 rad/s) and
#: 3e-8 on the 3-PRR, 5e-5 and 7e-7 at ``|cos|`` = 6e-4 / 8e-4; 5e-7 at 0.3 m/s and
#: 1.5 rad/s (the speeds the guarantee covers), 1e-5 at 1 m/s and 5 rad/s
TYPE_I_TOL = 2e-3
#: a pose is type-II singular for every route of every robot when
#: ``sigma_min(A_hat) < TYPE_II_TOL`` (``A_hat``: :func:`closure_matrix_hat`). The round-trip
#: error grows like ``5e-15 / sigma_min(A_hat)``: measured at most 4e-7 at 1e-8 on both robots
TYPE_II_TOL = 1e-8


def condition_number(singular_values: np.ndarray | None) -> float:
    """``sigma_max / sigma_min`` from singular values in descending order (last axis).

    ``inf`` where ``sigma_min == 0`` or the values are None (a type-I singularity).
    Works on one set (returns a float) or a stack (returns an array).
    """
    if singular_values is None:
        return math.inf
    sv = np.asarray(singular_values, dtype=float)
    top, low = sv[..., 0], sv[..., -1]
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.where(low > 0.0, top / np.where(low > 0.0, low, 1.0), np.inf)
    return float(out) if out.ndim == 0 else out


def closure_matrix_hat(directions: np.ndarray, moments: np.ndarray,
                       characteristic_length: float) -> np.ndarray:
    """The dimensionless closure matrix ``A_hat`` with rows ``[e_i, m_i / length]``.

    Args:
        directions: unit directions ``e_i`` of each chain's last link, (..., n, d).
        moments: ``r_i x e_i`` (..., n, 3) in space, (..., n) or (..., n, 1) in the plane.
        characteristic_length: the length dividing the angular columns (m), > 0.
    """
    mom = np.asarray(moments, dtype=float)
    if mom.ndim == np.ndim(directions) - 1:
        mom = mom[..., None]
    return np.concatenate([np.asarray(directions, dtype=float),
                           mom / characteristic_length], axis=-1)


def singularity_measures(jacobian: np.ndarray | None, cosines: np.ndarray,
                         a_hat: np.ndarray, characteristic_length: float
                         ) -> SingularityMeasures:
    """Assemble :class:`SingularityMeasures` of one pose.

    Args:
        jacobian: ``J`` (n_act, dim), or None at a type-I singularity.
        cosines: ``|cos|`` between each chain's last link and its actuator direction (n_act,).
        a_hat: :func:`closure_matrix_hat` of the pose (n, dim).
        characteristic_length: the length used in ``a_hat`` (m).
    """
    cosines = np.abs(np.asarray(cosines, dtype=float))
    worst = int(np.argmin(cosines))
    sv_a = np.linalg.svd(a_hat, compute_uv=False)
    sv_j = None if jacobian is None else np.linalg.svd(jacobian, compute_uv=False)
    return SingularityMeasures(sv_j, condition_number(sv_j), float(cosines[worst]), worst,
                               float(sv_a[-1]), sv_a, float(characteristic_length),
                               TYPE_I_TOL, TYPE_II_TOL)
