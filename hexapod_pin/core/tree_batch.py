"""Batches of the generic tree dynamics: forward and inverse dynamics over N states.

Same equations, routes, verification and conventions as
:func:`~hexapod_pin.core.dynamics.forward_dynamics_tree` and
:func:`~hexapod_pin.core.dynamics.inverse_dynamics_tree`; states along the first axis.
The inputs are checked once for the whole batch; every state is then solved and verified
like a single call. Inverse dynamics evaluates ``M a + h`` of all states with Pinocchio's
pooled ``rneaInParallel`` (OpenMP over a ``pin.ModelPool``). Pinocchio 4.1 has no pooled
constrained forward dynamics (only ``abaInParallel``, unconstrained), so forward dynamics
runs ``pin.constraintDynamics`` state after state on the calling thread, each on the
short verified path of a single call (the inputs were checked once).

Errors name the first failing state: :class:`~hexapod_pin.errors.SolverError` (detail
prefixed by ``state i``), :class:`~hexapod_pin.errors.BatchActuatorSaturationError`.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from ..errors import ActuatorSaturationError, BatchActuatorSaturationError, InputError, SolverError
from .checks import as_array
from .closed_loop import ClosedLoopModel
from .dynamics import (
    FORWARD_METHODS,
    INVERSE_METHODS,
    TreeForwardDynamics,
    TreeInverseDynamics,
    dynamics_of,
)


class _PerStateResults:
    """What both batch results read from their per-state results (``self.results``)."""

    if TYPE_CHECKING:              # a field or a cached property of each result class
        @property
        def results(self) -> tuple: ...

    @property
    def multipliers(self) -> np.ndarray:
        """Closure multipliers (N, n_rows), conventions of the single call."""
        return np.array([r.multipliers for r in self.results]).reshape(len(self.results), -1)

    @property
    def statuses(self) -> tuple[str, ...]:
        """Per-state status strings."""
        return tuple(r.status for r in self.results)


class TreeForwardDynamicsBatch(_PerStateResults):
    """Result of :func:`forward_dynamics_tree_batch`.

    Attributes:
        a: tree accelerations (N, nv).
        results: the per-state :class:`~hexapod_pin.core.dynamics.TreeForwardDynamics`
            (status, iterations, rank; multipliers converted on access), built on first
            access from what the solves stored.
    """

    def __init__(self, a: np.ndarray,
                 make_results: Callable[[], Sequence[TreeForwardDynamics]]):
        self.a = a
        self._make_results = make_results

    @cached_property
    def results(self) -> tuple[TreeForwardDynamics, ...]:
        return tuple(self._make_results())


@dataclass(frozen=True)
class TreeInverseDynamicsBatch(_PerStateResults):
    """Result of :func:`inverse_dynamics_tree_batch`.

    Attributes:
        actuator_forces: ``u`` (N, n_act) (N or N m), ``clm.actuated_joints`` order.
        residual: per-state max-abs equation-of-motion residual (N,) (N, N m).
        results: the per-state :class:`~hexapod_pin.core.dynamics.TreeInverseDynamics`
            (multipliers converted on access).
    """

    actuator_forces: np.ndarray
    residual: np.ndarray
    results: tuple[TreeInverseDynamics, ...]


#: batches with fewer states evaluate ``rneaInParallel`` on one thread
PARALLEL_MIN = 4096


def _states(clm: ClosedLoopModel, q, v, third, third_size: int, name: str):
    q = as_array(q, (clm.nq,), "q", batch=True)
    v = as_array(v, (clm.nv,), "v", batch=True)
    third = as_array(third, (third_size,), name, batch=True)
    if not q.shape[0] == v.shape[0] == third.shape[0]:
        raise InputError("q, v, " + name, (q.shape, v.shape, third.shape),
                         "the batches must have the same number of states")
    return q, v, third


def _tau_ext(clm: ClosedLoopModel, tau_ext, n: int) -> np.ndarray:
    if tau_ext is None:
        return np.zeros((n, clm.nv))
    arr = np.asarray(tau_ext, dtype=float)
    if arr.shape == (clm.nv,):
        arr = np.broadcast_to(arr, (n, clm.nv))
    return as_array(arr, (clm.nv,), "tau_ext", batch=True)


def _state_error(index: int, exc: SolverError) -> SolverError:
    return SolverError(exc.solver, exc.status, f"state {index}: {exc}")


def forward_dynamics_tree_batch(clm: ClosedLoopModel, q: np.ndarray, v: np.ndarray,
                                actuator_forces: np.ndarray,
                                tau_ext: np.ndarray | None = None,
                                method: str = "pinocchio") -> TreeForwardDynamicsBatch:
    """:func:`~hexapod_pin.core.dynamics.forward_dynamics_tree` over N states.

    Args:
        clm: the closed-loop model.
        q: configurations (N, nq), closures assembled.
        v: velocities (N, nv), keeping the closures.
        actuator_forces: ``u`` (N, n_act) (N or N m).
        tau_ext: generalised external forces (N, nv) or (nv,) for every state; default 0.
        method: "pinocchio", "qp" or "kkt" (see the single call).

    Returns:
        :class:`TreeForwardDynamicsBatch`.

    Raises:
        InputError: bad shapes, NaN / inf, different batch sizes, unknown method.
        SolverError: a state failed its verification (``state i`` in the message).
    """
    if method not in FORWARD_METHODS:
        raise InputError("method", method, f"expected one of {FORWARD_METHODS}")
    dyn = dynamics_of(clm)
    q, v, u = _states(clm, q, v, actuator_forces, clm.n_actuated, "actuator_forces")
    n = q.shape[0]
    tau = _tau_ext(clm, tau_ext, n).copy()
    tau[:, clm.actuated_v] += u
    acc = np.empty((n, clm.nv))
    # the short "pinocchio" path stores the answer and its iterations (0: a full result
    # in `full`); the per-state results are built from the stored rows on access
    lam = np.empty((n, clm.n_rows))
    iters = np.zeros(n, dtype=int)
    exact = np.zeros(n, dtype=bool)     # an exact solve answered (redundant rows)
    full: dict[int, TreeForwardDynamics] = {}
    verified = dyn.pinocchio_verified if method == "pinocchio" else None
    if verified is not None:
        q, v = q.copy(), v.copy()          # the results keep views of their rows
        ddq, lam_pin = dyn.data.ddq, dyn.data.lambda_c
    effects = clm.effects.has_forces
    for i in range(n):
        solve, at_rest = dyn.forward_total, False
        if effects:                        # the joint effects' force joins the applied one
            force, rest = dyn.effect_terms(q[i], v[i])
            if rest.size:                  # Coulomb friction at rest: the full route
                solve, at_rest = dyn.forward_unchecked, True
            else:
                tau[i] += force
        how = None if verified is None or at_rest else verified(q[i], v[i], tau[i])
        if how is not None:
            acc[i], lam[i], iters[i], exact[i] = ddq, lam_pin, how.iter, how.exact
            continue
        try:
            res = solve(q[i], v[i], tau[i], method)
        except SolverError as exc:
            raise _state_error(i, exc) from None
        acc[i] = res.a
        full[i] = res
        if verified is not None:       # the first call sets the short path up
            ddq, lam_pin = dyn.data.ddq, dyn.data.lambda_c
    rank = dyn.closure_rank(q[0]) if n else 0

    def make_results():
        return [full[i] if i in full else
                dyn.pinocchio_result_of(q[i], v[i], tau[i], acc[i], lam[i], int(iters[i]), rank,
                                        bool(exact[i]))
                for i in range(n)]
    return TreeForwardDynamicsBatch(acc, make_results)


def inverse_dynamics_tree_batch(clm: ClosedLoopModel, q: np.ndarray, v: np.ndarray,
                                a: np.ndarray, tau_ext: np.ndarray | None = None,
                                bounds: np.ndarray | None = None, method: str = "qp",
                                threads: int | None = None) -> TreeInverseDynamicsBatch:
    """:func:`~hexapod_pin.core.dynamics.inverse_dynamics_tree` over N states.

    Args:
        clm: the closed-loop model.
        q: configurations (N, nq), closures assembled.
        v: velocities (N, nv), keeping the closures.
        a: accelerations (N, nv), keeping the closures.
        tau_ext: generalised external forces (N, nv) or (nv,); default zero.
        bounds: ``abs(u) <= bounds`` for every state (scalar or (n_act,)); None: none.
        method: "qp" or "kkt".
        threads: OpenMP threads of ``pin.rneaInParallel``; default one below
            :data:`PARALLEL_MIN` states (waking OpenMP threads costs more than it saves
            there), else ``os.cpu_count()``.

    Returns:
        :class:`TreeInverseDynamicsBatch`.

    Raises:
        InputError: bad shapes, NaN / inf, different batch sizes, bad bounds or method.
        BatchActuatorSaturationError: a state needs ``abs(u) > bounds`` (``index``).
        SolverError: a state failed (``state i`` in the message), e.g. a motion that
            does not keep the closures.
    """
    if method not in INVERSE_METHODS:
        raise InputError("method", method, f"expected one of {INVERSE_METHODS}")
    dyn = dynamics_of(clm)
    q, v, a = _states(clm, q, v, a, clm.nv, "a")
    n = q.shape[0]
    ext = _tau_ext(clm, tau_ext, n)
    limits = dyn.check_bounds(bounds)
    if threads is None:
        threads = 1 if n < PARALLEL_MIN else (os.cpu_count() or 1)
    threads = max(1, int(threads))
    pool = dyn.model_pool(threads)
    force = pin.rneaInParallel(threads, pool, np.asfortranarray(q.T), np.asfortranarray(v.T),
                               np.asfortranarray(a.T))
    force = np.asarray(force).T
    u = np.empty((n, clm.n_actuated))
    residual = np.empty(n)
    results = []
    for i in range(n):
        try:
            res = dyn.inverse_from_force(q[i], v[i], a[i], force[i], ext[i], limits, method)
        except ActuatorSaturationError as exc:
            raise BatchActuatorSaturationError(i, exc.needed, exc.limit) from None
        except SolverError as exc:
            raise _state_error(i, exc) from None
        u[i], residual[i] = res.actuator_forces, res.residual
        results.append(res)
    return TreeInverseDynamicsBatch(u, residual, tuple(results))
