"""Design sweeps of the hexapod: workspace summaries over a grid of :class:`HexapodGeometry`
parameters.

The hexapod's face of :mod:`hexapod_pin.core.sweeps` (the sweeps of any robot, where the
summaries are defined): each design is a set of :class:`HexapodGeometry` fields changed from
a base geometry, measured on a box of platform positions ``x, y, z`` around its home position
at a constant orientation, and the table also has its ``home_height``.

Each design is evaluated independently (same random samples for every design,
from ``seed``), serially or on a Dask cluster (``dask.distributed``: a local
cluster by default, or the scheduler address of a real one). The two give
identical tables: the per-design function is the same and deterministic.

Needs the ``sweep`` extra (``pip install hexapod-pin[sweep]``: dask[distributed],
pandas). Below :data:`DASK_MIN_DESIGNS` designs the sweep runs serially by default
(starting a local cluster costs seconds, more than it saves). A local Dask cluster
starts worker processes that re-import the calling script: in a script, call
:func:`design_sweep` under ``if __name__ == "__main__":``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from ..core import sweeps as generic
from ..errors import InputError
from .geometry import HexapodGeometry
from .robot import Hexapod

if TYPE_CHECKING:    # pandas is optional (extra ``sweep``)
    import pandas as pd

DASK_MIN_DESIGNS = generic.DASK_MIN_DESIGNS
"""Fewest designs for which ``use_dask=None`` starts a local Dask cluster (a local cluster
costs a few seconds to start; a design of the default settings ~0.1 s)."""

#: columns of the summary table, in order (besides the swept parameters)
SUMMARY_COLUMNS = (*generic.SUMMARY_COLUMNS[:2], "home_height", *generic.SUMMARY_COLUMNS[2:])


@dataclass(frozen=True)
class SweepSettings:
    """What each design is measured with.

    Attributes:
        n_samples: uniform position samples per design (constant orientation).
        half_extent: half sides of the sampled box around the design's home
            position (m), (3,).
        orientation: roll, pitch, yaw of the platform (rad).
        max_condition: threshold of the well-conditioned workspace.
        seed: random seed of the samples (the same for every design).
        payload_samples: how many of the samples also get a force-capability
            evaluation (a mass at the platform origin, in kg).

    Raises:
        InputError: a count that is not a positive (non-negative) integer, not three
            half extents > 0 or three angles, ``max_condition <= 1``.
    """

    n_samples: int = 20_000
    half_extent: tuple[float, float, float] = (0.12, 0.12, 0.12)
    orientation: tuple[float, float, float] = (0.0, 0.0, 0.0)
    max_condition: float = 20.0
    seed: int = 0
    payload_samples: int = 2_000

    def __post_init__(self) -> None:
        if int(self.n_samples) != self.n_samples or self.n_samples < 1:
            raise InputError("n_samples", self.n_samples, "must be a positive integer")
        if len(self.half_extent) != 3 or min(self.half_extent) <= 0:
            raise InputError("half_extent", self.half_extent, "three values > 0")
        if len(self.orientation) != 3:
            raise InputError("orientation", self.orientation, "three angles (rad)")
        if not (self.max_condition > 1.0):
            raise InputError("max_condition", self.max_condition, "must be > 1")
        if int(self.payload_samples) != self.payload_samples or self.payload_samples < 0:
            raise InputError("payload_samples", self.payload_samples, "must be >= 0")
        self.generic()

    def generic(self) -> generic.SweepSettings:
        """The same settings for :mod:`hexapod_pin.core.sweeps`: the box over ``x, y, z``
        around the home position, centred at ``orientation`` in roll, pitch, yaw."""
        return generic.SweepSettings(
            n_samples=int(self.n_samples), half_extent=dict(zip("xyz", self.half_extent)),
            center=dict(zip(("roll", "pitch", "yaw"), self.orientation)),
            max_condition=self.max_condition, seed=int(self.seed),
            payload_samples=int(self.payload_samples))


def design_grid(**values: Sequence[float]) -> list[dict[str, float]]:
    """The Cartesian product of parameter values, as a list of field -> value dicts.

    Example: ``design_grid(rail_radius=[0.3, 0.35], leg_length=[0.4, 0.45, 0.5])``.

    Raises:
        InputError: a name that is not a HexapodGeometry field, or an empty list.
    """
    return generic.design_grid(values, HexapodGeometry)


def _home_height(robot: Hexapod) -> float:
    return robot.geometry.home_height


def _sweep(settings: SweepSettings | None, base: HexapodGeometry | None) -> generic.Sweep:
    return generic.Sweep(generic.GeometryFactory(Hexapod, base or HexapodGeometry()),
                         (settings or SweepSettings()).generic(),
                         {"home_height": _home_height})


def evaluate_design(params: Mapping[str, float], settings: SweepSettings,
                    base: HexapodGeometry | None = None) -> dict[str, Any]:
    """Workspace summaries of one design (a row of the sweep table).

    Invalid designs (a :class:`GeometryError`, e.g. a home that cannot be
    assembled) give ``valid=False`` with the message in ``error`` and empty
    (None) numeric fields instead of raising.

    Raises:
        ArgumentTypeError: a parameter that is not a HexapodGeometry field.
    """
    return _sweep(settings, base).evaluate(params)


def design_sweep(designs: Sequence[Mapping[str, float]], settings: SweepSettings | None = None,
                 base: HexapodGeometry | None = None, scheduler: str | None = None,
                 use_dask: bool | None = None, n_workers: int = 2,
                 progress: Callable[[int, int], None] | None = None) -> pd.DataFrame:
    """Evaluate many designs and return a pandas DataFrame, one row per design.

    Args:
        designs: list of {field: value} (see :func:`design_grid`).
        settings: sampling settings (:class:`SweepSettings`).
        base: geometry the designs modify (default the default geometry).
        scheduler: a running Dask scheduler's address, or None (see
            :func:`hexapod_pin.core.sweeps.design_sweep`).
        use_dask: False: serially here; True: on Dask; None (default): on Dask with a
            ``scheduler`` or from :data:`DASK_MIN_DESIGNS` designs on.
        n_workers: local-cluster worker processes.
        progress: ``progress(done, total)``, after each design.

    Returns:
        DataFrame with the swept parameters then :data:`SUMMARY_COLUMNS`, in the
        order of ``designs``.

    Raises:
        MissingDependencyError: pandas (or dask, on Dask) is not installed (the
            ``sweep`` extra).
        InputError: no designs; a local cluster that cannot start (in a script: call
            this under ``if __name__ == "__main__":``).
        ArgumentTypeError: a parameter that is not a HexapodGeometry field.
    """
    sweep = _sweep(settings, base)
    designs, on_dask = sweep.plan(designs, scheduler, use_dask)
    rows = (_dask_rows(sweep, designs, scheduler, n_workers, progress) if on_dask
            else sweep.rows(designs, progress))
    return sweep.table(designs, rows)


def _dask_rows(sweep: generic.Sweep, designs: list[dict[str, Any]], scheduler: str | None,
               n_workers: int, progress: Callable[[int, int], None] | None
               ) -> list[dict[str, Any]]:
    """The rows on Dask (:func:`hexapod_pin.core.sweeps.dask_rows`)."""
    return generic.dask_rows(sweep, designs, scheduler, n_workers, progress)
