"""``workspace``: how much of a box of poses around home the robot reaches, regularly and
well-conditioned (Monte Carlo, :func:`hexapod_pin.core.workspace_maps.volume`), for the
hexapod or any robot (``--robot PATH``)."""

from __future__ import annotations

from typing import Annotated

import numpy as np
import typer

from ..errors import InputError
from .common import (AsJson, GeometryFile, PlatformFrame, PoseAxes, Quiet, RobotFile,
                     SetFields, as_parallel, component_values, console, emit_json, guard,
                     load_cli_robot, pose_axes_of, progress_bar, quantity_table, robot_fields)

#: default half-widths of the box around home: 5 cm on positions, 0.2 rad on angles
DEFAULT_HALF = {"linear": 0.05, "angular": 0.2}

HalfExtent = Annotated[str | None, typer.Option(
    "--half-extent", metavar="A,B,...",
    help="half-widths of the box around home, one per pose component (m, rad); default "
         "0.05 m and 0.2 rad", show_default=False)]


@guard
def workspace(samples: Annotated[int, typer.Option("--samples", help="uniform samples "
                                                   "of the box")] = 2000,
              half_extent: HalfExtent = None,
              max_condition: Annotated[float | None, typer.Option(
                  "--max-condition", help="also count the samples with cond(J) at most "
                  "this (the well-conditioned workspace)", show_default=False)] = None,
              seed: Annotated[int, typer.Option("--seed", help="random seed")] = 0,
              as_json: AsJson = False, quiet: Quiet = False,
              robot: RobotFile = None, platform: PlatformFrame = None,
              pose_axes: PoseAxes = None,
              geometry: GeometryFile = None, set_: SetFields = None) -> None:
    """Monte-Carlo volume of the workspace in a box of poses around home.

    A sample counts when the robot reaches it within its strokes and away from both
    singularities (the routes' own thresholds); with `--max-condition`, also the part
    where cond(J) stays below the bound. Volumes are in the product of the pose
    components' units (m^3 rad^3 for a 6-D pose), with their one-sigma sampling error."""
    from ..core import workspace_maps
    from ..core.checks import count, real_number, within_magnitude
    bot = load_cli_robot(robot, platform, pose_axes, geometry, set_)
    count(samples, "--samples")
    if samples > workspace_maps.MAX_POSES:
        raise InputError("--samples", samples,
                         f"at most {workspace_maps.MAX_POSES:.0e} samples")
    if max_condition is not None:
        real_number(max_condition, "--max-condition", minimum=0.0)
    axes = pose_axes_of(bot)
    angular = np.array([a in ("roll", "pitch", "yaw") for a in axes])
    half = component_values(bot, half_extent, "half-extent", {a: a for a in axes})
    if half is None:
        half = np.where(angular, DEFAULT_HALF["angular"], DEFAULT_HALF["linear"])
    elif not np.all(half > 0.0):
        raise InputError("--half-extent", half_extent, "half-widths must be > 0 (m, rad)")
    half = within_magnitude(np.asarray(half, dtype=float), half_extent, "--half-extent")
    home = np.asarray(bot.home_pose, dtype=float)
    low, high = home - half, home + half
    units = " ".join(f"{u}^{n}" for u, n in (("m", int((~angular).sum())),
                                             ("rad", int(angular.sum()))) if n)
    runs = {"workspace": None} if max_condition is None else \
        {"workspace": None, f"cond(J) <= {max_condition:g}": max_condition}
    results = {}
    for label, bound in runs.items():
        with progress_bar(quiet, f"sampling ({label})", 100) as update:
            results[label] = workspace_maps.volume(
                as_parallel(bot), samples, low, high, seed, max_condition=bound,
                progress=lambda f: update(int(100 * f), 100))
    if as_json:
        emit_json({"low": low, "high": high, "units": units, "samples": samples,
                   "estimates": {k: {"volume": v.volume, "std_error": v.std_error,
                                     "fraction": v.fraction, "box_volume": v.box_volume}
                                 for k, v in results.items()}, **robot_fields(bot)})
        return
    rows = {f"box ({', '.join(axes)}) low": ", ".join(f"{x:+.4f}" for x in low),
            "high": ", ".join(f"{x:+.4f}" for x in high),
            f"box volume ({units})": f"{next(iter(results.values())).box_volume:.4e}"}
    for label, est in results.items():
        rows[f"{label}: fraction of the box"] = f"{est.fraction:.4f}"
        rows[f"{label}: volume ({units})"] = f"{est.volume:.4e} +- {est.std_error:.1e}"
    console.print(quantity_table(f"workspace around home, {samples} samples", rows))
