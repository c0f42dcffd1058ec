"""Exception hierarchy of hexapod_pin.

Every exception derives from :class:`HexapodPinError` and carries the offending
values as attributes, so a caller can react to the cause without parsing the
message.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np
import numpy.typing as npt


class HexapodPinError(Exception):
    """Base class of every error raised by hexapod_pin."""


class GeometryError(HexapodPinError, ValueError):
    """A design parameter is invalid (non-positive length or mass, ...).

    Attributes:
        field: name of the offending parameter.
        value: its value.
    """

    def __init__(self, field: str, value: Any, reason: str):
        self.field = field
        self.value = value
        self.reason = reason
        super().__init__(f"invalid geometry parameter {field}={value!r}: {reason}")


class InputError(HexapodPinError, ValueError):
    """A numeric input has the wrong shape, or contains NaN or inf.

    Attributes:
        name: argument name.
        value: the offending value (as given).
    """

    def __init__(self, name: str, value: Any, reason: str):
        self.name = name
        self.value = value
        self.reason = reason
        super().__init__(f"invalid {name}: {reason} (got {_short(value)})")



class ArgumentTypeError(InputError, TypeError):
    """An argument of the wrong type (e.g. a string where a geometry object is expected):
    an :class:`InputError` that is also a ``TypeError``."""

class DescriptionError(HexapodPinError, ValueError):
    """A URDF / xacro or loop-closure description is malformed.

    Attributes:
        source: file or description that is wrong.
        culprit: the element (frame, joint, key) at fault, if known.
    """

    def __init__(self, source: str, reason: str, culprit: str | None = None):
        self.source = source
        self.culprit = culprit
        self.reason = reason
        where = f" [{culprit}]" if culprit is not None else ""
        super().__init__(f"{source}{where}: {reason}")


class MissingFileError(HexapodPinError, FileNotFoundError):
    """A file to read does not exist (a motion, geometry, waypoint, measurement or
    description file): a ``FileNotFoundError`` of the library, not a malformed file.

    Attributes:
        path: the path as given (text).
        what: what the file was to be, e.g. "motion file".
    """

    def __init__(self, path: str, what: str = "file"):
        self.path = str(path)
        self.what = what
        super().__init__(f"{self.path}: {what} not found")
        self.filename = self.path

    def __str__(self) -> str:
        return f"{self.path}: {self.what} not found"


class AssemblyError(HexapodPinError, RuntimeError):
    """The closed chain could not be assembled (no convergence, singular).

    Attributes:
        residual_norm: norm of the closure residual at the last iterate (m / rad).
        iterations: Newton iterations done.
        q: the last iterate (Pinocchio configuration).
    """

    def __init__(self, reason: str, residual_norm: float, iterations: int,
                 q: np.ndarray | None = None):
        self.residual_norm = float(residual_norm)
        self.iterations = int(iterations)
        self.q = None if q is None else np.array(q, copy=True)
        super().__init__(
            f"assembly failed: {reason} (residual {self.residual_norm:.3e} "
            f"after {self.iterations} iterations)"
        )


class UnreachablePoseError(HexapodPinError, ValueError):
    """A leg cannot reach its platform point from its rail (or, for a robot loaded from a
    description, no configuration closes the loops at the pose: ``reason`` says why, and
    ``carriages`` / ``shortfall`` are empty).

    Attributes:
        carriages: indices of the carriages whose leg cannot reach.
        shortfall: for each, how much too short the leg is (m): the distance
            from the platform point to the rail line minus ``leg_length``.
    """

    def __init__(self, carriages: Iterable[int], shortfall: Iterable[float],
                 reason: str | None = None):
        self.carriages = [int(c) for c in carriages]
        self.shortfall = [float(s) for s in shortfall]
        parts = ", ".join(f"carriage {c} short by {s:.6g} m"
                          for c, s in zip(self.carriages, self.shortfall))
        super().__init__(f"pose unreachable: {parts}" if reason is None
                         else f"pose unreachable: {reason}")


class StrokeLimitError(HexapodPinError, ValueError):
    """A carriage leaves its stroke, or two carriages of a rail come too close.

    Attributes:
        q: the carriage positions (m), shape (6,).
        violations: human-readable list of the violated limits.
    """

    def __init__(self, q: npt.ArrayLike, violations: Iterable[str]):
        self.q = np.array(q, dtype=float, copy=True)
        self.violations = list(violations)
        super().__init__("stroke limits violated: " + "; ".join(self.violations))


class SingularityError(HexapodPinError, RuntimeError):
    """A configuration is singular where a regular one is needed.

    The message reads ``singular configuration: <what> (<measure> <value>, below the
    threshold <threshold>)``: the measure is named as it is (a ``|cos|`` is not called a
    singular value).

    Attributes:
        sigma_min: the singularity measure of the matrix at fault (its smallest singular
            value, or the measure ``what`` names, e.g. ``|cos|`` for a type-I singularity).
        what: which matrix (e.g. "workspace Jacobian").
        measure: what ``sigma_min`` is, as the message names it ("smallest singular
            value", "|cos|", "inverse condition number", ...).
        threshold: the value of the measure below which the routes refuse the pose (the
            answer's accuracy could no longer be guaranteed:
            :data:`hexapod_pin.core.measures.ACCURACY`), or None. A closed form that
            failed its own residual check near a singularity reports the pose's measure
            nearer its threshold, which may lie just above it (the message then says
            "near the threshold").
    """

    def __init__(self, what: str, sigma_min: float, threshold: float | None = None,
                 measure: str = "smallest singular value"):
        self.what = what
        self.sigma_min = float(sigma_min)
        self.threshold = None if threshold is None else float(threshold)
        self.measure = measure
        below = "" if threshold is None else \
            f", {'below' if sigma_min < threshold else 'near'} the threshold {threshold:.3g}"
        super().__init__(f"singular configuration: {what} ({measure} {sigma_min:.3e}{below})")


class ActuatorSaturationError(HexapodPinError, RuntimeError):
    """The motion needs more actuator force than the bounds allow.

    Attributes:
        needed: the unbounded actuator forces (N), shape (n_act,).
        limit: the bound (N).
    """

    def __init__(self, needed: npt.ArrayLike, limit: npt.ArrayLike):
        self.needed = np.array(needed, dtype=float, copy=True)
        self.limit = np.array(limit, dtype=float, copy=True)
        over = np.flatnonzero(np.abs(self.needed) > self.limit)
        super().__init__(
            f"actuator saturation: needed forces {np.array2string(self.needed, precision=4)} N "
            f"exceed the bound {np.array2string(self.limit, precision=4)} N "
            f"on actuators {over.tolist()}"
        )


class SolverError(HexapodPinError, RuntimeError):
    """A numerical solver (ProxSuite QP, linear solve) did not succeed.

    Attributes:
        solver: name of the solver.
        status: its status string.
    """

    def __init__(self, solver: str, status: str, detail: str = ""):
        self.solver = solver
        self.status = status
        super().__init__(f"{solver} failed with status {status}"
                         + (f": {detail}" if detail else ""))


class InconsistentMotionError(SolverError):
    """Given motion coordinates cannot keep the closures: ``J_c x = rhs`` has no solution
    with them (the given coordinates over-determine the closures: a singular
    configuration, an unassembled one, or values that contradict each other).

    Attributes:
        what: which motion (e.g. "velocity from actuated").
        residual: the least max-abs closure-row miss that can be reached.
    """

    def __init__(self, what: str, residual: float):
        self.what = what
        self.residual = float(residual)
        super().__init__("closure motion", "inconsistent",
                         f"{what} cannot keep the closures (rows missed by {residual:.3e})")



class NonFiniteResultError(HexapodPinError, ArithmeticError):
    """A computation from finite inputs produced NaN or inf (inputs of a magnitude whose
    products overflow, e.g. a twist of 1e160): raised instead of returning the value.

    Attributes:
        function: the method that produced it.
        field: which part of its result (e.g. "actuator_forces").
    """

    def __init__(self, function: str, field: str):
        self.function = function
        self.field = field
        super().__init__(f"{function}: the returned {field} is not finite (NaN or inf from "
                         "finite inputs: their magnitudes overflow double precision)")

def _short(value: Any, limit: int = 120) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


class BatchActuatorSaturationError(ActuatorSaturationError):
    """A state of a batch needs more actuator force than the bounds allow.

    Attributes:
        index: index of the first offending state.
        needed: as in :class:`ActuatorSaturationError`, for that state.
        limit: as in :class:`ActuatorSaturationError`.
    """

    def __init__(self, index: int, needed: npt.ArrayLike, limit: npt.ArrayLike):
        self.index = int(index)
        super().__init__(needed, limit)
        self.args = (f"state {self.index}: {self.args[0]}",)


class BatchUnreachablePoseError(UnreachablePoseError):
    """A pose of a batch cannot be reached (``index``: the first such state)."""

    def __init__(self, index: int, actuators: Iterable[int], shortfall: Iterable[float]):
        self.index = int(index)
        super().__init__(actuators, shortfall)
        self.args = (f"state {self.index}: {self.args[0]}",)


class BatchSingularityError(SingularityError):
    """A state of a batch is singular (``index``: the first such state)."""

    def __init__(self, index: int, what: str, sigma_min: float,
                 threshold: float | None = None, measure: str = "smallest singular value"):
        self.index = int(index)
        super().__init__(what, sigma_min, threshold, measure)
        self.args = (f"state {self.index}: {self.args[0]}",)


class MotionSampleError(HexapodPinError):
    """A computation failed at one sample of a motion.

    Attributes:
        index: the row (0-based sample index).
        time: its time (s).
        error: the library error raised there (also the ``__cause__``).
    """

    def __init__(self, index: int, time: float, error: Exception):
        self.index = index
        self.time = time
        self.error = error
        super().__init__(f"row {index} (t = {time:g} s): {error}")


class IdentifiabilityError(HexapodPinError, ValueError):
    """Measurements cannot identify the parameters asked for (:mod:`hexapod_pin.calibration`):
    too few of them, or too little variety (e.g. every pose at one orientation).

    Attributes:
        needed: how many independent parameter combinations were asked for.
        rank: how many the data determine (the numerical rank of the scaled
            identification Jacobian).
        combinations: the combinations the data leave undetermined, in words.
    """

    def __init__(self, reason: str, needed: int, rank: int,
                 combinations: Iterable[object] = ()):
        self.needed = int(needed)
        self.rank = int(rank)
        self.combinations = [str(c) for c in combinations]
        detail = "; ".join(self.combinations)
        super().__init__(f"{reason} (rank {self.rank} of {self.needed} needed)"
                         + (f": undetermined {detail}" if detail else ""))


class MissingDependencyError(HexapodPinError, ImportError):
    """An optional dependency is not installed.

    Attributes:
        package: the missing package.
        extra: the hexapod-pin extra that installs it.
    """

    def __init__(self, package: str, extra: str):
        self.package = package
        self.extra = extra
        super().__init__(f"{package} is needed for this: pip install \"hexapod-pin[{extra}]\"")


class InfeasiblePathError(HexapodPinError, ValueError):
    """A path cannot be followed within the limits (:mod:`hexapod_pin.planning`).

    Attributes:
        index: the grid point (0-based) where it fails.
        s: its path parameter (m).
        pose: the platform pose there, shape (dim,).
        reason: what fails (a pose the robot cannot hold statically within its force
            limits, a stroke left, an unreachable pose, a singularity, an end speed that
            cannot be reached, ...).
        actuator: the actuator at fault, or None.
        value: the offending value (units of the limit), or None.
        limit: its bound, or None.
    """

    def __init__(self, index: int, s: float, pose: npt.ArrayLike, reason: str,
                 actuator: int | None = None, value: float | None = None,
                 limit: float | None = None):
        self.index = int(index)
        self.s = float(s)
        self.pose = np.array(pose, dtype=float, copy=True)
        self.reason = reason
        self.actuator = None if actuator is None else int(actuator)
        self.value = None if value is None else float(value)
        self.limit = None if limit is None else float(limit)
        detail = "" if actuator is None else f" (actuator {actuator}"
        if actuator is not None:
            detail += "" if value is None else f": {value:.6g} against the limit {limit:.6g}"
            detail += ")"
        super().__init__(f"path infeasible at grid point {self.index} (s = {self.s:.6g} m, "
                         f"pose {np.array2string(self.pose, precision=4)}): {reason}{detail}")
