"""Planning commands: ``retime`` (the fastest timing of a path within the limits) and
``check`` (margins of a timed motion against the limits), over :mod:`hexapod_pin.planning`,
for the hexapod or any robot of ``--robot`` (poses, waypoints and motion files in its pose
axes, one bound or value per actuator)."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import numpy as np
import typer

from .common import (
    WRENCH_OF,
    AsJson,
    CliRobot,
    GeometryFile,
    PlatformFrame,
    PoseAxes,
    Quiet,
    RobotFile,
    SetFields,
    as_parallel,
    check_suffix,
    console,
    emit_json,
    guard,
    load_cli_robot,
    note,
    parse_numbers,
    quantity_table,
    read_robot_motion,
    robot_fields,
    robot_urdf,
    write_robot_motion,
)

if TYPE_CHECKING:
    from ..planning import Limits, Payload, TimedTrajectory

# -- the limit options shared by both commands ------------------------------------------------
MaxForce = Annotated[float | None, typer.Option(
    "--max-force", help="bound on |actuator force| (N; N m for a revolute actuator of "
                        "--robot); default the geometry's max_actuator_force",
    show_default=False)]
MaxVelocity = Annotated[float, typer.Option(
    "--max-velocity", help="bound on |actuator velocity| (m/s or rad/s)")]
MaxAcceleration = Annotated[float, typer.Option(
    "--max-acceleration", help="bound on |actuator acceleration| (m/s^2 or rad/s^2)")]
MaxLinear = Annotated[float, typer.Option(
    "--max-linear-speed", help="bound on the platform origin's speed (m/s)")]
MaxAngular = Annotated[float, typer.Option(
    "--max-angular-speed", help="bound on the platform's angular speed (rad/s)")]
PayloadMass = Annotated[float, typer.Option(
    "--payload-mass", help="point mass carried at the platform origin (kg)")]
PayloadWrench = Annotated[str | None, typer.Option(
    "--payload-wrench", help="constant wrench on the platform 'fx,fy,fz,mx,my,mz' "
                             "(N, N m, world axes; with --robot one value per pose axis)",
    show_default=False)]
NoStrokes = Annotated[bool, typer.Option(
    "--no-strokes", help="do not reject poses outside the actuator strokes")]


def _limits(max_force: float | None, max_velocity: float, max_acceleration: float,
            max_linear: float, max_angular: float, no_strokes: bool) -> Limits:
    from ..planning import Limits
    return Limits(actuator_force=max_force, actuator_velocity=max_velocity,
                  actuator_acceleration=max_acceleration, linear_speed=max_linear,
                  angular_speed=max_angular, strokes=not no_strokes)


def _payload(robot: CliRobot, mass: float, wrench: str | None) -> Payload:
    """The payload of ``--payload-mass`` and ``--payload-wrench`` (one value per pose axis
    of the robot, :data:`~hexapod_pin.cli.common.WRENCH_OF`)."""
    from ..hexapod.robot import Hexapod
    from ..planning import Payload
    if wrench is None:
        return Payload(mass=mass)
    if isinstance(robot, Hexapod):
        values = parse_numbers([wrench], 6, "payload-wrench", "fx fy fz mx my mz")
    else:
        values = parse_numbers([wrench], robot.pose_dim, "payload-wrench",
                               ", ".join(WRENCH_OF[a] for a in robot.geometry.pose_axes))
    return Payload(mass=mass, wrench=tuple(values))


@guard
def retime(path_file: Annotated[Path, typer.Argument(
               help="waypoints: .csv with columns x,y,z,roll,pitch,yaw (others ignored) "
                    "or .json with 'pose'")],
           out: Annotated[Path | None, typer.Option(
               help="write the timed motion (.csv / .json motion file)")] = None,
           max_force: MaxForce = None, max_velocity: MaxVelocity = float("inf"),
           max_acceleration: MaxAcceleration = float("inf"),
           max_linear_speed: MaxLinear = float("inf"),
           max_angular_speed: MaxAngular = float("inf"),
           payload_mass: PayloadMass = 0.0, payload_wrench: PayloadWrench = None,
           no_strokes: NoStrokes = False,
           margin: Annotated[float, typer.Option(
               help="plan within (1 - margin) of every bound, so that the motion between "
                    "grid points (and a resampled output) stays within the full bounds")
           ] = 0.0,
           grid: Annotated[int, typer.Option(help="grid points along the path")] = 1000,
           rate: Annotated[float | None, typer.Option(
               help="resample the output at this rate (Hz); default the grid points",
               show_default=False)] = None,
           plot: Annotated[Path | None, typer.Option(
               help="figure of the forces against their limits and of the phase plane "
                    "(.png / .svg / .pdf; the phase plane gets a '-phase' suffix)")] = None,
           html: Annotated[Path | None, typer.Option(
               help="write an animated HTML view")] = None,
           as_json: AsJson = False, quiet: Quiet = False,
           robot: RobotFile = None, platform: PlatformFrame = None, pose_axes: PoseAxes = None,
           geometry: GeometryFile = None, set_: SetFields = None) -> None:
    """Fastest timing of the path through the waypoints within the actuator limits
    (time-optimal path parameterisation on the closed-loop inverse dynamics), from rest
    to rest. The path is C2 through the waypoints, rotations interpolated on SO(3).

    With `--robot`: waypoints with one column per pose axis (e.g. `x, z`), the output
    motion file in its columns (`hexapod-pin id --help`), bounds per actuator in its
    joint's unit."""
    from .. import motion as motions
    from ..hexapod.robot import Hexapod
    from ..planning import time_optimal
    from ..planning.path import read_waypoints
    from ..viz import planning_plots, plotting
    quiet = quiet or as_json
    check_suffix("out", out, motions.MOTION_SUFFIXES)
    check_suffix("plot", plot, plotting.IMAGE_SUFFIXES)
    check_suffix("html", html, (".html", ".htm"))
    bot = load_cli_robot(robot, platform, pose_axes, geometry, set_)
    limits = dataclasses.replace(_limits(max_force, max_velocity, max_acceleration,
                                         max_linear_speed, max_angular_speed, no_strokes),
                                 margin=margin)
    planned = as_parallel(bot)
    waypoints = read_waypoints(path_file) if isinstance(bot, Hexapod) else \
        read_waypoints(path_file, pose_axes=bot.geometry.pose_axes)
    traj = time_optimal(planned, waypoints, limits=limits,
                        payload=_payload(bot, payload_mass, payload_wrench), grid_points=grid)
    timed = traj if rate is None else traj.resample(rate)
    if out is not None:
        write_robot_motion(out, motions.Motion(
            timed.t, timed.poses, timed.twists, timed.twist_dots, q=timed.actuator_positions,
            actuator_forces=timed.actuator_forces), bot)
        note(quiet, f"wrote {out}")
    if plot is not None:
        planning_plots.plot_forces_against_limits(traj, path=plot)
        phase = plot.with_name(plot.stem + "-phase" + plot.suffix)
        planning_plots.plot_phase_plane(traj, path=phase)
        note(quiet, f"wrote {plot} and {phase}")
    if html is not None:
        _retime_html(html, bot, timed, f"time-optimal motion, {traj.duration:.4g} s",
                     robot_urdf(bot, robot))
        note(quiet, f"wrote {html}")
    peak_force = float(np.max(np.abs(traj.actuator_forces)))
    peak_velocity = float(np.max(np.abs(traj.actuator_velocities)))
    if isinstance(bot, Hexapod):
        peaks = {"max_abs_actuator_force_n": peak_force,
                 "max_abs_actuator_velocity_m_s": peak_velocity}
    else:                               # N or N m, m/s or rad/s: each actuator its unit
        peaks = {"max_abs_actuator_force": peak_force,
                 "max_abs_actuator_velocity": peak_velocity}
    summary = {"duration_s": traj.duration, "grid_points": len(traj.t),
               "samples_written": len(timed.t),
               "path_length_m": traj.path.length, **peaks,
               "out": out, "plot": plot, "html": html}
    if as_json:
        summary.update(robot_fields(bot))
        emit_json(summary)
        return
    console.print(quantity_table("time-optimal retiming", {
        key: f"{value:.6g}" if isinstance(value, float) else str(value)
        for key, value in summary.items() if value is not None}))


def _retime_html(html: Path, robot: CliRobot, timed: TimedTrajectory, caption: str,
                 urdf: Path | None) -> None:
    """The animation of a retimed motion with its actuator forces: the hexapod's view, or
    the tree configurations of a loaded robot's poses (``robot.configuration``)."""
    from ..hexapod.robot import Hexapod
    from ..viz import hexapod_scenes, scenes
    if isinstance(robot, Hexapod):
        hexapod_scenes.write_hexapod_trajectory_html(
            html, robot, timed.t, timed.poses, carriages=timed.actuator_positions,
            actuator_forces=timed.actuator_forces, caption=caption)
        return
    qs = np.array([robot.configuration(pose) for pose in timed.poses])
    scenes.write_trajectory_html(html, robot, timed.t, qs,
                                 actuator_forces=timed.actuator_forces, caption=caption,
                                 urdf=urdf)


@guard
def check(motion_file: Annotated[Path, typer.Argument(
              help="timed motion file (.csv / .json, see `hexapod-pin id --help`)")],
          max_force: MaxForce = None, max_velocity: MaxVelocity = float("inf"),
          max_acceleration: MaxAcceleration = float("inf"),
          max_linear_speed: MaxLinear = float("inf"),
          max_angular_speed: MaxAngular = float("inf"),
          payload_mass: PayloadMass = 0.0, payload_wrench: PayloadWrench = None,
          no_strokes: NoStrokes = False,
          tolerance: Annotated[float, typer.Option(
              help="relative excess over a bound still called feasible (a retimed motion "
                   "resampled between its grid points may exceed by a fraction of a "
                   "percent)")] = 1e-9,
          as_json: AsJson = False,
          robot: RobotFile = None, platform: PlatformFrame = None, pose_axes: PoseAxes = None,
          geometry: GeometryFile = None, set_: SetFields = None) -> None:
    """Margins of a timed motion against the limits: the worst sample, and the smallest
    uniform slow-down factor that makes it feasible (< 1: it could run faster). Exit code
    1 when a limit is violated.

    With `--robot`: a motion file in its columns (`hexapod-pin id --help`); a file of
    another robot is an error naming the columns expected."""
    from .. import motion as motions
    from ..hexapod.robot import Hexapod
    from ..planning.feasibility import check_feasibility
    bot = load_cli_robot(robot, platform, pose_axes, geometry, set_)
    limits = _limits(max_force, max_velocity, max_acceleration, max_linear_speed,
                     max_angular_speed, no_strokes)
    motion: Path | motions.Motion = motion_file if isinstance(bot, Hexapod) else \
        read_robot_motion(motion_file, bot)
    report = check_feasibility(as_parallel(bot), motion, limits=limits,
                               payload=_payload(bot, payload_mass, payload_wrench),
                               tolerance=tolerance)
    largest = {key: float(np.max(report.values[key] / report.bounds[key]))
               for key in report.values if np.any(np.isfinite(report.bounds[key]))}
    summary = {"feasible": report.feasible, "samples": len(report.t),
               "slow_down": report.slow_down, "slow_down_reason": report.slow_down_reason,
               "worst": report.worst,
               "largest_ratio_to_limit": largest,
               "samples_outside_strokes": int(np.sum(~report.within_stroke))}
    if as_json:
        emit_json({**summary, **robot_fields(bot)})
    else:
        rows = {"feasible": str(report.feasible),
                "uniform slow-down factor": f"{report.slow_down:.6g}" if
                not report.slow_down_reason else f"none: {report.slow_down_reason}"}
        if report.worst is not None:
            w = report.worst
            rows["worst"] = (f"{w.limit} at sample {w.index} (t = {w.time:.6g} s), "
                             f"component {w.component}: {w.value:.6g} vs {w.bound:.6g}")
        rows.update({f"max {key} / limit": f"{value:.6g}" for key, value in largest.items()})
        console.print(quantity_table(f"feasibility of {motion_file}", rows))
    if not report.feasible:
        raise typer.Exit(code=1)
