"""The bounded inverse-dynamics QP on redundantly actuated robots.

``inverse_dynamics_tree(..., method="qp")`` minimises ``1/2 |u|^2 + 1/2 w |lambda|^2``
(``w = 1e-2``) subject to ``S^T u + J_c^T lambda = M a + h`` and ``|u| <= bounds``. On
Solo-12 standing (twelve actuators, four feet held: the actuator forces are not unique)
and on two ladders with three actuated bars for one degree of freedom (point closures;
planar welds, whose rows are redundant), checked against references written here:

* bounds inactive: the weighted minimum-norm solution of the equation by numpy
  (``lstsq`` of the column-scaled matrix), to 1e-9 relative, with no QP iteration;
* bounds that bind (between the smallest feasible bound, found by a linear program, and
  the largest unbounded force): every bound kept, the equation of motion met (residual
  from ``pin.rnea`` and the model's ``J_c``), and an objective no larger than scipy's
  SLSQP solution of the same QP; on the certified active-set route and on the ProxSuite
  route behind it;
* bounds below the smallest feasible one: ActuatorSaturationError.
"""

import numpy as np
import pinocchio as pin
import pytest
import scipy.optimize
import stress_robots

from hexapod_pin.core import inverse_routes
from hexapod_pin.core.dynamics import inverse_dynamics_tree
from hexapod_pin.core.linear_kernels import box_active_set_solve, weighted_minimum_norm_solve
from hexapod_pin.errors import ActuatorSaturationError, InputError
from hexapod_pin.loaders import robots

RTOL = 1e-9
WEIGHT = 1e-2


class Problem:
    """One state and its QP data in our rows: ``A x = rhs``, ``A = [S^T J_c^T]``."""

    def __init__(self, clm, q, v, a):
        self.clm, self.q, self.v, self.a = clm, q, v, a
        sel = np.zeros((clm.nv, clm.n_actuated))
        sel[clm.actuated_v, np.arange(clm.n_actuated)] = 1.0
        self.mat = np.hstack([sel, clm.constraint_jacobian(q).T])
        self.rhs = pin.rnea(clm.model, clm.model.createData(), q, v, a).copy()
        self.n_act = clm.n_actuated
        self.hess = np.concatenate([np.ones(self.n_act), np.full(clm.n_rows, WEIGHT)])

    def weighted_minimum(self):
        root_w = np.sqrt(self.hess)
        y, *_ = np.linalg.lstsq(self.mat / root_w, self.rhs, rcond=None)
        return y / root_w

    def objective(self, x):
        return 0.5 * float(x @ (self.hess * x))

    def eom_residual(self, x):
        """Relative residual of ``A x = rhs`` (max-abs, relative to the largest term)."""
        scale = max(np.max(np.abs(self.rhs)), np.max(np.abs(self.mat * x)))
        return np.max(np.abs(self.mat @ x - self.rhs)) / scale

    def smallest_bound(self):
        """``min t`` s.t. ``A x = rhs``, ``|u_i| <= t`` (scipy linear program)."""
        n, na = self.mat.shape[1], self.n_act
        cost = np.zeros(n + 1)
        cost[-1] = 1.0
        box = np.zeros((2 * na, n + 1))
        box[:na, :na], box[na:, :na] = np.eye(na), -np.eye(na)
        box[:, -1] = -1.0
        fit = scipy.optimize.linprog(cost, A_ub=box, b_ub=np.zeros(2 * na),
                                     A_eq=np.hstack([self.mat, np.zeros((self.mat.shape[0], 1))]),
                                     b_eq=self.rhs, bounds=[(None, None)] * (n + 1))
        assert fit.status == 0, fit.message
        return fit.x[-1]

    def slsqp(self, bound, start):
        """The bounded QP by :func:`slsqp_box` on the scaled problem (forces over their
        scale, equation rows over their norms), from ``start``."""
        scale = max(np.max(np.abs(self.rhs)), np.max(np.abs(start)))
        rows = 1.0 / np.linalg.norm(self.mat, axis=1)
        return scale * slsqp_box(self.hess, self.mat * rows[:, None], self.rhs * rows / scale,
                                 np.full(self.n_act, bound / scale), start / scale)


def slsqp_box(hess, mat, rhs, bounds, start):
    """``min 1/2 x^T diag(hess) x`` s.t. ``mat x = rhs``, ``|x_i| <= bounds_i`` for
    ``i < bounds.size``, by scipy's SLSQP from ``start``."""
    pick = np.eye(mat.shape[1])[:bounds.size]
    fit = scipy.optimize.minimize(
        lambda x: 0.5 * x @ (hess * x), start, jac=lambda x: hess * x, method="SLSQP",
        constraints=[{"type": "eq", "fun": lambda x: mat @ x - rhs, "jac": lambda x: mat},
                     {"type": "ineq", "fun": lambda x: bounds - pick @ x, "jac": lambda x: -pick},
                     {"type": "ineq", "fun": lambda x: bounds + pick @ x, "jac": lambda x: pick}],
        options={"ftol": 1e-14, "maxiter": 1000})
    assert fit.success, fit.message
    return fit.x


def solo_problems(count=3):
    clm = robots.solo12()
    rng = np.random.default_rng(21)
    out = []
    for _ in range(count):
        q = robots.solo12_stand(clm, [0.01, -0.005, 0.20] + 0.01 * rng.normal(size=3),
                                0.05 * rng.normal(size=3)).q
        v, a = robots.motion_with_base(clm, q, 0.3 * rng.normal(size=6), 2.0 * rng.normal(size=6))
        out.append(Problem(clm, q, v, a))
    return out


def ladder_problems(robot, count=3):
    clm = robot.clm
    rng = np.random.default_rng(22)
    out = []
    for _ in range(count):
        q, v = robot.sample(rng)
        # a closure-consistent acceleration: particular + null-space part (numpy SVD)
        jac = clm.constraint_jacobian(q)
        _, sv, vt = np.linalg.svd(jac)
        basis = vt[int(np.sum(sv > 1e-10 * sv[0])):].T
        a = np.linalg.pinv(jac, rcond=1e-10) @ -clm.constraint_drift(q, v) \
            + basis @ rng.normal(size=basis.shape[1])
        out.append(Problem(clm, q, v, a))
    return out


@pytest.fixture(scope="module", params=["solo12", "ladder_redundantly_actuated",
                                        "planar_ladder_weld_redundantly_actuated"])
def problems(request):
    if request.param == "solo12":
        return solo_problems()
    return ladder_problems(getattr(stress_robots, request.param)())


def solve(p, bounds):
    res = inverse_dynamics_tree(p.clm, p.q, p.v, p.a, method="qp", bounds=bounds)
    return res, np.concatenate([res.actuator_forces, res.multipliers])


def assert_close(value, ref, what):
    err = np.max(np.abs(value - ref)) / max(np.max(np.abs(ref)), 1e-300)
    assert err <= RTOL, f"{what}: relative error {err:.3e}"


def test_inactive_bounds_give_the_weighted_minimum_without_iterating(problems):
    for p in problems:
        ref = p.weighted_minimum()
        for bounds in (None, 10.0 * np.max(np.abs(ref[:p.n_act]))):
            res, _ = solve(p, bounds)
            assert_close(res.actuator_forces, ref[:p.n_act], "u")
            assert_close(res.multipliers, ref[p.n_act:], "lambda")
            assert (res.status, res.iterations) == ("solved", 0)


def binding_bounds(p):
    """Bounds between the smallest feasible one and the largest unbounded force."""
    lo = p.smallest_bound()
    hi = np.max(np.abs(p.weighted_minimum()[:p.n_act]))
    assert lo < 0.99 * hi, "the forces are not redundant enough to bind a bound"
    return [lo + frac * (hi - lo) for frac in (0.2, 0.6, 0.95)]


def check_bounded(p, bound):
    res, x = solve(p, bound)
    assert np.all(np.abs(res.actuator_forces) <= bound * (1.0 + RTOL))
    assert np.max(np.abs(res.actuator_forces)) >= bound * (1.0 - 1e-6), "the bound binds"
    assert p.eom_residual(x) <= RTOL
    start = p.weighted_minimum()
    start[:p.n_act] = np.clip(start[:p.n_act], -bound, bound)
    ref = p.slsqp(bound, start)
    f, f_ref = p.objective(x), p.objective(ref)
    assert f <= f_ref + 1e-8 * f_ref, (f, f_ref)
    # strictly convex: one minimiser; SLSQP's is accurate to its own tolerance only
    assert np.max(np.abs(res.actuator_forces - ref[:p.n_act])) <= 1e-5 * bound
    return res


def test_binding_bounds_keep_the_equation_and_the_optimum(problems):
    for p in problems:
        for bound in binding_bounds(p):
            res = check_bounded(p, bound)
            assert res.status == "solved (active set)" and res.iterations >= 1, res.status


def test_binding_bounds_through_proxsuite(problems, monkeypatch):
    """The ProxSuite route behind the active-set search (search switched off)."""
    monkeypatch.setattr(inverse_routes, "_ACTIVE_SET_STEPS", 0)
    for p in problems[:2]:
        for bound in binding_bounds(p)[::2]:
            res = check_bounded(p, bound)
            assert "active set" not in res.status and res.iterations > 0, res.status


@pytest.mark.parametrize("active_set", [True, False])
def test_infeasible_bounds_raise_saturation(problems, monkeypatch, active_set):
    if not active_set:
        monkeypatch.setattr(inverse_routes, "_ACTIVE_SET_STEPS", 0)
    p = problems[0]
    lo = p.smallest_bound()
    with pytest.raises(ActuatorSaturationError) as info:
        solve(p, 0.97 * lo)
    assert np.max(np.abs(info.value.needed)) > 0.97 * lo
    res, x = solve(p, 1.03 * lo)
    assert np.all(np.abs(res.actuator_forces) <= 1.03 * lo * (1.0 + RTOL))
    assert p.eom_residual(x) <= RTOL


def test_non_finite_load_is_an_input_error(problems):
    p = problems[0]
    load = np.zeros(p.clm.nv)
    load[3] = np.nan
    for bounds in (None, 1e-3):
        with pytest.raises(InputError, match="tau_ext"):
            inverse_dynamics_tree(p.clm, p.q, p.v, p.a, tau_ext=load, bounds=bounds,
                                  method="qp")


# ------------------------------------------------------------------- compiled kernels
def test_weighted_minimum_norm_kernel_with_held_entries_and_dependent_rows():
    """Against numpy: held entries fixed, the rest the weighted minimum-norm solution;
    the multiplier ``z`` satisfies ``x_j / inv_w_j^2 = (A^T z)_j`` on the free entries;
    with a repeated row (singular Gram matrix) the SVD fallback, ``z`` NaN."""
    rng = np.random.default_rng(5)
    mat = rng.normal(size=(5, 9))
    rhs = rng.normal(size=5)
    inv_w = rng.uniform(0.5, 3.0, 9)
    held = np.array([True, False, True, False])
    held_u = np.array([0.7, 0.0, -0.2, 0.0])
    for case in ("full rank", "repeated row"):
        if case == "repeated row":
            mat = np.vstack([mat, mat[2]])
            rhs = np.append(rhs, rhs[2])
        free = np.ones(9, dtype=bool)
        free[:4] = ~held
        fixed = np.where(held, held_u, 0.0)
        y, *_ = np.linalg.lstsq(mat[:, free] * inv_w[free], rhs - mat[:, :4] @ fixed,
                                rcond=None)
        ref = np.zeros(9)
        ref[:4][held] = held_u[held]
        ref[free] = y * inv_w[free]
        x, z = np.empty(9), np.empty(mat.shape[0])
        miss = weighted_minimum_norm_solve(mat, rhs, inv_w, held, held_u, x, z, np.empty(2),
                                           RTOL)
        assert miss <= RTOL
        assert_close(x, ref, case)
        if case == "full rank":
            assert_close((x / inv_w**2)[free], (mat.T @ z)[free], "multiplier")
        else:
            assert np.all(np.isnan(z))


def test_active_set_kernel_against_slsqp():
    """Random box-bounded weighted minimum-norm problems against scipy's SLSQP."""
    rng = np.random.default_rng(6)
    for _ in range(5):
        mat = rng.normal(size=(4, 10))
        rhs = rng.normal(size=4)
        inv_w = rng.uniform(0.5, 3.0, 10)
        hess = inv_w**-2
        x0, *_ = np.linalg.lstsq(mat * inv_w, rhs, rcond=None)
        x0 *= inv_w
        bounds = 0.6 * np.max(np.abs(x0[:6])) * np.ones(6)
        x = x0.copy()
        steps = box_active_set_solve(mat, rhs, inv_w, bounds, x, np.empty(4), np.empty(2),
                                     RTOL, 20)
        start = x0.copy()
        start[:6] = np.clip(x0[:6], -bounds, bounds)
        ref = slsqp_box(hess, mat, rhs, bounds, start)
        assert steps >= 1
        assert np.all(np.abs(x[:6]) <= bounds * (1 + RTOL))
        assert np.max(np.abs(mat @ x - rhs)) <= RTOL * np.max(np.abs(rhs))
        assert 0.5 * x @ (hess * x) <= 0.5 * ref @ (hess * ref) * (1 + 1e-8)
        np.testing.assert_allclose(x, ref, atol=1e-6 * np.max(np.abs(x)))
