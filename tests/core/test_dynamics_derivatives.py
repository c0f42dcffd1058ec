"""Analytic forward-dynamics derivatives (hexapod_pin.core.dynamics_derivatives and
hexapod_pin.core.platform_derivatives) against finite differences.

Independent route: Richardson-extrapolated central differences (steps h, h/2, h/4, two
extrapolations, the finer one kept) of the library's verified forward dynamics
("kkt" route on the tree, the robots' default "nullspace" route at platform level),
moving along the closure manifold: ``q(s) = assemble(integrate(q, s dq))`` with the
actuators held, ``v(s)`` the orthogonal projection of ``v`` on ``null(J_c(q(s)))``; platform poses moved by
``(dp, exp(dtheta) R)`` in world axes. Robots: the hexapod (home and the other branch, an
as-built geometry), the planar 3-PRR, the Stewart platform, the delta (welds), the
four-bar and five-bar (redundant point rows), Cassie (tree level, its SDF damping and
springs); every one rigid and with damping, springs (relaxed away from the state),
armature and sliding Coulomb friction. Tolerance 1e-7 relative.

Pinocchio's ``computeConstraintDynamicsDerivatives``: right on the hexapod, the planar
robot and the delta, wrong (``d ddq / dq`` along the closures) on the four-bar, the
five-bar and the Stewart platform (point loops between two moving bodies whose branches
start with a revolute joint): ``test_pinocchio_constraint_derivatives_*``.

Also here: the batch of forward-dynamics derivatives against the single-state answers,
``d(J_c^T y)/dq`` (the projection's second-order term of the step Jacobians) against
central differences, and the inverse-dynamics derivatives from the core (the
implicit-function theorem on the forward ones) against central differences of the loaded
robots' inverse dynamics and against the hexapod's and planar robot's closed-form
derivations.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin
import pytest
import robot_registry

import hexapod_pin as hp
from hexapod_pin.calibration import random_as_built
from hexapod_pin.core import derivative_kernels as dk
from hexapod_pin.core.derivative_kernels import reduced_gain_kernel
from hexapod_pin.core.dynamics import forward_dynamics_tree
from hexapod_pin.core.dynamics_derivatives import (
    closure_force_derivative,
    forward_dynamics_derivatives_tree,
    frame_rates,
    linearize_tree,
    spring_jacobian,
)
from hexapod_pin.core.effects import passive_forces
from hexapod_pin.core.pose import rotation_from_rpy, rpy_from_rotation
from hexapod_pin.errors import InputError, SingularityError
from hexapod_pin.hexapod.kinematics import HOME_BRANCH
from hexapod_pin.loaders import robots as loaded

RTOL = 1e-7
ROBOTS = ("hexapod", "planar", "stewart", "delta", "four-bar", "five-bar")


def richardson(fun, h):
    """``d fun / ds`` at 0: central differences at h, h/2, h/4, extrapolated twice."""
    diffs = [(fun(s) - fun(-s)) / (2 * s) for s in (h, h / 2, h / 4)]
    return (4 * diffs[2] - diffs[1]) / 3


def relative(num, ana):
    return float(np.max(np.abs(num - ana)) / max(1.0, np.max(np.abs(num))))


def with_effects(clm, q, v, rng):
    """The model with damping, springs (relaxed at a random configuration), armature and
    Coulomb friction on the coordinates that slide fast enough to stay sliding."""
    nv = clm.nv
    coulomb = np.where(np.abs(v) > 0.05, rng.uniform(0.1, 0.3, nv), 0.0)
    return clm.with_effects(damping=rng.uniform(0.1, 0.5, nv), stiffness=rng.uniform(1, 5, nv),
                            spring_reference=pin.integrate(clm.model, q,
                                                           rng.uniform(-0.5, 0.5, nv)),
                            armature=rng.uniform(0.01, 0.05, nv), coulomb=coulomb)


def project(clm, q, v):
    """The orthogonal projection of ``v`` on ``null(J_c(q))`` (numpy SVD, rank to 1e-10
    relative; written here: the library's Euclidean projection is not the orthogonal one
    where rows are nearly dependent, e.g. Cassie's right plantar loop)."""
    jac = clm.constraint_jacobian(q)
    _, sv, vt = np.linalg.svd(jac)
    null = vt[int(np.sum(sv > 1e-10 * sv[0])):]
    return null.T @ (null @ v)


def tree_state(clm, q, seed):
    rng = np.random.default_rng(seed)
    v = project(clm, q, rng.normal(size=clm.nv))
    return rng, v, rng.normal(size=clm.n_actuated), 0.1 * rng.normal(size=clm.nv)


def check_tree(clm, q, v, u, tau, rng):
    """Every derivative of forward_dynamics_derivatives_tree against finite differences."""
    der = forward_dynamics_derivatives_tree(clm, q, v, u, tau)

    def solve(qq, vv, uu=u, tt=tau):
        res = forward_dynamics_tree(clm, qq, vv, uu, tt, method="kkt")
        return np.concatenate([res.a, res.multipliers])

    def along(direction):
        def moved(s):
            qq = clm.assemble(pin.integrate(clm.model, q, s * direction), tol=1e-14).q
            return solve(qq, project(clm, qq, v))
        return moved

    worst = 0.0
    for k in range(der.tangent_basis.shape[1]):
        num = richardson(along(der.tangent_basis[:, k]), 1e-3)
        worst = max(worst, relative(num, np.concatenate([der.d_q[:, k],
                                                         der.multipliers_d_q[:, k]])))
    for _ in range(2):     # random directions, each testing every column at once
        dv = rng.normal(size=clm.nv)
        num = richardson(lambda s: solve(q, project(clm, q, v + s * dv)), 1e-3)
        worst = max(worst, relative(num, np.concatenate([der.d_v @ dv,
                                                         der.multipliers_d_v @ dv])))
        dt = rng.normal(size=clm.nv)
        num = richardson(lambda s: solve(q, v, u, tau + s * dt), 1.0)
        worst = max(worst, relative(num, np.concatenate([der.d_tau_ext @ dt,
                                                         der.multipliers_d_tau_ext @ dt])))
    for k in range(clm.n_actuated):
        du = np.eye(clm.n_actuated)[k]
        num = richardson(lambda s: solve(q, v, u + s * du), 1.0)
        worst = max(worst, relative(num, np.concatenate(
            [der.d_actuator_forces[:, k], der.multipliers_d_actuator_forces[:, k]])))
    return worst, der


@pytest.mark.parametrize("effects", [False, True], ids=["rigid", "effects"])
@pytest.mark.parametrize("name", ROBOTS)
def test_tree_derivatives_match_finite_differences(name, effects):
    robot = robot_registry.get(name)
    clm, q = robot.model, robot.home_configuration
    rng, v, u, tau = tree_state(clm, q, 3)
    if effects:
        clm = with_effects(clm, q, v, rng)
    worst, der = check_tree(clm, q, v, u, tau, rng)
    assert worst < RTOL
    # the basis is orthonormal and spans null(J_c)
    basis = der.tangent_basis
    np.testing.assert_allclose(basis.T @ basis, np.eye(basis.shape[1]), atol=1e-12)
    assert np.max(np.abs(clm.constraint_jacobian(q) @ basis)) < 1e-10
    assert basis.shape[1] == clm.mobility(q)


def test_tree_derivatives_cassie():
    """Cassie hanging from its pelvis: 22 coordinates, four rod loops (one redundant row
    per leg, ~1e-12 on the right leg), its SDF damping and springs."""
    cassie = loaded.cassie()
    rng = np.random.default_rng(7)
    dq = np.zeros(cassie.nv)
    dq[cassie.actuated_v] = 0.1 * rng.normal(size=cassie.n_actuated)
    q = cassie.assemble(pin.integrate(cassie.model, pin.neutral(cassie.model), dq)).q
    _, v, u, tau = tree_state(cassie, q, 8)
    assert cassie.effects.stiffness.any() and cassie.effects.damping.any()
    worst, _ = check_tree(cassie, q, v, u, tau, rng)
    assert worst < RTOL


def pinocchio_frame_motion(model, data, q, v, a, frame, world):
    """(acc, vel) (6,) of ``frame`` from Pinocchio's own frame motion at ``(q, v, a)``:
    world rows the classical acceleration and velocity in LOCAL_WORLD_ALIGNED axes, LOCAL
    rows the spatial ones."""
    pin.forwardKinematics(model, data, q, v, a)
    ref = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED if world else pin.ReferenceFrame.LOCAL
    vel = pin.getFrameVelocity(model, data, frame, ref).vector
    if world:
        acc = pin.getFrameClassicalAcceleration(model, data, frame, ref).vector
    else:
        acc = pin.getFrameAcceleration(model, data, frame, ref).vector
    return np.concatenate([acc, vel])


@pytest.mark.parametrize("name", ROBOTS + ("cassie",))
def test_frame_rates_match_finite_differences_of_pinocchio(name):
    """frame_rates (all frames in one compiled call) against Richardson central
    differences of Pinocchio's frame velocity and (classical or spatial) acceleration, in
    q (along pin.integrate), v and a, on random frames, states and row kinds (world /
    LOCAL); off the closures (frame_rates knows none)."""
    clm = loaded.cassie() if name == "cassie" else robot_registry.get(name).model
    model = clm.model
    data = model.createData()
    rng = np.random.default_rng(11)
    q = pin.integrate(model, pin.neutral(model), 0.3 * rng.normal(size=model.nv))
    v, a = rng.normal(size=model.nv), rng.normal(size=model.nv)
    frames = [int(f) for f in rng.choice(np.arange(1, model.nframes), 6, replace=False)]
    world = rng.random(len(frames)) < 0.5
    world[:2] = [True, False]
    pin.computeForwardKinematicsDerivatives(model, data, q, v, a)
    pin.updateFramePlacements(model, data)
    rates = frame_rates(model, data, frames, v, a, world)
    ref_data = model.createData()
    worst = 0.0
    for k, (frame, w) in enumerate(zip(frames, world)):
        def motion(qq, vv, aa, frame=frame, w=w):
            return pinocchio_frame_motion(model, ref_data, qq, vv, aa, frame, w)
        base = motion(q, v, a)
        worst = max(worst, relative(base, np.concatenate([rates.acc[k], rates.vel[k]])))
        np.testing.assert_allclose(rates.rot[k], pin.updateFramePlacement(
            model, ref_data, frame).rotation, atol=1e-12)
        for c in range(model.nv):
            e = np.eye(model.nv)[c]
            num_q = richardson(lambda s, e=e: motion(pin.integrate(model, q, s * e), v, a),
                               1e-3)
            num_v = richardson(lambda s, e=e: motion(q, v + s * e, a), 1e-3)
            num_a = richardson(lambda s, e=e: motion(q, v, a + s * e), 1e-3)
            worst = max(worst,
                        relative(num_q, np.concatenate([rates.acc_q[k][:, c],
                                                        rates.vel_q[k][:, c]])),
                        relative(num_v[:6], rates.acc_v[k][:, c]),
                        relative(num_v[6:], rates.jac[k][:, c]),
                        relative(num_a[:6], rates.jac[k][:, c]))
    assert worst < RTOL


def test_reduced_gain_against_numpy_and_its_refusal():
    """G = N L^-T of the compiled Cholesky: G G^T = N (N^T M N)^-1 N^T against numpy's
    inverse; a mass matrix without mass on a null-space direction is refused (status 1),
    and KKTLinearization turns that into a SingularityError."""
    rng = np.random.default_rng(5)
    nv, m = 7, 4
    basis = np.linalg.qr(rng.normal(size=(nv, nv)))[0][:, :m].copy()
    root = rng.normal(size=(nv, nv))
    mass = root @ root.T + 0.1 * np.eye(nv)
    gain = np.empty((nv, m))
    assert reduced_gain_kernel(basis, mass, gain) == 0
    expected = basis @ np.linalg.inv(basis.T @ mass @ basis) @ basis.T
    np.testing.assert_allclose(gain @ gain.T, expected, rtol=0, atol=1e-12)
    massless = mass - (mass @ basis[:, 0])[:, None] * basis[:, 0][None, :] \
        - basis[:, 0][:, None] * (basis[:, 0] @ mass)[None, :] \
        + (basis[:, 0] @ mass @ basis[:, 0]) * np.outer(basis[:, 0], basis[:, 0])
    assert abs(basis[:, 0] @ massless @ basis[:, 0]) < 1e-12
    assert reduced_gain_kernel(basis, massless, gain) == 1
    assert reduced_gain_kernel(basis, np.full((nv, nv), np.nan), gain) == 1

@pytest.mark.parametrize("name", ["four-bar", "hexapod"])
def test_a_massless_null_space_is_refused(name, monkeypatch):
    """KKTLinearization turns a refused Cholesky into a SingularityError, on the SVD route
    of redundant rows (four-bar) and the compiled QR route (hexapod): Pinocchio's mass
    matrix replaced by zeros."""
    robot = robot_registry.get(name)
    clm, q = robot.model, robot.home_configuration
    rnea_derivatives = pin.computeRNEADerivatives

    def massless(*args):
        dq, dv, mass = rnea_derivatives(*args)
        return dq, dv, np.zeros_like(mass)
    monkeypatch.setattr(pin, "computeRNEADerivatives", massless)
    with pytest.raises(SingularityError, match="null space"):
        linearize_tree(clm, q, np.zeros(clm.nv), np.zeros(clm.n_actuated))


def test_compiled_linearisation_kernels_against_numpy():
    """The compiled pieces of KKTLinearization against numpy written here: the point
    forces' turning (einsum), the closure rows and anchor forces (fancy indexing), the
    factors of linearize_kernel (J N = 0, N^T N = I, J J^+ = I, G G^T = N (N^T M N)^-1
    N^T) and its statuses (dependent rows, NaN, no mass), and the verified solve against a
    dense KKT solve (numpy lstsq) with its residuals."""
    rng = np.random.default_rng(3)
    nv, n_pts = 9, 2
    anchor_jac = rng.normal(size=(2 * n_pts, 6, nv))
    forces = rng.normal(size=3 * n_pts + 2)
    point_rows = np.array([0, 1, 2, 5, 6, 7])
    point_anchors = np.arange(2 * n_pts)
    out = np.zeros((nv, nv))
    dk.point_turning_kernel(anchor_jac, forces, point_rows, point_anchors, out)
    lam = forces[point_rows].reshape(n_pts, 3)
    expected = np.zeros((nv, nv))
    for k in range(n_pts):
        for anchor, sign in ((2 * k, 1.0), (2 * k + 1, -1.0)):
            turned = np.cross(lam[k][:, None], anchor_jac[anchor, 3:], axis=0)
            expected -= sign * anchor_jac[anchor, :3].T @ turned
    np.testing.assert_allclose(out, expected, rtol=0, atol=1e-13)
    rows1, rows2 = np.array([0, 1, 2, 15]), np.array([6, 7, 8, 21])
    fields = [rng.normal(size=(2 * n_pts, 6, nv)) for _ in range(4)]
    for got, field in zip(dk.closure_rows_kernel(*fields, rows1, rows2), fields):
        flat = field.reshape(-1, nv)
        np.testing.assert_array_equal(got, flat[rows1] - flat[rows2])
    rot = np.array([np.linalg.qr(rng.normal(size=(3, 3)))[0] for _ in range(2 * n_pts)])
    to_joints = rng.normal(size=(12, 6 * 2 * n_pts))
    local = np.zeros((2 * n_pts, 6))
    local[:, 3:] = rng.normal(size=(2 * n_pts, 3))
    want = local.copy()
    for k in range(n_pts):
        want[2 * k, :3], want[2 * k + 1, :3] = rot[2 * k].T @ lam[k], -rot[2 * k + 1].T @ lam[k]
    got = dk.anchor_forces_kernel(rot, forces, point_rows, point_anchors, local, to_joints)
    np.testing.assert_allclose(got, (to_joints @ want.reshape(-1)).reshape(-1, 6), atol=1e-13)

    n_rows = 5
    jac = rng.normal(size=(n_rows, nv))
    root = rng.normal(size=(nv, nv))
    mass_full = root @ root.T + np.eye(nv)
    mass_up = np.triu(mass_full) + np.tril(rng.normal(size=(nv, nv)), -1)   # junk below
    dtau_dq, dtau_dv, damping = rng.normal(size=(nv, nv)), rng.normal(size=(nv, nv)), \
        rng.uniform(size=nv)
    mass, e_q, e_v = np.empty((nv, nv)), np.empty((nv, nv)), np.empty((nv, nv))

    def linearize(jac_c, mass_in=mass_up):
        return dk.linearize_kernel(mass_in, dtau_dq, dtau_dv, anchor_jac, forces, point_rows,
                                   point_anchors, damping, jac_c, 1e-8, mass, e_q, e_v)
    status, basis, pinv, gain, norm_m, norm_j = linearize(jac)
    assert status == dk.LINEARIZED
    np.testing.assert_array_equal(mass, mass_full)
    np.testing.assert_allclose(e_q, dtau_dq + expected, atol=1e-13)
    np.testing.assert_array_equal(e_v, dtau_dv + np.diag(damping))
    assert basis.shape == (nv, nv - n_rows)
    np.testing.assert_allclose(jac @ basis, 0.0, atol=1e-13)
    np.testing.assert_allclose(basis.T @ basis, np.eye(nv - n_rows), atol=1e-13)
    np.testing.assert_allclose(jac @ pinv, np.eye(n_rows), atol=1e-12)
    np.testing.assert_allclose(gain @ gain.T, basis @ np.linalg.inv(basis.T @ mass_full @ basis)
                               @ basis.T, atol=1e-12)
    assert (norm_m, norm_j) == (np.max(np.abs(mass_full)), np.max(np.abs(jac)))
    assert linearize(np.vstack([jac, jac[:1]]))[0] == dk.DEPENDENT_ROWS
    assert linearize(np.full((n_rows, nv), np.nan))[0] == dk.NOT_FINITE
    assert linearize(np.zeros((0, nv)))[0] == dk.DEPENDENT_ROWS
    assert linearize(jac, np.zeros((nv, nv)))[0] == dk.NOT_POSITIVE

    rhs_e, rhs_c = rng.normal(size=(nv, 3)), jac @ rng.normal(size=(nv, 3))
    da, dlam, eom, con = dk.kkt_solve_kernel(mass_full, jac, pinv, gain, norm_m, norm_j,
                                             rhs_e, rhs_c)
    kkt = np.block([[mass_full, -jac.T], [jac, np.zeros((n_rows, n_rows))]])
    dense = np.linalg.lstsq(kkt, np.vstack([rhs_e, rhs_c]), rcond=None)[0]
    np.testing.assert_allclose(da, dense[:nv], atol=1e-10)
    np.testing.assert_allclose(dlam, dense[nv:], atol=1e-10)
    assert eom < 1e-13 and con < 1e-13
    off = dk.kkt_solve_kernel(mass_full, jac, pinv, gain, norm_m, norm_j, rhs_e,
                              rhs_c + 1.0)                  # still solvable: rows independent
    assert off[3] < 1e-13
    bad = dk.kkt_solve_kernel(mass_full, jac, pinv, gain, norm_m, norm_j, rhs_e * np.nan,
                              rhs_c)
    assert np.isnan(bad[2])
    dq, dv, force = (rng.normal(size=(nv, 2)) for _ in range(3))
    along = dk.kkt_along_kernel(e_q, e_v, jac, 2 * jac, mass_full, jac, pinv, gain, norm_m,
                                norm_j, dq, dv, force)
    direct = dk.kkt_solve_kernel(mass_full, jac, pinv, gain, norm_m, norm_j,
                                 force - e_q @ dq - e_v @ dv, -(jac @ dq + 2 * jac @ dv))
    for x, y in zip(along[:2], direct[:2]):
        np.testing.assert_allclose(x, y, atol=1e-12)


def test_given_basis_and_its_check():
    robot = robot_registry.get("stewart")
    clm, q = robot.model, robot.home_configuration
    _, v, u, tau = tree_state(clm, q, 1)
    full = forward_dynamics_derivatives_tree(clm, q, v, u, tau)
    mix = full.tangent_basis @ np.random.default_rng(0).normal(size=(6, 2))
    part = forward_dynamics_derivatives_tree(clm, q, v, u, tau, basis=mix)
    np.testing.assert_allclose(part.d_q, full.d_q @ np.linalg.lstsq(full.tangent_basis, mix,
                                                                   rcond=None)[0], atol=1e-9)
    with pytest.raises(InputError, match="null"):
        forward_dynamics_derivatives_tree(clm, q, v, u, tau, basis=np.eye(clm.nv)[:, :2])
    with pytest.raises(InputError):
        forward_dynamics_derivatives_tree(clm, q, v, u, tau, basis=np.ones(clm.nv))


def test_coulomb_friction_at_rest_is_refused():
    robot = robot_registry.get("four-bar")
    clm = robot.model.with_effects(coulomb=np.full(robot.model.nv, 0.2))
    with pytest.raises(InputError, match="at rest"):
        forward_dynamics_derivatives_tree(clm, robot.home_configuration, np.zeros(clm.nv),
                                          np.zeros(1))


def test_bad_input_is_refused():
    robot = robot_registry.get("four-bar")
    clm, q = robot.model, robot.home_configuration
    with pytest.raises(InputError):
        forward_dynamics_derivatives_tree(clm, q[:2], np.zeros(3), np.zeros(1))
    with pytest.raises(InputError):
        forward_dynamics_derivatives_tree(clm, q, np.full(3, np.nan), np.zeros(1))
    with pytest.raises(InputError):       # a velocity that breaks the closure
        forward_dynamics_derivatives_tree(clm, q, np.array([1.0, 0.0, 0.0]), np.zeros(1))
    with pytest.raises(InputError):
        linearize_tree(clm, q, np.zeros(3), np.zeros(1), frames=[10_000])


def test_spring_jacobian_on_a_free_joint():
    """The springs' force on a free-flyer is the energy gradient ``-D^T K dq``: its
    curvature block against central differences of passive_forces (steps 1e-6)."""
    robot = robot_registry.get("stewart")
    clm = robot.model
    q = robot.home_configuration
    eff = clm.with_effects(stiffness=np.linspace(1, 3, clm.nv), spring_reference=pin.integrate(
        clm.model, q, np.linspace(-0.4, 0.5, clm.nv))).effects
    zero = np.zeros(clm.nv)
    num = np.array([(passive_forces(clm.model, eff, pin.integrate(clm.model, q, 1e-6 * e), zero)
                     - passive_forces(clm.model, eff, pin.integrate(clm.model, q, -1e-6 * e),
                                      zero)) / 2e-6 for e in np.eye(clm.nv)]).T
    np.testing.assert_allclose(spring_jacobian(clm.model, eff, q), num, atol=1e-7)


@pytest.mark.parametrize("name", ["stewart", "four-bar", "hexapod"])
def test_closure_force_derivative_matches_finite_differences(name):
    """``d(J_c^T y)/dq`` (point closures, forces held in world axes) against central
    differences of ``constraint_jacobian(q)^T y`` along ``pin.integrate`` in random
    directions, on and off the closures (steps 1e-3)."""
    robot = robot_registry.get(name)
    clm = robot.model
    rng = np.random.default_rng(5)
    y = rng.normal(size=clm.n_rows)
    for q in (robot.home_configuration,
              pin.integrate(clm.model, robot.home_configuration, 0.05 * rng.normal(size=clm.nv))):
        got = closure_force_derivative(clm, clm.model.createData(), q, y)
        dq = rng.normal(size=clm.nv)
        num = richardson(lambda s: clm.constraint_jacobian(
            pin.integrate(clm.model, q, s * dq)).T @ y, 1e-3)
        assert relative(num, got @ dq) < RTOL


@pytest.mark.parametrize("name", ["delta", "stewart", "hexapod"])
def test_kkt_partials_off_the_closures(name):
    """The KKT linearisation at a state off the closures (an RK4 stage state of the step
    Jacobians), in every direction: ``da`` against central differences of the library's
    unchecked "kkt" forward dynamics (steps 1e-3); the welds' rows and forces are exact
    there too (``J_rel``, ``-Ad(M12)^T mu``), not only along the closures."""
    from hexapod_pin.core.dynamics import dynamics_of
    from hexapod_pin.core.dynamics_derivatives import KKTLinearization

    robot = robot_registry.get(name)
    clm = robot.model
    rng = np.random.default_rng(3)
    q = pin.integrate(clm.model, robot.home_configuration, 1e-3 * rng.normal(size=clm.nv))
    v = rng.normal(size=clm.nv)
    tau = np.zeros(clm.nv)
    tau[clm.actuated_v] = rng.normal(size=clm.n_actuated)
    dyn = dynamics_of(clm)

    def acc(qq, vv):
        return np.array(dyn.forward_unchecked(qq, vv, tau, "kkt").a)

    res = dyn.forward_unchecked(q, v, tau, "kkt")
    lin = KKTLinearization(clm, clm.model.createData(), q, v, np.array(res.a),
                           np.array(res.multipliers), ())
    dq, dv = rng.normal(size=(clm.nv, 1)), rng.normal(size=(clm.nv, 1))
    got, _ = lin.solve(-(lin.e_q @ dq + lin.e_v @ dv), -(lin.c_q @ dq + lin.c_v @ dv))
    num = richardson(lambda s: acc(pin.integrate(clm.model, q, s * dq[:, 0]), v + s * dv[:, 0]),
                     1e-3)
    assert relative(num, got[:, 0]) < RTOL


# -- Pinocchio's computeConstraintDynamicsDerivatives ---------------------------------------
def pinocchio_along(clm, q, v, u):
    """Pinocchio's ``d ddq`` along our tangent directions: ``ddq_dq N + ddq_dv dv``."""
    lin = linearize_tree(clm, q, v, u)
    cms, cds = clm.pinocchio_constraints()
    data = clm.model.createData()
    pin.initConstraintDynamics(clm.model, data, cms, cds)
    tau = np.zeros(clm.nv)
    tau[clm.actuated_v] = u
    prox = pin.ProximalSettings(1e-12, 1e-10 if lin.rank < clm.n_rows else 0.0, 100)
    pin.constraintDynamics(clm.model, data, q, v, tau, cms, cds, prox)
    pin.computeConstraintDynamicsDerivatives(clm.model, data, cms, cds, prox)
    basis = lin.basis
    return (data.ddq_dq @ basis + data.ddq_dv @ lin.transport(basis), data.ddq_dv @ basis,
            data.ddq_dtau[:, clm.actuated_v], basis)


@pytest.mark.parametrize("name", ["hexapod", "planar", "delta"])
def test_pinocchio_constraint_derivatives_right_here(name):
    """Rail-rooted legs (prismatic first), the planar 3-PRR, the delta's welds: Pinocchio
    agrees with ours (which finite differences check above)."""
    robot = robot_registry.get(name)
    clm, q = robot.model, robot.home_configuration
    _, v, u, _ = tree_state(clm, q, 1)
    d_q, d_v, d_u, basis = pinocchio_along(clm, q, v, u)
    ours = forward_dynamics_derivatives_tree(clm, q, v, u, basis=basis)
    assert relative(ours.d_q, d_q) < 1e-9
    assert relative(ours.d_v @ basis, d_v) < 1e-9
    assert relative(ours.d_actuator_forces, d_u) < 1e-9


@pytest.mark.parametrize("name", ["four-bar", "five-bar", "stewart"])
def test_pinocchio_constraint_derivatives_wrong_for_point_loops_between_moving_bodies(name):
    """A minimal repro for upstream: the four-bar of tests/data/four_bar (one CONTACT_3D
    between the coupler and the rocker, LOCAL, both on revolute-rooted branches).
    ``ddq_dq`` of ``pin.computeConstraintDynamicsDerivatives`` misses the derivative along
    the closure surface by a relative 0.4 to 10 (``ddq_dv`` and ``ddq_dtau`` are right),
    while ours matches the finite differences of ``test_tree_derivatives_*``."""
    robot = robot_registry.get(name)
    clm, q = robot.model, robot.home_configuration
    _, v, u, _ = tree_state(clm, q, 1)
    d_q, d_v, d_u, basis = pinocchio_along(clm, q, v, u)
    ours = forward_dynamics_derivatives_tree(clm, q, v, u, basis=basis)
    assert relative(ours.d_q, d_q) > 0.1              # wrong
    assert relative(ours.d_v @ basis, d_v) < 1e-9      # right
    assert relative(ours.d_actuator_forces, d_u) < 1e-9


# -- robot level ---------------------------------------------------------------------------
def displaced(robot, pose, dx):
    """The pose moved by the world tangent ``dx = (dp, dtheta)`` (``R -> exp(dtheta) R``)."""
    lay = robot.pose_layout
    out = pose.copy()
    out[lay.linear] += dx[lay.linear]
    if lay.full_rotation:
        rot = pin.exp3(dx[lay.angular]) @ rotation_from_rpy(pose[lay.angular])
        out[lay.angular] = rpy_from_rotation(rot)
    else:
        out[lay.angular] += dx[lay.angular]
    return out


def check_robot(robot, branch=None, seed=3):
    dim = robot.pose_layout.dim
    rng = np.random.default_rng(seed)
    pose = robot.home_pose + 0.01 * rng.uniform(-1, 1, dim)
    twist, wrench = 0.05 * rng.normal(size=dim), rng.normal(size=dim)
    u = robot.static_forces(pose, bounded=False, branch=branch) + rng.normal(size=robot.n_actuators)
    der = robot.forward_dynamics_derivatives(pose, twist, u, wrench, branch=branch)

    def acc(p, t=twist, uu=u, w=wrench):
        return robot.forward_dynamics(p, t, uu, w, branch=branch).twist_dot

    eye = np.eye(dim)
    np.testing.assert_allclose(der.twist_dot, acc(pose), rtol=1e-9, atol=1e-9)
    worst = 0.0
    for got, column, h in (
            (der.d_world, lambda k: lambda s: acc(displaced(robot, pose, s * eye[k])), 1e-3),
            (der.d_pose, lambda k: lambda s: acc(pose + s * eye[k]), 1e-3),
            (der.d_twist, lambda k: lambda s: acc(pose, twist + s * eye[k]), 1e-2),
            (der.d_wrench, lambda k: lambda s: acc(pose, twist, u, wrench + s * eye[k]), 1.0)):
        num = np.array([richardson(column(k), h) for k in range(dim)]).T
        worst = max(worst, relative(num, got))
    num = np.array([richardson(lambda s: acc(pose, twist, u + s * np.eye(robot.n_actuators)[k]),
                               1.0) for k in range(robot.n_actuators)]).T
    return max(worst, relative(num, der.d_actuator_forces)), der, pose


@pytest.mark.parametrize("effects", [False, True], ids=["rigid", "effects"])
@pytest.mark.parametrize("name", ROBOTS)
def test_robot_derivatives_match_finite_differences(name, effects):
    robot = robot_registry.get(name)
    if effects:
        clm, q = robot.model, robot.home_configuration
        nv = clm.nv
        rng = np.random.default_rng(11)
        robot = robot.with_effects(damping=rng.uniform(0.1, 0.5, nv),
                                   stiffness=rng.uniform(1, 5, nv),
                                   spring_reference=pin.integrate(clm.model, q,
                                                                  rng.uniform(-0.5, 0.5, nv)),
                                   armature=rng.uniform(0.01, 0.05, nv))
    worst, der, pose = check_robot(robot)
    assert worst < RTOL
    # the reduced dynamics, another route: d_wrench = M_x^-1, d_u = M_x^-1 J^T
    red = robot.reduced_dynamics(pose, np.zeros(robot.pose_layout.dim))
    np.testing.assert_allclose(der.d_wrench @ red.mass_matrix, np.eye(robot.pose_layout.dim),
                               atol=1e-9)


@pytest.mark.parametrize("seed", [0, 1])
def test_robot_derivatives_as_built_hexapod_both_branches(seed):
    robot = hp.Hexapod(random_as_built(hp.HexapodGeometry(), 1e-3, seed))
    for branch in (None, -np.asarray(HOME_BRANCH)):
        worst, _, _ = check_robot(robot, branch=branch, seed=seed)
        assert worst < RTOL


def test_linearize_blocks_and_rotation_term():
    robot = robot_registry.get("hexapod")
    pose, twist = robot.home_pose, np.array([0.01, 0.0, -0.02, 0.1, -0.2, 0.3])
    u = robot.static_forces(pose, bounded=False)
    model = robot.linearize(pose, twist, u)
    der = robot.forward_dynamics_derivatives(pose, twist, u)
    np.testing.assert_array_equal(model.a[6:, :6], der.d_world)
    np.testing.assert_array_equal(model.a[6:, 6:], der.d_twist)
    np.testing.assert_array_equal(model.a[:6, 6:], np.eye(6))
    np.testing.assert_array_equal(model.b[6:], der.d_actuator_forces)
    assert not model.b[:6].any()
    # d dtheta / dt = dw + w x dtheta: the rotation of R exp... at the operating twist
    w = twist[3:]
    np.testing.assert_allclose(model.a[3:6, 3:6] @ np.array([1.0, 2.0, 3.0]),
                               np.cross(w, [1.0, 2.0, 3.0]), atol=1e-15)
    planar = robot_registry.get("planar")
    lin = planar.linearize(planar.home_pose, np.array([0.1, 0.0, 0.5]), np.zeros(3))
    assert not lin.a[:3, :3].any()


def test_robot_level_bad_input():
    robot = robot_registry.get("four-bar")
    with pytest.raises(InputError):
        robot.forward_dynamics_derivatives([0.0, 1.0], [0.0], [0.0])
    with pytest.raises(InputError):
        robot.forward_dynamics_derivatives(robot.home_pose, [np.inf], [0.0])
    with pytest.raises(InputError):
        robot.linearize(robot.home_pose, [0.0], [0.0, 1.0])
    with pytest.raises(InputError):
        robot.forward_dynamics_derivatives(robot.home_pose, [0.0], [0.0], wrench=[1.0, 2.0])


def test_other_geometry_robots():
    """Robots the code was not written for: another hexapod and planar geometry."""
    for name in ("hexapod-other", "planar-other"):
        worst, _, _ = check_robot(robot_registry.get(name), seed=5)
        assert worst < RTOL


def test_result_is_frozen():
    robot = robot_registry.get("four-bar")
    der = robot.forward_dynamics_derivatives(robot.home_pose, [0.0], [0.0])
    with pytest.raises(dataclasses.FrozenInstanceError):
        der.twist_dot = None


def test_lqr_example_stabilises_the_hexapod(capsys):
    """examples/hexapod_lqr.py: the LQR gain from robot.linearize puts every closed-loop
    eigenvalue in the left half-plane (the open loop at held forces is unstable), and the
    simulated nonlinear closed loop brings the pose error down by two orders."""
    import re
    import runpy
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    runpy.run_path(str(root / "examples" / "hexapod_lqr.py"), run_name="__main__")
    out = capsys.readouterr().out
    number = r"([-+0-9.e]+)"
    assert float(re.search("open-loop max real part " + number, out).group(1)) > 0
    assert float(re.search("closed-loop max real part " + number, out).group(1)) < 0
    assert "status completed" in out
    start, half, end = (float(x) for x in re.search(
        f"pose error start {number} half {number} end {number}", out).groups())
    assert end < 1e-2 * start and half < start


@pytest.mark.parametrize("name", ["hexapod", "planar", "delta", "five-bar"])
def test_batch_equals_single_states(name):
    """forward_dynamics_derivatives_batch: row k is the single-state answer of state k
    (with and without wrenches); a bad row count and an unreachable row are named."""
    robot = robot_registry.get(name)
    dim, n_act = robot.pose_layout.dim, robot.n_actuators
    rng = np.random.default_rng(2)
    poses = robot.home_pose + 0.01 * rng.uniform(-1, 1, (3, dim))
    twists, wrenches = 0.05 * rng.normal(size=(3, dim)), rng.normal(size=(3, dim))
    forces = rng.normal(size=(3, n_act))
    for w in (None, wrenches):
        batch = robot.forward_dynamics_derivatives_batch(poses, twists, forces, w)
        for k in range(3):
            one = robot.forward_dynamics_derivatives(poses[k], twists[k], forces[k],
                                                     None if w is None else w[k])
            for field in dataclasses.fields(one):
                np.testing.assert_array_equal(getattr(batch, field.name)[k],
                                              getattr(one, field.name))
    with pytest.raises(InputError, match="rows"):
        robot.forward_dynamics_derivatives_batch(poses, twists[:2], forces)
    far = poses.copy()
    far[1, 0] += 100.0
    with pytest.raises((hp.errors.BatchUnreachablePoseError,
                        hp.errors.BatchSingularityError)) as info:
        robot.forward_dynamics_derivatives_batch(far, twists, forces)
    assert info.value.index == 1


# -- inverse-dynamics derivatives from the core ----------------------------------------------
def id_state(robot, seed):
    dim = robot.pose_layout.dim
    rng = np.random.default_rng(seed)
    return (robot.home_pose + 0.01 * rng.uniform(-1, 1, dim), 0.05 * rng.normal(size=dim),
            rng.normal(size=dim), rng.normal(size=dim))


@pytest.mark.parametrize("effects", [False, True], ids=["rigid", "effects"])
@pytest.mark.parametrize("name", ["stewart", "delta", "four-bar", "five-bar"])
def test_loaded_inverse_dynamics_derivatives_match_finite_differences(name, effects):
    """ClosedLoopRobot.inverse_dynamics_derivatives (analytic, the implicit-function theorem
    on the core's KKT derivatives) against Richardson central differences of the robot's
    verified inverse dynamics (steps 1e-3 pose, 1e-2 twist, 1.0 twist_dot and wrench)."""
    robot = robot_registry.get(name)
    if effects:
        clm, q = robot.model, robot.home_configuration
        rng = np.random.default_rng(4)
        robot = robot.with_effects(damping=rng.uniform(0.1, 0.5, clm.nv),
                                   stiffness=rng.uniform(1, 5, clm.nv),
                                   spring_reference=pin.integrate(
                                       clm.model, q, rng.uniform(-0.5, 0.5, clm.nv)),
                                   armature=rng.uniform(0.01, 0.05, clm.nv))
    pose, twist, twist_dot, wrench = id_state(robot, 6)
    der = robot.inverse_dynamics_derivatives(pose, twist, twist_dot, wrench)
    dim = robot.pose_layout.dim
    eye = np.eye(dim)

    def tau(p=pose, t=twist, td=twist_dot, w=wrench):
        return robot.inverse_dynamics(p, t, td, w, bounded=False).actuator_forces

    np.testing.assert_allclose(der.actuator_forces, tau(), atol=1e-12)
    for got, column, h in (
            (der.d_world, lambda k: lambda s: tau(p=displaced(robot, pose, s * eye[k])), 1e-3),
            (der.d_pose, lambda k: lambda s: tau(p=pose + s * eye[k]), 1e-3),
            (der.d_twist, lambda k: lambda s: tau(t=twist + s * eye[k]), 1e-2),
            (der.d_twist_dot, lambda k: lambda s: tau(td=twist_dot + s * eye[k]), 1.0),
            (der.d_wrench, lambda k: lambda s: tau(w=wrench + s * eye[k]), 1.0)):
        num = np.array([richardson(column(k), h) for k in range(dim)]).T
        assert relative(num, got) < RTOL


@pytest.mark.parametrize("effects", [False, True], ids=["rigid", "effects"])
@pytest.mark.parametrize("name", ["hexapod", "planar", "hexapod-other", "planar-other"])
def test_core_inverse_dynamics_derivatives_match_the_closed_forms(name, effects):
    """The core's tree route and the hexapod's / planar robot's closed-form kernels (their
    Newton-Euler closed forms differentiated, what the robots answer) agree: two
    independent routes."""
    from hexapod_pin.core.platform_derivatives import inverse_dynamics_derivatives

    robot = robot_registry.get(name)
    if effects:
        nv = robot.model.nv
        rng = np.random.default_rng(9)
        robot = robot.with_effects(damping=rng.uniform(0.1, 0.5, nv),
                                   stiffness=rng.uniform(1, 5, nv),
                                   armature=rng.uniform(0.01, 0.05, nv))
    pose, twist, twist_dot, wrench = id_state(robot, 8)
    own = robot.inverse_dynamics_derivatives(pose, twist, twist_dot, wrench)
    core = inverse_dynamics_derivatives(robot, pose, twist, twist_dot, own.actuator_forces,
                                        wrench)
    for field in dataclasses.fields(own):
        assert relative(getattr(own, field.name), getattr(core, field.name)) < 1e-8, field.name


def test_core_inverse_dynamics_derivatives_check_their_forces():
    from hexapod_pin.core.platform_derivatives import inverse_dynamics_derivatives
    from hexapod_pin.errors import SolverError

    robot = robot_registry.get("planar")
    pose, twist, twist_dot, wrench = id_state(robot, 8)
    forces = robot.inverse_dynamics(pose, twist, twist_dot, wrench, bounded=False).actuator_forces
    with pytest.raises(SolverError, match="misses twist_dot"):
        inverse_dynamics_derivatives(robot, pose, twist, twist_dot, forces + 1.0, wrench)
