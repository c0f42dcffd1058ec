"""Input checks shared by every module: arrays, branches, geometry scalars, scalar
options (numbers and counts), and the finiteness check of returned values.

Each raises a specific :class:`~hexapod_pin.errors.HexapodPinError` naming the argument
(or the returned field) and the offending values; nothing here returns NaN or prints.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import numbers
import operator
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import (ArgumentTypeError, GeometryError, InputError, MissingFileError,
                      NonFiniteResultError, SolverError)
from .compiled import all_finite, all_finite4, all_within

#: the largest magnitude an input may have: above it, squares and products of two inputs
#: overflow double precision (sqrt of the largest double is 1.34e154), so no answer
#: computed from it could be certified. No quantity in SI units comes near it.
MAX_MAGNITUDE = 1e150


def as_array(value, shape_tail: tuple[int, ...], name: str, batch: bool = False) -> np.ndarray:
    """Check and convert a numeric input.

    Args:
        value: array-like.
        shape_tail: the expected shape (single) or trailing shape (batch).
        name: argument name for the error message.
        batch: when True, accept ``(N,) + shape_tail``.

    Raises:
        InputError: not real numbers (ragged nesting, complex, bool, text, None), wrong
            shape, NaN / inf entries, or entries beyond :data:`MAX_MAGNITUDE`.
    """
    arr = real_array(value, name)
    expected = ("N",) + shape_tail if batch else shape_tail
    ok = (arr.ndim == len(shape_tail) + 1 and arr.shape[1:] == shape_tail) if batch \
        else arr.shape == shape_tail
    if not ok:
        raise InputError(name, value, f"expected shape {expected}, got {arr.shape}")
    return within_magnitude(arr, value, name)


def check_batch(dim: int, n_actuators: int, **arrays: npt.ArrayLike | None) -> list[Any]:
    """Validate the arrays of a batch: each (N, dim) (``actuator_forces`` (N, n_actuators)),
    all with the N of the first; ``wrenches`` may be None (passed through).

    Args:
        dim: the pose size.
        n_actuators: the actuator count.
        **arrays: the arrays by name, ``poses`` first.

    Returns:
        The checked float arrays (C-contiguous, owned copies) in the order given.

    Raises:
        InputError: a missing array, bad shapes, NaN / inf, or rows of different lengths.
    """
    out: list[Any] = []
    n = None
    for name, value in arrays.items():
        if value is None and name == "wrenches":
            out.append(None)
            continue
        required(**{name: value})
        arr = as_array(value, (n_actuators if name == "actuator_forces" else dim,), name,
                       batch=True)
        if n is None:
            n = arr.shape[0]
        elif arr.shape[0] != n:
            raise InputError(name, value, f"expected {n} rows like the poses, got "
                             f"{arr.shape[0]}")
        out.append(arr)
    return out


def real_array(value, name: str) -> np.ndarray:
    """``value`` as a C-contiguous float64 array of any shape, its entries not yet checked.

    Raises:
        InputError: ragged nesting, complex, bool, text, bytes or other objects.
    """
    if type(value) is np.ndarray and value.dtype == np.float64 and value.flags.c_contiguous:
        return value                      # what np.ascontiguousarray would return
    try:
        raw = np.asarray(value) if not isinstance(value, np.ndarray) else value
        if raw.dtype.kind in "cbOSUV" and not (raw.dtype.kind == "O" and _all_real(raw)):
            # complex (its imaginary part would be dropped), bool, text, bytes or objects
            raise InputError(name, value, f"expected real numbers, got dtype {raw.dtype}")
        if isinstance(value, (list, tuple)) and _has_bool(value):
            # a bool among numbers (numpy makes it 0.0 or 1.0)
            raise InputError(name, value, "expected real numbers, got a bool among them")
        return np.asarray(raw, dtype=float, order="C")     # (a 0-d array stays 0-d)
    except (TypeError, ValueError, OverflowError) as exc:
        if isinstance(exc, InputError):
            raise
        # ragged nesting, unconvertible objects, integers beyond double precision
        raise InputError(name, value, "not a regular array of real numbers") from None


def within_magnitude(arr: np.ndarray, value, name: str) -> np.ndarray:
    """``arr`` after checking that every entry is finite and at most
    :data:`MAX_MAGNITUDE` in magnitude (one pass when they are).

    Raises:
        InputError: NaN / inf entries, or entries beyond :data:`MAX_MAGNITUDE`.
    """
    if arr.size and not all_within(arr.reshape(-1), MAX_MAGNITUDE):
        bad = np.argwhere(~np.isfinite(arr))
        if bad.size:
            raise InputError(name, value, f"contains NaN or inf at {bad[:5].tolist()}")
        bad = np.argwhere(np.abs(arr) > MAX_MAGNITUDE)
        raise InputError(name, value, f"entries beyond {MAX_MAGNITUDE:g} in magnitude at "
                         f"{bad[:5].tolist()} (products of such numbers overflow double "
                         "precision)")
    return arr


def existing_file(path, what: str = "file", folder: bool = False) -> Path:
    """``path`` as a :class:`~pathlib.Path` after checking that the file exists (or, with
    ``folder``, that a file or a folder does).

    Raises:
        MissingFileError: it does not (naming the path and ``what`` it was to be).
    """
    path = Path(path)
    if not (path.exists() if folder else path.is_file()):
        raise MissingFileError(str(path), what)
    return path


def vector(value, size: int, name: str) -> np.ndarray:
    """A C-contiguous float64 ``(size,)`` array, for the compiled kernels' fast path.

    A float64 array of that shape whose entries are finite and within
    :data:`MAX_MAGNITUDE` is passed through (copied only when not contiguous; one compiled
    scan); anything else goes through :func:`as_array` (real, finite numbers of that shape,
    else :class:`InputError`).
    """
    if type(value) is np.ndarray and value.dtype == np.float64 and value.shape == (size,):
        arr = value if value.flags.c_contiguous else np.ascontiguousarray(value)
        return arr if all_within(arr, MAX_MAGNITUDE) else within_magnitude(arr, value, name)
    return as_array(value, (size,), name)


def vec6(value, name: str) -> np.ndarray:
    """:func:`vector` of size 6 (a pose, twist or wrench in space)."""
    return vector(value, 6, name)


#: the float64 dtype (:func:`vec6_unscanned` compares by identity, falling back on ``==``)
_FLOAT64 = np.dtype(np.float64)


def vec6_unscanned(value, name: str) -> np.ndarray:
    """:func:`vec6` for a caller whose compiled kernel scans the entries itself: a
    C-contiguous float64 (6,) array is passed through as given, unscanned (the kernel
    must refuse an entry beyond :data:`MAX_MAGNITUDE` or NaN / inf, and the caller then
    name it with :func:`as_array`, e.g. ``kernels.tree_state_within``); anything else is
    :func:`vec6` (checked here)."""
    if type(value) is np.ndarray and value.dtype is _FLOAT64 and value.shape == (6,) \
            and value.flags.c_contiguous:
        return value
    return vector(value, 6, name)


def check_signs(branch, home: np.ndarray, name: str = "branch") -> np.ndarray:
    """Validate a branch: ``len(home)`` values, each +1 or -1; ``None`` -> a copy of ``home``.

    Raises:
        InputError: wrong length, or a value other than +1 / -1.
    """
    if branch is None:
        return np.array(home, dtype=float)
    expected = f"expected {len(home)} values, each +1 or -1"
    try:
        arr = np.asarray(branch, dtype=float)
    except (TypeError, ValueError):
        raise InputError(name, branch, expected) from None
    if arr.shape != (len(home),) or not np.all((arr == 1.0) | (arr == -1.0)):
        raise InputError(name, branch, expected)
    return arr
def validate_scalars(obj, positive: tuple[str, ...], non_negative: tuple[str, ...] = (),
                     skip: tuple[str, ...] = (), may_be_inf: tuple[str, ...] = (
                         "max_actuator_force",)) -> None:
    """Coerce a frozen dataclass's scalar fields to float and check their signs.

    Every field but ``skip`` must be a real number (not bool), finite and at most
    :data:`MAX_MAGNITUDE` in magnitude unless in ``may_be_inf`` (any magnitude, ``+inf``
    included, then); ``positive`` ones ``> 0``, ``non_negative`` ones ``>= 0``.

    Raises:
        GeometryError: naming the first offending field and its value.
    """
    for f in dataclasses.fields(obj):
        if f.name in skip:
            continue
        value = getattr(obj, f.name)
        if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
            raise GeometryError(f.name, value, "must be a real number")
        # beyond MAX_MAGNITUDE (an int beyond double precision included): +-inf (NaN kept)
        value = math.copysign(math.inf, value) if abs(value) > MAX_MAGNITUDE else float(value)
        if math.isnan(value) or (math.isinf(value) and f.name not in may_be_inf):
            raise GeometryError(f.name, getattr(obj, f.name), "must be finite and at most "
                                f"{MAX_MAGNITUDE:g} in magnitude")
        object.__setattr__(obj, f.name, value)
    for name in positive:
        if getattr(obj, name) <= 0.0:
            raise GeometryError(name, getattr(obj, name), "must be > 0")
    for name in non_negative:
        if getattr(obj, name) < 0.0:
            raise GeometryError(name, getattr(obj, name), "must be >= 0")



def required(**arrays) -> None:
    """Refuse a required array argument given as None.

    Raises:
        InputError: naming the first argument that is None.
    """
    for name, value in arrays.items():
        if value is None:
            raise InputError(name, value, "required (an array, not None)")


def real_number(value, name: str, *, minimum: float | None = None,
                strict: bool = True) -> float:
    """A finite real scalar option (a gain, a tolerance, a duration) as a float.

    Args:
        value: the option as given.
        name: its argument name, for the error.
        minimum: the lower bound, or None.
        strict: the bound excluded (``value > minimum``) or included.

    Raises:
        InputError: not a real number (None, text, bool, complex), NaN / inf, beyond
            :data:`MAX_MAGNITUDE`, or below the bound.
    """
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise InputError(name, value, "expected a real number")
    try:
        out = float(value)
    except OverflowError:                       # an integer beyond double precision
        out = math.inf
    if not math.isfinite(out):
        raise InputError(name, value, "must be finite")
    if abs(out) > MAX_MAGNITUDE:
        raise InputError(name, value, f"must be at most {MAX_MAGNITUDE:g} in magnitude "
                         "(products of such numbers overflow double precision)")
    if minimum is not None and not (out > minimum if strict else out >= minimum):
        raise InputError(name, value, f"must be {'>' if strict else '>='} {minimum:g}")
    return out


def bounds(value, n: int, name: str) -> np.ndarray:
    """A positive bound (scalar, broadcast) or ``n`` positive bounds as an (n,) array;
    ``inf`` means none.

    Raises:
        InputError: not real numbers (text, bools, complex, ragged), NaN, a bound <= 0, a
            finite bound above :data:`MAX_MAGNITUDE`, or the wrong length.
    """
    expected = f"expected a bound > 0 or {n} bounds > 0 (inf: none)"
    if isinstance(value, (bool, np.bool_, str, bytes)) or value is None:
        raise InputError(name, value, expected)
    try:
        raw = np.asarray(value)
    except (TypeError, ValueError):
        raise InputError(name, value, expected) from None
    if raw.dtype.kind not in "iuf" or (isinstance(value, (list, tuple)) and _has_bool(value)):
        raise InputError(name, value, expected)
    arr = np.full(n, float(raw)) if raw.ndim == 0 else raw.astype(float)
    if arr.shape != (n,) or np.isnan(arr).any() or (arr <= 0).any():
        raise InputError(name, value, expected)
    if (np.isfinite(arr) & (arr > MAX_MAGNITUDE)).any():
        raise InputError(name, value, f"a finite bound above {MAX_MAGNITUDE:g} cannot be "
                         "certified in double precision (inf: none)")
    return arr


def per_actuator(value, n: int, name: str) -> np.ndarray:
    """A scalar (broadcast) or ``n`` real, finite numbers as an (n,) array.

    Raises:
        InputError: as :func:`as_array` (ragged, complex, bool, text, NaN / inf, beyond
            :data:`MAX_MAGNITUDE`), or another shape.
    """
    arr = real_array(value, name)
    if arr.ndim == 0:
        arr = np.full(n, float(arr))
    if arr.shape != (n,):
        raise InputError(name, value, f"expected a number or shape ({n},), got {arr.shape}")
    return within_magnitude(arr, value, name)


def of_type(value, kind: type, name: str):
    """``value`` after checking that it is a ``kind``.

    Raises:
        ArgumentTypeError: anything else, naming ``name``, the value and ``kind``.
    """
    if not isinstance(value, kind):
        raise ArgumentTypeError(name, value, f"expected a {kind.__name__}, got "
                                f"{type(value).__name__}")
    return value


def flag(value, name: str) -> bool:
    """A yes / no option as a bool (``True``, ``False`` or numpy's bools only).

    Raises:
        InputError: anything else (a string such as "no" would be truthy, a number
            ambiguous).
    """
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    raise InputError(name, value, "expected True or False")


def count(value, name: str, minimum: int = 1) -> int:
    """An integer option (an iteration count, a recording period) as an int.

    Raises:
        InputError: not an integer (floats, bool and text refused) or below ``minimum``.
    """
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise InputError(name, value, "expected an integer")
    if value < minimum:
        raise InputError(name, value, f"must be >= {minimum}")
    return int(value)

def generator(seed, name: str = "seed") -> np.random.Generator:
    """A random generator from a seed (an integer >= 0; a ``numpy.random.Generator`` is
    used as it is).

    Raises:
        InputError: anything else (a bool, a float, text, a negative integer).
    """
    if isinstance(seed, np.random.Generator):
        return seed
    return np.random.default_rng(count(seed, name, minimum=0))


def max_abs(x: np.ndarray) -> float:
    """Largest absolute entry of ``x`` (0 for an empty array)."""
    return float(np.max(np.abs(x), initial=0.0))


def owned_copy(checked: np.ndarray, given) -> np.ndarray:
    """``checked`` (an input after :func:`vec6`), copied when it is the caller's own
    array, so that results computed on first access cannot change with it."""
    return checked.copy() if checked is given else checked


def _has_bool(value: list | tuple) -> bool:
    """Whether a (nested) list or tuple holds a bool (Python's or numpy's)."""
    return any(isinstance(x, (bool, np.bool_)) or (isinstance(x, (list, tuple))
                                                   and _has_bool(x)) for x in value)


def _all_real(raw: np.ndarray) -> bool:
    """Whether every element of an object array is a real number (not bool, not complex)."""
    return all(isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, bool)
               for x in raw.ravel())


#: result fields allowed to be +inf (a condition number at a type-I singularity)
_INF_ALLOWED = frozenset({"condition_number"})


def check_finite_result(function: str, value: Any, field: str = "value") -> Any:
    """Return ``value`` after checking that every number in it is finite.

    Walks arrays, floats, tuples, lists, mappings and dataclasses (their public fields;
    parts computed on first access are not forced). ``condition_number`` may be ``+inf``.
    Float64 arrays are scanned by the compiled :func:`~hexapod_pin.core.compiled.all_finite`
    (no temporary array), so that the check costs little next to the call it guards.

    Raises:
        NonFiniteResultError: a NaN anywhere, or an inf outside ``condition_number``
            (naming the function and the field).
    """
    layout = _result_layout(type(value))
    if layout is not None and _result_finite(layout, value):
        return value                    # a result type's fast path: every field finite
    if isinstance(value, np.ndarray):
        if value.dtype == np.float64:
            bad = not all_finite(value.reshape(-1))
        else:
            bad = value.dtype.kind in "fc" and not np.isfinite(value).all()
        if bad and not (field in _INF_ALLOWED and (value > 0).all()):
            raise NonFiniteResultError(function, field)
    elif isinstance(value, float):
        if not math.isfinite(value) and not (field in _INF_ALLOWED and value > 0):
            raise NonFiniteResultError(function, field)
    elif isinstance(value, (tuple, list)):
        names = getattr(value, "_fields", None)
        for k, item in enumerate(value):
            check_finite_result(function, item, names[k] if names else f"{field}[{k}]")
    elif isinstance(value, dict):
        for key, item in value.items():
            check_finite_result(function, item, f"{field}[{key!r}]")
    elif not isinstance(value, (str, int, bool, type(None))):
        fields = _public_fields(type(value))
        if not _fields_finite(function, value, fields):
            _name_nonfinite_field(function, value, fields)
    return value


def _result_finite(layout: tuple[Callable, Callable], value: Any) -> bool:
    """Whether a result of a known layout (:func:`_result_layout`) is finite: its float64
    vectors in one compiled call, its other fields labels or counts. False also when a
    field holds something else (the caller then walks it field by field)."""
    vectors, others = layout[0](value), layout[1](value)
    for item in vectors:
        if type(item) is not np.ndarray or item.dtype is not _FLOAT64 or item.ndim != 1:
            return False
    for item in others:
        if type(item) not in _SCALAR_KINDS:
            return False
    return all_finite4(*vectors)


@functools.cache
def _result_layout(kind: type) -> tuple[Callable, Callable] | None:
    """For a dataclass whose public fields are one to four vectors (annotated
    ``np.ndarray``) and labels or counts (``str``, ``int``): getters of the vectors (padded
    to four with an empty one) and of the others; None for any other type."""
    if not dataclasses.is_dataclass(kind):
        return None
    public = [item for item in dataclasses.fields(kind) if not item.name.startswith("_")]
    vectors = [item.name for item in public if item.type == "np.ndarray"
               and item.name not in _INF_ALLOWED]
    others = [item.name for item in public if item.name not in vectors]
    if not 1 <= len(vectors) <= 4 or any(item.type not in ("str", "int") for item in public
                                         if item.name in others):
        return None
    pad = (_NO_VECTOR,) * (4 - len(vectors))
    get = operator.attrgetter(*vectors)
    vectors_of = (lambda value: (get(value), *pad)) if len(vectors) == 1 else \
        (lambda value: (*get(value), *pad))
    others_of = operator.attrgetter(*others) if len(others) > 1 else \
        (lambda value: (getattr(value, others[0]),)) if others else (lambda value: ())
    return vectors_of, others_of


def _fields_finite(function: str, value: Any, fields: tuple[str, ...]) -> bool:
    """Whether every public field of a result is finite, its float64 vectors scanned four
    to a compiled call (:func:`~hexapod_pin.core.compiled.all_finite4`), a label or a count
    skipped, anything else by :func:`check_finite_result` (False when that raises)."""
    vectors: list[np.ndarray] = []
    for name in fields:
        item = getattr(value, name)
        kind = type(item)
        if kind is np.ndarray and (item.dtype is _FLOAT64 or item.dtype == _FLOAT64) \
                and name not in _INF_ALLOWED and (item.ndim == 1 or item.flags.c_contiguous):
            vectors.append(item if item.ndim == 1 else item.reshape(-1))
            if len(vectors) == 4:
                if not all_finite4(*vectors):
                    return False
                vectors.clear()
        elif kind not in _SCALAR_KINDS:
            try:
                check_finite_result(function, item, name)
            except NonFiniteResultError:
                return False
    if vectors:
        vectors += [_NO_VECTOR] * (4 - len(vectors))
        return all_finite4(*vectors)
    return True


#: pads the vectors of :func:`_fields_finite` to the four of ``all_finite4``
_NO_VECTOR = np.empty(0)


def _name_nonfinite_field(function: str, value: Any, fields: tuple[str, ...]) -> None:
    """Raise the :class:`NonFiniteResultError` of the first field (in order) of a result
    that :func:`_fields_finite` found not finite; return when none is (``condition_number``
    may be ``+inf``)."""
    for name in fields:
        item = getattr(value, name)
        kind = type(item)
        if kind is np.ndarray and item.dtype == np.float64 and item.ndim == 1:
            if not all_finite(item) and not (name in _INF_ALLOWED and (item > 0).all()):
                raise NonFiniteResultError(function, name)
        elif kind not in _SCALAR_KINDS:
            check_finite_result(function, item, name)


#: field types that hold no float to check (inlined by :func:`check_finite_result`)
_SCALAR_KINDS = frozenset({str, int, bool, type(None)})


@functools.lru_cache(maxsize=None)
@functools.cache
def _public_fields(kind: type) -> tuple[str, ...]:
    """The public dataclass fields of a type (empty for a type that is not a dataclass)."""
    if not dataclasses.is_dataclass(kind):
        return ()
    return tuple(item.name for item in dataclasses.fields(kind)
                 if not item.name.startswith("_"))


def solve_checked(solve, *inputs):
    """``solve()``, re-validating the named ``inputs`` (pairs of name and array) when it
    raises SolverError: a NaN / inf input gives InputError naming it (the solves run on
    unchecked arrays and their verification rejects non-finite answers)."""
    try:
        return solve()
    except SolverError:
        for name, value in inputs:
            if value is not None and not all_finite(value):
                as_array(value, value.shape, name)
        raise
