"""Shared pieces of the compiled (numba) kernels of every robot.

Kernels are compiled with ``@njit(cache=True)``: the machine code is cached next to the
module (or in numba's user cache directory when that is read-only), so only the first
call after an install compiles. Kernels never raise: they return an integer status and
the caller raises the library's exception with its values.
"""

from __future__ import annotations

import math

import numba

#: options of every kernel: cached machine code, numpy's error model (a division by zero
#: gives inf / NaN, which the kernels' finiteness checks catch, never an exception)
FLAGS = {"cache": True, "error_model": "numpy"}

#: a compiled kernel (plain arithmetic)
jit = numba.njit(**FLAGS)
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
#: a compiled kernel with the fast-math flags
jit_fast = numba.njit(**FAST_FLAGS)
#: a compiled kernel that never allocates (no reference counting)
jit_lean = numba.njit(**LEAN_FLAGS)
#: a small allocation-free helper, inlined by LLVM into its compiled callers
jit_inline = numba.njit(forceinline=True, **LEAN_FLAGS)


@jit
def all_finite(vec) -> bool:
    """Whether every entry of the 1-D array ``vec`` is finite."""
    for k in range(vec.shape[0]):
        if not math.isfinite(vec[k]):
            return False
    return True
