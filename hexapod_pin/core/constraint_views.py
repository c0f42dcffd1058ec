"""Stacked position errors of Pinocchio rigid constraints, read without per-call objects.

After ``RigidConstraintModel.calc``, each constraint data holds the placements of its two
anchors (``oMc1``, ``oMc2``) and the relative placement ``c1Mc2``. Reading them through
the Python properties builds an ``SE3`` and a numpy array per read (about 1.5 us per
closure and per call: more than the ``calc`` itself). The translation arrays that
Pinocchio's bindings return are views of the constraint data's own memory, updated in
place by every later ``calc``: :class:`ConstraintErrors` takes them once and gathers the
errors of all point closures with two or three numpy calls, whatever their number.

That the arrays are live views is a property of the bindings, not a documented contract:
it is checked when a :class:`ConstraintErrors` is made (the gathered errors compared with
fresh property reads at two configurations); where it does not hold, the errors are read
through the properties on every call (same values, slower).

Rows (Pinocchio's conventions for the constraint's reference frame):

* ``"local"``: the LOCAL rows of ``pin.getConstraintsJacobian`` (anchor-1 axes), the
  error of a point closure ``R_1^T (p_1 - p_2) = -c1Mc2.translation`` (m), of a weld
  ``log6(c2Mc1)`` (m, rad): the derivative of these errors along ``pin.integrate`` where
  they vanish is Pinocchio's LOCAL constraint Jacobian;
* ``"world"``: point closures only, ``p_1 - p_2`` in world axes (m), the rows of
  ``LOCAL_WORLD_ALIGNED`` constraints.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import pinocchio as pin

from ..errors import InputError
from .compiled import jit

ROWS = ("local", "world")


class ConstraintErrors:
    """The stacked errors of Pinocchio point / weld constraints after their ``calc``.

    Args:
        model: the Pinocchio model the constraints belong to.
        constraint_models: the constraint models (``CONTACT_3D`` or ``CONTACT_6D``).
        constraint_datas: their datas, in the same order (kept alive by the caller: the
            views read their memory).
        rows: "local" or "world" (see the module docstring; "world" takes point closures
            only).

    Raises:
        InputError: an unknown ``rows``, or a weld with ``rows="world"``.
    """

    def __init__(self, model: pin.Model, constraint_models: Sequence[Any],
                 constraint_datas: Sequence[Any], rows: str = "local") -> None:
        if rows not in ROWS:
            raise InputError("rows", rows, f"expected one of {ROWS}")
        self._cms, self._cds = constraint_models, constraint_datas
        self._points = [cm.type == pin.ContactType.CONTACT_3D for cm in constraint_models]
        if rows == "world" and not all(self._points):
            raise InputError("rows", rows, "world rows take point closures only")
        self._local = rows == "local"
        self.n_rows = sum(3 if p else 6 for p in self._points)
        self._all_points = all(self._points)
        self._views: tuple[np.ndarray, ...] | None = self._live_views(model)

    def _read(self, k: int) -> np.ndarray:
        """The error of constraint ``k`` through the properties (fresh objects)."""
        cd = self._cds[k]
        if not self._points[k]:
            return -pin.log6(cd.c1Mc2).vector        # log6(c2Mc1)
        if self._local:
            return -cd.c1Mc2.translation
        return cd.oMc1.translation - cd.oMc2.translation

    def _live_views(self, model: pin.Model) -> tuple[np.ndarray, ...] | None:
        """Views of the point closures' translations, when they follow later ``calc``
        calls (checked at two configurations against fresh reads), else None."""
        if not self._all_points or not self._points:
            return None
        cds = self._cds
        # local rows: the c1Mc2 translations; world rows: the oMc1 translations, then the
        # oMc2 ones
        views = (tuple(cd.c1Mc2.translation for cd in cds) if self._local
                 else tuple(cd.oMc1.translation for cd in cds)
                 + tuple(cd.oMc2.translation for cd in cds))
        data = model.createData()
        neutral = pin.neutral(model)
        # two configurations (deterministic: Pinocchio's random generator is left alone)
        for q in (neutral, pin.integrate(model, neutral, np.linspace(0.1, 0.3, model.nv))):
            pin.forwardKinematics(model, data, q)
            for cm, cd in zip(self._cms, cds):
                cm.calc(model, data, cd)
            fresh = np.concatenate([self._read(k) for k in range(len(cds))])
            if not np.array_equal(self._gather_views(views, np.empty(self.n_rows)), fresh):
                return None
        return views

    def _gather_views(self, views: tuple[np.ndarray, ...], out: np.ndarray) -> np.ndarray:
        if self._local:
            gather_negated(views, out)
        else:
            half = len(views) // 2
            gather_difference(views[:half], views[half:], out)
        return out

    @property
    def local_views(self) -> tuple[np.ndarray, ...] | None:
        """The live views of the local rows (the c1Mc2 translations, one per point
        closure), for :func:`gather_negated` in a caller's own kernel; None when the rows
        are world rows or the views are not live."""
        return self._views if self._local else None

    @property
    def live(self) -> bool:
        """Whether the errors are gathered from live views (else from property reads)."""
        return self._views is not None

    def gather(self, out: np.ndarray) -> np.ndarray:
        """The stacked errors (n_rows,) into ``out`` (returned), from the constraint datas
        as their last ``calc`` left them (m; rad for the weld rotations)."""
        views = self._views
        if views is not None:
            return self._gather_views(views, out)
        if self.n_rows:
            np.concatenate([self._read(k) for k in range(len(self._cds))], out=out)
        return out


@jit
def gather_negated(views, out):
    """``out = -(v_1, v_2, ...)`` stacked, for a tuple of 1-D arrays ``views``."""
    k = 0
    for view in views:
        for i in range(view.shape[0]):
            out[k] = -view[i]
            k += 1


@jit
def gather_difference(first, second, out):
    """``out = (a_1 - b_1, a_2 - b_2, ...)`` stacked, for tuples of 1-D arrays ``first``
    (the a) and ``second`` (the b) of the same shapes."""
    k = 0
    for j in range(len(first)):
        a, b = first[j], second[j]
        for i in range(a.shape[0]):
            out[k] = a[i] - b[i]
            k += 1
