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

jit = numba.njit(**FLAGS)


@jit
def all_finite(vec) -> bool:
    """Whether every entry of the 1-D array ``vec`` is finite."""
    for k in range(vec.shape[0]):
        if not math.isfinite(vec[k]):
            return False
    return True
