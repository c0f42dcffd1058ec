"""Shared pieces of the compiled (numba) kernels of every robot.

Kernels are made by the decorators here (:func:`kernel`, :data:`jit`, :data:`jit_fast`,
:data:`jit_lean`, :data:`jit_inline`): ``numba.njit(cache=True)``, the machine code cached
next to the module (or in numba's user cache directory when that is read-only), with
tiered execution (:mod:`hexapod_pin.core.tiers`): a kernel whose machine code is neither in
memory nor in the disk cache runs its own Python source until that has cost about a
compile time, then compiles (``HEXAPOD_PIN_COMPILE=eager``: compile on the first call).
Kernels never raise: they return an integer status and the caller raises the library's
exception with its values.

Cache freshness: numba keys a cached kernel on its own source file only, but a kernel
compiled into another module's kernel (``batch`` and ``fast`` inline ``kernels``) is
frozen into that module's cache. The cache locators registered here (:func:`source_stamp`)
key every kernel of this package on the contents of ALL its compiled modules instead, so
an edit to any of them recompiles every kernel on next use (never stale machine code).
With ``NUMBA_CACHE_DIR`` set, the cache lives there (numba's own rule), stamped the same way.

Compile notice: compiling a kernel that is not in the cache (a fraction of a second to
seconds each, the compilation of a kernel compiling the kernels it calls) logs one line at
level INFO on the logger ``"hexapod_pin"`` (:class:`CompileNotice`, with the reason of the
tiered execution: the interpreted time spent, a large call, an exception; a call served
from memory, from the disk cache or interpreted logs nothing). ``hexapod_pin.warmup()`` /
``hexapod-pin warmup`` compile every kernel at once.
"""

from __future__ import annotations

import functools
import hashlib
import logging
import math
import threading
from pathlib import Path

import numba
from numba.core import caching, event

from . import tiers

#: the library's logger (the compile notice, :class:`CompileNotice`)
LOGGER = logging.getLogger("hexapod_pin")

#: the package's source folder (``hexapod_pin/``)
PACKAGE_DIR = Path(__file__).resolve().parents[1]


def compiled_modules() -> list[Path]:
    """The package's source files that hold compiled kernels (those mentioning ``jit``),
    sorted."""
    return sorted(path for path in PACKAGE_DIR.rglob("*.py")
                  if "jit" in path.read_text(encoding="utf-8"))


@functools.lru_cache(maxsize=1)
def source_stamp() -> str:
    """SHA-256 of the contents of every file of :func:`compiled_modules` (and their paths
    relative to the package): the freshness stamp of every cached kernel of the package."""
    digest = hashlib.sha256()
    for path in compiled_modules():
        digest.update(str(path.relative_to(PACKAGE_DIR)).encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def _in_package(py_file: str) -> bool:
    try:
        Path(py_file).resolve().relative_to(PACKAGE_DIR)
    except (OSError, ValueError):
        return False
    return True


class PackageUserProvidedLocator(caching.UserProvidedCacheLocator):
    """numba's ``NUMBA_CACHE_DIR`` locator for this package's kernels (used only when that
    variable is set, as numba's own), stamped with :func:`source_stamp`."""

    def get_source_stamp(self) -> str:
        return source_stamp()

    @classmethod
    def from_function(cls, py_func, py_file):  # type: ignore[no-untyped-def]
        return super().from_function(py_func, py_file) if _in_package(py_file) else None


class PackageInTreeLocator(caching.InTreeCacheLocator):
    """numba's ``__pycache__`` locator for this package's kernels, stamped with
    :func:`source_stamp` instead of the kernel's own file."""

    def get_source_stamp(self) -> str:
        return source_stamp()

    @classmethod
    def from_function(cls, py_func, py_file):  # type: ignore[no-untyped-def]
        return super().from_function(py_func, py_file) if _in_package(py_file) else None


class PackageUserWideLocator(caching.UserWideCacheLocator):
    """numba's user-wide locator (read-only installs) for this package's kernels, stamped
    with :func:`source_stamp`."""

    def get_source_stamp(self) -> str:
        return source_stamp()

    @classmethod
    def from_function(cls, py_func, py_file):  # type: ignore[no-untyped-def]
        return super().from_function(py_func, py_file) if _in_package(py_file) else None


def _register_locators() -> None:
    """Put the package's locators first in numba's list (functions of other packages fall
    through to numba's own locators). A numba without that list keeps its default."""
    classes = getattr(getattr(caching, "CacheImpl", None), "_locator_classes", None)
    if isinstance(classes, list) and PackageInTreeLocator not in classes:
        classes[0:0] = [PackageUserProvidedLocator, PackageInTreeLocator,
                        PackageUserWideLocator]


_register_locators()


def kernel_name(dispatcher: object) -> str:
    """``module.function`` of a compiled kernel (a numba dispatcher), e.g.
    ``hexapod_pin.hexapod.kernels.inverse_dynamics``."""
    func = getattr(dispatcher, "py_func", dispatcher)
    return f"{getattr(func, '__module__', '?')}.{getattr(func, '__qualname__', '?')}"


class CompileNotice(event.Listener):
    """Logs one INFO line on the ``"hexapod_pin"`` logger when a kernel of this package is
    compiled (numba's ``"numba:compile"`` event, sent only on a cache miss: not for a call
    served from memory, loaded from the disk cache or interpreted); the line quotes why
    tiered execution compiles it now (:func:`hexapod_pin.core.tiers.compile_reason`). Kernels compiled inside the
    compilation of another (its callees) add no line: one notice per first call."""

    def __init__(self) -> None:
        self._depth = threading.local()
        #: kernels of this package compiled in this process (callees included)
        self.compiled = 0

    def on_start(self, ev: event.Event) -> None:
        depth = getattr(self._depth, "value", 0)
        self._depth.value = depth + 1
        dispatcher = (ev.data or {}).get("dispatcher")
        name = kernel_name(dispatcher)
        if not name.startswith("hexapod_pin."):
            return
        self.compiled += 1
        if depth == 0:
            reason = tiers.compile_reason()
            LOGGER.info("compiling %s%s (numba, once per install: the machine code is cached "
                        "on disk; 'hexapod-pin warmup' compiles every kernel)", name,
                        f" ({reason})" if reason else "")

    def on_end(self, ev: event.Event) -> None:
        self._depth.value = max(getattr(self._depth, "value", 1) - 1, 0)


#: the listener registered with numba (one per process)
COMPILE_NOTICE = CompileNotice()
event.register("numba:compile", COMPILE_NOTICE)

#: options of every kernel: cached machine code, numpy's error model (a division by zero
#: gives inf / NaN, which the kernels' finiteness checks catch, never an exception)
FLAGS = {"cache": True, "error_model": "numpy"}


def kernel(flags: dict, work: int | None = None, always_compile: bool = False):
    """Decorator: a kernel compiled with the numba options ``flags``, with tiered execution
    (:mod:`hexapod_pin.core.tiers`: its Python source runs until compiling it pays).

    Args:
        flags: numba's ``njit`` options.
        work: index of the argument that counts the work of a call (an int, or an array
            whose first axis counts states or steps), for a loop over states or steps;
            None: each call does a bounded amount of work.
        always_compile: compile on the first call (a kernel that cannot run as Python).
    """
    def decorate(func):
        return tiers.install(numba.njit(**flags)(func), work, always_compile)
    return decorate


#: a compiled kernel (plain arithmetic)
jit = kernel(FLAGS)
#: the kernel options plus the fast-math flags ``contract, reassoc, nsz`` (no ``nnan`` /
#: ``ninf``: the finiteness checks stay exact); results differ from plain arithmetic by
#: round-off only
FAST_FLAGS = dict(FLAGS, fastmath={"contract", "reassoc", "nsz"})


def _lean_options() -> dict:
    """numba's private option compiling without the reference-counting runtime (for
    kernels that never allocate); plain options when this numba lacks it."""
    try:
        from numba.core.options import DefaultOptions
    except ImportError:  # pragma: no cover - another numba layout: plain options
        return {}
    return {"_nrt": False} if hasattr(DefaultOptions, "_nrt") else {}


LEAN_FLAGS = dict(FAST_FLAGS, **_lean_options())
#: inline options of the small helpers
INLINE_FLAGS = dict(LEAN_FLAGS, forceinline=True)
#: a compiled kernel with the fast-math flags
jit_fast = kernel(FAST_FLAGS)
#: a compiled kernel that never allocates (no reference counting)
jit_lean = kernel(LEAN_FLAGS)
#: a small allocation-free helper, inlined by LLVM into its compiled callers
jit_inline = kernel(INLINE_FLAGS)


@jit
def all_finite(vec) -> bool:
    """Whether every entry of the 1-D array ``vec`` is finite."""
    for k in range(vec.shape[0]):
        if not math.isfinite(vec[k]):
            return False
    return True


@jit
def all_finite4(a, b, c, d) -> bool:
    """Whether every entry of the four 1-D arrays is finite (one call for the vectors of a
    result: :func:`~hexapod_pin.core.checks.check_finite_result`)."""
    return all_finite(a) and all_finite(b) and all_finite(c) and all_finite(d)


@jit
def all_within(vec, limit: float) -> bool:
    """Whether every entry of the 1-D array ``vec`` is finite and at most ``limit`` in
    magnitude (False for NaN)."""
    for k in range(vec.shape[0]):
        if not abs(vec[k]) <= limit:
            return False
    return True
