"""The ``demo`` command: the main job of the library in one command; ``warmup``: compile
every compiled kernel at once, with a progress bar (the demo runs it first)."""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import numpy as np
import typer
from rich.table import Table
from rich.text import Text

from .common import (
    AsJson,
    GeometryFile,
    Quiet,
    SetFields,
    console,
    emit_json,
    fmt,
    guard,
    note,
    progress_bar,
    quantity_table,
    robot_of,
)

if TYPE_CHECKING:
    from ..precompile import WarmupReport

#: the tilted pose of the IK / FK round trip: home plus this offset (m, rad)
ROUND_TRIP_OFFSET = np.array([0.01, -0.015, -0.02, 0.04, -0.03, 0.08])


@guard
def demo(as_json: AsJson = False,
         html: Annotated[Path | None, typer.Option(
             help="HTML file of the home pose (default: in the temp folder)")] = None,
         no_html: Annotated[bool, typer.Option("--no-html", help="write no HTML")] = False,
         quiet: Quiet = False, geometry: GeometryFile = None, set_: SetFields = None) -> None:
    """The main job in one command: home pose, IK/FK round trip, statics, a short
    simulation, and an HTML view of the home pose (`--geometry`, `--set`: another
    design)."""
    from .. import motion as motions
    from ..viz import scenes
    quiet = quiet or as_json
    robot = robot_of(geometry, set_)
    report = compile_kernels(quiet)
    q = robot.home_configuration
    pose = robot.home_pose + ROUND_TRIP_OFFSET
    q_tilted = robot.inverse_kinematics(pose)
    back = robot.forward_kinematics(q_tilted)
    tau = robot.static_forces(robot.home_pose)
    with progress_bar(quiet, "simulating 0.5 s"):
        run = motions.simulate_circle(robot, duration=0.5, dt=1e-3,
                                      controller="computed-torque", radius=0.01, period=0.5)
    traj = run.trajectory
    result = {
        "home_pose": robot.home_pose,
        "home_q": robot.home_q,
        "closure_rows": robot.model.n_rows,
        "closure_residual_max_abs_m": float(np.max(np.abs(robot.model.residual(q)))),
        "constraint_rank": robot.model.rank(q).rank,
        "mobility": robot.model.mobility(q),
        "round_trip": {"pose": pose, "q": q_tilted, "fk_pose": back,
                       "error": float(np.max(np.abs(back - pose)))},
        "statics": {"pose": robot.home_pose, "actuator_forces": tau},
        "simulation": {"controller": "computed-torque", "duration_s": float(traj.times[-1]),
                       "samples": len(traj.times), "status": run.status,
                       "max_closure_residual_m": float(np.max(np.abs(
                           getattr(traj, "closure_residual", 0.0)))),
                       "max_tracking_error_m": run.tracking_error,
                       "max_abs_actuator_force_n": float(np.max(np.abs(traj.actuator_forces)))},
        "html": None,
        "warmup": warmup_fields(report),
    }
    if not no_html:
        path = html or Path(tempfile.gettempdir()) / "hexapod_pin_demo.html"
        scenes.write_pose_html(path, robot, q, actuator_forces=tau,
                               caption="hexapod_pin demo: home pose, static actuator forces")
        result["html"] = str(path)
    if as_json:
        emit_json(result)
        return
    console.print(demo_table(result))


def demo_table(result: dict) -> Table:
    """The demo's results as a table of quantities with their units."""
    trip, sim = result["round_trip"], result["simulation"]
    return quantity_table("hexapod_pin demo", {
        "home pose (x, y, z) (m)": fmt(result["home_pose"][:3], ".6f"),
        "home pose (roll, pitch, yaw) (rad)": fmt(result["home_pose"][3:], ".3f"),
        "carriages q (m)": fmt(result["home_q"], "+.3f"),
        "closure rows / rank": f"{result['closure_rows']} / {result['constraint_rank']}",
        "mobility of the closed chain": str(result["mobility"]),
        "max closure residual (m)": f"{result['closure_residual_max_abs_m']:.2e}",
        "IK of a tilted pose: q (m)": fmt(trip["q"], "+.4f"),
        "FK(IK(pose)) - pose, max abs (m, rad)": f"{trip['error']:.2e}",
        "static actuator forces at home (N)": fmt(result["statics"]["actuator_forces"], "+.3f"),
        "0.5 s simulation (computed torque, 1 cm circle): max tracking error (m)":
            f"{sim['max_tracking_error_m']:.2e}",
        "  max closure residual (m) / status":
            f"{sim['max_closure_residual_m']:.1e} / {sim['status']}",
        "HTML of the home pose": result["html"] or "not written",
        "compiled kernels: wall time (s) / compiled now":
            f"{result['warmup']['seconds']:.1f} / {result['warmup']['compiled']}",
    })


def compile_kernels(quiet: bool) -> WarmupReport:
    """:func:`hexapod_pin.precompile.warmup` with a progress bar on a terminal (none when
    ``quiet``)."""
    from ..precompile import N_STEPS
    from ..precompile import warmup as warmup_kernels
    with progress_bar(quiet, "compiling the kernels (once per install)",
                      total=N_STEPS) as progress:
        return warmup_kernels(progress)


def warmup_fields(report: WarmupReport) -> dict:
    """The ``--json`` object of a warmup: total seconds, kernels compiled, every step
    (label, seconds, compiled) and the kernels still uncompiled."""
    return {"seconds": report.seconds, "compiled": report.compiled,
            "kernels": len(report.kernels), "uncompiled": list(report.uncompiled),
            "steps": [{"label": step.label, "seconds": step.seconds,
                       "compiled": step.compiled} for step in report.steps]}


@guard
def warmup(as_json: AsJson = False, quiet: Quiet = False) -> None:
    """Compile every compiled (numba) kernel of the library now, with a progress bar: the
    first calls after an install then wait for no compiler (the machine code is cached on
    disk; a second run takes about a second). `hexapod-pin demo` runs it first."""
    report = compile_kernels(quiet or as_json)
    if as_json:
        emit_json(warmup_fields(report))
        return
    table = Table(title=f"{len(report.kernels)} compiled kernels in the library: "
                        f"{report.compiled} compilations now (one per kernel and argument "
                        f"types; 0: all from the disk cache), {report.seconds:.1f} s")
    table.add_column("step")
    table.add_column("wall time (s)", justify="right")
    table.add_column("compiled now", justify="right")
    for step in report.steps:
        table.add_row(Text(step.label), f"{step.seconds:.2f}", str(step.compiled))
    console.print(table)
    if report.uncompiled:
        note(quiet, "not compiled (reached only by rarer routes; compiled on first use): "
                    + ", ".join(report.uncompiled))
