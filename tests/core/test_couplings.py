"""Joint couplings ``q1 = f(q2)`` (hexapod_pin.core.couplings) in every route of the core.

Robots: a gear pair of hinges (``q_follower = 2 q_driver``) written as a URDF and a loops
file with a ``couplings:`` section, and a four-bar carrying a pendulum whose hinge follows
the crank through a quartic (``tests/data/mjcf/coupled_fourbar.xml``; MuJoCo's form
relative to ``qpos0``, the pendulum's hinge with a ``ref``). Independent routes: a numpy
KKT solve on Pinocchio's ``M`` and ``h`` with the coupling's row and drift written here
from the polynomial (the closure's rows from Pinocchio's frame Jacobians and classical
accelerations), energy conservation, central differences, and MuJoCo's own compiled
terms (``mj_fullM``, ``qfrc_bias`` and the equality rows of ``efc_J``; the coupling's drift
from the polynomial, the connect's from ``mj_jacDot``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from conftest import null_space_kkt

import hexapod_pin as hp
from hexapod_pin.core.closed_loop import ClosedLoopModel
from hexapod_pin.core.couplings import JointCoupling
from hexapod_pin.core.description import parse_loops
from hexapod_pin.core.dynamics import forward_dynamics_tree, inverse_dynamics_tree
from hexapod_pin.core.dynamics_derivatives import forward_dynamics_derivatives_tree
from hexapod_pin.core.freeze import freeze_joints
from hexapod_pin.core.mujoco_export import closed_loop_mjcf
from hexapod_pin.core.simulate import simulate
from hexapod_pin.errors import DescriptionError, InputError

DATA = Path(__file__).resolve().parents[1] / "data" / "mjcf"
METHODS = ("pinocchio", "kkt", "qp")

GEAR_URDF = """<robot name="gears">
  <link name="base"/>
  <link name="driver"><inertial><origin xyz="0.1 0 0.02"/><mass value="1.2"/>
    <inertia ixx="0.01" iyy="0.02" izz="0.015" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="follower"><inertial><origin xyz="0.05 0 -0.03"/><mass value="0.7"/>
    <inertia ixx="0.004" iyy="0.006" izz="0.005" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="driver_joint" type="revolute"><parent link="base"/><child link="driver"/>
    <origin xyz="0 0 0.5"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="10" velocity="10"/></joint>
  <joint name="follower_joint" type="revolute"><parent link="base"/><child link="follower"/>
    <origin xyz="0.3 0 0.5"/><axis xyz="0 1 0"/>
    <limit lower="-6" upper="6" effort="10" velocity="10"/></joint>
</robot>
"""
GEAR_LOOPS = """actuated: [driver_joint]
couplings:
  - name: gear
    joint1: follower_joint
    joint2: driver_joint
    polycoef: [0, 2, 0, 0, 0]
"""


def gear_model() -> ClosedLoopModel:
    model = pin.buildModelFromXML(GEAR_URDF)
    return ClosedLoopModel(model, parse_loops(GEAR_LOOPS), name="gears")


def fourbar_model() -> ClosedLoopModel:
    pytest.importorskip("mujoco")
    return hp.load_mjcf(DATA / "coupled_fourbar.xml")


@pytest.fixture(scope="module", params=["gear", "fourbar"])
def robot(request):
    return gear_model() if request.param == "gear" else fourbar_model()


# -- the coupling by hand --------------------------------------------------------------------
def coupling_terms(clm, q, v):
    """Each coupling's residual, row and drift written from its polynomial."""
    res, rows, drift = [], [], []
    for c in clm.couplings:
        poly = np.polynomial.Polynomial(c.polycoef)
        j1 = clm.model.joints[clm.model.getJointId(c.joint1)]
        j2 = clm.model.joints[clm.model.getJointId(c.joint2)]
        x, xd = q[j2.idx_q], v[j2.idx_v]
        row = np.zeros(clm.nv)
        row[j1.idx_v] = 1.0
        row[j2.idx_v] = -poly.deriv(1)(x)
        res.append(q[j1.idx_q] - poly(x))
        rows.append(row)
        drift.append(-poly.deriv(2)(x) * xd ** 2)
    return np.array(res), np.array(rows), np.array(drift)


def hand_terms(clm, q, v):
    """(M, h, J, gamma): Pinocchio's M and h; point closures' rows from the anchors' world
    Jacobians and classical accelerations; the couplings' rows by hand."""
    model = clm.model
    data = model.createData()
    mass = pin.crba(model, data, q)
    mass = np.triu(mass) + np.triu(mass, 1).T
    bias = pin.rnea(model, data, q, v, np.zeros(clm.nv))
    pin.computeJointJacobians(model, data, q)
    pin.forwardKinematics(model, data, q, v, np.zeros(clm.nv))
    pin.updateFramePlacements(model, data)
    lwa = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
    rows, drift = [], []
    for closure in clm.closures:
        assert closure.type == "point"
        f1 = model.getFrameId(f"{closure.name}/anchor1")
        f2 = model.getFrameId(f"{closure.name}/anchor2")
        rows.append(pin.getFrameJacobian(model, data, f1, lwa)[:3]
                    - pin.getFrameJacobian(model, data, f2, lwa)[:3])
        drift.append(pin.getFrameClassicalAcceleration(model, data, f1, lwa).linear
                     - pin.getFrameClassicalAcceleration(model, data, f2, lwa).linear)
    _, crow, cdrift = coupling_terms(clm, q, v)
    jac = np.vstack(rows + [crow])
    gamma = np.concatenate(drift + [cdrift])
    return mass, bias, jac, gamma


def states(clm, n=3, seed=0):
    rng = np.random.default_rng(seed)
    q0 = clm.reference_configurations.get("qpos0", clm.neutral())
    out = []
    for _ in range(n):
        start = pin.integrate(clm.model, q0, 0.3 * rng.standard_normal(clm.nv))
        q = clm.assemble(start, fixed=np.zeros(0, dtype=int)).q
        v = project(clm, q, rng.standard_normal(clm.nv))
        out.append((q, v))
    return out


def project(clm, q, v):
    """The orthogonal projection of ``v`` on ``null(J(q))`` (J written here)."""
    _, _, jac, _ = hand_terms(clm, q, v)
    _, sv, vt = np.linalg.svd(jac)
    null = vt[int(np.sum(sv > 1e-10 * sv[0])):]
    return null.T @ (null @ v)


def close(a, b, rtol=1e-10):
    scale = max(np.abs(np.asarray(b)).max(), 1.0)
    return np.abs(np.asarray(a) - np.asarray(b)).max() <= rtol * scale


# -- description --------------------------------------------------------------------------
def test_loops_file_couplings_are_parsed_and_checked():
    clm = gear_model()
    assert clm.couplings == (JointCoupling("gear", "follower_joint", "driver_joint",
                                           (0.0, 2.0, 0.0, 0.0, 0.0)),)
    assert (clm.n_rows, clm.n_closure_rows) == (1, 0)
    model = pin.buildModelFromXML(GEAR_URDF)
    bad = GEAR_LOOPS.replace("joint2: driver_joint", "joint2: nowhere")
    with pytest.raises(DescriptionError, match="nowhere"):
        ClosedLoopModel(model, parse_loops(bad))
    with pytest.raises(DescriptionError, match="polycoef"):
        parse_loops(GEAR_LOOPS.replace("[0, 2, 0, 0, 0]", "[0, 2, 0, 0, 0, 1]"))
    with pytest.raises(DescriptionError, match="unknown keys"):
        parse_loops(GEAR_LOOPS + "    extra: 1\n")
    # without joint2, q1 = c0 (a joint held)
    held = GEAR_LOOPS.replace("    joint2: driver_joint\n", "").replace("[0, 2,", "[0.4, 2,")
    clm = ClosedLoopModel(model, parse_loops(held))
    q = clm.assemble(np.array([0.3, -0.2]), fixed=[0]).q
    assert q[1] == pytest.approx(0.4, abs=1e-12)


def test_mjcf_refs_become_absolute_coefficients():
    """MuJoCo's ``q1 - q1_0 = f(q2 - q2_0)``: the loaded polynomial, evaluated here at
    random crank angles, against MuJoCo's form from the compiled eq_data and qpos0."""
    mujoco = pytest.importorskip("mujoco")
    clm = fourbar_model()
    mj = mujoco.MjModel.from_xml_path(str(DATA / "coupled_fourbar.xml"))
    coef = mj.eq_data[1][:5]
    j1, j2 = (mj.jnt_qposadr[mj.eq_obj1id[1]], mj.jnt_qposadr[mj.eq_obj2id[1]])
    ours = np.polynomial.Polynomial(clm.couplings[0].polycoef)
    for x in np.linspace(-1.0, 1.2, 7):
        theirs = mj.qpos0[j1] + np.polynomial.Polynomial(coef)(x - mj.qpos0[j2])
        assert ours(x) == pytest.approx(theirs, abs=1e-14)


# -- kinematics ----------------------------------------------------------------------------
def test_residual_jacobian_drift_and_assembly(robot):
    clm = robot
    for q, v in states(clm):
        res, _, _ = coupling_terms(clm, q, v)
        assert np.abs(res).max() < 1e-12                       # q1 = f(q2) assembled
        assert np.abs(clm.residual(q)).max() < 1e-12
        _, _, jac, gamma = hand_terms(clm, q, v)
        assert close(clm.constraint_jacobian(q), jac, 1e-12)
        assert close(clm.constraint_drift(q, v), gamma, 1e-12)
    assert clm.mobility(q) == 1


def test_the_coupling_rows_can_fail(robot):
    """A broken coupling is seen by the residual and refused by the dynamics."""
    clm = robot
    q, v = states(clm, 1)[0]
    q_bad = q.copy()
    q_bad[clm.joint_q_index(clm.couplings[0].joint1)] += 1e-3
    assert abs(clm.residual(q_bad)[-1] - 1e-3) < 1e-12
    with pytest.raises(InputError, match="coupling"):
        forward_dynamics_tree(clm, q_bad, v, np.zeros(clm.n_actuated), method="kkt")
    v_bad = v.copy()
    v_bad[clm.joint_v_index(clm.couplings[0].joint1)] += 1e-2
    with pytest.raises(InputError):
        forward_dynamics_tree(clm, q, v_bad, np.zeros(clm.n_actuated))


# -- dynamics ------------------------------------------------------------------------------
@pytest.mark.parametrize("method", METHODS)
def test_forward_dynamics_equal_a_numpy_kkt(robot, method):
    clm = robot
    rng = np.random.default_rng(4)
    for q, v in states(clm, seed=5):
        u = rng.normal(size=clm.n_actuated)
        mass, bias, jac, gamma = hand_terms(clm, q, v)
        tau = np.zeros(clm.nv)
        tau[clm.actuated_v] = u
        expected = null_space_kkt(mass, tau - bias, jac, -gamma)
        res = forward_dynamics_tree(clm, q, v, u, method=method)
        assert close(res.a, expected, 1e-9), np.abs(res.a - expected).max()
        # the multipliers balance the equation of motion with our rows
        lam = res.multipliers
        assert close(mass @ res.a + bias, tau + jac.T @ lam, 1e-9)
    if method == "pinocchio":
        assert "coupling" in res.status


@pytest.mark.parametrize("method", ("qp", "kkt"))
def test_inverse_of_forward_gives_back_the_forces(robot, method):
    clm = robot
    rng = np.random.default_rng(6)
    for q, v in states(clm, seed=7):
        u = rng.normal(size=clm.n_actuated)
        fwd = forward_dynamics_tree(clm, q, v, u, method="kkt")
        inv = inverse_dynamics_tree(clm, q, v, fwd.a, method=method)
        assert close(inv.actuator_forces, u, 1e-9)
        _, _, jac, _ = hand_terms(clm, q, v)
        assert close(jac.T @ inv.multipliers, jac.T @ fwd.multipliers, 1e-8)


def test_simulation_keeps_the_coupling_and_the_energy(robot):
    """RK4 without damping or drive: the couplings' residual stays at the projection's
    level and the total energy is constant to 1e-6 of the kinetic energy's scale."""
    clm = robot
    q, v = states(clm, 1, seed=8)[0]
    v = 2.0 * v / np.abs(v).max()
    traj = simulate(clm, 0.3, 1e-3, integrator="rk4", initial=(q, v),
                    actuator_forces=np.zeros(clm.n_actuated))
    data = clm.model.createData()
    energy, kinetic = [], []
    for qk, vk in zip(traj.q, traj.v):
        res, _, _ = coupling_terms(clm, qk, vk)
        assert np.abs(res).max() < 1e-9
        mass = pin.crba(clm.model, data, qk)
        mass = np.triu(mass) + np.triu(mass, 1).T
        kinetic.append(0.5 * vk @ mass @ vk)
        energy.append(kinetic[-1] + pin.computePotentialEnergy(clm.model, data, qk))
    assert np.max(traj.closure_residual) < 1e-9
    drift = np.max(np.abs(np.array(energy) - energy[0]))
    assert drift < 1e-6 * max(kinetic), (drift, max(kinetic))
    # the coupling moved: the test is not trivially at rest
    assert np.ptp(traj.q[:, clm.joint_q_index(clm.couplings[0].joint2)]) > 0.05


def richardson(fun, h):
    diffs = [(fun(s) - fun(-s)) / (2 * s) for s in (h, h / 2, h / 4)]
    return (4 * diffs[2] - diffs[1]) / 3


def relative(num, ana):
    return float(np.max(np.abs(num - ana)) / max(1.0, np.max(np.abs(num))))


def test_forward_dynamics_derivatives_with_couplings(robot):
    """Against central differences along the closure manifold (the pattern of
    tests/core/test_dynamics_derivatives.py), with damping and springs too."""
    clm = robot
    q, v = states(clm, 1, seed=9)[0]
    rng = np.random.default_rng(10)
    clm = clm.with_effects(damping=rng.uniform(0.1, 0.5, clm.nv),
                           stiffness=rng.uniform(1, 5, clm.nv))
    u, tau = rng.normal(size=clm.n_actuated), 0.1 * rng.normal(size=clm.nv)
    der = forward_dynamics_derivatives_tree(clm, q, v, u, tau)

    def solve(qq, vv, uu=u, tt=tau):
        res = forward_dynamics_tree(clm, qq, vv, uu, tt, method="kkt")
        return res.a

    worst = 0.0
    for k in range(der.tangent_basis.shape[1]):
        def moved(s, d=der.tangent_basis[:, k]):
            qq = clm.assemble(pin.integrate(clm.model, q, s * d), tol=1e-14).q
            return solve(qq, project(clm, qq, v))
        worst = max(worst, relative(richardson(moved, 1e-3), der.d_q[:, k]))
    dv = rng.normal(size=clm.nv)
    num = richardson(lambda s: solve(q, project(clm, q, v + s * dv)), 1e-3)
    worst = max(worst, relative(num, der.d_v @ dv))
    num = richardson(lambda s: solve(q, v, u + s), 1.0)
    worst = max(worst, relative(num, der.d_actuator_forces[:, 0]))
    assert worst < 1e-7


# -- MuJoCo ---------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["coupled_gear.xml", "coupled_fourbar.xml"])
def test_mjcf_constrained_acceleration_equals_a_kkt_on_mujocos_terms(name):
    """A numpy KKT on MuJoCo's mj_fullM, qfrc_bias and equality rows of efc_J (hinges
    only: qvel = v); the drift of the connect from mj_jacDot, the coupling's from its
    polynomial (MuJoCo's own qacc drops it)."""
    mujoco = pytest.importorskip("mujoco")
    clm = hp.load_mjcf(DATA / name)
    mj = mujoco.MjModel.from_xml_path(str(DATA / name))
    mj.opt.jacobian = mujoco.mjtJacobian.mjJAC_DENSE
    rng = np.random.default_rng(11)
    for q, v in states(clm, seed=12):
        ctrl = rng.uniform(-1, 1, mj.nu)
        d = mujoco.MjData(mj)
        d.qpos[:], d.qvel[:], d.ctrl[:] = q, v, ctrl
        mujoco.mj_forward(mj, d)
        full = np.zeros((mj.nv, mj.nv))
        mujoco.mj_fullM(mj, d, full)
        equality = d.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY
        eq_rows = d.efc_J.reshape(d.nefc, mj.nv)[equality]
        jac, drift = [], []
        for i in range(mj.neq):
            if mj.eq_type[i] == mujoco.mjtEq.mjEQ_CONNECT:
                b1, b2 = mj.eq_obj1id[i], mj.eq_obj2id[i]
                p1 = d.xpos[b1] + d.xmat[b1].reshape(3, 3) @ mj.eq_data[i][0:3]
                p2 = d.xpos[b2] + d.xmat[b2].reshape(3, 3) @ mj.eq_data[i][3:6]
                blocks = []
                for fn in (mujoco.mj_jac, mujoco.mj_jacDot):
                    parts = []
                    for p, b in ((p1, b1), (p2, b2)):
                        jp, jr = np.zeros((3, mj.nv)), np.zeros((3, mj.nv))
                        fn(mj, d, jp, jr, np.array(p), int(b))
                        parts.append(jp)
                    blocks.append(parts[0] - parts[1])
                jac.append(blocks[0])
                drift.append(blocks[1] @ d.qvel)
            else:
                a1, a2 = mj.jnt_qposadr[mj.eq_obj1id[i]], mj.jnt_qposadr[mj.eq_obj2id[i]]
                poly = np.polynomial.Polynomial(mj.eq_data[i][:5])
                x = d.qpos[a2] - mj.qpos0[a2]
                row = np.zeros(mj.nv)
                row[a1], row[a2] = 1.0, -poly.deriv(1)(x)
                jac.append(row[None])
                drift.append(np.array([-poly.deriv(2)(x) * d.qvel[a2] ** 2]))
                # MuJoCo's own coupling row is this one
                assert any(np.abs(r - row).max() < 1e-12 for r in eq_rows)
        jac, drift = np.vstack(jac), np.concatenate(drift)
        force = d.qfrc_passive + d.qfrc_actuator - d.qfrc_bias
        qacc = null_space_kkt(full, force, jac, -drift)
        u = d.actuator_force * mj.actuator_gear[:, 0]
        for method in METHODS:
            a = forward_dynamics_tree(clm, q, v, u, method=method).a
            assert close(a, qacc, 1e-10), (method, np.abs(a - qacc).max())


def test_export_round_trip_keeps_the_couplings(tmp_path):
    mujoco = pytest.importorskip("mujoco")
    for clm in (gear_model(), fourbar_model()):
        path = tmp_path / f"{clm.name}.xml"
        path.write_text(closed_loop_mjcf(clm))
        mj = mujoco.MjModel.from_xml_path(str(path))
        assert int(np.sum(mj.eq_type == mujoco.mjtEq.mjEQ_JOINT)) == len(clm.couplings)
        back = hp.load_mjcf(path)
        assert [c.name for c in back.couplings] == [c.name for c in clm.couplings]
        for c1, c2 in zip(back.couplings, clm.couplings):
            assert (c1.joint1, c1.joint2) == (c2.joint1, c2.joint2)
            np.testing.assert_allclose(c1.polycoef, c2.polycoef, rtol=0, atol=1e-15)
        for q, v in states(clm, 2, seed=13):
            assert close(back.residual(q), clm.residual(q), 1e-12)
            assert close(back.constraint_jacobian(q), clm.constraint_jacobian(q), 1e-12)


def test_mjcf_coupling_of_a_ball_joint_is_refused_by_name(tmp_path):
    pytest.importorskip("mujoco")
    path = tmp_path / "ball.xml"
    path.write_text("""<mujoco><worldbody>
      <body name="a"><joint name="hinge" axis="0 1 0"/><geom size="0.1" mass="1"/></body>
      <body name="b" pos="1 0 0"><joint name="ball" type="ball"/><geom size="0.1" mass="1"/></body>
    </worldbody><equality><joint name="bad" joint1="ball" joint2="hinge"/></equality>
    </mujoco>""")
    # MuJoCo's compiler refuses it already (hinge and slide only), naming the equality
    with pytest.raises(DescriptionError, match="(?s)HINGE and SLIDE.*'bad'"):
        hp.load_mjcf(path)


def test_freezing_keeps_the_couplings_and_refuses_a_frozen_coupled_joint():
    clm = fourbar_model()
    q = states(clm, 1, seed=14)[0][0]
    frozen = freeze_joints(clm, ["rocker_joint"], q)
    assert frozen.model.couplings == clm.couplings
    assert frozen.model.n_rows == clm.n_rows
    with pytest.raises(DescriptionError, match="crank_joint"):
        freeze_joints(clm, ["crank_joint"], q)
