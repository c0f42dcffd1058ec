"""Identifiability of the calibration parameters from a set of measurements.

Everything is judged on the SCALED identification Jacobian ``J_s = J diag(scales)``
(columns per millimetre / milliradian, :mod:`.parameters`), whose numerical rank counts
singular values above ``rcond * sigma_max``.

Two kinds of rank loss are told apart:

* structural: no data of the model can separate some combinations. The instrument frame
  trades with a rigid motion of all six lines (the measurements see the lines only
  relative to the instrument), the target frame with a rigid motion of the six platform
  joints, and, for point measurements, the target frame's rotation about the line (or
  point) through the measured points is not seen. (A sensor zero would also trade with a
  shift of its line point along the line; that coordinate is not a parameter, see
  :mod:`.parameters`.) These are found on a rich reference set of poses
  (:func:`reference_poses`), and the identification keeps a BASE set: the requested
  parameters taken greedily in the order chains, target, instrument, each kept when its
  scaled column is independent of those kept before (relative residual above
  :data:`INDEPENDENCE_TOL`). The others stay at their start values; their deviations are
  absorbed by the base parameters.
* from the data: the measurements given do not determine the base set (too few of them,
  one orientation only, ...): :class:`~hexapod_pin.errors.IdentifiabilityError`, naming
  the undetermined combinations, never a wrong answer.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import IdentifiabilityError
from .parameters import NAMES, PARAMETER_GROUPS, UNITS

#: a column is independent of the kept ones when its residual after projection exceeds
#: this fraction of its norm
INDEPENDENCE_TOL = 1e-6
#: default relative singular-value threshold of the numerical rank
RCOND = 1e-8
#: group order of the base-set selection (earlier groups are kept first)
PREFERENCE = ("line_points", "line_directions", "sensor_offsets", "leg_lengths",
              "platform_joints", "target", "instrument")


@dataclass(frozen=True)
class IdentifiabilityReport:
    """What the measurements can identify.

    Attributes:
        requested: names of the parameters asked for.
        singular_values: singular values of the scaled Jacobian of the requested
            parameters at the measurements, descending (residual units per mm or mrad).
        rank: its numerical rank (``sigma > rcond * sigma_max``).
        base: the base parameter set, identified (names).
        fixed: requested parameters outside the base set, held at their start values.
        unidentifiable: the structural combinations (``len(requested) - len(base)`` of
            them), in words.
        base_singular_values: singular values of the scaled Jacobian of the base set.
        condition_number: ``sigma_max / sigma_min`` of the base set's scaled Jacobian.
        rcond: the relative threshold of the rank.
    """

    requested: tuple[str, ...]
    singular_values: np.ndarray
    rank: int
    base: tuple[str, ...]
    fixed: tuple[str, ...]
    unidentifiable: tuple[str, ...]
    base_singular_values: np.ndarray
    condition_number: float
    rcond: float


def numerical_rank(sigma: np.ndarray, rcond: float) -> int:
    """Number of singular values above ``rcond * max(sigma)``."""
    if sigma.size == 0 or not sigma[0] > 0.0:
        return 0
    return int(np.sum(sigma > rcond * sigma[0]))


def preference_order(columns: np.ndarray) -> np.ndarray:
    """The parameter indices ``columns`` sorted by :data:`PREFERENCE` (stable)."""
    rank = {g: k for k, g in enumerate(PREFERENCE)}
    return np.array(sorted(columns, key=lambda c: (rank[PARAMETER_GROUPS[c]], c)), dtype=int)


def base_columns(scaled: np.ndarray, columns: np.ndarray) -> np.ndarray:
    """The base set among ``columns`` (parameter indices): greedy Gram-Schmidt in
    :func:`preference_order` on the scaled Jacobian ``scaled`` (rows, 66); ascending."""
    kept: list[int] = []
    basis: list[np.ndarray] = []
    for c in preference_order(columns):
        col = scaled[:, c].copy()
        norm = np.linalg.norm(col)
        if norm == 0.0:
            continue
        for b in basis:                 # twice: Gram-Schmidt re-orthogonalised
            col -= (b @ col) * b
        for b in basis:
            col -= (b @ col) * b
        rest = np.linalg.norm(col)
        if rest > INDEPENDENCE_TOL * norm:
            kept.append(int(c))
            basis.append(col / rest)
    return np.array(sorted(kept), dtype=int)


def combination_text(vector: np.ndarray, columns: np.ndarray, terms: int = 4) -> str:
    """A null-space vector over ``columns`` in words: its largest terms, e.g.
    ``0.71 chain2.sensor_offset - 0.70 chain2.leg_length``."""
    vec = vector / np.max(np.abs(vector))
    order = np.argsort(-np.abs(vec))[:terms]
    parts = []
    for k in order:
        if abs(vec[k]) < 1e-3:
            break
        sign = "-" if vec[k] < 0 else "+"
        parts.append(f"{sign} {abs(vec[k]):.2f} {NAMES[columns[k]]} [{UNITS[columns[k]]}]")
    text = " ".join(parts).lstrip("+ ")
    return text + (" ..." if np.sum(np.abs(vec) >= 1e-3) > terms else "")


def structural_text(null: np.ndarray, columns: np.ndarray, points: bool) -> list[str]:
    """The structural null space ``null`` (len(columns), k) in words."""
    groups = np.array([PARAMETER_GROUPS[c] for c in columns])
    out, counted = [], 0
    for frame, partner in (("instrument", ("line_points", "line_directions",
                                           "sensor_offsets")),
                           ("target", ("platform_joints",))):
        rows = groups == frame
        k = int(np.linalg.matrix_rank(null[rows], tol=1e-8)) if rows.any() else 0
        if k == 0:
            continue
        counted += k
        if frame == "instrument":
            out.append(f"{k} combination(s): the instrument frame trades with a rigid motion "
                       "of all six lines (the measurements see the lines only relative to "
                       "the instrument); the instrument frame is held at its guess")
        elif np.isin(groups, partner).any() and not points:
            out.append(f"{k} combination(s): the target frame trades with a rigid motion of "
                       "the six platform joints; the target frame is held at its guess")
        else:
            out.append(f"{k} combination(s): the target frame is seen only through the "
                       "measured points: with the platform joints identified it trades with "
                       "a rigid motion of the joints, and with fewer than three points its "
                       "rotation about the point(s) is not seen; held at its guess")
    if null.shape[1] > counted:
        out.extend(f"undetermined by any data of this model: {combination_text(v, columns)}"
                   for v in _rest(null, groups))
    return out


def _rest(null: np.ndarray, groups: np.ndarray) -> list[np.ndarray]:
    """Null vectors with no instrument or target component."""
    frames = np.isin(groups, ("instrument", "target"))
    if not frames.any():
        return list(null.T)
    # combinations c with null[frames] c = 0
    _, s, vt = np.linalg.svd(null[frames])
    k = int(np.sum(s > 1e-8))
    return list((null @ vt[k:].T).T)


def check_data(scaled: np.ndarray, base: np.ndarray, rcond: float, n_measurements: int,
               poses: np.ndarray | None) -> np.ndarray:
    """Singular values of the base columns of ``scaled`` at the measurements; raise when
    the data do not determine every base parameter.

    Raises:
        IdentifiabilityError: fewer residuals than base parameters plus one (no standard
            error), or a numerical rank below the size of the base set (the combinations
            left undetermined are named; one orientation only is said so).
    """
    sub = scaled[:, base]
    rows, n = sub.shape
    if rows <= n:
        raise IdentifiabilityError(
            f"too few measurements: {n_measurements} give {rows} equations for {n} base "
            "parameters (more equations than parameters are needed for a standard error)",
            n, min(rows, n))
    _, sigma, vt = np.linalg.svd(sub, full_matrices=False)
    rank = numerical_rank(sigma, rcond)
    if rank < n:
        combos = [combination_text(v, base) for v in vt[rank:][:6]]
        reason = "the measurements do not determine every base parameter"
        if poses is not None and np.ptp(poses[:, 3:], axis=0).max() < 1e-9:
            reason += " (every pose has the same orientation)"
        raise IdentifiabilityError(reason, n, rank, combos)
    return sigma


def null_space(scaled: np.ndarray, columns: np.ndarray, rcond: float) -> np.ndarray:
    """Orthonormal null space (len(columns), k) of the scaled columns."""
    sub = scaled[:, columns]
    _, sigma, vt = np.linalg.svd(sub, full_matrices=sub.shape[0] < sub.shape[1])
    rank = numerical_rank(sigma, rcond)
    return vt[rank:].T
