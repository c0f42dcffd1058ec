"""``stiffness``: the Cartesian stiffness ``K_x = J^T K_a J + K_g`` and the natural
frequencies of the hexapod or any robot (``--robot PATH``) at a pose
(:meth:`~hexapod_pin.core.robot_base.RobotBase.vibration_modes`), or, with ``--map``, the
weakest translational and rotational stiffness and the lowest frequency over a slice of
one or two pose axes through it (:func:`hexapod_pin.core.stiffness_maps.stiffness_slice`,
the figure of :func:`hexapod_pin.viz.stiffness_plots.plot_stiffness_slice`)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import numpy as np
import typer
from rich.table import Table
from rich.text import Text

from .common import (
    ANGLES,
    WRENCH_OF,
    AsJson,
    CliRobot,
    CliUsageError,
    Degrees,
    EffectsFile,
    GeometryFile,
    PlatformFrame,
    PoseAxes,
    Quiet,
    RobotFile,
    SetFields,
    Values,
    check_suffix,
    console,
    effects_fields,
    emit_json,
    guard,
    load_cli_robot,
    note,
    parse_numbers,
    pose_axes_of,
    print_effects,
    progress_bar,
    quantity_table,
    robot_fields,
    robot_pose_in,
    robot_pose_out,
)

ActuatorStiffness = Annotated[str, typer.Option(
    "--actuator-stiffness", "-k", metavar="K[,K2,...]",
    help="actuator stiffness, one value for all or one per actuator (N/m for a prismatic "
         "actuator, N m/rad for a revolute one)", show_default=False)]


@guard
def stiffness(actuator_stiffness: ActuatorStiffness, pose: Values = None,
              as_map: Annotated[bool, typer.Option(
                  "--map", help="map over a slice through the pose (default home) instead "
                  "of the pose alone")] = False,
              axes: Annotated[str | None, typer.Option(
                  "--axes", metavar="A[,B]", help="--map: one or two pose axes of the slice "
                  "(default: the first two position axes)", show_default=False)] = None,
              half_width: Annotated[str | None, typer.Option(
                  "--half-width", metavar="W[,W2]", help="--map: half width of the slice "
                  "around the pose (m, rad; one value or one per axis; default 0.05 m, "
                  "0.2 rad)", show_default=False)] = None,
              resolution: Annotated[int | None, typer.Option(
                  "--resolution", help="--map: samples per side (default 21)",
                  show_default=False)] = None,
              out: Annotated[Path | None, typer.Option(
                  "--out", "-o", help="--map: write the figure (.png / .svg / .pdf)",
                  show_default=False)] = None,
              degrees: Degrees = False, as_json: AsJson = False, quiet: Quiet = False,
              robot: RobotFile = None, platform: PlatformFrame = None,
              pose_axes: PoseAxes = None, geometry: GeometryFile = None,
              set_: SetFields = None, effects: EffectsFile = None) -> None:
    """Cartesian stiffness and natural frequencies at a pose (default home), under
    gravity, with the actuators as springs of `--actuator-stiffness`.

    K_x maps a small platform displacement (dp, dtheta; world axes, m and rad) to minus
    the wrench change (N, N m); it holds the actuators' elastic part J^T K_a J and the
    geometric part of the preload holding gravity. Its translational and rotational blocks
    are reported apart (their smallest eigenvalues, N/m and N m/rad: the stiffness in the
    weakest direction with the other kind of motion held), with the frequencies (Hz) of
    K_x phi = omega^2 M_x phi. With `--map`: the same measures over a slice (`--axes`,
    `--half-width`, `--resolution`), poses out of reach, beyond a stroke, singular or
    statically unstable marked; `--out` writes the figure."""
    from ..core import stiffness_maps as sm
    from ..viz import plotting
    quiet = quiet or as_json
    if not as_map:
        given = [flag for flag, value in (("--axes", axes), ("--half-width", half_width),
                                          ("--resolution", resolution), ("--out", out))
                 if value is not None]
        if given:
            raise CliUsageError(f"{', '.join(given)}: options of --map")
    check_suffix("out", out, plotting.IMAGE_SUFFIXES)
    bot = load_cli_robot(robot, platform, pose_axes, geometry, set_, effects)
    values = parse_numbers([actuator_stiffness], None, "actuator-stiffness")
    k = values[0] if values.size == 1 else values
    p = robot_pose_in(bot, pose, degrees)
    if as_map:
        _map(bot, p, k, axes, half_width, resolution, out, degrees, as_json, quiet, effects)
        return
    modes = bot.vibration_modes(p, k)
    st = modes.stiffness
    layout = bot.pose_layout
    blocks = {name: None if rows.size == 0 else sm.block_minimum(st.matrix, rows)
              for name, rows in (("translational", layout.linear),
                                 ("rotational", layout.angular))}
    if as_json:
        emit_json({"pose": robot_pose_out(bot, p, degrees), "actuator_stiffness": k,
                   "stiffness": st.matrix, "elastic": st.elastic, "geometric": st.geometric,
                   "mass_matrix": st.mass_matrix,
                   "translational_min": blocks["translational"],
                   "rotational_min": blocks["rotational"],
                   "frequencies": modes.frequencies, "mode_shapes": modes.shapes,
                   **robot_fields(bot), **effects_fields(bot, effects)})
        return
    print_effects(bot, effects)
    console.print(stiffness_table(st.matrix, pose_axes_of(bot)))
    rows = {"smallest translational stiffness (N/m)": blocks["translational"],
            "smallest rotational stiffness (N m/rad)": blocks["rotational"]}
    shown = {key: f"{value:.6g}" for key, value in rows.items() if value is not None}
    shown["natural frequencies (Hz)"] = " ".join(f"{f:.4g}" for f in modes.frequencies)
    console.print(quantity_table("stiffness under gravity (blocks of K_x; modes of K_x, "
                                 "M_x)", shown))


def stiffness_table(matrix: np.ndarray, axes: tuple[str, ...]) -> Table:
    """``K_x`` as a table: rows the wrench components (fx .. mz), columns the displacement
    components (dx .. dtheta_z), each entry in its block's unit."""
    table = Table(title="Cartesian stiffness K_x: -dW = K_x (dp, dtheta), N/m, N/rad, "
                        "N m/m, N m/rad by block")
    table.add_column("", justify="right")
    for axis in axes:
        table.add_column(_displacement(axis), justify="right")
    for axis, row in zip(axes, matrix):
        table.add_row(Text(WRENCH_OF[axis]), *(f"{v:+.4e}" for v in row))
    return table


def _displacement(axis: str) -> str:
    """The column name of a displacement component: ``dx`` .. ``dz``, ``dthx`` ..
    ``dthz`` (the world rotation's components for roll, pitch, yaw)."""
    return "dth" + "xyz"[ANGLES.index(axis)] if axis in ANGLES else "d" + axis


def _map(bot: CliRobot, center: np.ndarray, k: float | np.ndarray, axes: str | None,
         half_width: str | None, resolution: int | None, out: Path | None, degrees: bool,
         as_json: bool, quiet: bool, effects: Path | None) -> None:
    """``stiffness --map``: the slice, its summary (or JSON), the figure with ``out``."""
    from ..core import stiffness_maps as sm
    from ..viz import stiffness_plots
    widths = None if half_width is None else parse_numbers([half_width], None, "half-width")
    with progress_bar(quiet, "stiffness over the slice", 100) as update:
        ws = sm.stiffness_slice(bot, k, axes, center=center, half_width=widths,
                                resolution=21 if resolution is None else resolution,
                                progress=lambda f: update(int(100 * f), 100))
    if out is not None:
        stiffness_plots.plot_stiffness_slice(ws, path=out)
        note(quiet, f"wrote {out}")
    values = stiffness_plots.panels(ws)
    if as_json:
        emit_json({"axes": list(ws.axes), "coordinates": list(ws.coordinates),
                   "center": robot_pose_out(bot, ws.center, degrees),
                   "actuator_stiffness": k, "status": ws.grid(ws.map.status),
                   "status_names": list(sm.STATUS_NAMES),
                   **{name: ws.grid(v) for name, v in values.items()},
                   "failures": dict(ws.map.failures), "figure": out,
                   **robot_fields(bot), **effects_fields(bot, effects)})
        return
    print_effects(bot, effects)
    labels = {"translational": "smallest translational stiffness (N/m)",
              "rotational": "smallest rotational stiffness (N m/rad)",
              "lowest_frequency": "lowest natural frequency (Hz)"}
    rows = {"axes": ", ".join(ws.axes), "grid": " x ".join(str(n) for n in ws.shape),
            "poses ok": f"{int(np.count_nonzero(ws.map.ok))} of {len(ws.map.status)}"}
    rows.update({f"poses {key}": str(v) for key, v in ws.map.failures.items()})
    for name, v in values.items():
        finite = np.isfinite(v)
        if np.any(finite):
            low = int(np.nanargmin(v))
            at = ", ".join(f"{a} = {ws.map.poses[low, pose_axes_of(bot).index(a)]:+.4f}"
                           for a in ws.axes)
            rows[f"{labels[name]}: min"] = f"{v[low]:.6g} at {at}"
            rows[f"{labels[name]}: max"] = f"{np.nanmax(v):.6g}"
    console.print(quantity_table("stiffness map (blocks of K_x; lowest mode of K_x, M_x)",
                                 rows))
