"""The generic closed-loop core on test robots of each hard class (tests/stress_robots.py).

Independent reference, written here: the null-space solution of the constrained dynamics
from Pinocchio's crba / nle and the closed-loop model's own J_c and gamma (themselves
checked against finite differences in test_closed_loop.py), with an SVD basis of ker J_c
and the minimum-norm multipliers (J_c^T)^+ (M a + h - tau). Every forward and inverse
route must agree with it to 1e-9 relative, on every class, for every sampled state (no
SolverError on these well-posed states), and must raise on a deliberately inconsistent
problem.
"""

import numpy as np
import pinocchio as pin
import pytest
import stress_robots

from hexapod_pin.core.closed_loop import ClosedLoopModel
from hexapod_pin.core.description import build_model, parse_loops
from hexapod_pin.core.dynamics import (
    FORWARD_METHODS,
    INVERSE_METHODS,
    dynamics_of,
    forward_dynamics_tree,
    inverse_dynamics_tree,
)
from hexapod_pin.errors import ActuatorSaturationError, InputError, SolverError

RTOL = 1e-9
STATES = 4


@pytest.fixture(scope="module", params=sorted(stress_robots.BUILDERS))
def stress(request):
    return stress_robots.build(request.param)


def reference_terms(clm, q, v):
    data = clm.model.createData()
    mass = pin.crba(clm.model, data, q)
    mass = np.triu(mass) + np.triu(mass, 1).T
    bias = pin.nonLinearEffects(clm.model, data, q, v)
    return mass, bias, clm.constraint_jacobian(q), clm.constraint_drift(q, v)


def reference_forward(clm, q, v, tau):
    """(a, minimum-norm lambda) by the null-space method (numpy SVD)."""
    mass, bias, jac, gamma = reference_terms(clm, q, v)
    _, sv, vt = np.linalg.svd(jac)
    r = int(np.sum(sv > 1e-10 * sv[0]))
    a_p = np.linalg.pinv(jac, rcond=1e-10) @ -gamma
    basis = vt[r:].T
    z = np.linalg.solve(basis.T @ mass @ basis, basis.T @ (tau - bias - mass @ a_p))
    acc = a_p + basis @ z
    lam = np.linalg.pinv(jac.T, rcond=1e-10) @ (mass @ acc + bias - tau)
    return acc, lam


def assert_close(value, ref, what):
    scale = max(np.max(np.abs(ref)), 1e-300)
    err = np.max(np.abs(value - ref)) / scale
    assert err <= RTOL, f"{what}: relative error {err:.3e}"


def _tau(clm, rng):
    tau = np.zeros(clm.nv)
    tau[clm.actuated_v] = rng.normal(size=clm.n_actuated)
    return tau


def test_every_forward_route_matches_the_nullspace_reference(stress):
    rng = np.random.default_rng(1)
    clm = stress.clm
    for _ in range(STATES):
        q, v = stress.sample(rng)
        tau = _tau(clm, rng)
        a_ref, lam_ref = reference_forward(clm, q, v, tau)
        for method in FORWARD_METHODS:
            res = forward_dynamics_tree(clm, q, v, tau[clm.actuated_v], method=method)
            assert_close(res.a, a_ref, f"{stress.name} {method} a")
            assert_close(res.multipliers, lam_ref, f"{stress.name} {method} lambda")
            redundant = np.linalg.matrix_rank(clm.constraint_jacobian(q)) < clm.n_rows
            assert ("redundant" in res.status) == redundant, res.status


def test_every_inverse_route_matches_the_reference(stress):
    rng = np.random.default_rng(2)
    clm = stress.clm
    for _ in range(STATES):
        q, v = stress.sample(rng)
        tau = _tau(clm, rng)
        a_ref, lam_ref = reference_forward(clm, q, v, tau)
        for method in INVERSE_METHODS:
            for bounds in (None, 10.0 * np.max(np.abs(tau))):
                inv = inverse_dynamics_tree(clm, q, v, a_ref, method=method, bounds=bounds)
                assert_close(inv.actuator_forces, tau[clm.actuated_v],
                             f"{stress.name} {method} u")
                assert_close(inv.multipliers, lam_ref, f"{stress.name} {method} lambda")


def test_saturation_only_when_the_bounds_are_infeasible(stress):
    rng = np.random.default_rng(3)
    clm = stress.clm
    q, v = stress.sample(rng)
    tau = _tau(clm, rng)
    a_ref, _ = reference_forward(clm, q, v, tau)
    needed = np.abs(tau[clm.actuated_v])
    with pytest.raises(ActuatorSaturationError):
        inverse_dynamics_tree(clm, q, v, a_ref, bounds=0.5 * np.max(needed), method="qp")
    ok = inverse_dynamics_tree(clm, q, v, a_ref, bounds=1.001 * np.max(needed), method="qp")
    assert_close(ok.actuator_forces, tau[clm.actuated_v], f"{stress.name} u at the bound")


def test_inverse_of_a_motion_that_breaks_the_closures_raises(stress):
    rng = np.random.default_rng(4)
    clm = stress.clm
    q, v = stress.sample(rng)
    a_ref, _ = reference_forward(clm, q, v, _tau(clm, rng))
    jac = clm.constraint_jacobian(q)
    # a direction that the closures forbid (in the row space of J_c)
    bad = a_ref + 0.1 * np.max(np.abs(a_ref)) * jac.T @ rng.normal(size=clm.n_rows) \
        / np.max(np.abs(jac))
    for method in INVERSE_METHODS:
        with pytest.raises(SolverError, match="closure equation"):
            inverse_dynamics_tree(clm, q, v, bad, method=method)


PENDULUM = """<?xml version="1.0"?>
<robot name="pendulum">
  <link name="world"/>
  <joint name="hinge" type="revolute"><parent link="world"/><child link="rod"/>
    <axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <link name="rod"><inertial><origin xyz="0 0 -0.25"/><mass value="1"/>
    <inertia ixx="0.02" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.001"/></inertial></link>
  <joint name="tip_mount" type="fixed"><parent link="rod"/><child link="tip"/>
    <origin xyz="0 0 -0.5"/></joint>
  <link name="tip"/>
  <joint name="slider" type="prismatic"><parent link="world"/><child link="cart"/>
    <axis xyz="1 0 0"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <link name="cart"><inertial><mass value="1"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>
</robot>
"""


def test_gamma_outside_the_range_of_the_jacobian_raises():
    """A pendulum whose tip is pinned to the world (3 rows, rank 1), moving: the drift
    (centripetal, radial) is outside the range of J_c (tangential), so J_c a = -gamma has
    no solution; every forward route must raise instead of returning a least-squares a.
    (A free slider beside it keeps nv = 2.)"""
    loops = parse_loops("closures:\n  - {name: pin, type: point, frame1: tip, "
                        "frame2: world, offset2: {xyz: [0, 0, -0.5]}}\nactuated: [hinge, slider]\n")
    clm = ClosedLoopModel(build_model(PENDULUM), loops)
    q, v = np.zeros(2), np.array([2.0, 0.0])
    gamma = clm.constraint_drift(q, v)
    assert np.max(np.abs(gamma)) > 1.0
    for method in FORWARD_METHODS:
        # the public route refuses the velocity first (it breaks the closures) ...
        with pytest.raises(InputError, match="breaks the closures") as err:
            forward_dynamics_tree(clm, q, v, np.zeros(2), method=method)
        assert err.value.name == "v"
        # ... and the solvers below it refuse the inconsistent system themselves
        with pytest.raises(SolverError):
            dynamics_of(clm).forward_unchecked(q, v, np.zeros(2), method)


def test_pinocchio_route_reports_its_fallback_on_massless_links():
    robot = stress_robots.build("ladder_massless")
    q, v = robot.sample(np.random.default_rng(5))
    res = forward_dynamics_tree(robot.clm, q, v, np.ones(1), method="pinocchio")
    assert res.status.startswith("pin.constraintDynamics unverified")
    dyn = dynamics_of(robot.clm)
    tau = np.zeros(robot.clm.nv)
    tau[robot.clm.actuated_v] = 1.0
    acc, _ = dyn.pinocchio_call(q, v, tau, False)
    assert acc is None                          # the raw call is refused, not returned


# ------------------------------------------------------------------------- MuJoCo export
def test_mujoco_export_has_the_same_mass_matrix_and_inverse_dynamics(stress):
    """MuJoCo's own M and mj_inverse (without the equalities), projected on the null space
    of MuJoCo's own constraint Jacobian, give back our actuator forces."""
    mujoco = pytest.importorskip("mujoco")
    from hexapod_pin.core.mujoco_export import to_mujoco

    clm = stress.clm
    model = to_mujoco(clm)
    data = mujoco.MjData(model)
    rng = np.random.default_rng(6)
    selection = np.zeros((clm.nv, clm.n_actuated))
    selection[clm.actuated_v, np.arange(clm.n_actuated)] = 1.0
    for _ in range(2):
        q, v = stress.sample(rng)
        tau = _tau(clm, rng)
        a_ref, _ = reference_forward(clm, q, v, tau)
        inv = inverse_dynamics_tree(clm, q, v, a_ref, method="kkt")
        model.opt.disableflags = 0
        data.qpos[:], data.qvel[:] = q, v
        mujoco.mj_forward(model, data)
        assert np.max(np.abs(data.efc_pos)) < 1e-12            # closures hold at q
        mass = np.zeros((model.nv, model.nv))
        mujoco.mj_fullM(model, data, mass)
        mass_ref = reference_terms(clm, q, v)[0]
        assert np.max(np.abs(mass - mass_ref)) <= 1e-8 * np.max(np.abs(mass_ref))
        jac = data.efc_J.reshape(data.nefc, model.nv).copy()
        _, sv, vt = np.linalg.svd(jac)
        basis = vt[int(np.sum(sv > 1e-10 * sv[0])):].T
        model.opt.disableflags = int(mujoco.mjtDisableBit.mjDSBL_EQUALITY)
        data.qacc[:] = a_ref
        mujoco.mj_inverse(model, data)
        u_mj, *_ = np.linalg.lstsq(basis.T @ selection, basis.T @ data.qfrc_inverse,
                                   rcond=None)
        scale = np.max(np.abs(inv.actuator_forces))
        assert np.max(np.abs(u_mj - inv.actuator_forces)) <= 1e-8 * scale


def _delta_with_ball_wrists(tmp_path):
    """The delta of tests/data/parallel with spherical wrists (MuJoCo ball joints)."""
    from hexapod_pin.loaders.parallel_robots import load_parallel_robot

    src = stress_robots.DATA / "delta"
    (tmp_path / "robot.urdf").write_text((src / "robot.urdf").read_text())
    yaml = (src / "robot.yaml").read_text()
    old = "'UJOINT_ZY', 'UJOINT_ZY', 'UJOINT_ZY'"
    assert old in yaml
    (tmp_path / "robot.yaml").write_text(yaml.replace(old, "'SPHERICAL', 'SPHERICAL', 'SPHERICAL'"))
    return load_parallel_robot(tmp_path)


def _consistent_state(clm, q, rng):
    _, sv, vt = np.linalg.svd(clm.constraint_jacobian(q))
    basis = vt[int(np.sum(sv > 1e-10 * sv[0])):].T
    return basis @ rng.normal(size=basis.shape[1])


@pytest.mark.parametrize("robot", ["solo12_free_flyer", "delta_ball_wrists"])
def test_mujoco_export_of_free_flyer_and_ball_joints(robot, tmp_path):
    """Free flyer (Solo-12) and ball joints: the converted qpos puts MuJoCo's closure sites
    on Pinocchio's anchor frames, the converted qvel gives every body Pinocchio's
    velocity; MuJoCo's mass matrix is ours in its coordinates
    (qvel = T v, T built here from MuJoCo's own body rotation: M_mj = T^-T M T^-1); and
    mj_inverse (without equalities), mapped back (tau = T^T qfrc) and projected on the
    null space of MuJoCo's constraint Jacobian, matches our actuator forces to 1e-8 (on
    the null space: Solo-12's forces are not unique)."""
    mujoco = pytest.importorskip("mujoco")
    from hexapod_pin.core.mujoco_export import mujoco_state, to_mujoco
    from hexapod_pin.loaders import robots

    rng = np.random.default_rng(10)
    if robot == "solo12_free_flyer":
        clm = robots.solo12()
        q = robots.solo12_stand(clm, [0.01, -0.005, 0.20], 0.05 * rng.normal(size=3)).q
    else:
        clm = _delta_with_ball_wrists(tmp_path)
        dq = np.zeros(clm.nv)
        dq[clm.actuated_v] = 0.1 * rng.normal(size=clm.n_actuated)
        q = clm.assemble(pin.integrate(clm.model, pin.neutral(clm.model), dq)).q
    kinds = {clm.model.joints[j].shortname() for j in range(1, clm.model.njoints)}
    assert kinds & {"JointModelFreeFlyer", "JointModelSpherical"}
    v = _consistent_state(clm, q, rng)
    tau = _tau(clm, rng)
    a_ref, _ = reference_forward(clm, q, v, tau)
    inv = inverse_dynamics_tree(clm, q, v, a_ref, method="kkt")
    model = to_mujoco(clm)
    data = mujoco.MjData(model)
    state = mujoco_state(clm, q, v, a_ref)
    data.qpos[:], data.qvel[:] = state.qpos, state.qvel
    mujoco.mj_forward(model, data)
    assert np.max(np.abs(data.efc_pos)) < 1e-12                 # closures hold at q
    pdata = clm.model.createData()
    pin.forwardKinematics(clm.model, pdata, q, v)
    pin.updateFramePlacements(clm.model, pdata)
    for j in range(1, clm.model.njoints):                     # qvel: every body's velocity
        body = model.body(clm.model.names[j]).id
        twist = np.zeros(6)               # (angular, linear) at the body's COM, world axes
        mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_BODY, body, twist, 0)
        ref = pin.getVelocity(clm.model, pdata, j, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
        at_com = ref.linear + np.cross(ref.angular, data.xipos[body] - data.xpos[body])
        assert np.max(np.abs(twist - np.concatenate([ref.angular, at_com]))) <= 1e-12 * \
            max(1.0, np.max(np.abs(v)))
    for closure in clm.closures:
        for tag in ("anchor1", "anchor2"):
            site = model.site(f"{closure.name}__{tag}").id
            frame = pdata.oMf[clm.model.getFrameId(f"{closure.name}/{tag}")]
            assert np.max(np.abs(data.site_xpos[site] - frame.translation)) < 1e-12
            assert np.max(np.abs(data.site_xmat[site].reshape(3, 3) - frame.rotation)) < 1e-12
    t_map = np.eye(clm.nv)
    for j in range(1, clm.model.njoints):
        if clm.model.joints[j].shortname() == "JointModelFreeFlyer":
            iv = clm.model.joints[j].idx_v
            t_map[iv:iv + 3, iv:iv + 3] = data.xmat[model.body(clm.model.names[j]).id].reshape(3, 3)
    t_inv = np.linalg.inv(t_map)
    mass = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, mass)
    mass_ref = t_inv.T @ reference_terms(clm, q, v)[0] @ t_inv
    assert np.max(np.abs(mass - mass_ref)) <= 1e-8 * np.max(np.abs(mass_ref))
    jac = data.efc_J.reshape(data.nefc, model.nv).copy()
    _, sv, vt = np.linalg.svd(jac)
    basis = t_inv @ vt[int(np.sum(sv > 1e-10 * sv[0])):].T        # ker J_c in our coordinates
    model.opt.disableflags = int(mujoco.mjtDisableBit.mjDSBL_EQUALITY)
    data.qacc[:] = state.qacc
    mujoco.mj_inverse(model, data)
    tau_mj = t_map.T @ data.qfrc_inverse
    selection = np.zeros((clm.nv, clm.n_actuated))
    selection[clm.actuated_v, np.arange(clm.n_actuated)] = 1.0
    miss = basis.T @ (tau_mj - selection @ inv.actuator_forces)
    assert np.max(np.abs(miss)) <= 1e-8 * np.max(np.abs(tau_mj))
    if robot == "delta_ball_wrists":                           # forces unique there
        u_mj, *_ = np.linalg.lstsq(basis.T @ selection, basis.T @ tau_mj, rcond=None)
        assert np.max(np.abs(u_mj - inv.actuator_forces)) <= 1e-8 * np.max(np.abs(u_mj))


def test_mujoco_export_needs_mujoco(monkeypatch):
    import sys

    from hexapod_pin.core.mujoco_export import closed_loop_mjcf, to_mujoco
    from hexapod_pin.errors import MissingDependencyError

    clm = stress_robots.build("ladder_mixed").clm
    assert "<connect" in closed_loop_mjcf(clm)
    monkeypatch.setitem(sys.modules, "mujoco", None)
    with pytest.raises(MissingDependencyError):
        to_mujoco(clm)


# ----------------------------------------------------------------------------- batches
def test_batches_equal_single_calls():
    from hexapod_pin.core.tree_batch import forward_dynamics_tree_batch, inverse_dynamics_tree_batch

    robot = stress_robots.build("planar_ladder_weld")
    clm = robot.clm
    rng = np.random.default_rng(7)
    states = [robot.sample(rng) for _ in range(5)]
    q = np.array([s[0] for s in states])
    v = np.array([s[1] for s in states])
    u = rng.normal(size=(5, clm.n_actuated))
    for method in FORWARD_METHODS:
        batch = forward_dynamics_tree_batch(clm, q, v, u, method=method)
        for i in range(5):
            single = forward_dynamics_tree(clm, q[i], v[i], u[i], method=method)
            np.testing.assert_array_equal(batch.a[i], single.a)
            np.testing.assert_allclose(batch.multipliers[i], single.multipliers, rtol=0,
                                       atol=1e-12 * np.max(np.abs(single.multipliers)))
    acc = forward_dynamics_tree_batch(clm, q, v, u, method="kkt").a
    for method in INVERSE_METHODS:
        inv = inverse_dynamics_tree_batch(clm, q, v, acc, method=method, threads=2)
        for i in range(5):
            single = inverse_dynamics_tree(clm, q[i], v[i], acc[i], method=method)
            np.testing.assert_allclose(inv.actuator_forces[i], single.actuator_forces,
                                       rtol=1e-12, atol=0)
            assert_close(inv.actuator_forces[i], u[i], "batch u")
    from hexapod_pin.errors import BatchActuatorSaturationError

    bound = 0.5 * np.abs(u[3]).max()
    if np.all(np.abs(u[:3]) < bound):
        with pytest.raises(BatchActuatorSaturationError) as info:
            inverse_dynamics_tree_batch(clm, q, v, acc, bounds=bound)
        assert info.value.index == 3
    bad = acc.copy()
    bad[2] += 1.0
    with pytest.raises(SolverError, match="state 2"):
        inverse_dynamics_tree_batch(clm, q, v, bad, method="kkt")


# -------------------------------------------------------------------------- simulation
@pytest.mark.parametrize("name", ["ladder_mixed", "planar_ladder_weld", "five_bar_massless"])
@pytest.mark.parametrize("integrator", ["rk4", "semi_implicit_euler"])
def test_generic_step_keeps_the_closures(name, integrator):
    """Steps of the tree integrator keep every closure (position and velocity) to 1e-9."""
    from hexapod_pin.core.simulation import ClosedLoopIntegrator

    robot = stress_robots.build(name)
    clm = robot.clm
    q, v = robot.sample(np.random.default_rng(8))
    sim = ClosedLoopIntegrator(clm, integrator=integrator)
    tau = np.zeros(clm.nv)
    for _ in range(20):
        q, v, residual = sim.step(q, v, tau, 1e-4)
        assert residual <= 1e-9
        assert np.max(np.abs(clm.residual(q))) <= 1e-9
        assert np.max(np.abs(clm.constraint_jacobian(q) @ v)) <= 1e-9 * max(
            1.0, np.max(np.abs(v)))


def _moving_cassie(seed):
    """``(clm, q, v)``: Cassie assembled from random actuator angles (0.1 rad), moving
    with a random closure-consistent velocity (seeded)."""
    from hexapod_pin.loaders import robots

    clm = robots.cassie()
    rng = np.random.default_rng(seed)
    dq = np.zeros(clm.nv)
    dq[clm.actuated_v] = 0.1 * rng.normal(size=clm.n_actuated)
    q = clm.assemble(pin.integrate(clm.model, pin.neutral(clm.model), dq)).q
    return clm, q, 0.5 * _consistent_state(clm, q, rng)


@pytest.mark.parametrize(("integrator", "dt"), [("rk4", 5e-4), ("rk4", 1e-3),
                                               ("semi_implicit_euler", 5e-4)])
def test_generic_step_keeps_cassies_closures(integrator, dt):
    """Cassie (four point closures, 12 rows of rank 10: the projection drops dependent
    rows), steps from a moving state: after every step the closures hold to 1e-9 in
    position and velocity, checked with ClosedLoopModel's own residual and Jacobian.
    (Semi-implicit Euler at 0.5 ms: the SDF's knee and heel springs, 1500 and 1250 N m/rad
    on light links, are part of the model's effects; at 1 ms the explicit spring step is
    unstable and the projection onto the closures fails at the fifth step.)
    (RK4 at 1 ms from this 0.8 m/s state: unprojected stage states would leave the
    closures far enough for the drift to fall outside the range of the nearly redundant
    rows, and the verified dynamics would raise; the stages are projected.)"""
    from hexapod_pin.core.simulation import ClosedLoopIntegrator

    clm, q, v = _moving_cassie(11)
    sim = ClosedLoopIntegrator(clm, integrator=integrator)
    tau = np.zeros(clm.nv)
    for _ in range(10):
        q, v, residual = sim.step(q, v, tau, dt)
        assert residual <= 1e-9
        assert np.max(np.abs(clm.residual(q))) <= 1e-9
        assert np.max(np.abs(clm.constraint_jacobian(q) @ v)) <= 1e-9 * max(
            1.0, np.max(np.abs(v)))


def test_rk4_keeps_a_falling_cassies_closures():
    """Cassie falling freely for 0.3 s at 1 ms RK4 steps (joint speeds up to ~18 rad/s):
    every step keeps the closures (position and velocity, checked with ClosedLoopModel's
    own residual and Jacobian). A stage whose dynamics are refused (drift outside the
    range of the nearly redundant rows: this fall raised SolverError at step 112 before)
    is projected to the trigger and solved again."""
    from hexapod_pin.core.simulation import ClosedLoopIntegrator

    clm, q, v = _moving_cassie(3)
    sim = ClosedLoopIntegrator(clm, integrator="rk4")
    tau = np.zeros(clm.nv)
    fastest = 0.0
    for k in range(300):
        q, v, residual = sim.step(q, v, tau, 1e-3)
        assert residual <= 1e-10
        fastest = max(fastest, np.max(np.abs(v)))
        if k % 10 == 9:
            assert np.max(np.abs(clm.residual(q))) <= 1e-9
            assert np.max(np.abs(clm.constraint_jacobian(q) @ v)) <= 1e-9 * max(
                1.0, np.max(np.abs(v)))
    assert fastest > 10.0                      # the fall did reach high joint speeds


# ------------------------------------------------------- inverse-dynamics QP, redundant u
def test_inverse_qp_on_redundant_actuation_is_the_weighted_minimum():
    """Three actuators for one degree of freedom: the QP picks ``min |u|^2 + w |lambda|^2``
    (w = 1e-2) subject to the equation of motion; reference: the weighted minimum-norm
    solution by numpy (bounds inactive), and with a bound that binds, a feasible point
    with every |u| <= bound that still satisfies the equation of motion."""
    robot = stress_robots.ladder_redundantly_actuated()
    clm = robot.clm
    rng = np.random.default_rng(9)
    sel = np.zeros((clm.nv, clm.n_actuated))
    sel[clm.actuated_v, np.arange(clm.n_actuated)] = 1.0
    for _ in range(STATES):
        q, v = robot.sample(rng)
        tau = _tau(clm, rng)
        a_ref, _ = reference_forward(clm, q, v, tau)
        mass, bias, jac, _ = reference_terms(clm, q, v)
        mat = np.hstack([sel, jac.T])
        rhs = mass @ a_ref + bias
        root_w = np.sqrt(np.concatenate([np.ones(clm.n_actuated), np.full(clm.n_rows, 1e-2)]))
        x_ref = np.linalg.pinv(mat / root_w, rcond=1e-10) @ rhs / root_w
        free = inverse_dynamics_tree(clm, q, v, a_ref, method="qp")
        assert_close(free.actuator_forces, x_ref[:clm.n_actuated], "weighted minimum u")
        bound = 0.9 * np.max(np.abs(free.actuator_forces))
        try:
            tight = inverse_dynamics_tree(clm, q, v, a_ref, method="qp", bounds=bound)
        except ActuatorSaturationError:
            continue
        assert np.max(np.abs(tight.actuator_forces)) <= bound * (1 + 1e-9)
        x = np.concatenate([tight.actuator_forces, tight.multipliers])
        assert np.max(np.abs(mat @ x - rhs)) <= 1e-9 * np.max(np.abs(rhs))
        # the kkt route cannot choose among the forces; it must not claim saturation
        kkt_u = inverse_dynamics_tree(clm, q, v, a_ref, method="kkt").actuator_forces
        if np.max(np.abs(kkt_u)) > bound:
            with pytest.raises(SolverError, match="use method='qp'"):
                inverse_dynamics_tree(clm, q, v, a_ref, method="kkt", bounds=bound)
