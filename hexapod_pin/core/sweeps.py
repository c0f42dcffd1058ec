"""Design sweeps of any parallel robot: workspace summaries over a grid of design parameters.

A sweep builds one robot per design with a factory, ``make_robot(params) -> robot`` (any
:class:`~hexapod_pin.core.robot_api.ParallelRobot`: :class:`GeometryFactory` for a robot
made from a geometry record, e.g. ``GeometryFactory(Planar3PRR, PlanarGeometry())``, or
any function, e.g. one that loads a description written for the design), samples a box of
poses around the robot's home pose over chosen pose axes (:class:`SweepSettings`; the
same random samples for every design, from ``seed``) and summarises them with
:mod:`~hexapod_pin.core.workspace_maps`, one row per design:

* ``reachable_volume``: the volume of the ``ok`` region (reachable, within the strokes,
  regular) in the box, in the product of the sampled axes' units (m^3 for x, y, z;
  m^2 rad for x, y, yaw), with its binomial standard error ``reachable_volume_se``;
* ``well_conditioned_volume`` (and ``_se``): the part where ``cond(J) <= max_condition``
  (``J`` unscaled: m and rad columns);
* ``median_condition``: the median ``cond(J)`` over the ``ok`` samples;
* ``median_payload_kg``, ``min_payload_kg``: the largest mass (kg) at the platform origin
  that the actuators hold (:func:`~hexapod_pin.core.workspace_maps.force_capability`
  along :func:`gravity_wrench`, the weight of 1 kg in the robot's wrench selection) over
  the first ``payload_samples`` ``ok`` samples; ``inf`` where no actuator bound limits it,
  None where gravity has no component in the wrench selection (a pose of horizontal axes
  only) or no sample is ``ok``.

A design whose robot cannot be built (the factory raises a library error other than
:class:`~hexapod_pin.errors.ArgumentTypeError`: a :class:`~hexapod_pin.errors.GeometryError`,
a :class:`~hexapod_pin.errors.DescriptionError`, ...) gives a row with ``valid=False``, the
message in ``error`` and None numbers; bad input (an unknown parameter, settings that do
not fit the robot) raises.

The designs are evaluated independently, serially or on a Dask cluster
(``dask.distributed``: a local cluster by default, or the scheduler address of a running
one): the two give identical tables, the per-design function being the same and
deterministic. Needs the ``sweep`` extra (``pip install hexapod-pin[sweep]``:
dask[distributed], pandas). Below :data:`DASK_MIN_DESIGNS` designs a sweep runs serially
by default. A local Dask cluster starts worker processes that re-import the calling
script: in a script, call :func:`design_sweep` under ``if __name__ == "__main__":``, and
give a factory the workers can unpickle (a module-level function, a
:class:`GeometryFactory`, or a lambda: Dask pickles with cloudpickle).
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from ..errors import ArgumentTypeError, HexapodPinError, InputError, MissingDependencyError
from . import workspace_maps
from .checks import count, real_number
from .platform_map import POSE_AXES
from .robot_api import ParallelRobot, pose_layout

if TYPE_CHECKING:    # pandas is optional (extra ``sweep``)
    import pandas as pd

DASK_MIN_DESIGNS = 100
"""Fewest designs for which ``use_dask=None`` starts a local Dask cluster (a local cluster
costs a few seconds to start; a hexapod design of the default settings ~0.1 s)."""

#: half side (m) of the default box on each position axis of the robot (angles fixed)
DEFAULT_HALF_EXTENT = 0.1

#: columns of the summary table, in order (after the swept parameters; a sweep's own
#: ``columns`` come after ``error``)
SUMMARY_COLUMNS = (
    "valid", "error", "reachable_volume", "reachable_volume_se",
    "well_conditioned_volume", "well_conditioned_volume_se", "median_condition",
    "median_payload_kg", "min_payload_kg",
)

#: a factory of robots: the design's parameters -> the robot
RobotFactory = Callable[[dict[str, Any]], ParallelRobot]
#: a column of the table read from each design's robot (a float)
Column = Callable[[Any], float]
#: a progress callback, ``progress(done, total)``
DesignProgress = Callable[[int, int], None]


def _axis_values(values: Mapping[str, float] | None, name: str,
                 positive: bool) -> dict[str, float] | None:
    """``values`` as a plain dict of pose axis -> finite float (> 0 with ``positive``)."""
    if values is None:
        return None
    if not isinstance(values, Mapping):
        raise InputError(name, values, "expected a mapping of pose axis -> value, e.g. "
                         "{'x': 0.1, 'y': 0.1}")
    out = {}
    for axis, value in values.items():
        if axis not in POSE_AXES:
            raise InputError(name, axis, f"not a pose axis (one of {', '.join(POSE_AXES)})")
        out[axis] = real_number(value, f"{name}[{axis!r}]",
                                minimum=0.0 if positive else None)
    return out


@dataclass(frozen=True)
class SweepSettings:
    """What each design is measured with.

    Attributes:
        n_samples: uniform pose samples per design (>= 1).
        half_extent: half sides of the sampled box around the centre, pose axis -> value
            (m or rad, > 0); the pose axes not named stay at the centre. None (default):
            :data:`DEFAULT_HALF_EXTENT` on each position axis (x, y, z) of the robot.
        center: the box centre, pose axis -> value (m or rad); the axes not named are
            those of the robot's home pose (default: the home pose).
        max_condition: threshold of the well-conditioned workspace (> 1).
        seed: random seed of the samples (the same for every design, >= 0): the
            sampled axes (in the robot's pose-axis order) are ``center + u * half`` with
            ``u = numpy.random.default_rng(seed).uniform(-1, 1, (n_samples, k))``.
        payload_samples: how many of the ``ok`` samples also get a force-capability
            evaluation (>= 0).

    Raises:
        InputError: a count that is not a positive (non-negative) integer, an axis that
            is not one of x, y, z, roll, pitch, yaw, a half extent that is not > 0, a
            value that is not finite, ``max_condition <= 1``.
    """

    n_samples: int = 20_000
    half_extent: Mapping[str, float] | None = field(default=None, hash=False)
    center: Mapping[str, float] = field(default_factory=dict, hash=False)
    max_condition: float = 20.0
    seed: int = 0
    payload_samples: int = 2_000

    def __post_init__(self) -> None:
        count(self.n_samples, "n_samples", minimum=1)
        if self.n_samples > workspace_maps.MAX_POSES:
            raise InputError("n_samples", self.n_samples,
                             f"at most MAX_POSES = {workspace_maps.MAX_POSES:.0e} samples")
        count(self.payload_samples, "payload_samples", minimum=0)
        count(self.seed, "seed", minimum=0)
        real_number(self.max_condition, "max_condition", minimum=1.0)
        half = _axis_values(self.half_extent, "half_extent", positive=True)
        if half is not None and not half:
            raise InputError("half_extent", self.half_extent, "names no pose axis")
        object.__setattr__(self, "half_extent", half)
        object.__setattr__(self, "center", _axis_values(self.center, "center", False))


class SweepSamples(NamedTuple):
    """The poses one design is measured at.

    Attributes:
        poses: (n_samples, dim) poses in the robot's pose axes (m, rad).
        axes: the sampled pose axes, in the robot's order.
        box_volume: the volume of the sampled box (the product of its sides, in the
            sampled axes' units).
    """

    poses: np.ndarray
    axes: tuple[str, ...]
    box_volume: float


def sample_poses(robot: ParallelRobot, settings: SweepSettings) -> SweepSamples:
    """The uniform samples of the settings' box for one robot (see :class:`SweepSettings`).

    Args:
        robot: any :class:`~hexapod_pin.core.robot_api.ParallelRobot`.
        settings: the box, the count and the seed.

    Returns:
        :class:`SweepSamples`.

    Raises:
        InputError: a ``half_extent`` or ``center`` axis that is not a pose axis of the
            robot, or no ``half_extent`` for a robot without a position axis.
    """
    axes = tuple(robot.pose_axes)
    half = settings.half_extent
    if half is None:
        half = {a: DEFAULT_HALF_EXTENT for a in axes if a in ("x", "y", "z")}
        if not half:
            raise InputError("half_extent", None, f"the robot's pose axes {axes} have no "
                             "position axis: give half_extent")
    center = dict(settings.center)
    for name, given in (("half_extent", half), ("center", center)):
        foreign = [a for a in given if a not in axes]
        if foreign:
            raise InputError(name, foreign[0], f"not a pose axis of the robot {axes}")
    middle = np.asarray(robot.home_pose, dtype=float).copy()
    for axis, value in center.items():
        middle[axes.index(axis)] = value
    picked = [i for i, axis in enumerate(axes) if axis in half]
    sides = np.array([half[axes[i]] for i in picked])
    unit = np.random.default_rng(settings.seed).uniform(-1.0, 1.0,
                                                        size=(settings.n_samples, len(picked)))
    poses = np.tile(middle, (settings.n_samples, 1))
    poses[:, picked] = middle[picked] + unit * sides
    return SweepSamples(poses, tuple(axes[i] for i in picked), float(np.prod(2 * sides)))


def gravity_wrench(robot: ParallelRobot, mass: float = 1.0) -> np.ndarray | None:
    """The wrench (dim,) of a mass at the platform origin, in the robot's wrench selection.

    The force ``mass * g`` (``g`` the gravity of the robot's Pinocchio model, world axes)
    and no moment about the platform origin, restricted to the components of
    ``robot.pose_axes`` (``(f, m)``: N, N m).

    Args:
        robot: any :class:`~hexapod_pin.core.robot_api.ParallelRobot`.
        mass: the mass (kg).

    Returns:
        the wrench (dim,), or None where it is zero (no gravity, or none of its
        components in the selection: a pose of horizontal axes only).
    """
    weight = mass * np.asarray(robot.model.model.gravity.linear, dtype=float)
    wrench = np.concatenate([weight, np.zeros(3)])[pose_layout(robot).components]
    return wrench if np.any(wrench) else None


def design_grid(values: Mapping[str, Sequence[Any]],
                geometry: type | None = None) -> list[dict[str, Any]]:
    """The Cartesian product of parameter values, as a list of name -> value dicts.

    Args:
        values: parameter name -> the values it takes, e.g. ``{"link_length": [0.28,
            0.30], "rail_radius": [0.35, 0.40]}``; the last name varies fastest.
        geometry: a geometry dataclass (e.g. ``PlanarGeometry``): the names must be its
            fields; None: any names (those the sweep's factory reads).

    Returns:
        the designs, one dict per combination.

    Raises:
        InputError: a name that is not a field of ``geometry``, a value that is not a
            list of values, or an empty list.
        ArgumentTypeError: ``geometry`` is not a dataclass.
    """
    names: set[str] | None = None
    owner = getattr(geometry, "__name__", "geometry")
    if geometry is not None:
        if not (isinstance(geometry, type) and dataclasses.is_dataclass(geometry)):
            raise ArgumentTypeError("geometry", geometry, "expected a geometry dataclass "
                                    "(e.g. PlanarGeometry) or None")
        names = {f.name for f in dataclasses.fields(geometry) if f.init}
    for name, vals in values.items():
        if names is not None and name not in names:
            raise InputError("parameter", name, f"not a {owner} field "
                             f"({sorted(names)})")
        if isinstance(vals, (str, bytes, Mapping)) or not isinstance(vals, (Sequence,
                                                                             np.ndarray)):
            raise InputError(name, vals, "expected a list of values")
        if len(vals) == 0:
            raise InputError(name, vals, "needs at least one value")
    keys = list(values)
    return [dict(zip(keys, combo)) for combo in itertools.product(*(values[k] for k in keys))]


@dataclass(frozen=True)
class GeometryFactory:
    """The factory of a robot made from a geometry record:
    ``robot_class(dataclasses.replace(base, **params))``.

    Attributes:
        robot_class: the robot's constructor from a geometry (``Hexapod``,
            ``Planar3PRR``).
        base: the geometry the designs modify (a dataclass instance, validated again
            with each design's fields).

    Raises:
        ArgumentTypeError: ``robot_class`` not callable, ``base`` not a dataclass
            instance; when called, a parameter that is not a field of ``base``.

    Example:
        >>> make = GeometryFactory(Planar3PRR, PlanarGeometry())
        >>> make({"link_length": 0.32}).geometry.link_length
        0.32
    """

    robot_class: Callable[[Any], ParallelRobot]
    base: Any

    def __post_init__(self) -> None:
        if not callable(self.robot_class):
            raise ArgumentTypeError("robot_class", self.robot_class, "expected a robot "
                                    "class (a callable of a geometry)")
        if not dataclasses.is_dataclass(self.base) or isinstance(self.base, type):
            raise ArgumentTypeError("base", self.base, "expected a geometry dataclass "
                                    f"instance, got {type(self.base).__name__}")

    def __call__(self, params: Mapping[str, Any]) -> ParallelRobot:
        """The robot of one design.

        Raises:
            ArgumentTypeError: a parameter that is not a field of ``base``.
            GeometryError: an invalid geometry (from the geometry's own checks).
        """
        names = {f.name for f in dataclasses.fields(self.base) if f.init}
        unknown = sorted(set(params) - names)
        if unknown:
            raise ArgumentTypeError("parameter", unknown[0], f"not a "
                                    f"{type(self.base).__name__} field ({sorted(names)})")
        return self.robot_class(dataclasses.replace(self.base, **params))


def _pandas() -> Any:
    try:
        import pandas
    except ImportError:
        raise MissingDependencyError("pandas", "sweep") from None
    return pandas


@dataclass(frozen=True)
class Sweep:
    """One sweep: how each design's robot is built and measured, and its table.

    Attributes:
        make_robot: the factory, ``make_robot(params) -> robot`` (params: a dict of the
            design's parameters).
        settings: the samples each design is measured at.
        columns: extra columns, name -> ``read(robot) -> float``, read from each built
            robot and placed after ``error`` (e.g. the hexapod's ``home_height``).

    Raises:
        ArgumentTypeError: ``make_robot`` or a column reader not callable, settings that
            are not :class:`SweepSettings`.
        InputError: a column named like a summary column.
    """

    make_robot: RobotFactory
    settings: SweepSettings = field(default_factory=SweepSettings)
    columns: Mapping[str, Column] = field(default_factory=dict, hash=False)

    def __post_init__(self) -> None:
        if not callable(self.make_robot):
            raise ArgumentTypeError("make_robot", self.make_robot, "expected a callable "
                                    "make_robot(params) -> robot")
        if not isinstance(self.settings, SweepSettings):
            raise ArgumentTypeError("settings", self.settings, "expected SweepSettings, got "
                                    f"{type(self.settings).__name__}")
        for name, read in self.columns.items():
            if name in SUMMARY_COLUMNS:
                raise InputError("columns", name, "is the name of a summary column")
            if not callable(read):
                raise ArgumentTypeError(f"columns[{name!r}]", read, "expected a callable "
                                        "read(robot) -> float")
        object.__setattr__(self, "columns", dict(self.columns))

    @property
    def column_names(self) -> tuple[str, ...]:
        """The summary columns of the table, in order (after the parameters)."""
        return (*SUMMARY_COLUMNS[:2], *self.columns, *SUMMARY_COLUMNS[2:])

    def evaluate(self, params: Mapping[str, Any]) -> dict[str, Any]:
        """The row of one design: its parameters, then :attr:`column_names`.

        Raises:
            ArgumentTypeError: the factory refuses the parameters as such (an unknown
                name) or returns something that is not a parallel robot.
            InputError: settings that do not fit the robot (:func:`sample_poses`).
        """
        params = dict(params)
        row: dict[str, Any] = {**params, **dict.fromkeys(self.column_names)}
        try:
            robot = self.make_robot(params)
        except ArgumentTypeError:
            raise
        except HexapodPinError as exc:
            row.update(valid=False, error=str(exc))
            return row
        if not isinstance(robot, ParallelRobot):
            raise ArgumentTypeError("make_robot", self.make_robot, "returned "
                                    f"{type(robot).__name__}, expected a parallel robot")
        samples = sample_poses(robot, self.settings)
        row.update(valid=True, error="",
                   **{name: float(read(robot)) for name, read in self.columns.items()})
        row.update(self._summary(robot, samples))
        return row

    def _summary(self, robot: ParallelRobot, samples: SweepSamples) -> dict[str, float]:
        settings = self.settings
        measures = workspace_maps.evaluate(robot, samples.poses, statics=False,
                                           singularity=False)
        reach = workspace_maps.volume_estimate(measures.ok, samples.box_volume)
        good = measures.ok & (measures.condition_number <= settings.max_condition)
        well = workspace_maps.volume_estimate(good, samples.box_volume)
        out = {"reachable_volume": reach.volume, "reachable_volume_se": reach.std_error,
               "well_conditioned_volume": well.volume,
               "well_conditioned_volume_se": well.std_error}
        ok_idx = np.flatnonzero(measures.ok)
        if ok_idx.size == 0:
            return out
        out["median_condition"] = float(np.median(measures.condition_number[ok_idx]))
        picked = ok_idx[: settings.payload_samples]
        direction = gravity_wrench(robot)
        if picked.size and direction is not None:
            cap = workspace_maps.force_capability(robot, samples.poses[picked], direction)
            out["median_payload_kg"] = float(np.median(cap.scale))
            out["min_payload_kg"] = float(np.min(cap.scale))
        return out

    def plan(self, designs: Sequence[Mapping[str, Any]], scheduler: str | None = None,
             use_dask: bool | None = None) -> tuple[list[dict[str, Any]], bool]:
        """The checked designs and whether they run on Dask (see :func:`design_sweep`).

        Raises:
            MissingDependencyError: pandas is not installed (the ``sweep`` extra).
            InputError: no designs, or a parameter named like a column of the table.
            ArgumentTypeError: a design that is not a mapping.
        """
        _pandas()
        checked = []
        for design in designs:
            if not isinstance(design, Mapping):
                raise ArgumentTypeError("designs", design, "expected a mapping of "
                                        "parameter -> value per design (design_grid)")
            clash = [name for name in design if name in self.column_names]
            if clash:
                raise InputError("parameter", clash[0], "is the name of a column of the "
                                 "table")
            checked.append(dict(design))
        if not checked:
            raise InputError("designs", list(designs), "needs at least one design")
        if use_dask is None:
            return checked, scheduler is not None or len(checked) >= DASK_MIN_DESIGNS
        return checked, bool(use_dask)

    def rows(self, designs: Sequence[Mapping[str, Any]],
             progress: DesignProgress | None = None) -> list[dict[str, Any]]:
        """The rows of the designs, evaluated in this process in order; ``progress(done,
        total)`` after each."""
        rows = []
        for params in designs:
            rows.append(self.evaluate(params))
            if progress is not None:
                progress(len(rows), len(designs))
        return rows

    def table(self, designs: Sequence[Mapping[str, Any]],
              rows: Sequence[Mapping[str, Any]]) -> pd.DataFrame:
        """The DataFrame of the rows: the swept parameters (in order of first
        appearance), then :attr:`column_names`; numbers as nullable ``Float64``.

        Raises:
            MissingDependencyError: pandas is not installed.
        """
        pandas = _pandas()
        params = list(dict.fromkeys(itertools.chain.from_iterable(designs)))
        frame = pandas.DataFrame(list(rows), columns=params + list(self.column_names))
        numeric = [c for c in self.column_names if c not in ("valid", "error")]
        frame[numeric] = frame[numeric].astype("Float64")
        return frame


def evaluate_design(make_robot: RobotFactory, params: Mapping[str, Any],
                    settings: SweepSettings | None = None, *,
                    columns: Mapping[str, Column] | None = None) -> dict[str, Any]:
    """The workspace summaries of one design (a row of :func:`design_sweep`'s table).

    Args:
        make_robot: ``make_robot(params) -> robot`` (see the module docstring).
        params: the design's parameters.
        settings: the samples (:class:`SweepSettings`; default its defaults).
        columns: extra columns read from the robot (see :class:`Sweep`).

    Returns:
        the row: ``params``, then ``valid``, ``error``, the extra columns and the
        summaries (None where not computed, see the module docstring).

    Raises:
        ArgumentTypeError: see :meth:`Sweep.evaluate`, or a factory that is not callable.
        InputError: settings that do not fit the robot.
    """
    return Sweep(make_robot, settings or SweepSettings(), columns or {}).evaluate(params)


def design_sweep(make_robot: RobotFactory, designs: Sequence[Mapping[str, Any]],
                 settings: SweepSettings | None = None, *,
                 columns: Mapping[str, Column] | None = None, scheduler: str | None = None,
                 use_dask: bool | None = None, n_workers: int = 2,
                 progress: DesignProgress | None = None) -> pd.DataFrame:
    """Evaluate many designs and return a pandas DataFrame, one row per design.

    Args:
        make_robot: ``make_robot(params) -> robot`` (see the module docstring).
        designs: list of {parameter: value} (see :func:`design_grid`).
        settings: the samples (:class:`SweepSettings`; default its defaults).
        columns: extra columns read from each robot (see :class:`Sweep`).
        scheduler: address of a running Dask scheduler (``"tcp://host:8786"``);
            None starts a local cluster of ``n_workers`` processes (and closes it).
        use_dask: False evaluates serially in this process (same results); True on Dask;
            None (default): on Dask when a ``scheduler`` is given or there are at least
            :data:`DASK_MIN_DESIGNS` designs, serially otherwise.
        n_workers: local-cluster worker processes (one thread each).
        progress: called as ``progress(done, total)`` after each design.

    Returns:
        DataFrame with the swept parameters then :attr:`Sweep.column_names`, in the
        order of ``designs``.

    Raises:
        MissingDependencyError: pandas (or dask, on Dask) is not installed (the
            ``sweep`` extra).
        InputError: no designs; settings that do not fit a robot; a local cluster that
            cannot start (in a script: call this under ``if __name__ == "__main__":``).
        ArgumentTypeError: see :meth:`Sweep.evaluate`.
    """
    sweep = Sweep(make_robot, settings or SweepSettings(), columns or {})
    designs, on_dask = sweep.plan(designs, scheduler, use_dask)
    rows = (dask_rows(sweep, designs, scheduler, n_workers, progress) if on_dask
            else sweep.rows(designs, progress))
    return sweep.table(designs, rows)


def dask_rows(sweep: Sweep, designs: Sequence[Mapping[str, Any]], scheduler: str | None,
              n_workers: int = 2,
              progress: DesignProgress | None = None) -> list[dict[str, Any]]:
    """The rows of the designs evaluated on Dask (``sweep.evaluate`` per design), in the
    order of ``designs``.

    Args:
        sweep: the sweep.
        designs: the checked designs (:meth:`Sweep.plan`).
        scheduler: a running scheduler's address, or None for a local cluster.
        n_workers: local-cluster worker processes (one thread each).
        progress: called as ``progress(done, total)`` as designs complete.

    Raises:
        MissingDependencyError: dask[distributed] is not installed.
        InputError: a bad ``n_workers``, or a local cluster that cannot start.
    """
    try:
        from dask.distributed import Client, LocalCluster, as_completed
    except ImportError:
        raise MissingDependencyError("dask[distributed]", "sweep") from None

    cluster = None
    if scheduler is None:
        workers = count(n_workers, "n_workers", minimum=1)
        try:
            cluster = LocalCluster(n_workers=workers, threads_per_worker=1,
                                   processes=True, dashboard_address=None)
        except Exception as exc:       # dask raises plain exceptions when a worker dies
            raise InputError("use_dask", True, (
                f"a local Dask cluster could not start ({type(exc).__name__}: {exc}); its "
                "worker processes re-import the calling script: call design_sweep under "
                "'if __name__ == \"__main__\":', or pass use_dask=False")) from exc
    client = Client(cluster if cluster is not None else scheduler)
    try:
        futures = [client.submit(sweep.evaluate, params, pure=False) for params in designs]
        index = {f.key: i for i, f in enumerate(futures)}
        rows: list[dict[str, Any]] = [{} for _ in designs]
        for done, future in enumerate(as_completed(futures), start=1):
            rows[index[future.key]] = future.result()
            if progress is not None:
                progress(done, len(designs))
        return rows
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
