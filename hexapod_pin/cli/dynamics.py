"""Dynamics commands: ``statics``, ``id`` (inverse dynamics along a motion file),
``simulate`` (closed-loop simulation tracking a circle)."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from .. import motion as motions
from ..viz import hexapod_scenes, plotting
from .common import (
    AsJson,
    Degrees,
    GeometryFile,
    Quiet,
    SetFields,
    Values,
    carriage_table,
    check_suffix,
    console,
    emit_json,
    guard,
    note,
    parse_numbers,
    pose_in,
    pose_out,
    progress_bar,
    quantity_table,
    robot_of,
)


@guard
def statics(pose: Values = None,
            wrench: Annotated[str | None, typer.Option(
                help="wrench on the platform 'fx,fy,fz,mx,my,mz' (N, N m, world axes)")] = None,
            degrees: Degrees = False, as_json: AsJson = False,
            geometry: GeometryFile = None, set_: SetFields = None) -> None:
    """Actuator forces (N) holding the platform at rest at a pose (default home)."""
    robot = robot_of(geometry, set_)
    p = pose_in(pose, degrees) if pose else robot.home_pose
    w = None if wrench is None else parse_numbers([wrench], 6, "wrench", "fx fy fz mx my mz")
    tau = robot.static_forces(p, wrench=w)
    if as_json:
        emit_json({"pose": pose_out(p, degrees), "wrench": w, "actuator_forces": tau})
        return
    console.print(carriage_table("static actuator forces (+ along the rail direction u_k)",
                                 {"tau (N)": tau}))


@guard
def inverse_dynamics(motion_file: Annotated[Path, typer.Argument(
                         help="motion file (.csv / .json; format: see above)")],
                     out: Annotated[Path | None, typer.Option(
                         help="write the motion with the forces (.csv / .json)")] = None,
                     method: Annotated[str, typer.Option(
                         help="kkt (the square system solved exactly) or qp (ProxSuite, "
                              "certifying the force bounds)")] = "kkt",
                     as_json: AsJson = False, quiet: Quiet = False,
                     geometry: GeometryFile = None, set_: SetFields = None) -> None:
    """Inverse dynamics along a motion file: actuator forces (N) at every sample.

    Motion file, CSV: a header row, then one row per sample; columns `t` (s), `x, y, z`
    (m), `roll, pitch, yaw` (rad), optional `vx, vy, vz, wx, wy, wz` (twist, world axes),
    `ax, ay, az, alphax, alphay, alphaz` (its derivative), `fx, fy, fz, mx, my, mz`
    (wrench on the platform, N, N m), `q0..q5`, `tau0..tau5`, `residual`. JSON: keys
    `t`, `pose` (N x 6), optional `twist`, `twist_dot`, `wrench`, `q`, `actuator_forces`,
    `closure_residual`. A missing twist is computed from the poses by finite differences.
    """
    quiet = quiet or as_json
    check_suffix("out", out, motions.MOTION_SUFFIXES)
    robot = robot_of(geometry, set_)
    motion = motions.read_motion(motion_file)
    with progress_bar(quiet, "inverse dynamics", total=len(motion.t)) as progress:
        tau = motions.inverse_dynamics_along(robot, motion, method, progress).actuator_forces
    if out is not None:
        twists, dots = motions.motion_rates(motion)
        motions.write_motion(out, dataclasses.replace(motion, twists=twists, twist_dots=dots,
                                                      actuator_forces=tau))
        note(quiet, f"wrote {out}")
    peak = np.max(np.abs(tau), axis=0)
    if as_json:
        emit_json({"t": motion.t, "actuator_forces": tau, "max_abs_actuator_forces": peak,
                   "out": out})
        return
    console.print(carriage_table(
        f"inverse dynamics over {len(motion.t)} samples, {motion.t[-1] - motion.t[0]:g} s",
        {"max |tau| (N)": peak, "at t (s)": motion.t[np.argmax(np.abs(tau), axis=0)],
         "mean tau (N)": tau.mean(axis=0)}))


@guard
def simulate(duration: Annotated[float, typer.Option(help="simulated time (s)")] = 2.0,
             dt: Annotated[float | None, typer.Option(
                 help="time step (s); default 0.25 ms for pid, 1 ms otherwise",
                 show_default=False)] = None,
             controller: Annotated[str, typer.Option(
                 help="pid (Quanser gains), computed-torque, or none (no actuator force)")
             ] = "pid",
             engine: Annotated[str, typer.Option(
                 help="fast (compiled, PID or none), python (Pinocchio tree route, every "
                      "controller), auto (fast unless computed-torque)")] = "auto",
             radius: Annotated[float, typer.Option(
                 help="radius of the reference circle of the platform about home (m)")] = 0.02,
             period: Annotated[float, typer.Option(help="period of the circle (s)")] = 2.0,
             out: Annotated[Path | None, typer.Option(
                 help="write the trajectory (.csv / .json motion file)")] = None,
             html: Annotated[Path | None, typer.Option(
                 help="write an animated HTML view")] = None,
             plot: Annotated[Path | None, typer.Option(
                 help="write a figure (.png / .svg / .pdf) of q, forces, residual")] = None,
             as_json: AsJson = False, quiet: Quiet = False,
             geometry: GeometryFile = None, set_: SetFields = None) -> None:
    """Simulate the closed-loop dynamics tracking a circle of the platform about home.

    Exit code 1 unless the run completed and tracked the circle (status `completed`):
    a stop at a stroke limit, a failure, or a tracking error above the circle's radius
    (status `tracking_lost`, e.g. a step too long for the PID gains) are failures.
    With `--json` the summary is printed with exit code 0 and its `status` says what
    happened.
    """
    quiet = quiet or as_json
    robot = robot_of(geometry, set_)
    check_suffix("out", out, motions.MOTION_SUFFIXES)
    check_suffix("html", html, (".html", ".htm"))
    check_suffix("plot", plot, plotting.IMAGE_SUFFIXES)
    compiled = engine == "fast" or (engine == "auto" and controller != "computed-torque")
    steps = round(duration / (dt or motions.DEFAULT_DT.get(controller, 1e-3))) \
        if np.isfinite(duration) and duration > 0 and not compiled else None
    # the compiled loop reports nothing until it ends: a spinner instead of a bar
    with progress_bar(quiet, f"simulating {duration:g} s",
                      total=None if steps is None else max(steps, 1)) as progress:
        run = motions.simulate_circle(robot, duration, dt, controller, radius, period,
                                      progress, engine=engine)
    traj = run.trajectory
    motion = motions.Motion.from_trajectory(traj)
    if out is not None:
        motions.write_motion(out, motion)
        note(quiet, f"wrote {out}")
    if html is not None:
        with progress_bar(quiet, "writing HTML"):
            hexapod_scenes.write_simulation_html(
                html, robot, traj,
                caption=f"simulation: {controller} control, circle r = {radius:g} m, "
                        f"{motion.t[-1]:g} s ({run.status})")
        note(quiet, f"wrote {html}")
    if plot is not None:
        plotting.plot_simulation(traj, path=plot, title=f"simulation, {controller} control")
        note(quiet, f"wrote {plot}")
    residual = motion.closure_residual
    summary = {"status": run.status, "message": run.message, "engine": run.engine,
               "duration_s": float(motion.t[-1] - motion.t[0]), "samples": len(motion.t),
               "wall_time_s": float(traj.wall_time),
               "max_tracking_error_m": run.tracking_error,
               "tracking_tolerance_m": run.tolerance,
               "max_abs_actuator_force_n": float(np.max(np.abs(traj.actuator_forces))),
               "saturated_fraction": float(np.mean(traj.saturated)),
               "max_closure_residual_m": None if residual is None else float(np.max(residual)),
               "out": out, "html": html, "plot": plot}
    if as_json:
        emit_json(summary)
        return
    console.print(quantity_table(
        f"simulation: {controller} control, circle r = {radius:g} m",
        {key: f"{value:.4g}" if isinstance(value, float) else str(value)
         for key, value in summary.items() if value not in (None, "")}))
    if run.status == "saturated":
        note(False, f"warning: {run.message}")
    if not run.ok:
        raise typer.Exit(code=1)
