"""TOPP-RA (reachability analysis) for constraints affine in ``(s_ddot, s_dot^2)``, compiled.

The path is discretised at N grid points ``s_0 < ... < s_{N-1}`` (steps ``d_k``); the
unknowns are ``x_k = s_dot^2`` at the grid points and ``u_k = s_ddot``, constant on the
segment ``[s_k, s_{k+1}]``, so that ``x_{k+1} = x_k + 2 d_k u_k``. Every limit is given as
rows ``alpha u + beta x + gamma <= 0`` at each grid point (``rows`` (N, m, 3); a row of
zeros is inert) plus an upper bound ``x <= x_max_k`` (velocity limits; ``inf`` for none).

Discretisation ("interpolation" scheme of Pham & Pham, TOPP-RA, 2018): on segment k the
constant ``u_k`` must satisfy the rows of BOTH ends, those of grid point k at ``x_k`` and
those of grid point k+1 at ``x_{k+1} = x_k + 2 d_k u_k``, so that the limits hold at the
grid points with either neighbouring segment's acceleration and the motion between grid
points deviates from them only by the curvature of the coefficients (second order in
``d_k``).

Backward pass: the controllable sets ``K_k = [lo_k, hi_k]`` (the ``x_k`` from which the
end speed can still be reached), each the projection on ``x`` of a two-variable polygon,
computed exactly by Fourier-Motzkin elimination of ``u`` (every pair of a lower and an
upper bound on ``u``: O(m^2) per grid point, no LP solver). Forward pass: from
``x_0 = start speed^2`` the largest ``u_k`` keeping ``x_{k+1}`` in ``K_{k+1}``.

Kernels never raise: they return a status and the offending grid index.
"""

from __future__ import annotations

import math

import numpy as np

from ..core.compiled import FLAGS, jit, kernel

#: kernel status codes
OK, EMPTY_SET, START_OUTSIDE = 0, 1, 2
#: relative slack accepted when an interval closes by round-off
_SLACK = 1e-9


@jit
def _x_interval(rows, k, d, x_max, lo1, hi1, with_next, al, be, ga):
    """``[x_lo, x_hi]`` of the x at grid point k for which some u satisfies the rows of
    point k, those of point k+1 (``with_next``) and ``lo1 <= x + 2 d u <= hi1``.
    ``al, be, ga`` are scratch arrays of length ``2 m + 2``."""
    m = rows.shape[1]
    n = 0
    for j in range(m):
        al[n], be[n], ga[n] = rows[k, j, 0], rows[k, j, 1], rows[k, j, 2]
        n += 1
    if with_next:
        for j in range(m):
            al[n] = rows[k + 1, j, 0] + 2.0 * d * rows[k + 1, j, 1]
            be[n], ga[n] = rows[k + 1, j, 1], rows[k + 1, j, 2]
            n += 1
        al[n], be[n], ga[n] = -2.0 * d, -1.0, lo1
        n += 1
        al[n], be[n], ga[n] = 2.0 * d, 1.0, -hi1
        n += 1
    x_lo, x_hi = 0.0, x_max
    for i in range(n):
        if al[i] == 0.0:
            if be[i] > 0.0:
                x_hi = min(x_hi, -ga[i] / be[i])
            elif be[i] < 0.0:
                x_lo = max(x_lo, -ga[i] / be[i])
            elif ga[i] > 0.0:
                return math.inf, -math.inf
    for i in range(n):
        if al[i] >= 0.0:
            continue
        for j in range(n):
            if al[j] <= 0.0:
                continue
            # eliminate u: alpha_j * row_i - alpha_i * row_j (positive multipliers)
            c = al[j] * be[i] - al[i] * be[j]
            r = al[i] * ga[j] - al[j] * ga[i]
            if c > 0.0:
                x_hi = min(x_hi, r / c)
            elif c < 0.0:
                x_lo = max(x_lo, r / c)
            elif r < 0.0:
                return math.inf, -math.inf
    return x_lo, x_hi


@kernel(FLAGS, work=0)
def backward_pass(rows: np.ndarray, steps: np.ndarray, x_max: np.ndarray, x_end: float,
                  lo: np.ndarray, hi: np.ndarray) -> tuple[int, int]:
    """Controllable sets ``[lo_k, hi_k]`` (filled), back from ``x_{N-1} = x_end``.

    Returns ``(status, k)``: ``EMPTY_SET`` and the grid index where no speed can still
    reach the end, else ``(OK, -1)``.
    """
    npts, m = rows.shape[0], rows.shape[1]
    al, be, ga = np.empty(2 * m + 2), np.empty(2 * m + 2), np.empty(2 * m + 2)
    last = npts - 1
    if x_end > x_max[last] * (1.0 + _SLACK):
        return EMPTY_SET, last
    lo[last], hi[last] = x_end, x_end
    for k in range(last - 1, -1, -1):
        x_lo, x_hi = _x_interval(rows, k, steps[k], x_max[k], lo[k + 1], hi[k + 1], True,
                                 al, be, ga)
        if x_lo > x_hi:
            if x_lo - x_hi > _SLACK * max(1.0, abs(x_hi)) or not math.isfinite(x_lo):
                return EMPTY_SET, k
            x_lo = x_hi
        lo[k], hi[k] = x_lo, x_hi
    return OK, -1


@kernel(FLAGS, work=0)
def forward_pass(rows: np.ndarray, steps: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                 x_start: float, x: np.ndarray, u: np.ndarray) -> tuple[int, int]:
    """Greedy forward pass: ``x`` (N,) and ``u`` (N-1,) filled, ``x_0 = x_start``.

    Returns ``(status, k)``: ``START_OUTSIDE`` when ``x_start`` is not in ``[lo_0, hi_0]``.
    """
    npts, m = rows.shape[0], rows.shape[1]
    if x_start > hi[0] * (1.0 + _SLACK) + 1e-300 or x_start < lo[0] * (1.0 - _SLACK):
        return START_OUTSIDE, 0
    x[0] = min(max(x_start, lo[0]), hi[0])
    for k in range(npts - 1):
        d = steps[k]
        xk = x[k]
        u_hi = (hi[k + 1] - xk) / (2.0 * d)
        for j in range(m):
            for nxt in range(2):
                a = rows[k + nxt, j, 0]
                b = rows[k + nxt, j, 1]
                if nxt == 1:
                    a += 2.0 * d * b
                if a > 0.0:
                    u_hi = min(u_hi, -(b * xk + rows[k + nxt, j, 2]) / a)
        x1 = min(max(xk + 2.0 * d * u_hi, lo[k + 1]), hi[k + 1])
        x1 = max(x1, 0.0)
        x[k + 1] = x1
        u[k] = (x1 - xk) / (2.0 * d)
    return OK, -1


@kernel(FLAGS, work=0)
def max_velocity_curve(rows: np.ndarray, x_max: np.ndarray, out: np.ndarray) -> None:
    """The largest ``x`` at each grid point for which some ``u`` meets that point's rows
    (``inf`` where nothing bounds it): the maximum-velocity curve (squared)."""
    npts, m = rows.shape[0], rows.shape[1]
    al, be, ga = np.empty(2 * m + 2), np.empty(2 * m + 2), np.empty(2 * m + 2)
    for k in range(npts):
        x_lo, x_hi = _x_interval(rows, k, 1.0, x_max[k], 0.0, 0.0, False, al, be, ga)
        out[k] = x_hi if x_hi >= x_lo else 0.0
