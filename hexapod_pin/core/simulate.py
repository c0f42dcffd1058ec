"""One simulation for every robot: :func:`simulate` and its :class:`Trajectory`.

:func:`simulate` integrates any :class:`~hexapod_pin.core.robot_api.ParallelRobot` (through
its protocol members only) or a bare :class:`~hexapod_pin.core.closed_loop.ClosedLoopModel`
with :class:`~hexapod_pin.core.simulation.ClosedLoopIntegrator`, under actuator forces
given as a constant, a function of time, or a controller (:mod:`hexapod_pin.core.controllers`).

Conventions:

* the state is the tree's ``(q, v)`` (Pinocchio conventions), projected onto the closures
  after every step (see :mod:`hexapod_pin.core.simulation`);
* actuator forces ``u`` (n_act,) (N or N m) act along each actuator's positive direction:
  the tree's generalised force is ``tau[clm.actuated_v] = u``, zero elsewhere; the command
  of each step is held over it (zero-order hold) and clipped to the robot's
  ``geometry.max_actuator_force`` (a scalar or (n_act,); status "saturated" then);
* actuator positions are ``robot.actuator_positions(q)`` (a bare model: the tree
  coordinates of the actuated joints), actuator velocities the tree velocity at the
  actuated joints, ``v[clm.actuated_v]``;
* the joint and drive effects of the model (``clm.effects``,
  :mod:`~hexapod_pin.core.effects`: armature, damping, springs, Coulomb friction) act in
  every step; the integrator is :func:`~hexapod_pin.core.simulation.resolve_integrator`'s
  (``"auto"``: ``"stick_slip"``, exact stick-slip at velocity level, for a model with
  Coulomb friction, else RK4; RK4 and plain Euler refuse exact Coulomb friction, a
  ``friction_regularisation`` makes it smooth for any integrator);
* energies are those of :func:`~hexapod_pin.core.energy.model_energies`: kinetic with the
  rotors' (armature), potential of gravity (zero when every centre of mass is at height
  zero) and of the springs; the actuators' work is exact for the zero-order hold,
  ``sum_k u_k . (q_act(t_{k+1}) - q_act(t_k))`` (the integral of ``u . qdot_act`` with
  ``u`` held over each step, displacements by ``pin.difference``); the dissipated work is
  the integral of the power of damping and friction, ``sum(damping v^2 + coulomb |v|)``
  (:attr:`~hexapod_pin.core.simulation.ClosedLoopIntegrator.dissipated` of each step: the
  RK4 quadrature over its stage velocities, or the work of the held forces of an Euler
  step). So ``E(t) + dissipated_work(t) - work(t) = E(0)``
  (:attr:`Trajectory.energy_residual`) up to the integrator's error (``O(dt^4)`` for RK4,
  ``O(dt)`` for the Euler schemes).

The library never prints: pass ``progress`` to follow a long run.
"""

from __future__ import annotations

import contextlib
import importlib
import math
import time as _time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..errors import ArgumentTypeError, HexapodPinError, InputError, NonFiniteResultError
from .checks import as_array, count, max_abs, real_number
from .closed_loop import ClosedLoopModel
from .controllers import Controller, SimState
from .dynamics import FORWARD_METHODS
from .energy import energy_totals
from .robot_api import ParallelRobot, state_branch
from .simulation import PROJECTION_TOL, ClosedLoopIntegrator, resolve_integrator

#: simulation backends: the Pinocchio tree (every robot) or a robot's compiled simulator
BACKENDS = ("tree", "compiled")


class CompiledSimulator(NamedTuple):
    """A robot class's compiled simulator (:func:`register_compiled_simulator`)."""

    #: ``run(robot, duration, dt, *, actuator_forces, integrator, record_every)``
    run: Callable[..., "Trajectory"]
    #: whether it models the joint and drive effects (``robot.effects``); when False,
    #: ``simulate`` refuses a robot whose effects are not rigid
    supports_effects: bool = False


#: robot class -> its compiled simulator (:func:`register_compiled_simulator`)
COMPILED_SIMULATORS: dict[type, CompiledSimulator] = {}
#: the most steps (``round(duration / dt)``) one run may take
MAX_STEPS = 10 ** 8
#: the most samples one run may record (each holds the tree state, a few hundred bytes)
MAX_SAMPLES = 2 * 10 ** 6
#: the largest closure residual (m / rad) and closure-velocity miss ``|J_c v|`` (relative
#: to ``1 + |v|``) accepted in an ``initial`` state (it is then projected onto the closures)
INITIAL_TOL = 1e-8
#: the statuses of a :class:`Trajectory`
STATUSES = ("completed", "saturated", "failed")
#: the protocol members :func:`simulate` uses of a robot
ROBOT_MEMBERS = ("model", "home_configuration", "actuator_positions", "pose_from_configuration",
                 "twist_from_actuator_velocities", "inverse_dynamics", "n_actuators",
                 "pose_dim", "geometry")

#: actuator forces as a function of time: ``t -> (n_act,)`` (N or N m)
ForceFunction = Callable[[float], npt.ArrayLike]


@dataclass(frozen=True)
class Trajectory:
    """A simulated motion, sampled every ``record_every`` steps and at the end (N samples).

    Attributes:
        times: (N,) (s).
        q: (N, nq) tree configurations (Pinocchio conventions).
        v: (N, nv) tree velocities.
        poses: (N, dim) platform poses (m, rad), or None for a bare model.
        twists: (N, dim) platform twists ``(v, w)``, world axes, or None for a bare model.
        actuator_positions: (N, n_act) (m or rad).
        actuator_velocities: (N, n_act) (m/s or rad/s).
        actuator_forces: (N, n_act) the forces applied from each sample over the next step
            (after clipping; N or N m); the last row: the command computed at the final
            state.
        saturated: (N,) True where that row's command was clipped.
        energies: (N,) total mechanical energy, ``kinetic + potential`` (J).
        kinetic: (N,) kinetic energy ``1/2 v^T M v``, the rotors' (armature) included (J).
        potential: (N,) potential energy of gravity and of the joint springs (J).
        work: (N,) cumulative work done by the actuators since t = 0 (J; the only
            applied forces of this simulator).
        closure_residual: (N,) max-abs closure residual of each sample (m / rad).
        status: "completed", "saturated" (completed, some commands clipped to the
            bound: ``message`` gives the fraction of steps) or "failed" (a step, the
            controller or a platform state raised: the samples up to there are kept and
            ``message`` says why).
        message: details of the status ("" when completed).
        dt: the step (s).
        wall_time: seconds spent in the integration loop.
        dissipated_power: (N,) power dissipated by damping and Coulomb friction at each
            sample, ``sum(damping v^2 + coulomb |v|)`` (W, >= 0; with a
            ``friction_regularisation`` the friction's ``coulomb v tanh(v / v_eps)``).
            Zeros when a backend leaves it out (a model without these effects).
        dissipated_work: (N,) energy dissipated by damping and friction since t = 0 (J),
            the integral of the dissipated power by the integrator's own quadrature
            (module docstring): ``energies + dissipated_work - work`` stays at
            ``energies[0]`` (:attr:`energy_residual`). Zeros when a backend leaves it out.
        integrator: the integrator that ran ("rk4", "semi_implicit_euler",
            "stick_slip", a compiled backend's name; "" when the backend does not say).
    """

    times: np.ndarray
    q: np.ndarray
    v: np.ndarray
    poses: np.ndarray | None
    twists: np.ndarray | None
    actuator_positions: np.ndarray
    actuator_velocities: np.ndarray
    actuator_forces: np.ndarray
    saturated: np.ndarray
    energies: np.ndarray
    kinetic: np.ndarray
    potential: np.ndarray
    work: np.ndarray
    closure_residual: np.ndarray
    status: str
    message: str
    dt: float
    wall_time: float
    dissipated_power: np.ndarray = field(default_factory=lambda: np.zeros(0))
    dissipated_work: np.ndarray = field(default_factory=lambda: np.zeros(0))
    integrator: str = ""

    def __post_init__(self) -> None:
        for name in ("dissipated_power", "dissipated_work"):   # left out: no dissipation
            if getattr(self, name).size == 0 and self.times.size:
                object.__setattr__(self, name, np.zeros(self.times.size))

    @property
    def energy_residual(self) -> np.ndarray:
        """(N,) ``energies + dissipated_work - work - energies[0]`` (J): the miss of the
        energy balance, zero up to the integrator's error."""
        if not self.times.size:
            return np.zeros(0)
        return self.energies + self.dissipated_work - self.work - self.energies[0]

    @property
    def real_time_factor(self) -> float:
        """Simulated time divided by wall time (:func:`real_time_factor`)."""
        return real_time_factor(self.times, self.wall_time)


def real_time_factor(times: np.ndarray, wall_time: float) -> float:
    """Simulated time (the span of ``times``, s) divided by ``wall_time`` (s); inf for a
    zero wall time. One formula for every simulation result of the library."""
    span = float(times[-1] - times[0]) if times.size else 0.0
    return span / wall_time if wall_time > 0 else float("inf")


def simulate(robot: ParallelRobot | ClosedLoopModel, duration: float, dt: float = 1e-3, *,
             controller: Controller | None = None,
             actuator_forces: npt.ArrayLike | ForceFunction | None = None,
             integrator: str = "auto", method: str = "pinocchio",
             initial: tuple[npt.ArrayLike, npt.ArrayLike] | None = None,
             record_every: int = 1, progress: Callable[[float], Any] | None = None,
             projection_tol: float = PROJECTION_TOL, backend: str = "tree",
             friction_regularisation: float | None = None) -> Trajectory:
    """Integrate the closed-loop dynamics of any robot or closed-loop model.

    Args:
        robot: a :class:`~hexapod_pin.core.robot_api.ParallelRobot` (poses and twists
            recorded) or a bare :class:`~hexapod_pin.core.closed_loop.ClosedLoopModel`.
        duration: simulated time (s), > 0; rounded to a whole number of steps (at least
            one).
        dt: the step and control period (s), > 0.
        controller: ``controller(state, robot) -> u`` (n_act,) (N or N m), called once per
            step with a :class:`~hexapod_pin.core.controllers.SimState` (and once at the
            final state); its ``reset()`` is called first when it has one.
        actuator_forces: without a controller: (n_act,) constant, or a callable
            ``t -> (n_act,)`` (N or N m); default zero (unactuated).
        integrator: "auto" (default: "stick_slip" for a model with Coulomb friction and
            no ``friction_regularisation``, else "rk4"), "rk4", "semi_implicit_euler" or
            "stick_slip" (semi-implicit Euler with exact stick-slip friction at velocity
            level); see :func:`~hexapod_pin.core.simulation.resolve_integrator`.
        method: forward-dynamics route, "pinocchio" (default), "qp" or "kkt".
        initial: the initial tree state ``(q (nq,), v (nv,))``, on the closures (residual
            and ``J_c v`` within :data:`INITIAL_TOL`); None: the robot's
            ``home_configuration`` at rest (required for a bare model).
        record_every: record one sample every this many steps (an integer >= 1; the final
            state is always recorded).
        progress: called as ``progress(fraction_done)`` at most about 100 times.
        projection_tol: closure residual (m / rad) above which a state is projected back.
        backend: "tree" (default: the Pinocchio tree with its closures, every robot) or
            "compiled": the robot's own compiled simulator
            (:func:`register_compiled_simulator`; the hexapod's integrates in platform
            coordinates, :func:`hexapod_pin.hexapod.compiled_backend.compiled_trajectory`),
            from home at rest under constant actuator forces (no controller, force
            function or ``initial``; ``method`` and ``projection_tol`` do not apply), the
            same :class:`Trajectory` returned. The two integrate different coordinates:
            they agree to the integrator's accuracy, and the compiled one also stops at
            the robot's stroke limits (status "failed", the message says which). A robot
            with joint effects runs there only if its simulator was registered with
            ``supports_effects=True``.
        friction_regularisation: ``v_eps`` (m/s or rad/s, > 0): Coulomb friction becomes
            the smooth ``-coulomb tanh(v / v_eps)`` (an approximation: a joint under a load
            below its friction creeps at ``v_eps atanh(load / coulomb)`` instead of
            sticking; any integrator; stiff: RK4 needs ``dt`` below about ``2.8 m v_eps /
            coulomb``, ``m`` the joint's effective inertia). None (default): the exact
            friction.

    Returns:
        :class:`Trajectory`. A step, controller or platform-state failure (a library
        error) ends the run with status "failed", the samples up to there and the reason.

    Raises:
        InputError: a ``duration`` or ``dt`` that is not a positive finite real number,
            more than :data:`MAX_STEPS` steps or :data:`MAX_SAMPLES` samples, an unknown
            integrator or method, an integrator that does not take the model's Coulomb
            friction ("rk4" / "semi_implicit_euler" without a regularisation,
            "stick_slip" with one), a ``friction_regularisation`` that is not a finite
            number > 0, both ``controller`` and ``actuator_forces``, forces or
            an ``initial`` state of the wrong shape, with NaN / inf or off the closures, a
            ``record_every`` that is not a positive integer, a controller's or force
            function's output of the wrong shape.
        InputError: ``backend`` unknown, "compiled" for a robot without a compiled
            simulator, with options it does not take, or with joint effects it does not
            model.
        ArgumentTypeError: ``robot`` is neither a robot nor a closed-loop model, or a
            ``controller`` / ``progress`` that is not callable.
        NonFiniteResultError: a controller or force function returned NaN / inf (the
            message names the time).
    """
    clm, platform = _resolve(robot)
    duration = real_number(duration, "duration", minimum=0.0)
    dt = real_number(dt, "dt", minimum=0.0)
    record_every = count(record_every, "record_every")
    projection_tol = real_number(projection_tol, "projection_tol", minimum=0.0)
    if not (isinstance(backend, str) and backend in BACKENDS):
        raise InputError("backend", backend, f"expected one of {BACKENDS}")
    if friction_regularisation is not None:
        friction_regularisation = real_number(friction_regularisation,
                                              "friction_regularisation", minimum=0.0)
    integrator = resolve_integrator(clm, integrator, friction_regularisation)
    if not (isinstance(method, str) and method in FORWARD_METHODS):
        raise InputError("method", method, f"expected one of {FORWARD_METHODS}")
    steps = duration / dt
    if not steps <= MAX_STEPS:
        raise InputError("dt", dt, f"duration / dt = {steps:.3g} steps (duration "
                         f"{duration:g} s), more than MAX_STEPS = {MAX_STEPS:.0e}")
    if round(steps) < 1:
        raise InputError("duration", duration, f"shorter than half a step (dt = {dt:g} s): "
                         "no step to take")
    if backend == "compiled":
        return _compiled(robot, duration, dt, controller, actuator_forces, integrator, method,
                         initial, record_every, progress, friction_regularisation)
    for name, fn in (("controller", controller), ("progress", progress)):
        if fn is not None and not callable(fn):
            raise ArgumentTypeError(name, fn, "expected a callable or None")
    if controller is not None and actuator_forces is not None:
        raise InputError("actuator_forces", actuator_forces,
                         "give actuator forces or a controller, not both")
    n_steps = round(steps)
    n_rec = n_steps // record_every + 1 + (1 if n_steps % record_every else 0)
    if n_rec > MAX_SAMPLES:
        raise InputError("record_every", record_every, f"{n_rec} recorded samples, more "
                         f"than MAX_SAMPLES = {MAX_SAMPLES:.0e}: raise record_every")
    n_act = clm.n_actuated
    limit = _force_limit(robot, n_act) if platform else np.full(n_act, math.inf)
    forces_of = _command_source(controller, actuator_forces, robot, n_act)
    q, v = _initial_state(robot, clm, platform, initial)
    integ = ClosedLoopIntegrator(clm, method, integrator,
                                 friction_regularisation=friction_regularisation)
    q, v, res = integ.project(q, v, projection_tol, velocity=True)
    run = _Run(robot, clm, platform, n_rec, n_act, integ)
    reset = getattr(controller, "reset", None)
    if callable(reset):
        reset()

    status, message, t = "completed", "", 0.0
    clipped = 0
    every = max(1, -(-n_steps // 100))            # at most 100 calls and the last
    start = _time.perf_counter()
    try:
        state = run.state(t, q, v, need_platform=controller is not None)
        forces, sat = _clip(forces_of(state), limit)
        run.record(state, forces, sat, res)
    except HexapodPinError as exc:
        if isinstance(exc, (InputError, NonFiniteResultError)):
            raise
        status, message = "failed", f"at t = 0 s: {exc}"
    tau = np.zeros(clm.nv)
    step = 0
    while status != "failed" and step < n_steps:
        tau[clm.actuated_v] = forces
        try:
            q_new, v_new, res = integ.step(q, v, tau, dt, projection_tol)
            if not (np.isfinite(q_new).all() and np.isfinite(v_new).all()):
                raise NonFiniteResultError("ClosedLoopIntegrator.step", "state")
        except HexapodPinError as exc:
            status, message = "failed", f"step at t = {t:.6g} s: {exc}"
            break
        run.add_step(forces, q, q_new)
        clipped += sat
        step += 1
        q, v, t = q_new, v_new, step * dt
        try:
            state = run.state(t, q, v, need_platform=controller is not None)
            forces, sat = _clip(forces_of(state), limit)
            if step % record_every == 0 or step == n_steps:
                run.record(state, forces, sat, res)
        except HexapodPinError as exc:
            if isinstance(exc, (InputError, NonFiniteResultError)):
                raise
            status, message = "failed", f"at t = {t:.6g} s: {exc}"
            break
        if progress is not None and (step % every == 0 or step == n_steps):
            progress(step / n_steps)
    wall = _time.perf_counter() - start
    if clipped:
        bound = f"{limit[0]:g}" if (limit == limit[0]).all() else np.array2string(limit)
        note = (f"actuator commands clipped to the bound +/-{bound} at "
                f"{clipped / max(step, 1):.2%} of the {step} steps")
        status, message = ("saturated", note) if status == "completed" else \
            (status, f"{message}; {note}")
    return run.trajectory(status, message, dt, wall)


class _Failure(HexapodPinError):
    """A library error of the controller (other than InputError) or of the robot's
    platform maps during a run (the run ends "failed"), wrapped so that it is told apart
    from the run's own checks (InputError, NonFiniteResultError: raised)."""


def register_compiled_simulator(kind: type, run: Callable[..., Trajectory], *,
                                supports_effects: bool = False) -> None:
    """Register a robot class's compiled simulator for ``simulate(..., backend="compiled")``
    (called by the robot's own package when it is imported: core names no robot; a robot
    class's ``COMPILED_SIMULATOR`` names that module, imported on the first compiled run).

    Args:
        kind: the robot class (its subclasses use the same simulator).
        run: ``run(robot, duration, dt, *, actuator_forces, integrator, record_every)``
            returning a :class:`Trajectory` sampled every ``record_every`` steps and at the
            end, starting at the robot's home at rest; ``integrator`` is the one
            :func:`~hexapod_pin.core.simulation.resolve_integrator` picked. With
            ``supports_effects`` it also takes ``friction_regularisation`` (None or
            ``v_eps``) and fills the trajectory's ``dissipated_power`` and
            ``dissipated_work``.
        supports_effects: whether ``run`` models the joint and drive effects
            (``robot.effects``: armature, damping, springs, Coulomb friction). When False
            (default), ``simulate`` refuses a robot whose effects are not rigid.
    """
    COMPILED_SIMULATORS[kind] = CompiledSimulator(run, bool(supports_effects))


def compiled_simulator_of(kind: type) -> CompiledSimulator | None:
    """The compiled simulator registered for the robot class ``kind`` or its nearest base
    (None: none). A class names the module that registers it in ``COMPILED_SIMULATOR``,
    imported here on first use (the package imports it lazily)."""
    registering = getattr(kind, "COMPILED_SIMULATOR", None)
    if isinstance(registering, str):
        importlib.import_module(registering)
    return next((COMPILED_SIMULATORS[k] for k in kind.__mro__ if k in COMPILED_SIMULATORS),
                None)


def _compiled(robot, duration: float, dt: float, controller, actuator_forces,
              integrator: str, method: str, initial, record_every: int, progress,
              friction_regularisation: float | None) -> Trajectory:
    """The robot's registered compiled simulator, after checking that the run asks for
    nothing it does not do (:func:`compiled_simulator_of`)."""
    sim = compiled_simulator_of(type(robot))
    if sim is None:
        raise InputError("backend", "compiled", f"{type(robot).__name__} has no compiled "
                         "simulator (backend='tree' works for every robot)")
    effects = robot.model.effects
    if not (sim.supports_effects or effects.is_rigid):
        raise InputError("backend", "compiled", f"the compiled simulator of "
                         f"{type(robot).__name__} does not model joint effects and this "
                         f"robot has {effects!r} (backend='tree' includes them)")
    given = [name for name, value in (("controller", controller), ("initial", initial),
                                      ("progress", progress)) if value is not None]
    if method != "pinocchio":
        given.append(f"method={method!r}")
    if callable(actuator_forces):
        given.append("actuator_forces (a function)")
    if given:
        raise InputError("backend", "compiled", "the compiled simulator runs from home at "
                         f"rest under constant forces: {', '.join(given)} not supported")
    options = {"friction_regularisation": friction_regularisation} \
        if sim.supports_effects else {}
    if friction_regularisation is not None and not sim.supports_effects:
        raise InputError("friction_regularisation", friction_regularisation,
                         "the compiled simulator does not model friction")
    return sim.run(robot, duration, dt, actuator_forces=actuator_forces,
                   integrator=integrator, record_every=record_every, **options)


def _resolve(robot) -> tuple[ClosedLoopModel, bool]:
    """``(clm, has_platform)`` of a robot or a bare model."""
    if isinstance(robot, ClosedLoopModel):
        return robot, False
    missing = [name for name in ROBOT_MEMBERS if not hasattr(robot, name)]
    if missing or not isinstance(getattr(robot, "model", None), ClosedLoopModel):
        raise ArgumentTypeError("robot", robot, "expected a ParallelRobot or a ClosedLoopModel"
                                + (f" (missing {missing})" if missing else ""))
    if robot.n_actuators != robot.model.n_actuated:
        raise InputError("robot", robot, f"n_actuators = {robot.n_actuators} but its model "
                         f"actuates {robot.model.n_actuated} joints")
    return robot.model, True


def _force_limit(robot, n_act: int) -> np.ndarray:
    """The robot's actuator-force bounds (n_act,) (N or N m; inf: unbounded) from
    ``geometry.max_actuator_force``, a scalar or (n_act,)."""
    value = getattr(robot.geometry, "max_actuator_force", math.inf)
    try:
        limit = np.broadcast_to(np.asarray(value, dtype=float), (n_act,)).copy()
    except (TypeError, ValueError):
        limit = np.full(n_act, math.nan)
    if isinstance(value, bool) or np.isnan(limit).any() or (limit <= 0).any():
        raise InputError("geometry.max_actuator_force", value,
                         f"expected a bound > 0 or {n_act} bounds > 0 (inf: none)")
    return limit


def _clip(forces: np.ndarray, limit: np.ndarray) -> tuple[np.ndarray, bool]:
    """The command clipped to ``+/- limit`` and whether it was."""
    if (np.abs(forces) > limit).any():
        return np.clip(forces, -limit, limit), True
    return forces, False


def _checked_forces(value, n_act: int, name: str, t: float) -> np.ndarray:
    """A command (n_act,) as a float array: InputError for a wrong shape or type,
    NonFiniteResultError (naming the time) for NaN / inf."""
    label = f"{name} at t = {t:.6g} s"
    try:
        raw = np.asarray(value)
        arr = np.array(raw, dtype=float)
    except (TypeError, ValueError):
        raise InputError(label, value, "not real numbers") from None
    if raw.dtype.kind not in "iuf" and not (raw.dtype.kind == "O" and all(
            isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, bool)
            for x in raw.ravel())):
        raise InputError(label, value, f"expected real numbers, got dtype {raw.dtype}")
    if arr.shape != (n_act,):
        raise InputError(label, value, f"expected real numbers of shape ({n_act},), got "
                         f"shape {arr.shape}")
    if not np.isfinite(arr).all():
        raise NonFiniteResultError(label, "actuator forces")
    return arr


def _checked_source(produce: Callable[[SimState], Any], what: str, label: str, n_act: int
                    ) -> Callable[[SimState], np.ndarray]:
    """``produce`` with its output checked (:func:`_checked_forces`) and its library
    errors, other than bad input, ending the run as a failure that names ``what``."""
    def command(state: SimState) -> np.ndarray:
        try:
            out = produce(state)
        except InputError:
            raise
        except HexapodPinError as exc:
            raise _Failure(f"{what}: {exc}") from exc
        return _checked_forces(out, n_act, label, state.t)
    return command


def _command_source(controller, actuator_forces, robot, n_act: int
                    ) -> Callable[[SimState], np.ndarray]:
    """``state -> u`` (n_act,) for a controller, a force function, constant forces or none."""
    if controller is not None:
        return _checked_source(lambda state: controller(state, robot), "controller",
                               "controller output", n_act)
    if callable(actuator_forces):
        return _checked_source(lambda state: actuator_forces(state.t), "actuator_forces",
                               "actuator_forces(t)", n_act)
    const = np.zeros(n_act) if actuator_forces is None else \
        as_array(actuator_forces, (n_act,), "actuator_forces")
    return lambda state: const


def _initial_state(robot, clm: ClosedLoopModel, platform: bool, initial
                   ) -> tuple[np.ndarray, np.ndarray]:
    """The checked initial tree state ``(q, v)``."""
    if initial is None:
        if not platform:
            raise InputError("initial", None, "a bare ClosedLoopModel needs initial=(q, v)")
        return clm.check_q(robot.home_configuration, "home_configuration"), np.zeros(clm.nv)
    if not isinstance(initial, (tuple, list)) or len(initial) != 2:
        raise InputError("initial", initial, "expected a (q, v) pair")
    q = clm.check_q(initial[0], "initial q").copy()
    v = clm.check_v(initial[1], "initial v").copy()
    with getattr(robot, "lock", contextlib.nullcontext()):     # the model's shared data
        return _checked_initial(clm, q, v)


def _checked_initial(clm: ClosedLoopModel, q: np.ndarray, v: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
    """``(q, v)`` after checking that they keep the closures (InputError otherwise)."""
    res = max_abs(clm.residual(q))
    if not res <= INITIAL_TOL:
        raise InputError("initial q", q, f"closure residual {res:.3e} above {INITIAL_TOL:g} "
                         "(assemble it first: ClosedLoopModel.assemble)")
    miss = max_abs(clm.constraint_jacobian(q) @ v)
    if not miss <= INITIAL_TOL * (1.0 + max_abs(v)):
        raise InputError("initial v", v, f"closure velocity |J_c v| = {miss:.3e} above "
                         f"{INITIAL_TOL:g} (1 + |v|) (ClosedLoopModel.project_velocity)")
    return q, v


class _Run:
    """The recorded samples of one run and the actuators' work."""

    def __init__(self, robot, clm: ClosedLoopModel, platform: bool, n_rec: int,
                 n_act: int, integ: ClosedLoopIntegrator) -> None:
        self.robot, self.clm, self.platform, self.integ = robot, clm, platform, integ
        self.act_v = clm.actuated_v
        self.act_q = np.array([clm.model.joints[clm.model.getJointId(j)].idx_q
                               for j in clm.actuated_joints], dtype=int)
        self.work = 0.0
        self.dissipated = 0.0
        self.k = 0
        dim = robot.pose_dim if platform else 0
        self.t = np.empty(n_rec)
        self.q = np.empty((n_rec, clm.nq))
        self.v = np.empty((n_rec, clm.nv))
        self.poses = np.empty((n_rec, dim)) if platform else None
        self.twists = np.empty((n_rec, dim)) if platform else None
        self.qa = np.empty((n_rec, n_act))
        self.va = np.empty((n_rec, n_act))
        self.u = np.empty((n_rec, n_act))
        self.sat = np.zeros(n_rec, dtype=bool)
        self.kin = np.empty(n_rec)
        self.pot = np.empty(n_rec)
        self.w = np.empty(n_rec)
        self.res = np.empty(n_rec)
        self.power = np.empty(n_rec)
        self.lost = np.empty(n_rec)

    def state(self, t: float, q: np.ndarray, v: np.ndarray, need_platform: bool) -> SimState:
        """The controller's view of ``(q, v)`` (the platform state only when asked)."""
        if self.platform:
            robot = self.robot
            try:
                qa = np.asarray(robot.actuator_positions(q), dtype=float)
            except HexapodPinError as exc:
                raise _Failure(f"actuator_positions: {exc}") from exc
        else:
            qa = q[self.act_q].copy()
        va = v[self.act_v].copy()
        pose = twist = None
        if need_platform and self.platform:
            pose, twist = self._platform(q, v, va)
        return SimState(t, q, v, qa, va, pose, twist)

    def _platform(self, q, v, va):
        try:
            robot = self.robot
            pose = np.asarray(robot.pose_from_configuration(q), dtype=float)
            # the twist of this configuration's working mode (not the one reached from home)
            twist_of = getattr(robot, "twist_from_configuration", None)
            twist = np.asarray(twist_of(q, v) if twist_of is not None else
                               robot.twist_from_actuator_velocities(
                                   pose, va, branch=state_branch(robot, pose, q)), dtype=float)
        except HexapodPinError as exc:
            raise _Failure(f"platform state: {exc}") from exc
        return pose, twist

    def add_step(self, forces: np.ndarray, q0: np.ndarray, q1: np.ndarray) -> None:
        """Add the work of the held command over a step, ``u . (q_act(t_1) -
        q_act(t_0))``, and the energy the integrator's step dissipated."""
        step = pin.difference(self.clm.model, q0, q1)
        self.work += float(forces @ step[self.act_v])
        self.dissipated += self.integ.dissipated

    def record(self, state: SimState, forces: np.ndarray, sat: bool, res: float) -> None:
        """Store one sample (its platform state and energies computed here)."""
        k = self.k
        if self.platform and self.poses is not None and self.twists is not None:
            pose, twist = state.pose, state.twist
            if pose is None or twist is None:
                pose, twist = self._platform(state.q, state.v, state.actuator_velocities)
            self.poses[k], self.twists[k] = pose, twist
        kinetic, potential = energy_totals(self.clm, state.q, state.v)
        self.t[k], self.q[k], self.v[k] = state.t, state.q, state.v
        self.qa[k], self.va[k] = state.actuator_positions, state.actuator_velocities
        self.u[k], self.sat[k], self.res[k] = forces, sat, res
        self.kin[k], self.pot[k], self.w[k] = kinetic, potential, self.work
        self.power[k], self.lost[k] = self.integ.dissipated_power(state.v), self.dissipated
        self.k = k + 1

    def trajectory(self, status: str, message: str, dt: float, wall: float) -> Trajectory:
        """The recorded samples as a :class:`Trajectory`."""
        n = self.k

        def cut(arr):
            return None if arr is None else arr[:n].copy()

        return Trajectory(cut(self.t), cut(self.q), cut(self.v), cut(self.poses),
                          cut(self.twists), cut(self.qa), cut(self.va), cut(self.u),
                          cut(self.sat), self.kin[:n] + self.pot[:n], cut(self.kin),
                          cut(self.pot), cut(self.w), cut(self.res), status, message,
                          float(dt), wall, cut(self.power), cut(self.lost),
                          self.integ.integrator)
