"""Compile every compiled (numba) kernel of the library at once: :func:`warmup`.

The kernels are cached on disk once compiled (:mod:`hexapod_pin.core.compiled`); until
then a kernel runs its Python source and is compiled once that has cost it about as much
time as compiling (:mod:`hexapod_pin.core.tiers`), so after an install (or an edit of a
compiled module) a session's calls are slower at first and pause for compilations now and
then. :func:`warmup` compiles everything once, up front, by running each family of kernels on small inputs: the hexapod's and the planar
robot's closed forms (single state and batches, both the serial and the parallel
compilation of every batch loop), the hexapod's compiled simulator (every integrator),
the time-optimal planner, and the tree routes of a robot loaded from a description (the
forward-dynamics derivatives included, both factor routes: independent and redundant rows). A
warm cache makes it take about a second. ``hexapod-pin warmup`` runs it with a progress bar.
"""

from __future__ import annotations

import importlib
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any, cast

import numpy as np
import pinocchio as pin
from numba.core.dispatcher import Dispatcher

from .core import tiers
from .core.batching import BatchDriver
from .core.compiled import COMPILE_NOTICE, PACKAGE_DIR, compiled_modules, kernel_name
from .core.dynamics import inverse_dynamics_tree
from .core.dynamics_derivatives import forward_dynamics_derivatives_tree
from .core.integrator_kernels import normalise_pairs
from .core.linear_kernels import reduced_kkt_solve
from .core.robot import ClosedLoopRobot
from .core.robot_api import FORWARD_DYNAMICS_METHODS, INVERSE_DYNAMICS_METHODS, ParallelRobot
from .core.simulate import simulate
from .errors import SingularityError
from .hexapod import workspace
from .hexapod.fast import INTEGRATORS, simulate_fast
from .hexapod.robot import Hexapod
from .planar.robot import Planar3PRR

#: a progress callback ``update(done, total)`` (steps of :func:`warmup`)
Progress = Callable[[int, int], object]


@dataclass(frozen=True)
class WarmupStep:
    """One step of :func:`warmup`.

    Attributes:
        label: what it compiled, e.g. ``"hexapod: batches"``.
        seconds: its wall time (s).
        compiled: kernels compiled in it (cache misses; 0 with a warm cache).
    """

    label: str
    seconds: float
    compiled: int


@dataclass(frozen=True)
class WarmupReport:
    """What :func:`warmup` did.

    Attributes:
        steps: the steps in order (:class:`WarmupStep`).
        kernels: names (``module.function``) of every kernel of the package.
        uncompiled: the kernels neither compiled nor inlined into a compiled one
            afterwards (:func:`uncompiled`; those reached only by rarer routes).
    """

    steps: tuple[WarmupStep, ...]
    kernels: tuple[str, ...]
    uncompiled: tuple[str, ...]

    @property
    def seconds(self) -> float:
        """Total wall time (s)."""
        return sum(step.seconds for step in self.steps)

    @property
    def compiled(self) -> int:
        """Kernels compiled in all (0 with a warm cache)."""
        return sum(step.compiled for step in self.steps)


def dispatchers() -> dict[str, Dispatcher]:
    """Every compiled kernel of the package by name (``module.function``; a batch loop's
    two compilations as ``...[serial]`` and ``...[parallel]``), importing each module of
    :func:`~hexapod_pin.core.compiled.compiled_modules`."""
    out: dict[str, Dispatcher] = {}
    for path in compiled_modules():
        parts = path.relative_to(PACKAGE_DIR.parent).with_suffix("").parts
        module = importlib.import_module(".".join(parts))
        for value in vars(module).values():
            if isinstance(value, Dispatcher) and value.py_func.__module__ == module.__name__:
                out[kernel_name(value)] = value
            elif isinstance(value, BatchDriver) and \
                    value.serial.py_func.__module__ == module.__name__:
                out[kernel_name(value.serial) + "[serial]"] = value.serial
                out[kernel_name(value.serial) + "[parallel]"] = value.parallel
    return out


def _single_state(robot: Hexapod | Planar3PRR, pose: np.ndarray, twist: np.ndarray,
                  acc: np.ndarray) -> np.ndarray:
    """The protocol's single-state routes of a robot with a closed form (kinematics, every
    dynamics method, statics, reduced dynamics, inverse-dynamics derivatives); returns the
    inverse-dynamics forces."""
    q = robot.inverse_kinematics(pose)
    robot.forward_kinematics(q)
    robot.assembly_modes(q)
    robot.jacobian(pose)
    robot.jacobian_derivative(pose, twist)
    robot.singularity(pose)
    tau = robot.inverse_dynamics(pose, twist, acc).actuator_forces
    for method in INVERSE_DYNAMICS_METHODS:
        robot.inverse_dynamics(pose, twist, acc, method=method)
    for method in FORWARD_DYNAMICS_METHODS:
        robot.forward_dynamics(pose, twist, tau, method=method)
    robot.static_forces(pose)
    robot.reduced_dynamics(pose, twist)
    robot.inverse_dynamics_derivatives(pose, twist, acc)
    return tau


def _hexapod_single(robot: Hexapod) -> None:
    pose = robot.home_pose + np.array([0.005, -0.004, 0.003, 0.02, -0.01, 0.03])
    twist = np.array([0.01, -0.02, 0.01, 0.05, 0.02, -0.03])
    acc = np.array([0.1, 0.0, -0.1, 0.2, 0.1, 0.0])
    tau = _single_state(robot, pose, twist, acc)
    robot.leg_motion(pose, twist, acc)
    robot.inverse_dynamics(pose, twist, acc).joint_wrenches
    robot.inverse_dynamics(pose, twist, acc, method="qp").closure_forces   # the tree route's
    robot.with_effects(damping={"carriage_0": 1.0}).forward_dynamics(pose, twist, tau)
    robot.dynamics.actuator_forces_at(robot.configuration(pose), twist, acc)
    robot.energies(pose, twist)
    robot.forward_dynamics_derivatives(pose, twist, tau)      # independent rows
    poses = np.repeat(pose[None, :], 2, axis=0)
    robot.dynamics.regressor(pose, twist, acc)                # the closed-form regressor
    robot.dynamics.regressor_batch(poses, poses * 0.0, poses * 0.0)
    workspace.evaluate(robot, poses)
    workspace.leg_reachable(robot, poses)
    try:                                    # a type-II singular pose: its error's measure
        robot.static_forces(np.zeros(6))
    except SingularityError:
        pass
    q, rest = robot.configuration(pose), np.zeros(robot.model.nv)
    for method, bounds in (("kkt", None), ("qp", None), ("qp", 1e3)):  # the square tree system
        inverse_dynamics_tree(robot.model, q, rest, rest, bounds=bounds, method=method)


def _batches(robot: Hexapod | Planar3PRR) -> None:
    poses = np.repeat(robot.home_pose[None, :], 2, axis=0)
    twists = np.zeros_like(poses)
    robot.inverse_kinematics_batch(poses)
    robot.jacobian_batch(poses)
    tau = robot.inverse_dynamics_batch(poses, twists, twists).actuator_forces
    robot.forward_dynamics_batch(poses, twists, tau)
    robot.static_forces_batch(poses)
    robot.reduced_dynamics_batch(poses, twists)
    robot.energies(robot.home_pose, twists[0])


def _parallel_batches() -> None:
    """Compile each batch loop's parallel twin with the signatures its serial one has."""
    for name, dispatcher in dispatchers().items():
        if name.endswith("[parallel]"):
            serial = dispatchers()[name.replace("[parallel]", "[serial]")]
            for signature in serial.signatures:
                dispatcher.compile(signature)


def _planar_single(robot: Planar3PRR) -> None:
    pose = robot.home_pose + np.array([0.01, -0.01, 0.05])
    twist = np.array([0.02, -0.01, 0.1])
    tau = _single_state(robot, pose, twist, twist)
    robot.forward_dynamics_derivatives(pose, twist, tau)      # the closed-form chain rule


def _simulators(robot: Hexapod) -> None:
    for integrator in INTEGRATORS:
        simulate_fast(robot, 2e-3, 1e-3, integrator=integrator,
                      actuator_forces=robot.static_forces(robot.home_pose))
    # sampled poses and twists (the annotation names only the callable form)
    reference: Any = (np.repeat(robot.home_pose[None, :], 3, axis=0), np.zeros((3, 6)))
    simulate_fast(robot, 2e-3, 1e-3, reference=reference)
    simulate(robot, 2e-3, 1e-3, backend="compiled")


def _planning(robot: Hexapod) -> None:
    from .planning import Limits, time_optimal      # optional part: not at a bare import

    waypoints = robot.home_pose + np.array([[0.0] * 6, [0.01, 0.0, 0.005, 0.0, 0.0, 0.02]])
    time_optimal(robot, waypoints, limits=Limits(actuator_force=60.0), grid_points=5)


def _tree_routes(planar: Planar3PRR) -> None:
    robot = ClosedLoopRobot(planar.model, planar.platform_frame, planar.pose_axes,
                            home=planar.home_configuration)
    pose, twist = robot.home_pose, np.array([0.01, 0.0, 0.05])
    robot.inverse_kinematics(pose)
    tau = robot.inverse_dynamics(pose, twist, twist).actuator_forces
    for method in INVERSE_DYNAMICS_METHODS:
        robot.inverse_dynamics(pose, twist, twist, method=method)
    for method in FORWARD_DYNAMICS_METHODS:
        robot.forward_dynamics(pose, twist, tau, method=method)
    robot.forward_dynamics_derivatives(pose, twist, tau)     # redundant rows: the SVD route
    robot.inverse_dynamics_derivatives(pose, twist, twist)   # the tree's implicit function
    robot.inverse_dynamics_batch(pose[None, :], twist[None, :], twist[None, :])
    model, q = robot.model, robot.home_configuration
    model.velocity_from_actuated(q, np.full(model.n_actuated, 0.01))
    model.velocity_from_actuated(q, np.full(model.n_actuated, 0.01), method="qp")
    data = model.model.createData()
    pin.framesForwardKinematics(model.model, data, q)
    target = data.oMf[model.frame_id(robot.platform_frame)]
    for method in ("qp", "lstsq"):
        model.frame_inverse_kinematics(robot.platform_frame, target, q, method=method)
    for integrator in ("rk4", "semi_implicit_euler"):
        simulate(cast(ParallelRobot, robot), 2e-3, 1e-3, integrator=integrator)
    rest = np.zeros(model.nv)
    for method, bounds in (("kkt", None), ("qp", None), ("qp", 1e3)):
        inverse_dynamics_tree(model, q, rest, rest, bounds=bounds, method=method)
    forward_dynamics_derivatives_tree(model, q, rest, np.zeros(model.n_actuated))
    normalise_pairs(np.array([1.0, 0.0]), np.zeros(1, dtype=np.int64))  # quaternion-free here
    # the exact solve the redundant-row route falls back to (rarely reached by these inputs)
    reduced_kkt_solve(np.eye(2), np.zeros(2), np.zeros(2), np.ones((1, 2)), np.zeros(1),
                      np.zeros(1, dtype=np.int64), np.empty(2), np.empty(1))


def _steps() -> Iterator[tuple[str, Callable[[], None]]]:
    hexapod, planar = Hexapod.default(), Planar3PRR.default()
    yield "hexapod: single states", lambda: _hexapod_single(hexapod)
    yield "hexapod: batches", lambda: _batches(hexapod)
    yield "hexapod: compiled simulator", lambda: _simulators(hexapod)
    yield "planar 3-PRR: single states", lambda: _planar_single(planar)
    yield "planar 3-PRR: batches", lambda: _batches(planar)
    yield "time-optimal planning", lambda: _planning(hexapod)
    yield "tree routes (any robot)", lambda: _tree_routes(planar)
    yield "parallel batch loops", _parallel_batches


#: the number of steps of :func:`warmup`
N_STEPS = 8
#: kernels of routes that the small inputs of :func:`warmup` do not reach (frame inverse
#: kinematics' QP step with curvature, the tree inverse dynamics' kernels of redundant
#: actuation and of active force bounds): run interpreted, then compiled, when first reached
RARE = frozenset({
    "hexapod_pin.core.frame_ik._qp_data",
    "hexapod_pin.core.linear_kernels.box_active_set_solve",
    "hexapod_pin.core.linear_kernels.minimum_norm_dual_solve",
    "hexapod_pin.core.linear_kernels.minimum_norm_solve",
    "hexapod_pin.core.linear_kernels.weighted_minimum_norm_solve",
})


def warmup(progress: Progress | None = None) -> WarmupReport:
    """Compile every compiled kernel of the library (or load it from the disk cache), so
    that no later call of the session waits for the compiler.

    Each step runs one family of kernels on small inputs (module docstring), compiling
    every kernel it reaches on its first call (:func:`hexapod_pin.core.tiers.eager`: no
    interpreted runs, whatever ``HEXAPOD_PIN_COMPILE`` says); the compile notice of
    :mod:`hexapod_pin.core.compiled` logs each first compilation (logger ``"hexapod_pin"``,
    INFO).

    Args:
        progress: called as ``progress(done, total)`` after each step (``total`` =
            :data:`N_STEPS`), e.g. a progress bar's update; None: no calls.

    Returns:
        :class:`WarmupReport`: the steps with their wall times and numbers of kernels
        compiled, and every kernel still uncompiled (empty normally).
    """
    steps: list[WarmupStep] = []
    if progress is not None:
        progress(0, N_STEPS)
    with tiers.eager():                     # compile now, never interpret
        for label, run in _steps():
            before, start = COMPILE_NOTICE.compiled, time.perf_counter()
            run()
            steps.append(WarmupStep(label, time.perf_counter() - start,
                                    COMPILE_NOTICE.compiled - before))
            if progress is not None:
                progress(len(steps), N_STEPS)
    kernels = dispatchers()
    return WarmupReport(tuple(steps), tuple(sorted(kernels)), uncompiled(kernels))


def uncompiled(kernels: dict[str, Dispatcher] | None = None) -> tuple[str, ...]:
    """The kernels (of :func:`dispatchers`, by default all) that are neither compiled nor
    part of a compiled kernel: no signature of their own, and not called, directly or
    through other kernels, by a kernel that has one (a kernel loaded from the disk cache
    carries its callees' machine code inlined, their dispatchers stay empty)."""
    kernels = dispatchers() if kernels is None else kernels
    ready: set[int] = set()
    todo = [d for d in kernels.values() if d.signatures]
    while todo:
        dispatcher = todo.pop()
        if id(dispatcher) not in ready:
            ready.add(id(dispatcher))
            todo.extend(tiers.callees(dispatcher))
    return tuple(sorted(name for name, d in kernels.items() if id(d) not in ready))

