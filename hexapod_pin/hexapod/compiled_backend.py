"""The hexapod's compiled simulator as a backend of ``hexapod_pin.simulate``.

``hp.simulate(hexapod, duration, dt, backend="compiled")`` (registered with
:func:`~hexapod_pin.core.simulate.register_compiled_simulator` when this module is
imported, as ``hexapod_pin`` does) runs
:func:`~hexapod_pin.hexapod.fast.simulate_fast` (the dynamics in platform coordinates, in
compiled code, the closures held by construction) and returns the generic
:class:`~hexapod_pin.core.simulate.Trajectory`: each recorded platform state mapped to the
tree in closed form (``q``, ``v``), the energies from Pinocchio on that tree state, the
work of the (constant) actuator forces, the closure residual of each configuration. The
run starts at home at rest; the stroke limits and the carriage gap stop it (status
"failed", the message naming the limit).
"""

from __future__ import annotations

import math
import time

import numpy as np
import numpy.typing as npt

from ..core.checks import as_array
from ..core.energy import energy_totals
from ..core.simulate import MAX_SAMPLES, Trajectory, register_compiled_simulator
from ..errors import InputError
from .fast import simulate_fast
from .robot import Hexapod


def compiled_trajectory(robot: Hexapod, duration: float, dt: float, *,
                        actuator_forces: npt.ArrayLike | None = None,
                        integrator: str = "rk4", record_every: int = 1) -> Trajectory:
    """:func:`~hexapod_pin.hexapod.fast.simulate_fast` from home at rest under constant
    actuator forces (6,) (N; default zero), as a :class:`~hexapod_pin.core.simulate.Trajectory`
    (see the module docstring).

    Raises:
        InputError: bad forces, more than :data:`~hexapod_pin.core.simulate.MAX_SAMPLES`
            samples to record, or what :func:`simulate_fast` refuses.
    """
    forces = None if actuator_forces is None else as_array(actuator_forces, (6,),
                                                           "actuator_forces")
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
                         record_every=every)
    keep = np.unique(np.concatenate([np.arange(0, len(fast.times), record_every // every),
                                     [len(fast.times) - 1]]))
    times, poses, twists = fast.times[keep], fast.poses[keep], fast.twists[keep]
    qa, qd, applied, saturated = (fast.q[keep], fast.qdot[keep], fast.actuator_forces[keep],
                                  fast.saturated[keep])
    n = len(keep)
    clm = robot.model
    q, v = np.empty((n, clm.nq)), np.empty((n, clm.nv))
    kinetic, potential, residual = np.empty(n), np.empty(n), np.empty(n)
    with robot.lock:
        for k in range(n):
            q[k], v[k] = robot.dynamics.tree_state(poses[k], twists[k])
            kinetic[k], potential[k] = energy_totals(clm, q[k], v[k])
            residual[k] = robot.closed_form.closure_residual(q[k])
    # the work of the held forces over every step, summed up to each kept sample
    steps = np.einsum("ni,ni->n", fast.actuator_forces[:-1], np.diff(fast.q, axis=0))
    work = np.concatenate([[0.0], np.cumsum(steps)])[keep]
    status = fast.status if fast.status in ("completed", "saturated") else "failed"
    message = fast.message if status == fast.status else \
        f"{fast.status}: {fast.message}".rstrip(": ")
    return Trajectory(times, q, v, poses, twists, qa, qd, applied, saturated,
                      kinetic + potential, kinetic, potential, work, residual, status, message,
                      fast.dt, time.perf_counter() - start)


register_compiled_simulator(Hexapod, compiled_trajectory)
