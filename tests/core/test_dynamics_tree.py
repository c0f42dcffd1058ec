"""Generic closed-loop dynamics on the tree (forward / inverse, routes, redundancy, welds).

Independent checks: the equation of motion re-assembled here from Pinocchio's crba / nle
and the closed-loop model's own constraint Jacobian and drift (themselves checked against
finite differences in test_closed_loop.py); three forward routes against each other; the
inverse routes against the forward ones.
"""

import numpy as np
import pinocchio as pin
import pytest
from conftest import random_configuration, random_pose

from hexapod_pin.core.closed_loop import ClosedLoopModel
from hexapod_pin.hexapod.geometry import hexapod_urdf
from hexapod_pin.core.description import build_model, parse_loops
from conftest import forward_dynamics_full_tau

from hexapod_pin.core.dynamics import (ClosedLoopDynamics, dynamics_of, forward_dynamics_tree,
                                       inverse_dynamics_tree)
from hexapod_pin.errors import ActuatorSaturationError, InputError

FD_METHODS = ("pinocchio", "qp", "kkt")
ID_METHODS = ("qp", "kkt")


def _state(robot, clm, rng, speed=0.5):
    """A closure-consistent tree state (q, v) near a random pose."""
    q = robot.configuration(random_pose(robot, rng))
    ff = np.arange(robot.indices.platform_v.start, robot.indices.platform_v.stop)
    v = clm.complete_velocity(q, ff, speed * rng.normal(size=6))
    return q, v


def _tau(clm, rng, scale=5.0):
    tau = np.zeros(clm.nv)
    tau[clm.actuated_v] = scale * rng.normal(size=clm.n_actuated)
    return tau


def _eom_residual(clm, q, v, a, tau, lam):
    """max |M a + h - tau - J_c^T lam| from Pinocchio's crba / nle and clm's J_c."""
    data = clm.model.createData()
    mass = pin.crba(clm.model, data, q)
    mass = np.triu(mass) + np.triu(mass, 1).T
    bias = pin.nonLinearEffects(clm.model, data, q, v)
    return np.max(np.abs(mass @ a + bias - tau - clm.constraint_jacobian(q).T @ lam))


def _redundant_model(robot):
    """The hexapod with leg 1's tip also closed on leg 0's tip: 21 rows, rank 18."""
    text = ("closures:\n" + "".join(
        f"  - {{name: tip_{i}, type: point, frame1: leg_{i}_tip, "
        f"frame2: platform_anchor_{i}}}\n" for i in range(6))
        + "  - {name: extra, type: point, frame1: leg_1_tip, frame2: leg_0_tip}\n"
        + "actuated: [carriage_0, carriage_1, carriage_2, carriage_3, carriage_4, carriage_5]\n")
    return ClosedLoopModel(build_model(hexapod_urdf(robot.geometry)), parse_loops(text))


def test_forward_routes_satisfy_the_equations_and_agree(any_robot, rng):
    clm = any_robot.model
    for _ in range(3):
        q, v = _state(any_robot, clm, rng)
        tau = _tau(clm, rng)
        gamma = clm.constraint_drift(q, v)
        jac = clm.constraint_jacobian(q)
        results = {m: forward_dynamics_full_tau(clm, q, v, tau, m) for m in FD_METHODS}
        for method, res in results.items():
            assert res.method == method and res.rank == 18
            assert _eom_residual(clm, q, v, res.a, tau, res.multipliers) < 1e-10
            assert np.max(np.abs(jac @ res.a + gamma)) < 1e-10
        for method in ("qp", "kkt"):
            np.testing.assert_allclose(results[method].a, results["pinocchio"].a, atol=1e-10)
            np.testing.assert_allclose(results[method].multipliers,
                                       results["pinocchio"].multipliers, atol=1e-10)


def test_multiplier_of_a_point_closure_is_the_force_on_the_leg_tip(robot, rng):
    """Leg 0 alone, Newton-Euler about its universal joint: the moment of the closure force
    at the tip plus the weight must equal the rate of angular momentum of the rod."""
    clm = robot.model
    q, v = _state(robot, clm, rng)
    res = forward_dynamics_full_tau(clm, q, v, _tau(clm, rng), "pinocchio")
    lam0 = res.multipliers[:3]  # closure tip_0 on leg_0_tip, world axes
    model, data = clm.model, clm.model.createData()
    pin.forwardKinematics(model, data, q, v, res.a)
    leg = model.getJointId("u_0_b")
    placement = data.oMi[leg]
    inertia = model.inertias[leg]
    # spatial momentum rate of the leg (world frame, about the world origin)
    a_body = data.a[leg]
    v_body = data.v[leg]
    f_body = inertia * a_body + v_body.cross(inertia * v_body)
    f_world = placement.act(f_body)
    tip = placement.act(pin.SE3(np.eye(3), np.array([0.0, 0.0, robot.geometry.leg_length])))
    joint_point = placement.translation
    com = placement.act(inertia.lever)
    weight = np.array([0.0, 0.0, -robot.geometry.gravity * robot.geometry.leg_mass])
    # moments about the universal-joint centre (the U joint transmits no moment about
    # its two axes; the leg's axis carries no torque for a rod with zero axial inertia)
    moment_rate = f_world.angular - np.cross(joint_point, f_world.linear)
    applied = (np.cross(tip.translation - joint_point, lam0) + np.cross(com - joint_point, weight))
    ua = placement.rotation @ np.array([0.0, 1.0, 0.0])           # u_0_b axis (leg frame y)
    cross = data.oMi[model.getJointId("u_0_a")].rotation @ np.array([1.0, 0.0, 0.0])
    for axis in (ua, cross):
        assert abs(axis @ (moment_rate - applied)) < 1e-10


def test_inverse_routes_invert_forward_dynamics(any_robot, rng):
    clm = any_robot.model
    for _ in range(3):
        q, v = _state(any_robot, clm, rng)
        tau = _tau(clm, rng)
        fwd = forward_dynamics_full_tau(clm, q, v, tau, "kkt")
        for method in ID_METHODS:
            inv = inverse_dynamics_tree(clm, q, v, fwd.a, method=method, bounds=1e3)
            np.testing.assert_allclose(inv.actuator_forces, tau[clm.actuated_v], atol=1e-10)
            np.testing.assert_allclose(inv.multipliers, fwd.multipliers, atol=1e-9)
            assert inv.residual < 1e-10 and inv.status == "solved"


def test_inverse_with_external_generalised_force(robot, rng):
    clm = robot.model
    q, v = _state(robot, clm, rng)
    tau_ext = np.zeros(clm.nv)
    tau_ext[robot.indices.platform_v] = rng.normal(size=6)
    tau = _tau(clm, rng) + tau_ext
    fwd = forward_dynamics_full_tau(clm, q, v, tau, "pinocchio")
    inv = {m: inverse_dynamics_tree(clm, q, v, fwd.a, tau_ext=tau_ext, method=m)
           for m in ID_METHODS}
    for res in inv.values():
        np.testing.assert_allclose(res.actuator_forces, tau[clm.actuated_v], atol=1e-10)
    np.testing.assert_allclose(inv["qp"].actuator_forces, inv["kkt"].actuator_forces, atol=1e-10)


def test_fast_constraint_terms_match_the_model(robot, rng):
    clm = robot.model
    dyn = dynamics_of(clm)
    q, v = _state(robot, clm, rng)
    q_off = random_configuration(clm.model, rng)
    for qq in (q, q_off):
        np.testing.assert_allclose(dyn.constraint_jacobian(qq), clm.constraint_jacobian(qq),
                                   atol=1e-14)
        np.testing.assert_allclose(dyn.constraint_drift(qq, v), clm.constraint_drift(qq, v),
                                   atol=1e-12)
    assert dynamics_of(clm) is dyn


def test_redundant_closures_give_finite_correct_answers(robot, rng):
    red = _redundant_model(robot)
    base = robot.model
    for _ in range(2):
        q, v = _state(robot, base, rng)
        tau = _tau(base, rng)
        ref = forward_dynamics_full_tau(base, q, v, tau, "kkt")
        ref_force = base.constraint_jacobian(q).T @ ref.multipliers
        jac = red.constraint_jacobian(q)
        results = {m: forward_dynamics_full_tau(red, q, v, tau, m) for m in FD_METHODS}
        for method, res in results.items():
            assert np.all(np.isfinite(res.a)) and np.all(np.isfinite(res.multipliers))
            assert res.rank == 18 and "redundant" in res.status
            np.testing.assert_allclose(res.a, ref.a, atol=1e-10)
            # the generalised closure force is unique even if the multipliers are not
            np.testing.assert_allclose(jac.T @ res.multipliers, ref_force, atol=1e-9)
            # and every route returns the minimum-norm multipliers
            min_norm, *_ = np.linalg.lstsq(jac.T, ref_force, rcond=None)
            np.testing.assert_allclose(res.multipliers, min_norm, atol=1e-9)
        for method in ID_METHODS:
            inv = inverse_dynamics_tree(red, q, v, ref.a, method=method, bounds=1e3)
            assert np.all(np.isfinite(inv.multipliers))
            np.testing.assert_allclose(inv.actuator_forces, tau[base.actuated_v], atol=1e-10)
            np.testing.assert_allclose(inv.multipliers, results["kkt"].multipliers, atol=1e-9)


def test_redundant_closures_at_home_never_nan(robot):
    """At the symmetric home pose, pin.constraintDynamics with mu=0 is the NaN-prone case."""
    red = _redundant_model(robot)
    q = robot.home_configuration
    tau = np.zeros(red.nv)
    res = forward_dynamics_full_tau(red, q, np.zeros(red.nv), tau, "pinocchio")
    assert np.all(np.isfinite(res.a)) and np.all(np.isfinite(res.multipliers))
    ref = forward_dynamics_full_tau(robot.model, q, np.zeros(red.nv), tau, "kkt")
    np.testing.assert_allclose(res.a, ref.a, atol=1e-10)


def test_weld_closure_routes_agree(robot, rng):
    q = robot.configuration(random_pose(robot, rng))
    data = robot.model.model.createData()
    pin.framesForwardKinematics(robot.model.model, data, q)
    tip = data.oMf[robot.model.model.getFrameId("leg_0_tip")]
    anchor = data.oMf[robot.model.model.getFrameId("platform_anchor_0")]
    rel = anchor.actInv(tip)
    text = f"""closures:
  - {{name: w, type: weld, frame1: leg_0_tip, frame2: platform_anchor_0,
     offset2: {{xyz: {rel.translation.tolist()}, rpy: {pin.rpy.matrixToRpy(rel.rotation).tolist()}}}}}
  - {{name: p, type: point, frame1: leg_3_tip, frame2: platform_anchor_3}}
actuated: [carriage_0, carriage_3]
"""
    weld = ClosedLoopModel(build_model(hexapod_urdf(robot.geometry)), parse_loops(text))
    # the weld leaves the platform only leg 0's motions: a random platform twist cannot
    # keep the closures, so a random tree velocity is projected onto them
    v = weld.project_velocity(q, 0.3 * rng.normal(size=weld.nv), metric="euclidean")
    tau = rng.normal(size=weld.nv)
    results = {m: forward_dynamics_full_tau(weld, q, v, tau, m) for m in FD_METHODS}
    for res in results.values():
        assert _eom_residual(weld, q, v, res.a, tau, res.multipliers) < 1e-10
        np.testing.assert_allclose(res.a, results["kkt"].a, atol=1e-10)
        np.testing.assert_allclose(res.multipliers, results["kkt"].multipliers, atol=1e-10)


def test_saturation_raises_with_the_needed_forces(robot, rng):
    clm = robot.model
    q, v = _state(robot, clm, rng)
    tau = _tau(clm, rng, scale=200.0)
    a = forward_dynamics_full_tau(clm, q, v, tau).a
    for method in ID_METHODS:
        with pytest.raises(ActuatorSaturationError) as info:
            inverse_dynamics_tree(clm, q, v, a, bounds=100.0, method=method)
        np.testing.assert_allclose(info.value.needed, tau[clm.actuated_v], atol=1e-8)
        np.testing.assert_array_equal(info.value.limit, np.full(6, 100.0))
    # per-actuator bounds, and inf means unbounded
    res = inverse_dynamics_tree(clm, q, v, a, bounds=np.full(6, np.inf))
    np.testing.assert_allclose(res.actuator_forces, tau[clm.actuated_v], atol=1e-9)


def test_joint_wrenches_reproduce_the_actuator_forces(robot, rng):
    clm = robot.model
    dyn = dynamics_of(clm)
    q, v = _state(robot, clm, rng)
    tau = _tau(clm, rng)
    res = forward_dynamics_full_tau(clm, q, v, tau, "kkt")
    wrenches, tau_rnea = dyn.joint_wrenches(q, v, res.a, res.multipliers)
    np.testing.assert_allclose(tau_rnea, tau, atol=1e-10)
    for i in range(6):
        assert wrenches[f"carriage_{i}"][0] == pytest.approx(tau[clm.actuated_v[i]], abs=1e-10)
        assert abs(wrenches[f"u_{i}_a"][3]) < 1e-10 and abs(wrenches[f"u_{i}_b"][4]) < 1e-10
    assert np.max(np.abs(wrenches["platform_joint"])) < 1e-10


def test_bad_inputs_raise(robot):
    clm = robot.model
    q = robot.home_configuration
    zero = np.zeros(clm.nv)
    act = np.zeros(clm.n_actuated)
    with pytest.raises(InputError, match="method"):
        forward_dynamics_tree(clm, q, zero, act, method="magic")
    with pytest.raises(InputError):
        inverse_dynamics_tree(clm, q, zero, zero, method="pinocchio")
    with pytest.raises(InputError):
        forward_dynamics_tree(clm, q, zero[:3], act)
    with pytest.raises(InputError, match="actuator_forces"):
        forward_dynamics_tree(clm, q, zero, np.full(clm.n_actuated, np.nan))
    with pytest.raises(InputError, match="actuator_forces"):
        forward_dynamics_tree(clm, q, zero, zero)      # (nv,) is not the actuators' shape
    with pytest.raises(InputError, match="tau_ext"):
        forward_dynamics_tree(clm, q, zero, act, np.full(clm.nv, np.nan))
    with pytest.raises(InputError):
        inverse_dynamics_tree(clm, q, zero, zero, bounds=-1.0)
    with pytest.raises(InputError):
        inverse_dynamics_tree(clm, q, zero, zero, bounds=np.ones(3))
    with pytest.raises(InputError):
        ClosedLoopDynamics("not a model")


def test_workspace_is_dropped_with_its_model(robot):
    """dynamics_of keeps one workspace per model and thread, and none after the model is
    collected (the workspace refers to its model weakly); a non-model is refused."""
    import gc
    import weakref

    clm = _redundant_model(robot)
    dyn = dynamics_of(clm)
    assert dynamics_of(clm) is dyn and dyn.clm is clm
    ref = weakref.ref(dyn)
    del clm, dyn
    gc.collect()
    assert ref() is None
    with pytest.raises(InputError, match="ClosedLoopModel"):
        dynamics_of(robot)


def test_forward_calls_leave_no_state_behind(robot, rng):
    """The forward route builds ``S^T u + tau_ext`` in a buffer of the workspace: a call
    with ``tau_ext`` followed by one without must give what a fresh workspace gives, and a
    result that keeps its generalised force (redundant rows: multipliers computed when
    read) must not see later calls. References: the null-space solve written here."""
    for clm in (robot.model, _redundant_model(robot)):
        q, v = _state(robot, robot.model, rng)
        data = clm.model.createData()
        mass = pin.crba(clm.model, data, q)
        mass = np.triu(mass) + np.triu(mass, 1).T
        bias = pin.nonLinearEffects(clm.model, data, q, v)
        jac, gamma = clm.constraint_jacobian(q), clm.constraint_drift(q, v)

        def reference(u, tau_ext):
            tau = tau_ext.copy()
            tau[clm.actuated_v] += u
            a_p = -np.linalg.lstsq(jac, gamma, rcond=None)[0]
            _, sv, vt = np.linalg.svd(jac)
            basis = vt[int(np.sum(sv > 1e-10 * sv[0])):].T
            z = np.linalg.solve(basis.T @ mass @ basis,
                                basis.T @ (tau - bias - mass @ a_p))
            acc = a_p + basis @ z
            return acc, np.linalg.lstsq(jac.T, mass @ acc + bias - tau, rcond=None)[0]

        calls = []
        for with_ext in (True, False, True, False, False):
            u = 5.0 * rng.normal(size=clm.n_actuated)
            tau_ext = rng.normal(size=clm.nv) if with_ext else np.zeros(clm.nv)
            res = forward_dynamics_tree(clm, q, v, u, tau_ext if with_ext else None)
            calls.append((res, reference(u, tau_ext)))
        for res, (acc, lam) in calls:          # read after all calls were made
            np.testing.assert_allclose(res.a, acc, atol=1e-9)
            np.testing.assert_allclose(res.multipliers, lam, atol=1e-8)


def test_forward_result_does_not_alias_the_callers_force(robot, rng):
    """``ClosedLoopDynamics.forward`` with redundant rows computes the multipliers when read,
    from the generalised force of the call: changing the caller's array afterwards must
    not change them (reference: the same call on a copy that nobody touches)."""
    red = _redundant_model(robot)
    q, v = _state(robot, robot.model, rng)
    tau = _tau(red, rng)
    dyn = ClosedLoopDynamics(red)
    res = dyn.forward(q, v, tau)
    ref = ClosedLoopDynamics(red).forward(q, v, tau.copy()).multipliers
    tau += 100.0
    np.testing.assert_allclose(res.multipliers, ref, atol=1e-9)
    assert "redundant" in res.status
