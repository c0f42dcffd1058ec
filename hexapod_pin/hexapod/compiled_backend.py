"""The hexapod's compiled simulator as a backend of ``hexapod_pin.simulate``.

``hp.simulate(hexapod, duration, dt, backend="compiled")`` (registered with
:func:`~hexapod_pin.core.simulate.register_compiled_simulator` when this module is
imported: ``simulate`` imports it on the first compiled run, named by
``Hexapod.COMPILED_SIMULATOR``) runs
:func:`~hexapod_pin.hexapod.fast.simulate_fast` (the dynamics in platform coordinates, in
compiled code, the closures held by construction) and returns the generic
:class:`~hexapod_pin.core.simulate.Trajectory`: each recorded platform state mapped to the
tree in closed form (``q``, ``v``), the energies of
:func:`~hexapod_pin.core.energy.energy_totals` on that tree state (as the tree simulator
records them), the work of the (constant) actuator forces, the closure residual of each
configuration. The run starts at home at rest; the stroke limits and the carriage gap stop
it (status "failed", the message naming the limit).

Joint and drive effects (``robot.effects``): the compiled run carries the carriages' drives
(armature, damping, springs, and Coulomb friction made smooth by a
``friction_regularisation``), with the power they dissipate and its integral
(``dissipated_power``, ``dissipated_work``). Two cases are run by the tree simulator
instead (:func:`hexapod_pin.core.simulate.simulate`, ``backend="tree"``; the message says
so): effects on passive coordinates (universal joints, the platform's free flyer), which the
kernels do not model, and exact Coulomb friction (the "stick_slip" integrator: velocity-level
stick / slip, which explicit steps in platform coordinates cannot take).
"""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np
import numpy.typing as npt

from ..core.checks import as_array
from ..core.effects import dissipated_power
from ..core.energy import energy_totals
from ..core.simulate import MAX_SAMPLES, Trajectory, register_compiled_simulator, simulate
from ..errors import InputError
from . import kernels
from .fast import has_friction, simulate_fast
from .robot import Hexapod


def compiled_trajectory(robot: Hexapod, duration: float, dt: float, *,
                        actuator_forces: npt.ArrayLike | None = None,
                        integrator: str = "rk4", record_every: int = 1,
                        friction_regularisation: float | None = None) -> Trajectory:
    """:func:`~hexapod_pin.hexapod.fast.simulate_fast` from home at rest under constant
    actuator forces (6,) (N; default zero), as a :class:`~hexapod_pin.core.simulate.Trajectory`
    (see the module docstring).

    Args:
        robot: the :class:`~hexapod_pin.Hexapod`.
        duration: simulated time (s).
        dt: the step (s).
        actuator_forces: constant forces (6,) (N), default zero.
        integrator: "rk4", "rk2", "semi_implicit_euler" (compiled), "stick_slip" (the tree
            simulator's exact friction) or "auto" ("stick_slip" with exact Coulomb friction,
            else "rk4").
        record_every: record one sample every this many steps (and the final state).
        friction_regularisation: ``v_eps`` (m/s) of a smooth Coulomb friction, or None.

    Raises:
        InputError: bad forces, more than :data:`~hexapod_pin.core.simulate.MAX_SAMPLES`
            samples to record, or what :func:`simulate_fast` refuses.
    """
    forces = None if actuator_forces is None else as_array(actuator_forces, (6,),
                                                           "actuator_forces")
    geo = robot.closed_form.dynamics_geo
    exact = friction_regularisation is None and has_friction(geo)
    if integrator == "auto":
        integrator = "stick_slip" if exact else "rk4"
    if geo[kernels.PASSIVE] or integrator == "stick_slip":
        why = "joint effects on passive coordinates" if geo[kernels.PASSIVE] else \
            "exact Coulomb friction (stick_slip)"
        return _on_the_tree(robot, duration, dt, forces, integrator, record_every,
                            friction_regularisation, why)
    start = time.perf_counter()
    # the Trajectory's sampling (every record_every-th step and the final state) from a
    # run that records every g-th step, g = gcd(record_every, steps): the last step is a
    # multiple of g, so it is recorded, and every record_every-th step is one of them
    n_steps = round(duration / dt)
    every = math.gcd(record_every, n_steps)
    if n_steps // every + 1 > MAX_SAMPLES:
        raise InputError("record_every", record_every,
                         f"the compiled run would record {n_steps // every + 1} samples "
                         f"(every gcd(record_every, steps) = {every} steps), more than "
                         f"MAX_SAMPLES = {MAX_SAMPLES:.0e}: a record_every dividing the "
                         f"{n_steps} steps")
    fast = simulate_fast(robot, duration, dt, actuator_forces=forces, integrator=integrator,
                         record_every=every, friction_regularisation=friction_regularisation)
    keep = np.unique(np.concatenate([np.arange(0, len(fast.times), record_every // every),
                                     [len(fast.times) - 1]]))
    times, poses, twists = fast.times[keep], fast.poses[keep], fast.twists[keep]
    qa, qd, applied, saturated = (fast.q[keep], fast.qdot[keep], fast.actuator_forces[keep],
                                  fast.saturated[keep])
    n = len(keep)
    clm = robot.model
    q, v = np.empty((n, clm.nq)), np.empty((n, clm.nv))
    kinetic, potential, residual = np.empty(n), np.empty(n), np.empty(n)
    power = np.empty(n)
    with robot.lock:
        for k in range(n):
            q[k], v[k] = robot.dynamics.tree_state(poses[k], twists[k])
            kinetic[k], potential[k] = energy_totals(clm, q[k], v[k])
            residual[k] = robot.closed_form.closure_residual(q[k])
            power[k] = _power(clm.effects, v[k], friction_regularisation)
    # the work of the held forces over every step, summed up to each kept sample
    steps = np.einsum("ni,ni->n", fast.actuator_forces[:-1], np.diff(fast.q, axis=0))
    work = np.concatenate([[0.0], np.cumsum(steps)])[keep]
    status = fast.status if fast.status in ("completed", "saturated") else "failed"
    message = fast.message if status == fast.status else \
        f"{fast.status}: {fast.message}".rstrip(": ")
    return Trajectory(times, q, v, poses, twists, qa, qd, applied, saturated,
                      kinetic + potential, kinetic, potential, work, residual, status, message,
                      fast.dt, time.perf_counter() - start, power,
                      fast.dissipated_work[keep], integrator)


def _power(effects, v: np.ndarray, eps: float | None) -> float:
    """The power dissipated by damping and Coulomb friction at ``v`` (W): exact
    (:func:`~hexapod_pin.core.effects.dissipated_power`) or with the smooth friction
    ``c v tanh(v / eps)``."""
    if eps is None:
        return dissipated_power(effects, v)
    return float(np.dot(effects.damping * v, v) + np.dot(effects.coulomb,
                                                         v * np.tanh(v / eps)))


def _on_the_tree(robot: Hexapod, duration: float, dt: float, forces: np.ndarray | None,
                 integrator: str, record_every: int, friction_regularisation: float | None,
                 why: str) -> Trajectory:
    """The tree simulator's run of a robot the compiled kernels cannot step (``why``)."""
    run = simulate(robot, duration, dt, actuator_forces=forces, integrator=integrator,
                   record_every=record_every, friction_regularisation=friction_regularisation)
    note = f"{why}: run by the tree simulator"
    return dataclasses.replace(run, message=f"{run.message}; {note}" if run.message else note)


register_compiled_simulator(Hexapod, compiled_trajectory, supports_effects=True)
