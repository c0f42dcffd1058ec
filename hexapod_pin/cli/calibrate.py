"""The ``calibrate`` command: identify the as-built geometry from a measurement file
(:mod:`hexapod_pin.calibration`), report it and write the geometry file that
``--geometry`` reads."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import numpy as np
import typer

from .common import (
    AsJson,
    Degrees,
    GeometryFile,
    Quiet,
    SetFields,
    check_suffix,
    console,
    emit_json,
    guard,
    note,
    parse_numbers,
    plain,
    quantity_table,
    robot_of,
)

if TYPE_CHECKING:
    from .. import calibration as cal
    from ..calibration.problem import Measurements


def _subset(data: Measurements, rows: np.ndarray) -> Measurements:
    from ..calibration.problem import Measurements
    return Measurements(data.actuators[rows],
                        None if data.poses is None else data.poses[rows],
                        None if data.points is None else data.points[rows],
                        data.target_points)


def _pose_option(text: str | None, name: str, degrees: bool) -> np.ndarray | None:
    if text is None:
        return None
    pose = parse_numbers([text], 6, name, "x y z roll pitch yaw")
    if degrees:
        pose[3:] = np.radians(pose[3:])
    return pose


@guard
def calibrate(measurements: Annotated[Path, typer.Argument(
                  help="CSV: q0..q5 and x,y,z,roll,pitch,yaw (target pose in the instrument "
                       "frame) or p0_x,p0_y,p0_z,... (target points)")],
              out: Annotated[Path | None, typer.Option(
                  help="write the identified geometry (.toml / .yaml / .json), commanded in "
                       "the measurement frames; read it back with --geometry",
                  show_default=False)] = None,
              out_robot_frame: Annotated[Path | None, typer.Option(
                  "--out-robot-frame", help="also write the identified geometry in the "
                  "robot's own frames (for dynamics: gravity along its -z)",
                  show_default=False)] = None,
              select_poses: Annotated[int | None, typer.Option(
                  "--select-poses", help="identify from the N most informative rows (O1, "
                  "greedy) and validate on the others", show_default=False)] = None,
              identify: Annotated[str, typer.Option(
                  help="parameter groups: chains (or line_points, line_directions, "
                       "sensor_offsets, leg_lengths, platform_joints), instrument, target")
              ] = "chains,instrument,target",
              instrument: Annotated[str | None, typer.Option(
                  help="guessed instrument pose in the robot world 'x,y,z,roll,pitch,yaw' "
                       "(default: registered onto the nominal robot)",
                  show_default=False)] = None,
              target: Annotated[str | None, typer.Option(
                  help="guessed target pose in the platform frame 'x,y,z,roll,pitch,yaw'",
                  show_default=False)] = None,
              target_point: Annotated[list[str] | None, typer.Option(
                  "--target-point", help="target-frame coordinates 'x,y,z' of point j of a "
                  "file of points (repeat in column order)", show_default=False)] = None,
              validate: Annotated[Path | None, typer.Option(
                  help="held-out measurements (CSV, same columns) to validate on",
                  show_default=False)] = None,
              degrees: Degrees = False, as_json: AsJson = False, quiet: Quiet = False,
              geometry: GeometryFile = None, set_: SetFields = None) -> None:
    """Kinematic calibration: identify the per-chain geometry (lines, sensor zeros, leg
    lengths, platform joints) and the instrument and target frames from measured target
    poses or points and the actuator readings, by least squares on the base parameter
    set; report the residuals, the identifiability and the estimates with their standard
    errors."""
    from .. import calibration as cal
    from ..calibration.measurements import read_measurements
    from ..calibration.selection import select_measurements
    from ..files import GEOMETRY_SUFFIXES, save_geometry
    quiet = quiet or as_json
    check_suffix("out", out, GEOMETRY_SUFFIXES)
    check_suffix("out-robot-frame", out_robot_frame, GEOMETRY_SUFFIXES)
    robot = robot_of(geometry, set_)
    points = None if not target_point else np.array(
        [parse_numbers([p], 3, "target-point", "x y z") for p in target_point])
    data = read_measurements(measurements, points, degrees)
    groups = tuple(g.strip() for g in identify.split(",") if g.strip())
    inst_guess = _pose_option(instrument, "instrument", degrees)
    targ_guess = _pose_option(target, "target", degrees)
    rows = np.arange(data.count)
    held = None
    if select_poses is not None:
        chosen = select_measurements(robot, data, select_poses, identify=groups,
                                     instrument=inst_guess, target=targ_guess)
        rows = np.sort(chosen.indices)
        rest = np.setdiff1d(np.arange(data.count), rows)
        held = _subset(data, rest) if rest.size else None
    used = _subset(data, rows)
    result = cal.calibrate(robot, used.poses, used.actuators, points=used.points,
                           target_points=used.target_points, identify=groups,
                           instrument=inst_guess, target=targ_guess)
    if validate is not None:
        held = read_measurements(validate, points, degrees)
    report = None
    if held is not None:
        report = result.validate(held.poses, held.actuators, points=held.points)
    for path, geom in ((out, result.robot.geometry), (out_robot_frame, result.geometry)):
        if path is not None:
            save_geometry(geom, path)
            note(quiet, f"wrote {path}")
    if as_json:
        emit_json(_payload(result, rows, report, out))
        return
    _print_report(result, data.count, rows, report)


def _payload(result: cal.CalibrationResult, rows: np.ndarray,
             report: cal.ValidationReport | None, out: Path | None) -> dict:
    idr = result.identifiability
    return {"measurement": result.measurement, "rows_used": rows,
            "residuals_before": result.residuals_before,
            "residuals_after": result.residuals_after,
            "identifiability": {"requested": len(idr.requested), "rank": idr.rank,
                                "base": list(idr.base), "fixed": list(idr.fixed),
                                "unidentifiable": list(idr.unidentifiable),
                                "condition_number": idr.condition_number,
                                "singular_values": idr.singular_values},
            "parameters": [plain(p) for p in result.parameters],
            "instrument": result.instrument, "target": result.target,
            "iterations": result.iterations, "status": result.status,
            "validation": None if report is None else
            {"nominal": report.nominal.summary(), "identified": report.identified.summary()},
            "out": None if out is None else str(out)}


def _print_report(result: cal.CalibrationResult, count: int, rows: np.ndarray,
                  report: cal.ValidationReport | None) -> None:
    idr = result.identifiability
    before, after = result.residuals_before, result.residuals_after
    console.print(quantity_table("calibration", {
        "measurements used": f"{rows.size} of {count} ({result.measurement})",
        "parameters requested / base": f"{len(idr.requested)} / {len(idr.base)}",
        "rank at the data": str(idr.rank),
        "condition number (base, scaled)": f"{idr.condition_number:.4g}",
        "residual RMS before / after (m)": f"{before.rms:.3e} / {after.rms:.3e}",
        "residual max before / after (m)": f"{before.max:.3e} / {after.max:.3e}",
        "function evaluations": str(result.iterations),
        "instrument pose (m, rad)": " ".join(f"{v:+.6f}" for v in result.instrument),
        "target pose (m, rad)": " ".join(f"{v:+.6f}" for v in result.target)}))
    for text in idr.unidentifiable:
        console.print(f"not identifiable: {text}", markup=False, highlight=False)
    table = quantity_table("identified deviations from the nominal (m, rad)", {
        p.name: (f"{p.deviation:+.4e} +- {p.std_error:.2e}" if p.identified
                 else f"{p.deviation:+.4e} (held)") for p in result.parameters})
    console.print(table)
    if report is not None:
        rows_out = {}
        for name, errors in (("nominal", report.nominal), ("identified", report.identified)):
            for key, value in errors.summary().items():
                if key.endswith("failures"):
                    rows_out[f"{name} {key.replace('_', ' ')}"] = str(int(value))
                    continue
                unit = "rad" if key.startswith("rotation") else "m"
                rows_out[f"{name} {key.replace('_', ' ')} ({unit})"] = f"{value:.3e}"
        console.print(quantity_table("validation on held-out measurements", rows_out))
