"""Tiered execution of the compiled kernels: a kernel runs its Python source until
compiling it pays.

Every kernel of the library is a numba dispatcher made by the decorators of
:mod:`hexapod_pin.core.compiled`. numba compiles a kernel for the argument types of a call
that finds no machine code in memory; compiling takes 0.04 to 9 s per kernel (0.5 s on
average, measured over a cold :func:`hexapod_pin.warmup`), and a first call reaches tens of
kernels. Here, such a call (numba's ``_compile_for_args`` hook, replaced per kernel by
:class:`Tier`) decides instead, once per kernel and argument types:

1. **disk cache**: machine code in numba's disk cache is loaded and used (a cached kernel
   never runs interpreted; the cache index is read once per kernel and argument types);
2. **interpret**: otherwise the kernel runs its own Python source (``dispatcher.py_func``:
   the same formulas, interpreted, calling the other kernels through their dispatchers,
   so each follows this rule itself), timed;
3. **compile** (ski rental: rent until the rent paid reaches the price of buying): once
   the calls of the kernel with these argument types have spent, interpreted, its price
   (:meth:`Tier.price`: what compiling it would cost, estimated as the budget,
   :data:`DEFAULT_BUDGET` = 0.5 s, the mean compile time of one kernel, times the number
   of kernels its compilation compiles: itself and the kernels it calls, directly or
   not, that have no machine code yet), it is compiled (the compile notice of
   :mod:`~hexapod_pin.core.compiled` logs it) and runs machine code from then on. The
   time counted is that of its interpreted calls, the kernels they call included (time
   that compiling it saves), compilations excluded, plus typing the arguments. A small hot
   kernel (price 0.5 s) compiles long before the kernel that calls it (the price of its
   whole call tree, which drops as its callees compile). The waste is at most the price
   plus the compile time: at most twice the best choice made in hindsight when the
   estimate is right.

Loops over states or steps (batch drivers, the simulator loop) declare the argument that
counts their work (``work=``): such a call is compiled at once when its predicted
interpreted time (units times the seconds per unit measured by its earlier interpreted
calls, else :data:`PRIOR_SECONDS_PER_UNIT`) would take the kernel past its price, so a
large batch never crawls interpreted. A kernel that cannot run as Python may be marked
``always_compile`` (none is: the raw-pointer reads of
:func:`~hexapod_pin.core.dynamics_common.closure_state_errors` go through ctypes when
interpreted, through a numba intrinsic when compiled).

Same behaviour as machine code: an interpreted run executes under
``np.errstate(all="ignore")`` (numba's error model: 1/0 gives inf, never a warning); its
numpy scalars are returned as Python scalars (as numba returns them); and on ANY exception
in it (a Python float divided by zero, ``math.sqrt`` of a negative, an index out of
range ..., raised by the kernel or by a kernel it calls interpreted) the array arguments
of the outermost interpreted kernel, and arrays inside its tuple arguments, are restored
from copies taken before its run (kernels write outputs and scratch in place; the kernels
it calls write into those arrays or into arrays it made), that kernel is compiled (with
the kernels it calls) and the call rerun as machine code: the caller sees exactly what
the compiled kernel gives. Interpreted and compiled results agree to round-off (kernels
compiled with fast-math flags reassociate sums): ``tests/core/test_tiers.py`` checks every
call of every kernel that :func:`hexapod_pin.warmup`'s steps make (``tests/tier_verify.py``).

Cost: an interpreted kernel is 20 to 400 times slower than its machine code (1.6 ms
against 16 us for the hexapod's inverse dynamics; ``benchmarks/README.md``), about 5 us of
it per kernel call for this bookkeeping. A kernel with machine code pays nothing: numba
calls it before any of this.

Control: the environment variable ``HEXAPOD_PIN_COMPILE`` = ``tiered`` (default) or
``eager`` (compile every kernel on its first call, as numba does: bit-for-bit the same
results in every call of a session), and ``HEXAPOD_PIN_COMPILE_BUDGET`` (seconds, default
0.5; ``inf``: interpret until an exception), read at the first import of a kernel
(:data:`SETTINGS`, which may be changed at run time). :func:`eager` compiles within a
``with`` block of the calling thread (:func:`hexapod_pin.warmup` runs in one).

numba's ``_compile_for_args``, its cache index and the dispatcher's ``py_func`` are
private API: :func:`install` checks them (:func:`supported`) and leaves a kernel to
numba's plain behaviour (compile on first call) when this numba lacks them; a failure of
the bookkeeping itself (an unreadable cache index included) falls back to compiling.
Thread-safe: the bookkeeping takes a lock, compilation takes numba's; interpreted runs of
one kernel in several threads are independent (the kernels keep no state).
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import threading
import time
import types
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba.core.caching import NullCache
from numba.core.dispatcher import Dispatcher, OmittedArg

from ..errors import InputError

LOGGER = logging.getLogger("hexapod_pin")

#: environment variable choosing the mode: ``tiered`` (default) or ``eager``
MODE_VARIABLE = "HEXAPOD_PIN_COMPILE"
#: environment variable setting :attr:`Settings.budget` (seconds)
BUDGET_VARIABLE = "HEXAPOD_PIN_COMPILE_BUDGET"
#: interpreted seconds per kernel to compile (:meth:`Tier.price`): the mean compile time
#: of one kernel (0.52 s over the 211 compilations of a cold ``hexapod_pin.warmup()``,
#: each without the kernels it calls, 2-core VM; median 0.24 s, 95 % below 2.2 s)
DEFAULT_BUDGET = 0.5
#: interpreted seconds per unit of work (a state of a batch, a step of a simulation)
#: assumed before a loop kernel has run interpreted once: above the largest measured
#: (1.8 ms per RK4 step of the hexapod's simulator, 0.6 ms per state of its inverse
#: dynamics batch: ``benchmarks/bench_cold_start.py --per-call``)
PRIOR_SECONDS_PER_UNIT = 3e-3
MODES = ("tiered", "eager")

#: the numba hook replaced per kernel (None: this numba has none, kernels compile plainly)
_ORIGINAL: Callable[..., Any] | None = getattr(Dispatcher, "_compile_for_args", None)


@dataclass
class Settings:
    """The compile mode of the process (module docstring).

    Attributes:
        mode: ``"tiered"`` or ``"eager"``.
        budget: interpreted seconds per kernel to compile (:meth:`Tier.price`; ``inf``:
            only an exception compiles).
    """

    mode: str = "tiered"
    budget: float = DEFAULT_BUDGET


def read_settings(environ: Mapping[str, str]) -> Settings:
    """The settings that the variables :data:`MODE_VARIABLE` and :data:`BUDGET_VARIABLE`
    of ``environ`` give (unset: the defaults).

    Raises:
        InputError: an unknown mode, or a budget that is not a number of seconds >= 0.
    """
    mode = environ.get(MODE_VARIABLE, "").strip().lower() or "tiered"
    if mode not in MODES:
        raise InputError(MODE_VARIABLE, mode, f"expected one of {', '.join(MODES)}")
    text = environ.get(BUDGET_VARIABLE, "").strip()
    try:
        budget = float(text) if text else DEFAULT_BUDGET
    except ValueError:
        budget = math.nan
    if not budget >= 0.0:
        raise InputError(BUDGET_VARIABLE, text, "expected a number of seconds >= 0 (or inf)")
    return Settings(mode, budget)


#: the process's settings (read from the environment at import; may be changed)
SETTINGS = read_settings(os.environ)

_LOCK = threading.Lock()
class _ThreadState(threading.local):
    """Per thread: depth of :func:`eager` blocks, of interpreted kernel calls, seconds
    spent compiling through a :class:`Tier`, and why the current compilation runs."""

    eager = 0
    depth = 0
    compiling = 0.0
    reason = ""


_LOCAL = _ThreadState()


@contextlib.contextmanager
def eager() -> Iterator[None]:
    """Within the block, kernels called by this thread compile on their first call (as in
    mode ``eager``)."""
    _LOCAL.eager += 1
    try:
        yield
    finally:
        _LOCAL.eager -= 1


def compile_reason() -> str:
    """Why the kernel being compiled by this thread is compiled now (empty when not by a
    :class:`Tier` decision); the compile notice quotes it."""
    return _LOCAL.reason


def supported(dispatcher: object) -> bool:
    """Whether this numba offers what :class:`Tier` uses on ``dispatcher``: the
    ``_compile_for_args`` hook, ``py_func``, ``typeof_pyval`` and either no disk cache
    (``cache=False``) or one whose index can be read."""
    cache = getattr(dispatcher, "_cache", None)
    cache_file = getattr(cache, "_cache_file", None)
    return (_ORIGINAL is not None and isinstance(dispatcher, Dispatcher)
            and callable(getattr(dispatcher, "py_func", None))
            and callable(getattr(dispatcher, "typeof_pyval", None))
            and (isinstance(cache, NullCache)
                 or (callable(getattr(cache, "_index_key", None))
                     and callable(getattr(cache_file, "_load_index", None)))))


def install(dispatcher: Any, work: int | None = None, always_compile: bool = False) -> Any:
    """Give ``dispatcher`` (a numba CPU dispatcher) tiered execution; returns it.

    Args:
        dispatcher: the kernel.
        work: index of the argument counting the work of a call (an int, or an array whose
            first axis counts states or steps); None: a call of bounded work.
        always_compile: compile on the first call (a kernel that cannot run as Python).
    """
    if supported(dispatcher):
        dispatcher._compile_for_args = Tier(dispatcher, work, always_compile)
    return dispatcher


def tier_of(dispatcher: Any) -> Tier | None:
    """The :class:`Tier` installed on a kernel (None: compiled plainly)."""
    tier = getattr(dispatcher, "__dict__", {}).get("_compile_for_args")
    return tier if isinstance(tier, Tier) else None


def callees(dispatcher: Any) -> list[Any]:
    """The kernels a kernel's source names: global names (``leg_state(...)``), attributes
    of imported modules (``kernels.leg_state(...)``) and kernels it closes over."""
    func = dispatcher.py_func
    names, scope = func.__code__.co_names, func.__globals__
    out = [cell.cell_contents for cell in func.__closure__ or ()
           if isinstance(cell.cell_contents, Dispatcher)]
    for name in names:
        value = scope.get(name)
        if isinstance(value, Dispatcher):
            out.append(value)
        elif isinstance(value, types.ModuleType):
            out += [getattr(value, attr) for attr in names
                    if isinstance(getattr(value, attr, None), Dispatcher)]
    return out


def closure(dispatcher: Any) -> tuple[Any, ...]:
    """``dispatcher`` and every kernel it calls, directly or through others
    (:func:`callees`), each once."""
    seen: dict[int, Any] = {}
    todo = [dispatcher]
    while todo:
        item = todo.pop()
        if id(item) not in seen:
            seen[id(item)] = item
            todo += callees(item)
    return tuple(seen.values())


class _Record:
    """What a kernel did with one tuple of argument types."""

    __slots__ = ("cached", "calls", "key", "rate", "spent")

    def __init__(self, key: tuple) -> None:
        self.key = key                     # the numba types of the arguments
        self.spent = 0.0                   # interpreted seconds (calls, compilations out)
        self.calls = 0                     # interpreted calls
        self.rate: float | None = None     # interpreted seconds per unit of work
        self.cached: bool | None = None    # disk cache checked: None not yet


#: incremented by every compilation through a Tier (the prices are then recounted)
_GENERATION = [0]


class Tier:
    """The decision of one kernel for a call without machine code (module docstring):
    installed as the dispatcher's ``_compile_for_args``, which numba calls with the
    call's arguments and whose returned callable it then calls with them.

    Attributes:
        dispatcher: the kernel.
        work: index of the argument counting a call's work (None: bounded work).
        always_compile: whether the kernel compiles on its first call.
    """

    def __init__(self, dispatcher: Any, work: int | None, always_compile: bool) -> None:
        self.dispatcher = dispatcher
        self.work = work
        self.always_compile = always_compile
        self._records: dict[tuple, _Record] = {}
        self._by_fingerprint: dict[tuple, _Record] = {}
        #: no argument defaults: numba passes the arguments as they are (no OmittedArg)
        self.plain_args = not dispatcher.py_func.__defaults__
        self._closure: tuple[Any, ...] | None = None
        self._uncompiled = (-1, 1)         # (generation, kernels without machine code)

    def interpreted_seconds(self) -> float:
        """Interpreted seconds of the kernel's calls so far (the kernels they called
        included, compilations excluded), all argument types together."""
        with _LOCK:
            return sum(record.spent for record in self._records.values())

    def price(self) -> float:
        """The interpreted seconds after which the kernel compiles: the budget
        (:attr:`Settings.budget`) times the number of kernels compiling it would compile
        (itself and those it calls, directly or not, that have no machine code yet)."""
        generation, count = self._uncompiled
        if generation != _GENERATION[0]:
            if self._closure is None:
                self._closure = closure(self.dispatcher)
            generation = _GENERATION[0]
            count = max(sum(1 for d in self._closure if not d.overloads), 1)
            self._uncompiled = (generation, count)
        return count * SETTINGS.budget

    def __call__(self, *args: Any, **kws: Any) -> Any:
        start = time.perf_counter()
        try:
            choice = self._choose(args, kws)
        except Exception:  # the bookkeeping failed: numba's plain behaviour
            LOGGER.debug("tiered execution of %s failed", self.dispatcher, exc_info=True)
            choice = ""
        if isinstance(choice, str):
            return self._compile(args, kws, choice)
        choice.overhead = time.perf_counter() - start   # a cost of not compiling
        return choice

    def _choose(self, args: tuple, kws: dict) -> _Interpreted | str:
        """An interpreted run, or the reason to compile now ("" for none to tell)."""
        in_eager_block = _LOCAL.eager > 0
        if kws or self.always_compile or SETTINGS.mode != "tiered" or in_eager_block:
            return ""
        record = self._record(args)
        if record is None:                 # untypeable: numba reports it as it always did
            return ""
        if record.cached is None:
            record.cached = self._in_disk_cache(record.key)
        if record.cached is not False:     # cached (or unknown): numba loads (compiles)
            return ""
        price = self.price()
        units = _units(args[self.work]) if self.work is not None else None
        if units is not None:
            predicted = units * (record.rate if record.rate is not None
                                 else PRIOR_SECONDS_PER_UNIT)
            if record.spent + predicted > price:
                return (f"a call of {units} units of work: {predicted:.2g} s interpreted "
                        f"predicted, compiling about {price:.2g} s")
        if record.spent >= price:
            return f"after {record.spent:.2g} s interpreted, about what compiling takes"
        return _Interpreted(self, record, units)

    def _record(self, args: tuple) -> _Record | None:
        """The record of the arguments' numba types (None: numba cannot type them),
        found by :func:`_fingerprint` when it can (numba's ``typeof`` costs microseconds
        per argument)."""
        fingerprint = tuple(map(_fingerprint, args))
        known = None not in fingerprint
        record = self._by_fingerprint.get(fingerprint) if known else None
        if record is not None:
            return record
        try:
            key = tuple(self.dispatcher.typeof_pyval(a.value if isinstance(a, OmittedArg)
                                                     else a) for a in args)
        except Exception:  # noqa: BLE001 - any: numba's own call reports it
            return None
        with _LOCK:
            record = self._records.get(key)
            if record is None:
                record = self._records[key] = _Record(key)
            if known:
                self._by_fingerprint[fingerprint] = record
        return record

    def _compile(self, args: tuple, kws: dict, reason: str) -> Any:
        """numba's own hook: machine code from memory, the disk cache or the compiler."""
        previous, _LOCAL.reason = _LOCAL.reason, reason
        start = time.perf_counter()
        try:
            return _ORIGINAL(self.dispatcher, *args, **kws)  # type: ignore[misc]
        finally:
            _LOCAL.reason = previous
            _LOCAL.compiling += time.perf_counter() - start
            _GENERATION[0] += 1

    def _in_disk_cache(self, key: tuple) -> bool | None:
        """Whether numba's disk cache holds machine code for these argument types (its
        index, as numba's loader reads it); None: cannot tell."""
        cache = self.dispatcher._cache
        if isinstance(cache, NullCache):   # a kernel without disk cache
            return False
        try:
            index = cache._cache_file._load_index()
            return cache._index_key(key, self.dispatcher.targetctx.codegen()) in index
        except Exception:  # another numba layout, an unreadable index
            LOGGER.debug("cache index of %s unreadable", self.dispatcher, exc_info=True)
            return None


class _Interpreted:
    """One interpreted call of a kernel (numba calls it with the call's arguments)."""

    __slots__ = ("overhead", "record", "tier", "units")

    def __init__(self, tier: Tier, record: _Record, units: int | None) -> None:
        self.tier, self.record, self.units = tier, record, units
        self.overhead = 0.0

    def __call__(self, *args: Any) -> Any:
        values = args if self.tier.plain_args else tuple(
            a.value if isinstance(a, OmittedArg) else a for a in args)
        depth = _LOCAL.depth
        compiling, start = _LOCAL.compiling, time.perf_counter()
        if depth:          # inside an interpreted kernel: its exceptions go to the outermost
            _LOCAL.depth = depth + 1
            try:
                result = _plain(self.tier.dispatcher.py_func(*values))
            finally:
                _LOCAL.depth = depth
        else:
            saved = _snapshot(values)
            _LOCAL.depth = 1
            try:
                with np.errstate(all="ignore"):
                    result = _plain(self.tier.dispatcher.py_func(*values))
            except Exception as exc:  # noqa: BLE001 - any: the compiled kernel decides
                _restore(values, saved)
                LOGGER.debug("%s raised %r interpreted: compiled and rerun",
                             self.tier.dispatcher, exc)
                entry = self.tier._compile(args, {}, "its interpreted run raised "
                                           f"{type(exc).__name__}")
                return entry(*args)
            finally:
                _LOCAL.depth = 0
        seconds = time.perf_counter() - start - (_LOCAL.compiling - compiling)
        with _LOCK:
            self.record.spent += seconds + self.overhead
            self.record.calls += 1
            if self.units:
                self.record.rate = seconds / self.units
        return result


def run_interpreted(dispatcher: Any, args: tuple) -> Any:
    """Run a kernel's Python source on ``args`` as tiered execution does: under
    ``np.errstate(all="ignore")``, numpy scalars of the result returned as Python scalars;
    an exception propagates (no fallback, no bookkeeping). For tests and debugging."""
    with np.errstate(all="ignore"):
        return _plain(dispatcher.py_func(*args))


def _fingerprint(value: Any) -> Any:
    """A hashable key for the numba type of an argument (arrays: dtype number, ndim and
    the flags: contiguity, writability, alignment; scalars: their type), or None when only
    numba's ``typeof`` can tell. It serves the bookkeeping only (the cache lookup and the
    time spent): numba types the arguments itself when it compiles."""
    kind = type(value)
    if kind is np.ndarray:
        return value.dtype.num, value.ndim, value.flags.num
    if kind is float or kind is bool or (isinstance(value, np.generic)
                                         and kind.__module__ == "numpy"):
        return kind
    if kind is int:
        return int if -2**63 <= value < 2**63 else None
    if kind is tuple:
        items = tuple(map(_fingerprint, value))
        return None if None in items else ("tuple", items)
    return None


def _units(value: Any) -> int | None:
    """Units of work counted by an argument: an integer, or an array's first axis."""
    if isinstance(value, OmittedArg):
        value = value.value
    if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
        return int(value)
    shape = getattr(value, "shape", None)
    return int(shape[0]) if shape else None


def _snapshot(value: Any) -> Any:
    """Copies of the writable arrays in ``value`` (arrays, tuples of them)."""
    if isinstance(value, np.ndarray):
        return value.copy() if value.flags.writeable else None
    if isinstance(value, tuple):
        return tuple(_snapshot(v) for v in value)
    return None


def _restore(value: Any, saved: Any) -> None:
    """Write the copies of :func:`_snapshot` back into the arrays they were taken of."""
    if isinstance(value, np.ndarray):
        if saved is not None:
            value[...] = saved
    elif isinstance(value, tuple):
        for v, s in zip(value, saved):
            _restore(v, s)


def _plain(value: Any) -> Any:
    """numpy scalars as the Python scalars numba returns (tuples walked)."""
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, tuple):
        return tuple(_plain(v) for v in value)
    return value
