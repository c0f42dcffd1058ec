"""Choice of measurement poses: maximise an observability index of the identification.

The index is computed on the scaled identification Jacobian ``J_s`` (:mod:`.model`,
columns of the base parameter set, scaled per mm / mrad, :mod:`.identifiability`) that
exact measurements at the candidate poses would give on the nominal model. With ``m``
rows, ``n`` base parameters and singular values ``sigma_1 >= ... >= sigma_n``:

* ``"D"`` (D-optimality): ``log det(J_s^T J_s) = 2 sum log sigma_i``;
* ``"O1"`` (Borm and Menq): ``(sigma_1 ... sigma_n)^(1/n) / sqrt(m)``.

For a fixed number of poses the two rank sets of poses the same way (O1 is a monotone
function of D), so they choose the same poses; O1 is scale-free in the number of rows
and is what is reported to compare sets of different sizes. Both grow as the
determinant of the information matrix, i.e. as the volume of the confidence ellipsoid
of the parameters shrinks.

Methods: ``"greedy"`` adds the candidate that increases ``log det(A + eps I)`` most
(``A`` the information matrix so far, ``eps`` a tiny regularisation so the first picks
are ranked), by the determinant lemma ``det(A + J_k^T J_k) = det(A) det(I + J_k A^-1
J_k^T)``; ``"exchange"`` (Fedorov) starts from the greedy set and swaps a chosen pose for
a candidate while the index grows.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ..core.checks import as_array, count
from ..core.pose import rotation_from_rpy, rpy_from_rotation
from ..errors import IdentifiabilityError, InputError
from ..hexapod.robot import Hexapod
from .identifiability import RCOND
from .identify import base_set
from .model import PointModel, measured_poses, platform_from_measured
from .parameters import DEFAULT_IDENTIFY, N_PARAMETERS, ParameterModel, parameter_indices
from .problem import Measurements, Problem
from .registration import register_instrument

CRITERIA = ("O1", "D")
METHODS = ("greedy", "exchange")
#: regularisation of the information matrix, relative to its mean diagonal
REGULARISATION = 1e-9


@dataclass(frozen=True)
class PoseSelection:
    """Chosen measurement poses.

    Attributes:
        indices: indices into the candidates (n,), in the order chosen.
        poses: the chosen world poses (n, 6) (m, rad).
        criterion: ``"O1"`` or ``"D"``.
        value: the criterion's value for the chosen set.
        o1: the O1 index of the chosen set (dimensionless, per mm / mrad).
        log_det: ``log det`` of the scaled information matrix of the chosen set.
        swaps: exchanges made (0 for greedy).
    """

    indices: np.ndarray
    poses: np.ndarray
    criterion: str
    value: float
    o1: float
    log_det: float
    swaps: int


def observability(blocks: np.ndarray) -> tuple[float, float]:
    """``(O1, log det)`` of stacked scaled Jacobian blocks (k, r, n); ``(0, -inf)`` when
    rank deficient."""
    jac = blocks.reshape(-1, blocks.shape[-1])
    sigma = np.linalg.svd(jac, compute_uv=False)
    if sigma.size < jac.shape[1] or not sigma[-1] > RCOND * sigma[0]:
        return 0.0, -np.inf
    logs = np.log(sigma)
    return float(np.exp(logs.mean()) / np.sqrt(jac.shape[0])), float(2.0 * logs.sum())


def candidate_blocks(robot: Hexapod, candidates: np.ndarray,
                     identify: Sequence[str] | str = DEFAULT_IDENTIFY,
                     instrument: npt.ArrayLike | None = None, target: npt.ArrayLike | None = None,
                     target_points: npt.ArrayLike | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Scaled Jacobian blocks of the base set at each candidate, (C, r, n), and the mask
    (len(candidates),) of the candidates kept (reachable, within the strokes)."""
    if not isinstance(robot, Hexapod):
        raise InputError("robot", type(robot).__name__, "expected a Hexapod")
    params = ParameterModel(robot.geometry.chain_geometry, instrument, target)
    columns = parameter_indices(identify)
    kind = "poses" if target_points is None else "points"
    tp = None if target_points is None else as_array(target_points, (3,), "target_points",
                                                     batch=True)
    if tp is not None and not 1 <= len(tp) <= 3:      # as calibrate takes them
        raise InputError("target_points", target_points, f"one to three points (M, 3), got "
                                                         f"{len(tp)}")
    base, _ = base_set(robot, params, columns, kind, tp, RCOND)
    batch = robot.inverse_kinematics_batch(candidates)
    world, q = candidates[batch.ok], batch.actuator_positions[batch.ok]
    frames = params.frames(np.zeros(N_PARAMETERS))
    rot = rotation_from_rpy(world[:, 3:])
    if tp is None:
        data = Measurements(q, poses=measured_poses(rot, world[:, :3], frames))
    else:
        model = PointModel(params, np.zeros((len(world),) + tp.shape), tp, q, world)
        data = Measurements(q, points=model.predicted(np.zeros(N_PARAMETERS), world)[0],
                            target_points=tp)
    _, jac = Problem(params, data, world).evaluate(np.zeros(N_PARAMETERS))
    scaled = (jac * params.scales)[:, base]
    return scaled.reshape(len(world), -1, base.size), batch.ok


def _gains(blocks: np.ndarray, info: np.ndarray) -> np.ndarray:
    """``log det(I + J_k info^-1 J_k^T)`` for every block (C,)."""
    inv = np.linalg.inv(info)
    inner = (blocks @ inv) @ np.swapaxes(blocks, 1, 2)
    inner += np.eye(blocks.shape[1])
    return np.linalg.slogdet(inner)[1]


def select_poses(robot: Hexapod, candidates: npt.ArrayLike, n: int, *, criterion: str = "O1",
                 method: str = "greedy", identify: Sequence[str] | str = DEFAULT_IDENTIFY,
                 instrument: npt.ArrayLike | None = None, target: npt.ArrayLike | None = None,
                 target_points: npt.ArrayLike | None = None,
                 max_rounds: int = 20) -> PoseSelection:
    """Choose ``n`` measurement poses among ``candidates`` (see the module doc).

    Args:
        robot: the nominal robot.
        candidates: world platform poses (C, 6) (m, rad); those out of reach or stroke are
            skipped.
        n: poses to choose.
        criterion: ``"O1"`` or ``"D"``.
        method: ``"greedy"`` or ``"exchange"``.
        identify: the parameter groups to identify, as in
            :func:`~hexapod_pin.calibration.identify.calibrate`.
        instrument: guessed pose of the instrument frame in the world (6,) (m, rad), as in
            :func:`~hexapod_pin.calibration.identify.calibrate`; default the identity.
        target: guessed pose of the target frame in the platform frame (6,) (m, rad), as
            in :func:`~hexapod_pin.calibration.identify.calibrate`; default the identity.
        target_points: (M, 3) target-frame coordinates of measured points (m) for the
            point model, or None for the pose model.
        max_rounds: exchange passes at most.

    Returns:
        :class:`PoseSelection`.

    Raises:
        InputError: unknown criterion or method, malformed candidates, ``n`` not an
            integer in ``[1, number of usable candidates]``, ``target_points`` not one to
            three points (as :func:`~hexapod_pin.calibration.identify.calibrate` takes
            them), or options as in :func:`~hexapod_pin.calibration.identify.calibrate`.
        IdentifiabilityError: the chosen poses do not determine the parameters (their
            information matrix is singular: too few poses for the parameters asked for).
    """
    if not isinstance(criterion, str) or criterion not in CRITERIA:
        raise InputError("criterion", criterion, f"expected one of {CRITERIA}")
    if not isinstance(method, str) or method not in METHODS:
        raise InputError("method", method, f"expected one of {METHODS}")
    n = count(n, "n", minimum=1)
    max_rounds = count(max_rounds, "max_rounds", minimum=1)
    candidates = as_array(candidates, (6,), "candidates", batch=True)
    blocks, ok = candidate_blocks(robot, candidates, identify, instrument, target, target_points)
    kept = np.flatnonzero(ok)
    if not n <= kept.size:
        raise InputError("n", n, f"expected an integer in [1, {kept.size}] (usable candidates)")
    flat = blocks.reshape(-1, blocks.shape[2])
    normal = flat.T @ flat
    eps = REGULARISATION * float(np.trace(normal)) / normal.shape[0] / blocks.shape[0]
    info = eps * np.eye(blocks.shape[2])
    chosen: list[int] = []
    free = np.ones(blocks.shape[0], dtype=bool)
    for _ in range(n):
        gains = np.where(free, _gains(blocks, info), -np.inf)
        best = int(np.argmax(gains))
        chosen.append(best)
        free[best] = False
        info = info + blocks[best].T @ blocks[best]
    swaps = 0
    if method == "exchange":
        for _ in range(max_rounds):
            improved = False
            for pos in range(n):
                out = chosen[pos]
                without = info - blocks[out].T @ blocks[out]
                gains = _gains(blocks, without)
                current = gains[out]
                gains[~free] = -np.inf
                best = int(np.argmax(gains))
                if gains[best] > current + 1e-10:
                    free[out], free[best] = True, False
                    chosen[pos] = best
                    info = without + blocks[best].T @ blocks[best]
                    swaps += 1
                    improved = True
            if not improved:
                break
    o1, log_det = observability(blocks[chosen])
    if not np.isfinite(log_det):
        rank = int(np.linalg.matrix_rank(blocks[chosen].reshape(-1, blocks.shape[2])))
        raise IdentifiabilityError(f"the {n} chosen poses do not determine the parameters "
                                   f"(log det of their information matrix {log_det})",
                                   blocks.shape[2], rank)
    indices = kept[np.array(chosen)]
    return PoseSelection(indices, candidates[indices], criterion,
                         o1 if criterion == "O1" else log_det, o1, log_det, swaps)


def select_measurements(robot: Hexapod, data: Measurements, n: int, *, criterion: str = "O1",
                        method: str = "greedy",
                        identify: Sequence[str] | str = DEFAULT_IDENTIFY,
                        instrument: npt.ArrayLike | None = None,
                        target: npt.ArrayLike | None = None) -> PoseSelection:
    """Choose ``n`` rows of existing measurements (:func:`select_poses` on the world poses
    they correspond to on the nominal model: measured poses through the guessed frames,
    the instrument's by default registered as in
    :func:`~hexapod_pin.calibration.identify.calibrate`, or the forward kinematics of the
    readings for points).

    Returns:
        :class:`PoseSelection` whose ``indices`` are rows of ``data``.

    Raises:
        InputError: as :func:`select_poses`.
        AssemblyError: (points) the nominal forward kinematics of a reading fails.
    """
    if instrument is None:
        instrument = register_instrument(robot, data, target)
    if data.poses is not None:
        params = ParameterModel(robot.geometry.chain_geometry, instrument, target)
        rot, trans = platform_from_measured(params, np.zeros(N_PARAMETERS), data.poses)
        world = np.concatenate([trans, rpy_from_rotation(rot)], axis=1)
    else:
        world = np.array([robot.forward_kinematics(q) for q in data.actuators])
    return select_poses(robot, world, n, criterion=criterion, method=method,
                        identify=identify, instrument=instrument, target=target,
                        target_points=data.target_points)
