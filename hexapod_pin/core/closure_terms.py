"""The closure terms of the generic core from Pinocchio frame quantities: the rows of the
constraint Jacobian ``J_c`` and the drift ``gamma`` (``J_c a = -gamma``) of point and weld
closures, for any ``pin.Data`` of the tree.

Conventions (those of :mod:`hexapod_pin.core.closed_loop`): a point closure's rows are
the world-axes ``p1 - p2`` of its anchor points, a weld's the ``log6`` of ``M21 = oM2^-1
oM1`` (the twist of anchor 1 relative to anchor 2, anchor-1 axes). Used by
:class:`~hexapod_pin.core.closed_loop.ClosedLoopModel` (on its own data) and by the
dynamics workspaces (on theirs): each formula lives here once.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
import pinocchio as pin


class ClosureFrames(NamedTuple):
    """Where one closure sits in the tree: its type, rows and Pinocchio frame / joint ids
    (the anchor frames ``<closure>/anchor1`` and ``<closure>/anchor2``)."""

    is_point: bool
    rows: slice
    frame1: int
    frame2: int
    joint1: int
    joint2: int


def weld_jacobian(model: pin.Model, data: pin.Data, frame1: int, frame2: int) -> np.ndarray:
    """The six rows of a weld in ``J_c``: ``Jlog6(M21) (J_1 - Ad(M21^-1) J_2)`` (6, nv),
    ``M21 = oM2^-1 oM1`` and ``J_i`` the LOCAL Jacobians of the anchor frames (the
    derivative of ``log6(M21)``). ``data``: joint Jacobians and frame placements up to
    date."""
    loc = pin.ReferenceFrame.LOCAL
    m21 = data.oMf[frame2].actInv(data.oMf[frame1])
    return pin.Jlog6(m21) @ (pin.getFrameJacobian(model, data, frame1, loc)
                             - m21.inverse().action @ pin.getFrameJacobian(model, data, frame2,
                                                                           loc))


def closure_jacobian(model: pin.Model, data: pin.Data,
                     frames: Sequence[ClosureFrames], n_rows: int) -> np.ndarray:
    """``J_c`` (n_rows, nv) from frame Jacobians: point rows ``J_1 - J_2`` of the anchor
    points in world axes (LOCAL_WORLD_ALIGNED), weld rows :func:`weld_jacobian`.
    ``data``: joint Jacobians and frame placements up to date."""
    out = np.empty((n_rows, model.nv))
    lwa = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
    for is_point, rows, f1, f2, _, _ in frames:
        if is_point:
            out[rows] = (pin.getFrameJacobian(model, data, f1, lwa)[:3]
                         - pin.getFrameJacobian(model, data, f2, lwa)[:3])
        else:
            out[rows] = weld_jacobian(model, data, f1, f2)
    return out


def closure_drift(model: pin.Model, data: pin.Data, frames: Sequence[ClosureFrames],
                  n_rows: int) -> np.ndarray:
    """The drift ``gamma`` (n_rows,) with ``J_c a = -gamma`` (see
    :meth:`~hexapod_pin.core.closed_loop.ClosedLoopModel.constraint_drift`). ``data``:
    ``forwardKinematics(q, v, 0)`` and frame placements up to date.

    Point rows: the difference of the classical accelerations of the anchor points at
    zero joint acceleration, world axes (m/s^2). Weld rows: ``Jlog6(M21)`` times the
    relative spatial acceleration bias in anchor-1 axes,
    ``d/dt (v1 - Ad(M12) v2) = a1 - Ad(M12) a2 + v1 x Ad(M12) v2`` (exact at an
    assembled configuration with ``J_c v = 0``).
    """
    out = np.empty(n_rows)
    lwa, loc = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED, pin.ReferenceFrame.LOCAL
    for is_point, rows, f1, f2, _, _ in frames:
        if is_point:
            out[rows] = (pin.getFrameClassicalAcceleration(model, data, f1, lwa).linear
                         - pin.getFrameClassicalAcceleration(model, data, f2, lwa).linear)
        else:
            m21 = data.oMf[f2].actInv(data.oMf[f1])
            a1 = pin.getFrameAcceleration(model, data, f1, loc)
            a2 = pin.getFrameAcceleration(model, data, f2, loc)
            v1 = pin.getFrameVelocity(model, data, f1, loc)
            v2 = pin.getFrameVelocity(model, data, f2, loc)
            rel = a1 - m21.actInv(a2) + v1.cross(m21.actInv(v2))
            out[rows] = pin.Jlog6(m21) @ rel.vector
    return out
