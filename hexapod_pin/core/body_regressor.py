"""The Newton-Euler wrench of one rigid body, linear in its ten inertial parameters (the
body regressor), as a compiled helper for the closed forms' dynamic regressors.

Parameters: Pinocchio's convention (``pin.Inertia.toDynamicParameters``), in the body
frame about the body origin::

    pi = (m, m c_x, m c_y, m c_z, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz)

The wrench ``(f, n)`` (body axes, moment about the body origin) that the body needs for
its motion under gravity, with ``w``, ``dw`` its angular velocity and acceleration and
``acc`` the classical acceleration of its origin minus gravity (``acc = p'' - g``), all in
body axes, and ``h = m c``::

    f = m acc + dw x h + w x (w x h)
    n = I dw + w x (I w) + h x acc

is ``[f; n] = Y_b(w, dw, acc) pi`` with ``Y_b`` (6, 10). It equals
``pin.bodyRegressor(v, a)`` for the spatial velocity ``v = (v_o, w)`` and the spatial
acceleration ``a = (acc - w x v_o, dw)`` (Pinocchio's ``a`` holds ``p'' - w x v_o``: the
terms in ``v_o`` cancel, so the origin's velocity is not needed). Derivation: docs,
derivations page, "the dynamic regressor from the closed form".
"""

from __future__ import annotations

from .compiled import jit_inline


@jit_inline
def body_regressor(wx, wy, wz, dwx, dwy, dwz, ax, ay, az, out):
    """``Y_b`` (6, 10) into ``out`` (module docstring): rows ``(f, n)`` in body axes,
    columns Pinocchio's ten parameters; ``w`` (rad/s), ``dw`` (rad/s^2), ``acc`` (m/s^2,
    gravity subtracted) in body axes."""
    for r in range(6):
        for c in range(10):
            out[r, c] = 0.0
    # f: the mass column, then dw x h + w x (w x h) = ([dw]x + w w^T - |w|^2 I) h
    out[0, 0], out[1, 0], out[2, 0] = ax, ay, az
    w2 = wx * wx + wy * wy + wz * wz
    out[0, 1], out[0, 2], out[0, 3] = wx * wx - w2, wx * wy - dwz, wx * wz + dwy
    out[1, 1], out[1, 2], out[1, 3] = wy * wx + dwz, wy * wy - w2, wy * wz - dwx
    out[2, 1], out[2, 2], out[2, 3] = wz * wx - dwy, wz * wy + dwx, wz * wz - w2
    # n: h x acc = -[acc]x h
    out[3, 2], out[3, 3] = az, -ay
    out[4, 1], out[4, 3] = -az, ax
    out[5, 1], out[5, 2] = ay, -ax
    # n: I dw + w x (I w), I w = L(w) (I_xx, I_xy, I_yy, I_xz, I_yz, I_zz)
    out[3, 4], out[3, 5], out[3, 7] = dwx, dwy, dwz
    out[4, 5], out[4, 6], out[4, 8] = dwx, dwy, dwz
    out[5, 7], out[5, 8], out[5, 9] = dwx, dwy, dwz
    # w x L(w): the rows of L(w) are (wx, wy, 0, wz, 0, 0), (0, wx, wy, 0, wz, 0),
    # (0, 0, 0, wx, wy, wz); (w x L)_0 = wy L_2 - wz L_1, (w x L)_1 = wz L_0 - wx L_2,
    # (w x L)_2 = wx L_1 - wy L_0
    out[3, 5] -= wz * wx
    out[3, 6] -= wz * wy
    out[3, 7] += wy * wx
    out[3, 8] += wy * wy - wz * wz
    out[3, 9] += wy * wz
    out[4, 4] += wz * wx
    out[4, 5] += wz * wy
    out[4, 7] += wz * wz - wx * wx
    out[4, 8] -= wx * wy
    out[4, 9] -= wx * wz
    out[5, 4] -= wy * wx
    out[5, 5] += wx * wx - wy * wy
    out[5, 6] += wx * wy
    out[5, 7] -= wy * wz
    out[5, 8] += wx * wz
