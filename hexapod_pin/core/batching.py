"""Batch drivers of the compiled kernels of every robot: one source, two compilations.

A batch loop (``for c in numba.prange(n_chunks(n))``, each chunk of :data:`CHUNK` states
with its own scratch) is compiled twice from the same source with :func:`prange_jit`:
with ``parallel=True`` on numba's worker threads, and as a plain loop on the calling
thread (``prange`` is ``range`` there). Batches of fewer than :data:`PARALLEL_MIN`
states run serially: waking the worker threads costs more than it saves below that
size, and much more on a loaded machine. Both compilations give the same numbers.

The parallel twin is compiled from a copy of the function named ``<name>__parallel``: numba
keys its disk cache on the function's name and signature only (not on ``parallel=True``),
so two twins of one name would share one cache entry and load each other's machine code.

Both twins have tiered execution (:mod:`hexapod_pin.core.tiers`) with the states as their
work: a small batch may run interpreted (the parallel twin then runs its loop serially), a
batch whose predicted interpreted time exceeds the budget compiles at once.
"""

from __future__ import annotations

import types

from .compiled import FLAGS, jit, kernel

#: states per chunk of a prange loop (one scratch per chunk)
CHUNK = 64
#: batches with fewer states run on the calling thread
PARALLEL_MIN = 50_000


@jit
def n_chunks(n: int) -> int:
    """Number of chunks of :data:`CHUNK` states covering ``n`` states."""
    return (n + CHUNK - 1) // CHUNK


class BatchDriver:
    """A batch loop compiled with and without ``parallel=True`` (with the compile options
    ``flags``); a call picks one by the number of states (the first axis of argument
    ``states_arg``)."""

    def __init__(self, func, states_arg: int, flags: dict = FLAGS):
        self.parallel = kernel(dict(flags, parallel=True), work=states_arg)(
            _renamed(func, "__parallel"))
        self.serial = kernel(flags, work=states_arg)(func)
        self.states_arg = states_arg
        self.__doc__ = func.__doc__

    def __call__(self, *args):
        n = args[self.states_arg].shape[0]
        return (self.parallel if n >= PARALLEL_MIN else self.serial)(*args)


def _renamed(func, suffix: str):
    """A copy of the plain function ``func`` whose name and qualified name end in ``suffix``
    (its own disk-cache entry: see the module docstring)."""
    twin = types.FunctionType(func.__code__, func.__globals__, func.__name__ + suffix,
                              func.__defaults__, func.__closure__)
    twin.__qualname__ = func.__qualname__ + suffix
    twin.__module__ = func.__module__
    twin.__doc__ = func.__doc__
    return twin


def prange_jit(states_arg: int, flags: dict = FLAGS):
    """Decorator: a :class:`BatchDriver` whose states are argument ``states_arg``'s rows,
    compiled with ``flags`` (default :data:`~hexapod_pin.core.compiled.FLAGS`)."""
    return lambda func: BatchDriver(func, states_arg, flags)
