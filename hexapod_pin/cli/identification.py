"""The ``excite`` and ``identify`` commands: an optimised excitation trajectory written
as a motion file, and dynamic identification from a measured one
(:mod:`hexapod_pin.identification`)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import numpy as np
import typer

from ..errors import InputError
from .common import (
    AsJson,
    CliRobot,
    GeometryFile,
    PlatformFrame,
    PoseAxes,
    Quiet,
    RobotFile,
    SetFields,
    actuator_names,
    check_suffix,
    console,
    emit_json,
    guard,
    load_cli_robot,
    note,
    parse_numbers,
    progress_bar,
    quantity_table,
    read_robot_log,
    robot_fields,
    write_robot_motion,
)

#: the drive parameter kinds of the ``--drive`` help, a copy of
#: ``hexapod_pin.identification.parameters.DRIVE_KINDS`` (``--help`` does not import the
#: library; a test keeps them equal)
DRIVE_NAMES = ("armature", "viscous", "coulomb", "offset")

Drive = Annotated[str, typer.Option(
    help=f"drive parameters per actuator, comma-separated, of {', '.join(DRIVE_NAMES)} "
         "(none: 'none')")]


def _drive(text: str) -> tuple[str, ...]:
    from ..identification.parameters import check_drive

    if text.strip().lower() in ("", "none"):
        return ()
    return check_drive(tuple(part.strip() for part in text.split(",")))


@guard
def excite(out: Annotated[Path, typer.Option(
               help="the motion file to write (.csv / .json): t, pose, twist, its "
                    "derivative, q, tau (the nominal robot's forces)")] = Path("excite.csv"),
           harmonics: Annotated[int, typer.Option(help="harmonics of the Fourier series "
                                                  "(>= 2)")] = 3,
           frequency: Annotated[float, typer.Option(help="base frequency f0 (Hz); the "
                                                   "period is 1 / f0")] = 0.5,
           samples: Annotated[int, typer.Option(help="samples per period of the "
                                                "optimisation")] = 40,
           amplitude: Annotated[str, typer.Option(
               help="bound of every coefficient: 'linear,angular' (m, rad)")] = "0.02,0.1",
           iterations: Annotated[int, typer.Option(help="SLSQP iterations at most")] = 30,
           periods: Annotated[int, typer.Option(help="periods written")] = 1,
           rate: Annotated[int, typer.Option(
               "--rate", help="samples written per optimisation sample")] = 10,
           seed: Annotated[int, typer.Option(help="seed of the random start")] = 0,
           drive: Drive = "viscous,coulomb,offset",
           as_json: AsJson = False, quiet: Quiet = False,
           robot: RobotFile = None, platform: PlatformFrame = None,
           pose_axes: PoseAxes = None,
           geometry: GeometryFile = None, set_: SetFields = None) -> None:
    """An excitation trajectory for dynamic identification, written as a motion file.

    A Fourier series in the robot's pose space about home, at rest at both ends,
    optimised for the condition number of the base regressor within reach, strokes,
    singularity margins and actuator force bounds, and checked at 10x its sampling rate
    (hexapod_pin.identification.excitation). The file has `t`, the pose, twist and its
    derivative, `q0..` and `tau0..` (the nominal robot's forces)."""
    from .. import motion as motions
    from ..identification import optimise_excitation

    quiet = quiet or as_json
    check_suffix("out", out, motions.MOTION_SUFFIXES)
    bot = load_cli_robot(robot, platform, pose_axes, geometry, set_)
    amp = parse_numbers([amplitude], 2, "--amplitude", "linear,angular")
    with progress_bar(quiet, "optimising the excitation", total=100) as update:
        ex = optimise_excitation(bot, harmonics=harmonics, base_frequency=frequency,
                                 samples=samples, amplitude=(float(amp[0]), float(amp[1])),
                                 drive=_drive(drive), max_iterations=iterations, seed=seed,
                                 progress=lambda f: update(round(100 * f)))
    motion = ex.motion(rate_factor=rate, periods=periods)
    write_robot_motion(out, motion, bot)
    force = float(np.max(np.abs(ex.actuator_forces)))
    summary: dict[str, Any] = {
        "out": str(out), "samples_written": int(motion.t.size),
        "period_s": ex.series.period, "harmonics": harmonics,
        "condition_number": ex.condition_number,
        "initial_condition_number": ex.initial_condition_number,
        "iterations": ex.iterations, "shrinks": ex.shrinks,
        "max_abs_force": force, "base_parameters": ex.base.count}
    if as_json:
        emit_json({**summary, "robot": robot_fields(bot)})
        return
    console.print(quantity_table("excitation trajectory", {
        "file": str(out), "samples written": str(motion.t.size),
        "period (s)": f"{ex.series.period:.6g}", "harmonics": str(harmonics),
        "base parameters": str(ex.base.count),
        "condition number (start -> optimised)":
            f"{ex.initial_condition_number:.4g} -> {ex.condition_number:.4g}",
        "iterations": str(ex.iterations),
        "max |actuator force|": f"{force:.4g}"}))
    if ex.shrinks:
        note(quiet, f"scaled down {ex.shrinks} times to pass the check at "
                    f"{ex.check_factor}x the sampling rate")


@guard
def identify(data: Annotated[Path, typer.Argument(
                 help="motion file (.csv / .json) with t, q0.. (actuator positions) and "
                      "tau0.. (measured actuator forces); pose columns optional (used "
                      "with --use-poses)")],
             drive: Drive = "viscous,coulomb,offset",
             cutoff: Annotated[float | None, typer.Option(
                 help="low-pass cut-off of the positions (Hz); default a fifth of the "
                      "Nyquist frequency", show_default=False)] = None,
             trim: Annotated[int | None, typer.Option(
                 help="samples dropped at each end (default: three periods of the "
                      "cut-off)", show_default=False)] = None,
             position_noise: Annotated[float | None, typer.Option(
                 help="standard deviation of the actuator position sensors' white noise "
                      "(m or rad, e.g. 1e-6): identify removes the bias it causes and "
                      "widens the standard errors (default: estimated from the data, "
                      "the bias reported, not removed)", show_default=False)] = None,
             use_poses: Annotated[bool, typer.Option(
                 "--use-poses", help="use the file's poses (default: forward kinematics "
                 "of the measured actuator positions)")] = False,
             consistent: Annotated[bool, typer.Option(
                 "--consistent/--no-consistent",
                 help="also fit the physically consistent parameters")] = True,
             figure: Annotated[Path | None, typer.Option(
                 help="write a figure of measured against predicted forces (.png / .svg / "
                      ".pdf; needs matplotlib) and one of the parameters beside it "
                      "(<name>_parameters.<suffix>)", show_default=False)] = None,
             as_json: AsJson = False, quiet: Quiet = False,
             robot: RobotFile = None, platform: PlatformFrame = None,
             pose_axes: PoseAxes = None,
             geometry: GeometryFile = None, set_: SetFields = None) -> None:
    """Dynamic identification from a measured motion: the base parameters with standard
    errors, and the force residuals before (nominal robot) and after.

    The actuator positions are low-pass filtered zero-phase and differentiated; the
    forces are used as measured (hexapod_pin.identification.motion_data). Prints every
    base parameter (nominal, estimate, standard error, consistent estimate)."""
    from ..identification import MotionData
    from ..identification import identify as identify_motion

    quiet = quiet or as_json
    bot = load_cli_robot(robot, platform, pose_axes, geometry, set_)
    log = read_robot_log(data, bot)
    if use_poses and log.poses is None:
        raise InputError("use_poses", True, f"{data} has no pose columns (leave out "
                                            "--use-poses: forward kinematics)")
    measured = MotionData(log.t, log.q, log.actuator_forces,
                          log.poses if use_poses else None)
    with progress_bar(quiet, "identifying"):
        res = identify_motion(bot, measured, cutoff=cutoff, trim=trim, drive=_drive(drive),
                              position_noise_std=position_noise, consistent=consistent)
    if figure is not None:
        _figures(figure, bot, res, measured)
    payload: dict[str, Any] = {
        "names": list(res.names), "nominal": res.nominal_values, "values": res.values,
        "std_errors": res.std_errors, "consistent": res.consistent_values,
        "consistent_gap": res.consistent_gap, "noise_std": res.noise_std,
        "condition_number": res.condition_number,
        "residual_rms_before": res.before.rms, "residual_rms_after": res.after.rms,
        "residual_rms_per_actuator_before": res.before.rms_per_actuator,
        "residual_rms_per_actuator_after": res.after.rms_per_actuator,
        "samples": res.after.count, "rules": list(res.base.rules())}
    if as_json:
        emit_json({**payload, "robot": robot_fields(bot)})
        return
    console.print(res.table())
    console.print(quantity_table("force residuals (measured - predicted)", {
        "samples used": str(res.after.count),
        "rms before (nominal robot)": f"{res.before.rms:.4g}",
        "rms after (estimate)": f"{res.after.rms:.4g}",
        "noise per actuator": " ".join(f"{s:.3g}" for s in res.noise_std),
        "condition number": f"{res.condition_number:.4g}"}))
    if res.consistent_gap is not None:
        note(quiet, f"consistent estimate within {res.consistent_gap:.2f} standard errors "
                    "of the least-squares one")


def _figures(path: Path, bot: CliRobot, res: Any, measured: Any) -> None:
    """The two figures of ``--figure`` (``measured``: the
    :class:`~hexapod_pin.identification.MotionData`)."""
    from ..identification.motion_data import states_from_motion
    from ..viz.identification_plots import plot_force_prediction, plot_parameter_estimates

    st = states_from_motion(bot, measured, res.cutoff, res.trim)
    predicted = res.predict(st.poses, st.twists, st.twist_dots)
    plot_force_prediction(st.times, st.actuator_forces, predicted, path=path,
                          names=list(actuator_names(bot)))
    plot_parameter_estimates(res.names, res.values, res.std_errors, res.nominal_values,
                             path=path.with_name(f"{path.stem}_parameters{path.suffix}"))
