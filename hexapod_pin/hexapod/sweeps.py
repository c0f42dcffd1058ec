"""Design sweeps: workspace summaries over a grid of :class:`HexapodGeometry` parameters.

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

import itertools
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING, Callable, Mapping, Sequence

import numpy as np

from ..errors import HexapodPinError, InputError, MissingDependencyError
from . import workspace
from .geometry import HexapodGeometry
from .robot import Hexapod

if TYPE_CHECKING:    # pandas is optional (extra ``sweep``)
    import pandas as pd

DASK_MIN_DESIGNS = 100
"""Fewest designs for which ``use_dask=None`` starts a local Dask cluster (a local cluster
costs a few seconds to start; a design of the default settings ~0.1 s)."""

#: columns of the summary table, in order (besides the swept parameters)
SUMMARY_COLUMNS = (
    "valid", "error", "home_height", "reachable_volume", "reachable_volume_se",
    "well_conditioned_volume", "well_conditioned_volume_se", "median_condition",
    "median_payload_kg", "min_payload_kg",
)


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
        if not (self.max_condition > 1.0):
            raise InputError("max_condition", self.max_condition, "must be > 1")
        if int(self.payload_samples) != self.payload_samples or self.payload_samples < 0:
            raise InputError("payload_samples", self.payload_samples, "must be >= 0")


def design_grid(**values: Sequence[float]) -> list[dict[str, float]]:
    """The Cartesian product of parameter values, as a list of field -> value dicts.

    Example: ``design_grid(rail_radius=[0.3, 0.35], leg_length=[0.4, 0.45, 0.5])``.

    Raises:
        InputError: a name that is not a HexapodGeometry field, or an empty list.
    """
    names = {f.name for f in fields(HexapodGeometry)}
    for name, vals in values.items():
        if name not in names:
            raise InputError("parameter", name, f"not a HexapodGeometry field ({sorted(names)})")
        if len(vals) == 0:
            raise InputError(name, vals, "needs at least one value")
    keys = list(values)
    return [dict(zip(keys, combo)) for combo in itertools.product(*(values[k] for k in keys))]


def evaluate_design(params: Mapping[str, float], settings: SweepSettings,
                    base: HexapodGeometry | None = None) -> dict:
    """Workspace summaries of one design (a row of the sweep table).

    Invalid designs (a :class:`GeometryError`, e.g. a home that cannot be
    assembled) give ``valid=False`` with the message in ``error`` and empty
    (None) numeric fields instead of raising.
    """
    row: dict = dict(params)
    row.update({name: None for name in SUMMARY_COLUMNS})
    try:
        geometry = (base or HexapodGeometry()).replace(**params)
        robot = Hexapod(geometry)
    except HexapodPinError as exc:
        row.update(valid=False, error=str(exc))
        return row
    rng = np.random.default_rng(settings.seed)
    half = np.asarray(settings.half_extent, dtype=float)
    centre = robot.home_pose[:3]
    unit = rng.uniform(-1.0, 1.0, size=(settings.n_samples, 3))
    poses = np.concatenate([centre + unit * half,
                            np.broadcast_to(settings.orientation, unit.shape)], axis=1)
    measures = workspace.evaluate(robot, poses, singularity=False, statics=False)
    box = float(np.prod(2 * half))
    reach = workspace.volume_estimate(measures.ok, box)
    good = measures.ok & (measures.condition_number <= settings.max_condition)
    well = workspace.volume_estimate(good, box)
    ok_idx = np.flatnonzero(measures.ok)
    row.update(valid=True, error="", home_height=robot.geometry.home_height,
               reachable_volume=reach.volume, reachable_volume_se=reach.std_error,
               well_conditioned_volume=well.volume, well_conditioned_volume_se=well.std_error)
    if ok_idx.size:
        row["median_condition"] = float(np.median(measures.condition_number[ok_idx]))
        picked = ok_idx[: settings.payload_samples]
        if picked.size:
            cap = workspace.force_capability(robot, poses[picked],
                                             [0.0, 0.0, -geometry.gravity, 0.0, 0.0, 0.0])
            row["median_payload_kg"] = float(np.median(cap.scale))
            row["min_payload_kg"] = float(np.min(cap.scale))
    return row


def design_sweep(designs: Sequence[Mapping[str, float]], settings: SweepSettings | None = None,
                 base: HexapodGeometry | None = None, scheduler: str | None = None,
                 use_dask: bool | None = None, n_workers: int = 2,
                 progress: Callable[[int, int], None] | None = None) -> pd.DataFrame:
    """Evaluate many designs and return a pandas DataFrame, one row per design.

    Args:
        designs: list of {field: value} (see :func:`design_grid`).
        settings: sampling settings (:class:`SweepSettings`).
        base: geometry the designs modify (default the default geometry).
        scheduler: address of a running Dask scheduler (``"tcp://host:8786"``);
            None starts a local cluster of ``n_workers`` processes (and closes it).
        use_dask: False evaluates serially in this process (same results); True on Dask;
            None (default): on Dask when a ``scheduler`` is given or there are at least
            :data:`DASK_MIN_DESIGNS` designs, serially otherwise.
        n_workers: local-cluster worker processes (one thread each).
        progress: called as ``progress(done, total)`` after each design.

    Returns:
        DataFrame with the swept parameters then :data:`SUMMARY_COLUMNS`, in the
        order of ``designs``.

    Raises:
        MissingDependencyError: pandas (or dask, on Dask) is not installed (the
            ``sweep`` extra).
        InputError: no designs; a local cluster that cannot start (in a script: call
            this under ``if __name__ == "__main__":``).
    """
    try:
        import pandas as pd
    except ImportError:
        raise MissingDependencyError("pandas", "sweep") from None

    settings = settings or SweepSettings()
    designs = [dict(d) for d in designs]
    if not designs:
        raise InputError("designs", designs, "needs at least one design")
    total = len(designs)
    if use_dask is None:
        use_dask = scheduler is not None or total >= DASK_MIN_DESIGNS
    rows: list[dict | None] = [None] * total
    if not use_dask:
        for i, params in enumerate(designs):
            rows[i] = evaluate_design(params, settings, base)
            if progress is not None:
                progress(i + 1, total)
    else:
        rows = _dask_rows(designs, settings, base, scheduler, n_workers, progress)
    columns = list(dict.fromkeys(itertools.chain.from_iterable(designs)))
    frame = pd.DataFrame(rows, columns=columns + list(SUMMARY_COLUMNS))
    numeric = [c for c in SUMMARY_COLUMNS if c not in ("valid", "error")]
    frame[numeric] = frame[numeric].astype("Float64")
    return frame


def _dask_rows(designs, settings, base, scheduler, n_workers, progress):
    try:
        from dask.distributed import Client, LocalCluster, as_completed
    except ImportError:
        raise MissingDependencyError("dask[distributed]", "sweep") from None

    cluster = None
    if scheduler is None:
        if int(n_workers) != n_workers or n_workers < 1:
            raise InputError("n_workers", n_workers, "must be a positive integer")
        try:
            cluster = LocalCluster(n_workers=int(n_workers), threads_per_worker=1,
                                   processes=True, dashboard_address=None)
        except Exception as exc:       # dask raises plain exceptions when a worker dies
            raise InputError("use_dask", True, (
                f"a local Dask cluster could not start ({type(exc).__name__}: {exc}); its "
                "worker processes re-import the calling script: call design_sweep under "
                "'if __name__ == \"__main__\":', or pass use_dask=False")) from exc
    client = Client(cluster if cluster is not None else scheduler)
    try:
        futures = [client.submit(evaluate_design, params, settings, base, pure=False)
                   for params in designs]
        index = {f.key: i for i, f in enumerate(futures)}
        rows = [None] * len(designs)
        for done, future in enumerate(as_completed(futures), start=1):
            rows[index[future.key]] = future.result()
            if progress is not None:
                progress(done, len(designs))
        return rows
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
