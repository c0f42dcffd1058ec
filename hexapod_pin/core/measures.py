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

    ``inf`` where ``sigma_min`` is zero to round-off (at most ``n eps sigma_max``, ``n``
    the number of values) or the values are None (a type-I singularity).
    Works on one set (returns a float) or a stack (returns an array).
    """
    if singular_values is None:
        return math.inf
    sv = np.asarray(singular_values, dtype=float)
    top, low = sv[..., 0], sv[..., -1]
    # a smallest value at round-off of the largest is a zero (LAPACK builds differ in
    # whether an exact rank drop gives 0 or 1e-50: both are a singular matrix)
    zero = low <= top * sv.shape[-1] * np.finfo(float).eps
    with np.errstate(divide="ignore", invalid="ignore"):
        out = np.where(~zero, top / np.where(zero, 1.0, low), np.inf)
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


#: the type-I threshold of a robot loaded from a description
#: (:class:`~hexapod_pin.core.robot.ClosedLoopRobot`), on its own measure: the inverse
#: condition number of the scaled map ``A_hat`` from the closures' null space to the
#: platform twist (:func:`tree_singularity_measures`). The inverse -> forward dynamics
#: round trip loses accuracy like ``type_one^-4``: measured on the five-bar walking to a
#: straight arm (0.06-0.3 m/s), 4e-8 at 1.9e-3, 3e-6 at 6.5e-4, 1e-4 at 2.2e-4
#: (tests/core/test_closed_loop_robot.py)
TREE_TYPE_I_TOL = 2e-3
#: the type-II threshold of such a robot: the inverse condition number of the scaled map
#: ``B_hat`` from the closures' null space to the actuator velocities. The round trip
#: loses accuracy like ``type_two^-2``: measured on the five-bar walking to aligned
#: distal links, 9e-9 at 5.6e-4, 2e-7 at 1.5e-4, 1e-6 at 7.5e-5
TREE_TYPE_II_TOL = 5e-4


def inverse_condition(mat: np.ndarray, columns: int) -> tuple[float, np.ndarray]:
    """``sigma_min / sigma_max`` of ``mat`` as a map from ``R^columns`` (zero singular
    values appended where ``mat`` has fewer rows than columns) and its singular values."""
    sv = np.linalg.svd(mat, compute_uv=False) if mat.size else np.zeros(0)
    full = np.concatenate([sv, np.zeros(max(0, columns - sv.size))])
    if not full.size or full[0] <= 0.0:
        return 0.0, full
    return float(full[-1] / full[0]), full


def tree_singularity_measures(a_hat: np.ndarray, b_hat: np.ndarray,
                              jacobian: np.ndarray | None, characteristic_length: float
                              ) -> SingularityMeasures:
    """The measures of a robot loaded from a description (no closed form).

    With ``N`` an orthonormal basis of the closures' null space in scaled coordinates
    (every angular velocity coordinate times the characteristic length ``L``, so that all
    are m/s), ``A_hat = W T N`` (dim, m) maps a null-space motion to the platform twist
    (its angular rows times ``L``) and ``B_hat`` (n_act, m) to the actuator velocities
    (revolute actuators times ``L``). Both are dimensionless; the measures are their
    inverse condition numbers in [0, 1], as maps from ``R^m`` (a map with fewer rows than
    ``m`` has zero singular values): ``type_one`` for ``A_hat`` (0: the actuators can move
    with the platform held, a type-I singularity), ``type_two`` for ``B_hat`` (0: the
    platform can move with the actuators locked, a type-II singularity).
    ``type_one_actuator`` is the actuator that moves most along the motion that
    ``A_hat`` loses; ``type_two_singular_values`` are those of ``B_hat`` divided by the
    largest (so that ``type_two`` is the last). Thresholds: :data:`TREE_TYPE_I_TOL`, :data:`TREE_TYPE_II_TOL`.

    Args:
        a_hat: (dim, m).
        b_hat: (n_act, m).
        jacobian: ``J = B A^-1`` (n_act, dim), or None where ``A`` is not invertible.
        characteristic_length: ``L`` (m).
    """
    columns = a_hat.shape[1]
    type_one, _ = inverse_condition(a_hat, columns)
    type_two, sv_b = inverse_condition(b_hat, columns)
    if sv_b.size and sv_b[0] > 0.0:
        sv_b = sv_b / sv_b[0]
    worst = 0
    if columns and a_hat.size:
        _, _, vt = np.linalg.svd(a_hat, full_matrices=True)
        worst = int(np.argmax(np.abs(b_hat @ vt[-1])))
    sv_j = None if jacobian is None else np.linalg.svd(jacobian, compute_uv=False)
    return SingularityMeasures(sv_j, condition_number(sv_j), type_one, worst, type_two, sv_b,
                               float(characteristic_length), TREE_TYPE_I_TOL, TREE_TYPE_II_TOL)
