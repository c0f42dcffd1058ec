"""Dynamics commands: ``statics``, ``fd`` (forward dynamics of one state), ``id`` (inverse
dynamics along a motion file), ``simulate`` (the hexapod: closed-loop simulation tracking
a circle; any robot of ``--robot``: :func:`hexapod_pin.core.simulate.simulate` under
constant forces or computed torque holding home).

Each takes ``--effects FILE``: joint and drive effects (armature, damping, Coulomb
friction, springs, gears) over the robot's own, from a YAML or TOML file in the format of
a loops file's ``effects:`` section (:func:`hexapod_pin.core.description.read_effects_file`);
the output then says which effects are on (a line ``effects (FILE): damping on 6
joints, ...``; with ``--json`` an ``effects`` object) and ``simulate`` reports the work
they dissipated."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, NamedTuple

import numpy as np
import typer

from ..errors import InputError
from .common import (
    TWIST_OF,
    WRENCH_OF,
    AsJson,
    CliRobot,
    Degrees,
    EffectsFile,
    GeometryFile,
    PlatformFrame,
    PoseAxes,
    Quiet,
    RobotFile,
    SetFields,
    Values,
    actuator_table,
    as_parallel,
    check_suffix,
    component_values,
    console,
    effects_fields,
    emit_json,
    guard,
    hexapod_only,
    load_cli_robot,
    note,
    parse_numbers,
    pose_axes_of,
    print_effects,
    progress_bar,
    quantity_table,
    read_robot_motion,
    robot_fields,
    robot_pose_in,
    robot_pose_out,
    robot_urdf,
    write_robot_motion,
)

if TYPE_CHECKING:
    from .. import motion as motions
    from ..core.robot import ClosedLoopRobot
    from ..core.simulate import Trajectory

#: the integrators ``simulate --integrator`` takes, for its help: those of
#: :data:`hexapod_pin.core.simulation.INTEGRATORS` (``--help`` imports no library module;
#: tests/cli/test_startup.py checks that the two agree)
INTEGRATOR_NAMES = ("auto", "rk4", "semi_implicit_euler", "stick_slip")
#: the controllers of ``simulate --robot``
ROBOT_CONTROLLERS = ("none", "computed-torque")


@guard
def statics(pose: Values = None,
            wrench: Annotated[str | None, typer.Option(
                help="wrench on the platform 'fx,fy,fz,mx,my,mz' (N, N m, world axes)")] = None,
            degrees: Degrees = False, as_json: AsJson = False,
            robot: RobotFile = None, platform: PlatformFrame = None,
            pose_axes: PoseAxes = None,
            geometry: GeometryFile = None, set_: SetFields = None,
            effects: EffectsFile = None) -> None:
    """Actuator forces (N) holding the platform at rest at a pose (default home).

    With `--robot`: in its pose axes; `--wrench` has one value per pose axis (fx for x,
    mx for roll, ...); forces in N or N m along each actuated joint. With `--effects`:
    the springs' forces included (damping and friction give none at rest)."""
    from ..core.robot import ClosedLoopRobot
    bot = load_cli_robot(robot, platform, pose_axes, geometry, set_, effects)
    p = robot_pose_in(bot, pose, degrees)
    w = component_values(bot, wrench, "wrench", WRENCH_OF)
    tau = bot.static_forces(p, wrench=w)
    if as_json:
        emit_json({"pose": robot_pose_out(bot, p, degrees), "wrench": w,
                   "actuator_forces": tau, **robot_fields(bot),
                   **effects_fields(bot, effects)})
        return
    print_effects(bot, effects)
    title = ("static actuator forces (+ along the rail direction u_k)"
             if not isinstance(bot, ClosedLoopRobot) else
             "static actuator forces (+ along each actuated joint)")
    console.print(actuator_table(bot, title, {force_unit(bot): tau}))


def force_unit(robot: object) -> str:
    """The column name of actuator forces: ``tau (N)`` for the hexapod, ``tau (N | N m)``
    for a loaded robot (each in its joint's unit)."""
    from ..core.robot import ClosedLoopRobot
    return "tau (N | N m)" if isinstance(robot, ClosedLoopRobot) else "tau (N)"


@guard
def fd(pose: Values = None,
       twist: Annotated[str | None, typer.Option(
           help="platform twist 'vx,vy,vz,wx,wy,wz' (m/s, rad/s, world axes; with --robot "
                "one value per pose axis); default rest")] = None,
       forces: Annotated[str | None, typer.Option(
           help="actuator forces 'u0,u1,...' (N or N m, actuator order); default the "
                "static forces of the pose (the platform then stays at rest)")] = None,
       wrench: Annotated[str | None, typer.Option(
           help="wrench on the platform 'fx,fy,fz,mx,my,mz' (N, N m, world axes; with "
                "--robot one value per pose axis)")] = None,
       method: Annotated[str, typer.Option(
           help="nullspace, pinocchio, qp or kkt (every route agrees to 1e-10)")
       ] = "nullspace",
       degrees: Degrees = False, as_json: AsJson = False,
       robot: RobotFile = None, platform: PlatformFrame = None, pose_axes: PoseAxes = None,
       geometry: GeometryFile = None, set_: SetFields = None,
       effects: EffectsFile = None) -> None:
    """Forward dynamics of one state: the platform acceleration (twist derivative) and
    the actuator accelerations produced by actuator forces at a pose (default home) and
    twist (default rest).

    With `--effects`: the effects act with the forces (Coulomb friction of a joint at
    rest sticks or slips); the default forces are then the static forces with the
    springs."""
    bot = load_cli_robot(robot, platform, pose_axes, geometry, set_, effects)
    p = robot_pose_in(bot, pose, degrees)
    v = component_values(bot, twist, "twist", TWIST_OF)
    w = component_values(bot, wrench, "wrench", WRENCH_OF)
    u = bot.static_forces(p, wrench=w, bounded=False) if forces is None else \
        parse_numbers([forces], bot.n_actuators, "forces", f"{bot.n_actuators} actuator forces")
    v = np.zeros(bot.pose_dim) if v is None else v
    result = bot.forward_dynamics(p, v, u, wrench=w, method=method)
    if as_json:
        emit_json({"pose": robot_pose_out(bot, p, degrees), "twist": v, "wrench": w,
                   "actuator_forces": u, "twist_dot": result.twist_dot,
                   "actuator_accelerations": result.actuator_accelerations,
                   "method": result.method, **robot_fields(bot),
                   **effects_fields(bot, effects)})
        return
    print_effects(bot, effects)
    axes = pose_axes_of(bot)
    console.print(quantity_table("forward dynamics: twist derivative (world axes)", {
        f"d{TWIST_OF[a]}/dt ({'rad' if TWIST_OF[a][0] == 'w' else 'm'}/s^2)": f"{value:+.6g}"
        for a, value in zip(axes, result.twist_dot)}))
    console.print(actuator_table(bot, f"actuator forces and accelerations ({result.method})",
                                 {force_unit(bot): u,
                                  "acceleration (m/s^2 | rad/s^2)":
                                      result.actuator_accelerations}))


@guard
def inverse_dynamics(motion_file: Annotated[Path, typer.Argument(
                         help="motion file (.csv / .json; format: see above)")],
                     out: Annotated[Path | None, typer.Option(
                         help="write the motion with the forces (.csv / .json)")] = None,
                     method: Annotated[str, typer.Option(
                         help="kkt (the square system solved exactly) or qp (ProxSuite, "
                              "certifying the force bounds)")] = "kkt",
                     as_json: AsJson = False, quiet: Quiet = False,
                     robot: RobotFile = None, platform: PlatformFrame = None,
                     pose_axes: PoseAxes = None,
                     geometry: GeometryFile = None, set_: SetFields = None,
                     effects: EffectsFile = None) -> None:
    """Inverse dynamics along a motion file: actuator forces (N) at every sample.

    Motion file, CSV: a header row, then one row per sample; columns `t` (s), `x, y, z`
    (m), `roll, pitch, yaw` (rad), optional `vx, vy, vz, wx, wy, wz` (twist, world axes),
    `ax, ay, az, alphax, alphay, alphaz` (its derivative), `fx, fy, fz, mx, my, mz`
    (wrench on the platform, N, N m), `q0..q5`, `tau0..tau5`, `residual`. JSON: keys
    `t`, `pose` (N x 6), optional `twist`, `twist_dot`, `wrench`, `q`, `actuator_forces`,
    `closure_residual`. A missing twist is computed from the poses by finite differences.

    With `--robot`: the same selection of each group for its pose axes, one `qN` and
    `tauN` per actuator (a five-bar in x, z: `t, x, z, vx, vz, ..., q0, q1, tau0, tau1`);
    forces in N or N m along each actuated joint.

    With `--effects`: the forces also balance the effects (rotor inertia, damping,
    Coulomb friction of the moving joints, springs).
    """
    from .. import motion as motions
    from ..hexapod.robot import Hexapod
    quiet = quiet or as_json
    check_suffix("out", out, motions.MOTION_SUFFIXES)
    bot = load_cli_robot(robot, platform, pose_axes, geometry, set_, effects)
    motion = read_robot_motion(motion_file, bot)
    rates_of = None if isinstance(bot, Hexapod) else as_parallel(bot)
    with progress_bar(quiet, "inverse dynamics", total=len(motion.t)) as progress:
        tau = motions.inverse_dynamics_along(as_parallel(bot), motion, method,
                                             progress).actuator_forces
    if out is not None:
        twists, dots = motions.motion_rates(motion, rates_of)
        write_robot_motion(out, dataclasses.replace(motion, twists=twists, twist_dots=dots,
                                                    actuator_forces=tau), bot)
        note(quiet, f"wrote {out}")
    peak = np.max(np.abs(tau), axis=0)
    if as_json:
        emit_json({"t": motion.t, "actuator_forces": tau, "max_abs_actuator_forces": peak,
                   "out": out, **robot_fields(bot), **effects_fields(bot, effects)})
        return
    print_effects(bot, effects)
    unit = "N" if isinstance(bot, Hexapod) else "N | N m"
    console.print(actuator_table(
        bot, f"inverse dynamics over {len(motion.t)} samples, {motion.t[-1] - motion.t[0]:g} s",
        {f"max |tau| ({unit})": peak, "at t (s)": motion.t[np.argmax(np.abs(tau), axis=0)],
         f"mean tau ({unit})": tau.mean(axis=0)}))


@guard
def simulate(duration: Annotated[float, typer.Option(help="simulated time (s)")] = 2.0,
             dt: Annotated[float | None, typer.Option(
                 help="time step (s); default 0.25 ms for pid, 1 ms otherwise",
                 show_default=False)] = None,
             controller: Annotated[str | None, typer.Option(
                 help="pid (Quanser gains), computed-torque, or none (no actuator force); "
                      "default pid; with --robot: none (the forces of --forces) or "
                      "computed-torque (holding home)", show_default=False)] = None,
             engine: Annotated[str | None, typer.Option(
                 help="fast (compiled, PID or none), python (Pinocchio tree route, every "
                      "controller), auto (fast unless computed-torque); default auto",
                 show_default=False)] = None,
             radius: Annotated[float | None, typer.Option(
                 help="radius of the reference circle of the platform about home (m); "
                      "default 0.02", show_default=False)] = None,
             period: Annotated[float | None, typer.Option(
                 help="period of the circle (s); default 2", show_default=False)] = None,
             forces: Annotated[str | None, typer.Option(
                 help="with --robot and no controller: constant actuator forces "
                      "'u0,u1,...' (N or N m, actuator order); default zero")] = None,
             integrator: Annotated[str, typer.Option(
                 help=f"{', '.join(INTEGRATOR_NAMES)}: auto picks stick_slip (exact Coulomb "
                      "friction at velocity level) when the joints have Coulomb friction, "
                      "else rk4; the hexapod's fast engine steps rk4 or "
                      "semi_implicit_euler (auto runs stick_slip on the python engine)")
             ] = "auto",
             out: Annotated[Path | None, typer.Option(
                 help="write the trajectory (.csv / .json motion file)")] = None,
             html: Annotated[Path | None, typer.Option(
                 help="write an animated HTML view")] = None,
             plot: Annotated[Path | None, typer.Option(
                 help="write a figure (.png / .svg / .pdf) of q, forces, residual")] = None,
             allow_saturation: Annotated[bool, typer.Option(
                 "--allow-saturation", help="a run whose commands were clipped to the force "
                 "bound (status saturated) exits with code 0 (still with its warning)")
             ] = False,
             as_json: AsJson = False, quiet: Quiet = False,
             robot: RobotFile = None, platform: PlatformFrame = None,
             pose_axes: PoseAxes = None,
             geometry: GeometryFile = None, set_: SetFields = None,
             effects: EffectsFile = None) -> None:
    """Simulate the closed-loop dynamics tracking a circle of the platform about home.

    Exit code 1 unless the run completed and tracked the circle (status `completed`):
    a stop at a stroke limit, a failure, a tracking error above the circle's radius
    (status `tracking_lost`, e.g. a step too long for the PID gains) or commands clipped
    to the force bound (status `saturated`, with a warning; exit code 0 with
    `--allow-saturation`) are failures.
    With `--json` the summary is printed with exit code 0 and its `status` says what
    happened.

    With `--robot`: the generic simulation (`hexapod_pin.simulate`) from home at rest,
    under constant actuator forces (`--forces`, default zero) or computed torque holding
    the home pose; statuses `completed`, `saturated` (exit code 1) or `failed` (exit
    code 1).

    With `--effects` (or a robot whose description has effects): the summary reports the
    integrator that ran and the work the damping and friction dissipated
    (`dissipated_work_j`)."""
    from .. import motion as motions
    from ..core.robot import ClosedLoopRobot
    from ..viz import hexapod_scenes, plotting
    quiet = quiet or as_json
    bot = load_cli_robot(robot, platform, pose_axes, geometry, set_, effects)
    check_suffix("out", out, motions.MOTION_SUFFIXES)
    check_suffix("html", html, (".html", ".htm"))
    check_suffix("plot", plot, plotting.IMAGE_SUFFIXES)
    if isinstance(bot, ClosedLoopRobot):
        hexapod_only(bot, engine=engine, radius=radius, period=period)
        _simulate_loaded(bot, duration, dt, controller or "none", forces,
                         integrator, SimulateFiles(out, html, plot, effects), as_json, quiet,
                         robot_urdf(bot, robot), allow_saturation)
        return
    if forces is not None:
        raise InputError("forces", forces, "--forces is an option of simulate --robot")
    controller = controller or "pid"
    engine = engine or "auto"
    radius = 0.02 if radius is None else radius
    period = 2.0 if period is None else period
    compiled = engine == "fast" or (engine == "auto" and controller != "computed-torque")
    steps = round(duration / (dt or motions.DEFAULT_DT.get(controller, 1e-3))) \
        if np.isfinite(duration) and duration > 0 and not compiled else None
    # the compiled loop reports nothing until it ends: a spinner instead of a bar
    with progress_bar(quiet, f"simulating {duration:g} s",
                      total=None if steps is None else max(steps, 1)) as progress:
        run = motions.simulate_circle(bot, duration, dt, controller, radius, period,
                                      progress, engine=engine, integrator=integrator)
    traj = run.trajectory
    motion = motions.Motion.from_trajectory(traj)
    if out is not None:
        motions.write_motion(out, motion)
        note(quiet, f"wrote {out}")
    if html is not None:
        with progress_bar(quiet, "writing HTML"):
            hexapod_scenes.write_simulation_html(
                html, bot, traj,
                caption=f"simulation: {controller} control, circle r = {radius:g} m, "
                        f"{motion.t[-1]:g} s ({run.status})")
        note(quiet, f"wrote {html}")
    if plot is not None:
        plotting.plot_simulation(traj, path=plot, title=f"simulation, {controller} control")
        note(quiet, f"wrote {plot}")
    residual = motion.closure_residual
    summary = {"status": run.status, "message": run.message, "engine": run.engine,
               "integrator": traj.integrator,
               "duration_s": float(motion.t[-1] - motion.t[0]), "samples": len(motion.t),
               "wall_time_s": float(traj.wall_time),
               "max_tracking_error_m": run.tracking_error,
               "tracking_tolerance_m": run.tolerance,
               "max_abs_actuator_force_n": float(np.max(np.abs(traj.actuator_forces))),
               "saturated_fraction": float(np.mean(traj.saturated)),
               "max_closure_residual_m": None if residual is None else float(np.max(residual)),
               "dissipated_work_j": dissipated_work(bot, traj.dissipated_work),
               "out": out, "html": html, "plot": plot}
    if as_json:
        emit_json({**summary, **effects_fields(bot, effects)})
        return
    print_effects(bot, effects)
    console.print(quantity_table(
        f"simulation: {controller} control, circle r = {radius:g} m",
        {key: f"{value:.4g}" if isinstance(value, float) else str(value)
         for key, value in summary.items() if value not in (None, "")}))
    end_of_run(run.status, run.message, allow_saturation)


def end_of_run(status: str, message: str, allow_saturation: bool) -> None:
    """The end of ``simulate``'s text output: the warning of a saturated run on stderr,
    then exit code 1 unless the status is ``completed`` (or ``saturated`` with
    ``allow_saturation``)."""
    if status == "saturated":
        note(False, f"warning: {message}")
    if status != "completed" and not (allow_saturation and status == "saturated"):
        raise typer.Exit(code=1)


def dissipated_work(robot: CliRobot, work: np.ndarray) -> float | None:
    """The work (J) the joint effects dissipated over a run (the last of the cumulative
    ``work`` (n,)); None for a robot without damping or friction (left out of the
    summary)."""
    effects = robot.effects
    if not (effects.damping.any() or effects.coulomb.any()):
        return None
    return float(work[-1]) if np.size(work) else 0.0


class SimulateFiles(NamedTuple):
    """The files ``simulate --robot`` reads and writes (None: not asked for).

    Attributes:
        out: the motion file (:func:`trajectory_motion`). html: the animated view.
        plot: the figure of actuator positions, forces and closure residual.
        effects: the effects file read (``--effects``).
    """

    out: Path | None
    html: Path | None
    plot: Path | None
    effects: Path | None = None


def trajectory_motion(traj: Trajectory) -> motions.Motion:
    """The motion-file samples of a generic simulation
    (:func:`hexapod_pin.core.simulate.simulate`):
    :meth:`hexapod_pin.motion.Motion.from_trajectory` (times, poses, twists, actuator
    positions and forces, max-abs closure residual).

    Raises:
        InputError: a trajectory without poses (a bare model has no platform).
    """
    from .. import motion as motions
    return motions.Motion.from_trajectory(traj)


def _simulate_loaded(robot: ClosedLoopRobot, duration: float, dt: float | None,
                     controller: str, forces: str | None, integrator: str,
                     files: SimulateFiles, as_json: bool, quiet: bool,
                     urdf: Path | None, allow_saturation: bool = False) -> None:
    """``simulate --robot``: the generic simulation from home at rest, its files, its
    summary, and exit code 1 unless it completed (:func:`end_of_run`)."""
    from ..core.controllers import ComputedTorque
    from ..core.simulate import simulate as simulate_robot
    from ..core.simulation import INTEGRATORS
    from ..viz import plotting, scenes
    html = files.html
    if controller not in ROBOT_CONTROLLERS:
        raise InputError("controller", controller,
                         f"with --robot expected one of {', '.join(ROBOT_CONTROLLERS)}")
    if integrator not in INTEGRATORS:
        raise InputError("integrator", integrator, f"expected one of {', '.join(INTEGRATORS)}")
    n = robot.n_actuators
    ctrl = None
    u: np.ndarray | None = None
    if controller == "computed-torque":
        if forces is not None:
            raise InputError("forces", forces, "not with --controller computed-torque")
        home, rest = robot.home_pose, np.zeros(robot.pose_dim)
        ctrl = ComputedTorque(lambda t: (home, rest, rest))
    else:
        u = np.zeros(n) if forces is None else parse_numbers(
            [forces], n, "forces", ", ".join(robot.model.actuated_joints))
    with progress_bar(quiet, f"simulating {duration:g} s", total=100) as progress:
        traj = simulate_robot(as_parallel(robot), duration,
                              1e-3 if dt is None else dt, controller=ctrl,
                              actuator_forces=u, integrator=integrator,
                              progress=lambda done: progress(round(100 * done), 100))
    if html is not None:
        with progress_bar(quiet, "writing HTML"):
            scenes.write_trajectory_html(
                html, robot, traj.times, traj.q, actuator_forces=traj.actuator_forces, urdf=urdf,
                caption=f"simulation of {robot.geometry.name}: {controller} control, "
                        f"{traj.times[-1]:g} s ({traj.status})")
        note(quiet, f"wrote {html}")
    if files.out is not None or files.plot is not None:
        motion = trajectory_motion(traj)
        if files.out is not None:
            write_robot_motion(files.out, motion, robot)
            note(quiet, f"wrote {files.out}")
        if files.plot is not None:
            plotting.plot_simulation(motion, path=files.plot,
                                     title=f"simulation of {robot.geometry.name}, "
                                           f"{controller} control")
            note(quiet, f"wrote {files.plot}")
    summary = loaded_summary(robot, traj, controller, integrator, files)
    if as_json:
        emit_json({**summary, **effects_fields(robot, files.effects)})
        return
    print_effects(robot, files.effects)
    console.print(quantity_table(
        f"simulation of {robot.geometry.name}: {controller} control",
        {key: shown(value) for key, value in summary.items() if value not in (None, "", [])}))
    end_of_run(traj.status, traj.message, allow_saturation)


def shown(value: object) -> str:
    """A summary value as table text: floats to 4 digits, lists joined."""
    if isinstance(value, float):
        return f"{value:.4g}"
    if isinstance(value, list):
        return " ".join(f"{v:+.6g}" if isinstance(v, float) else str(v) for v in value)
    return str(value)


def loaded_summary(robot: ClosedLoopRobot, traj: Trajectory, controller: str,
                   integrator: str, files: SimulateFiles) -> dict:
    """The summary of ``simulate --robot`` (the ``--json`` object): ``integrator`` the one
    that ran ("auto" resolved), the energy balance ``energies + dissipated_work - work``
    against its start (:attr:`~hexapod_pin.core.simulate.Trajectory.energy_residual`)."""
    final = None if traj.poses is None else robot_pose_out(robot, traj.poses[-1], False)
    balance = traj.energy_residual
    return {"status": traj.status, "message": traj.message, "controller": controller,
            "integrator": traj.integrator or integrator, "dt_s": traj.dt,
            "duration_s": float(traj.times[-1] - traj.times[0]),
            "samples": len(traj.times), "wall_time_s": float(traj.wall_time),
            "max_abs_actuator_force": float(np.max(np.abs(traj.actuator_forces))),
            "saturated_fraction": float(np.mean(traj.saturated)),
            "max_closure_residual": float(np.max(traj.closure_residual)),
            "max_energy_balance_error_j": float(np.max(np.abs(balance))),
            "dissipated_work_j": dissipated_work(robot, traj.dissipated_work),
            "final_pose": final, "out": files.out, "html": files.html, "plot": files.plot,
            **robot_fields(robot)}
