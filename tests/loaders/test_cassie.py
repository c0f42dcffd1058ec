"""Cassie (example-robot-data's cassie_v2.sdf, read by hexapod_pin.loaders.sdf), hanging from a fixed pelvis.

Independent routes: link poses read here from the SDF text with ElementTree and numpy,
finite differences, a hand-reduced constraint set (the redundant plantar-loop row of each
leg projected out by hand, then a plain numpy KKT solve with the SDF's damping and springs
written here), and FD(ID) round trips. The SDF's springs are part of the model's effects:
every route applies them, no test adds them to ``tau``.
"""

import xml.etree.ElementTree as ET

import numpy as np
import pinocchio as pin
import pytest
import scipy.linalg
from test_sdf import homogeneous

from hexapod_pin.loaders import robots
from conftest import forward_dynamics_full_tau

from hexapod_pin.core.dynamics import inverse_dynamics_tree
from hexapod_pin.loaders.sdf import load_sdf

SPRINGS = ("left-knee-shin-joint", "left-tarsus-spring-joint", "right-knee-shin-joint",
           "right-tarsus-spring-joint")
LOOPS = {"left-pitch-rod-joint", "right-pitch-rod-joint", "left-plantar-foot-joint",
         "right-plantar-foot-joint"}


@pytest.fixture(scope="module")
def cassie():
    return robots.cassie()


@pytest.fixture(scope="module")
def assembled(cassie):
    """A closed configuration away from the SDF's zero pose (actuated joints moved)."""
    rng = np.random.default_rng(7)
    dq = np.zeros(cassie.nv)
    dq[cassie.actuated_v] = 0.1 * rng.normal(size=cassie.n_actuated)
    result = cassie.assemble(pin.integrate(cassie.model, pin.neutral(cassie.model), dq))
    return result.q


def test_tree_and_closures(cassie):
    model = cassie.model
    assert model.check(model.createData())
    assert (model.nq, model.nv, cassie.n_rows) == (22, 22, 12)
    assert {c.name for c in cassie.closures} == LOOPS
    assert all(c.type == "point" for c in cassie.closures)
    assert set(cassie.actuated_joints) == set(robots.CASSIE_ACTUATED)
    # depth-first: the 11 joints of each leg are contiguous
    names = list(model.names)[1:]
    assert all(n.startswith("left") for n in names[:11])
    assert all(n.startswith("right") for n in names[11:])
    root = ET.parse(robots.cassie_sdf_path()).getroot()
    sdf_mass = sum(float(m.text) for m in root.iter("mass"))
    assert sum(model.inertias[j].mass for j in range(model.njoints)) == pytest.approx(sdf_mass)
    assert model.inertias[0].mass == pytest.approx(10.33)  # the fixed pelvis, on the universe


def test_link_poses_match_the_sdf_text():
    """At q = 0 every link frame is where the SDF file says (numbers read here)."""
    path = robots.cassie_sdf_path()
    root = ET.parse(path).getroot()
    model = robots.cassie(snap_angles=0.0).model
    data = model.createData()
    pin.framesForwardKinematics(model, data, pin.neutral(model))
    links = root.find("model").findall("link")
    assert len(links) == 23
    for link in links:
        pose = [float(x) for x in link.find("pose").text.split()]
        fid = model.getFrameId(link.get("name"), pin.FrameType.BODY)
        np.testing.assert_allclose(data.oMf[fid].homogeneous, homogeneous(*pose), atol=1e-12)


def test_closures_hold_after_assembly(cassie, assembled):
    assert np.max(np.abs(cassie.residual(assembled))) <= 1e-10
    moved = pin.difference(cassie.model, pin.neutral(cassie.model), assembled)
    assert np.max(np.abs(moved[cassie.passive_v])) > 1e-2  # the passive joints did move
    # from perturbed passive joints, the actuated joints held
    rng = np.random.default_rng(8)
    dq = np.zeros(cassie.nv)
    dq[cassie.passive_v] = 0.03 * rng.normal(size=cassie.passive_v.size)
    start = pin.integrate(cassie.model, assembled, dq)
    result = cassie.assemble(start)
    assert result.residual_norm <= 1e-10
    np.testing.assert_array_equal(result.q[cassie.actuated_v], start[cassie.actuated_v])


def test_constraint_jacobian_matches_finite_differences(cassie):
    rng = np.random.default_rng(9)
    q = pin.neutral(cassie.model) + 0.2 * rng.normal(size=cassie.nq)
    h = 1e-6
    fd = np.array([(cassie.residual(q + h * e) - cassie.residual(q - h * e)) / (2 * h)
                   for e in np.eye(cassie.nv)]).T
    np.testing.assert_allclose(cassie.constraint_jacobian(q), fd, atol=1e-8)


def test_rank_and_actuation(cassie, assembled):
    report = robots.actuation_report(cassie, assembled)
    assert (report.nv, report.n_rows, report.rank, report.redundant_rows) == (22, 12, 10, 2)
    assert report.mobility == 12 and report.n_actuated == 10
    assert report.status == "under-actuated" and report.unactuated_mobility == 2
    # the redundant rows: one per planar plantar-rod loop
    jac = cassie.constraint_jacobian(assembled)
    sv = np.linalg.svd(jac, compute_uv=False)
    assert sv[-1] < 1e-13 and sv[-2] < 1e-13 and sv[-3] > 1e-4
    assert cassie.rank(assembled, tol=1e-9 * sv[0]).rank == 10
    for closure, rows in zip(cassie.closures, cassie.row_slices):
        expected = 2 if "plantar" in closure.name else 3
        assert np.linalg.matrix_rank(jac[rows], tol=1e-9) == expected
    # the springs are the unactuated motion: locking them as well leaves nothing free
    sel = np.zeros((cassie.n_actuated + 4, cassie.nv))
    cols = list(cassie.actuated_v) + [cassie.joint_v_index(s) for s in SPRINGS]
    sel[np.arange(len(cols)), cols] = 1.0
    assert np.linalg.matrix_rank(np.vstack([jac, sel]), tol=1e-9) == cassie.nv


def test_sdf_numbers_as_written_leave_a_nearly_redundant_row():
    """Without snapping 1.5708 to pi/2, the right plantar loop is planar only to ~1e-7 rad."""
    raw = robots.cassie(snap_angles=0.0)
    q = pin.neutral(raw.model)
    sv = np.linalg.svd(raw.constraint_jacobian(q), compute_uv=False)
    assert sv[-1] < 1e-14 and 1e-13 < sv[-2] < 1e-10
    assert robots.actuation_report(raw, q).rank == 10
    assert raw.rank(q).rank == 10  # the default relative tolerance (1e-10) calls it redundant
    eps_tol = max(raw.constraint_jacobian(q).shape) * np.finfo(float).eps * sv[0]
    assert raw.rank(q, tol=eps_tol).rank == 11  # at machine precision it is not


def _plane_projector(cassie, q, closure_name):
    """2 x 3 basis of the plane of a plantar loop (normal: the crank joint's world axis)."""
    side = closure_name.split("-")[0]
    model, data = cassie.model, cassie.model.createData()
    jid = model.getJointId(f"{side}-tarsus-crank-joint")
    pin.computeJointJacobians(model, data, q)
    axis = pin.getJointJacobian(model, data, jid, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)[
        3:, model.joints[jid].idx_v]
    basis = scipy.linalg.null_space(axis[None, :])
    return basis.T


def _hand_reduced(cassie, q, v):
    """J and gamma with each plantar closure's out-of-plane row removed by hand."""
    jac = cassie.constraint_jacobian(q)
    gamma = cassie.constraint_drift(q, v)
    rows_j, rows_g = [], []
    for closure, rows in zip(cassie.closures, cassie.row_slices):
        proj = _plane_projector(cassie, q, closure.name) if "plantar" in closure.name \
            else np.eye(3)
        rows_j.append(proj @ jac[rows])
        rows_g.append(proj @ gamma[rows])
    return np.vstack(rows_j), np.concatenate(rows_g)


def _sdf_dynamics(cassie):
    """(damping (nv,), [(idx_q, idx_v, stiffness, reference)]) read here from the SDF text."""
    damping, springs = np.zeros(cassie.nv), []
    for joint in ET.parse(robots.cassie_sdf_path()).getroot().find("model").iter("joint"):
        dyn = joint.find("axis/dynamics")
        if dyn is None or not cassie.model.existJointName(joint.get("name")):
            continue
        jmodel = cassie.model.joints[cassie.model.getJointId(joint.get("name"))]
        damping[jmodel.idx_v:jmodel.idx_v + jmodel.nv] = float(dyn.findtext("damping", "0"))
        k = float(dyn.findtext("spring_stiffness", "0"))
        if k:
            springs.append((jmodel.idx_q, jmodel.idx_v, k,
                            float(dyn.findtext("spring_reference", "0"))))
    return damping, springs


def _sdf_spring_forces(cassie, q):
    """``-k (q_j - q_ref)`` of the SDF's springs (nv,), N m."""
    tau = np.zeros(cassie.nv)
    for iq, iv, k, ref in _sdf_dynamics(cassie)[1]:
        tau[iv] = -k * (q[iq] - ref)
    return tau


def _kkt_forward(cassie, q, v, tau, jac, gamma):
    model, data = pin.Model(cassie.tree_model), cassie.tree_model.createData()
    mass = pin.crba(model, data, q)
    mass = np.triu(mass) + np.triu(mass, 1).T
    # the joint damping of the SDF acts as -D v, its springs as -k (q - q_ref)
    bias = pin.rnea(model, data, q, v, np.zeros(cassie.nv)) + _sdf_dynamics(cassie)[0] * v \
        - _sdf_spring_forces(cassie, q)
    n, m = cassie.nv, jac.shape[0]
    kkt = np.block([[mass, -jac.T], [jac, np.zeros((m, m))]])
    sol = np.linalg.solve(kkt, np.concatenate([tau - bias, -gamma]))
    return sol[:n], sol[n:]


def _state(cassie, q, seed, v_scale=0.1):
    rng = np.random.default_rng(seed)
    null = scipy.linalg.null_space(cassie.constraint_jacobian(q), rcond=1e-9)
    return v_scale * null @ rng.normal(size=null.shape[1]), rng


def test_redundant_rows_give_the_answer_of_the_hand_reduced_system(cassie, assembled):
    q = assembled
    v, rng = _state(cassie, q, 10)
    assert np.abs(_sdf_spring_forces(cassie, q)).max() > 1.0      # the springs are loaded
    tau = np.zeros(cassie.nv)
    tau[cassie.actuated_v] = 0.5 * rng.normal(size=cassie.n_actuated)
    jac_r, gamma_r = _hand_reduced(cassie, q, v)
    assert np.linalg.matrix_rank(jac_r) == 10 == jac_r.shape[0]
    a_ref, lam_r = _kkt_forward(cassie, q, v, tau, jac_r, gamma_r)
    result = forward_dynamics_full_tau(cassie, q, v, tau, method="kkt")
    assert np.all(np.isfinite(result.a)) and np.all(np.isfinite(result.multipliers))
    np.testing.assert_allclose(result.a, a_ref, atol=1e-8 * max(1.0, np.abs(a_ref).max()))
    # same generalised closure force, J^T lambda, although the multipliers differ
    jac = cassie.constraint_jacobian(q)
    np.testing.assert_allclose(jac.T @ result.multipliers, jac_r.T @ lam_r, atol=1e-7)
    # the "pinocchio" route returns the same acceleration (directly or by its fallback)
    pin_route = forward_dynamics_full_tau(cassie, q, v, tau, method="pinocchio")
    np.testing.assert_allclose(pin_route.a, a_ref, atol=1e-8 * max(1.0, np.abs(a_ref).max()))
    # and the ProxSuite Gauss-principle QP (tolerance scaled with the problem's magnitude)
    qp_route = forward_dynamics_full_tau(cassie, q, v, tau, method="qp")
    np.testing.assert_allclose(qp_route.a, a_ref, atol=1e-8 * max(1.0, np.abs(a_ref).max()))
    # inverse dynamics on both: the actuator torques of the reduced system
    for method in ("qp", "kkt"):
        inv = inverse_dynamics_tree(cassie, q, v, a_ref, method=method)
        np.testing.assert_allclose(inv.actuator_forces, tau[cassie.actuated_v], atol=1e-8)


def test_forward_inverse_round_trip(cassie, assembled):
    """Under-actuated: a motion the robot can make is FD's answer; ID(FD(u)) = u, and FD of
    those torques reproduces the acceleration."""
    q = assembled
    for seed in (11, 12):
        v, rng = _state(cassie, q, seed)
        u0 = 0.5 * rng.normal(size=cassie.n_actuated)
        tau = np.zeros(cassie.nv)
        tau[cassie.actuated_v] = u0
        a = forward_dynamics_full_tau(cassie, q, v, tau, method="kkt").a
        assert np.max(np.abs(cassie.constraint_jacobian(q) @ a + cassie.constraint_drift(q, v))) \
            < 1e-8
        inv = inverse_dynamics_tree(cassie, q, v, a, method="kkt")
        np.testing.assert_allclose(inv.actuator_forces, u0, atol=1e-9)
        a_qp = forward_dynamics_full_tau(cassie, q, v, tau, method="qp").a
        np.testing.assert_allclose(a_qp, a, atol=1e-8 * max(1.0, np.abs(a).max()))
        inv_qp = inverse_dynamics_tree(cassie, q, v, a, method="qp")
        np.testing.assert_allclose(inv_qp.actuator_forces, u0, atol=1e-7)
        tau2 = np.zeros(cassie.nv)
        tau2[cassie.actuated_v] = inv.actuator_forces
        a2 = forward_dynamics_full_tau(cassie, q, v, tau2, method="kkt").a
        np.testing.assert_allclose(a2, a, atol=1e-8 * max(1.0, np.abs(a).max()))


def test_spring_torques_follow_the_sdf(cassie, assembled):
    """The model's effects hold the SDF's springs and damping (read here with ElementTree);
    cassie_spring_torques is what the springs of the effects give."""
    tau = robots.cassie_spring_torques(cassie, assembled)
    np.testing.assert_allclose(tau, _sdf_spring_forces(cassie, assembled), rtol=1e-14)
    stiff = {j.name: j.spring_stiffness for j in load_sdf(robots.cassie_sdf_path()).joints}
    for name in SPRINGS:
        idx = cassie.joint_v_index(name)
        assert tau[idx] == pytest.approx(-stiff[name] * assembled[cassie.joint_q_index(name)])
        assert cassie.effects.stiffness[idx] == stiff[name] > 1000.0
    others = np.setdiff1d(np.arange(cassie.nv), [cassie.joint_v_index(n) for n in SPRINGS])
    assert np.all(tau[others] == 0.0) and np.all(cassie.effects.stiffness[others] == 0.0)
    np.testing.assert_array_equal(cassie.effects.damping, _sdf_dynamics(cassie)[0])
    np.testing.assert_array_equal(cassie.effects.spring_reference, pin.neutral(cassie.model))


def test_free_flyer_variant(cassie):
    free = robots.cassie(root="free_flyer")
    assert (free.nq, free.nv, free.n_rows) == (29, 28, 12)
    q = pin.neutral(free.model)
    assert np.max(np.abs(free.residual(q))) < 1e-14
    report = robots.actuation_report(free, q)
    assert report.mobility == 18 and report.unactuated_mobility == 8  # 6 base + 2 springs


def test_example_runs(capsys):
    import runpy
    from pathlib import Path

    runpy.run_path(str(Path(__file__).resolve().parents[2] / "examples" / "cassie_leg.py"),
                   run_name="__main__")
    out = capsys.readouterr().out
    assert "inverse dynamics recovers the motor torques" in out


def test_urdf_route_is_the_same_mechanism(cassie):
    """SDF -> URDF text -> Pinocchio's own URDF parser: same joints, dynamics, closures."""
    via = robots.cassie(via_urdf=True)
    assert sorted(via.model.names) == sorted(cassie.model.names)
    assert via.model.check(via.model.createData())
    assert [c.name for c in via.closures] == [c.name for c in cassie.closures]
    # Pinocchio's URDF parser orders sibling subtrees its own way: map by joint name
    perm = np.array([via.joint_q_index(n) for n in list(cassie.model.names)[1:]])
    rng = np.random.default_rng(13)
    d1, d2 = cassie.model.createData(), via.model.createData()
    for _ in range(2):
        q = rng.uniform(-0.5, 0.5, cassie.nq)
        v = rng.normal(size=cassie.nv)
        qv, vv = np.empty(22), np.empty(22)
        qv[perm], vv[perm] = q, v
        np.testing.assert_allclose(via.residual(qv), cassie.residual(q), atol=1e-12)
        np.testing.assert_allclose(via.constraint_jacobian(qv)[:, perm],
                                   cassie.constraint_jacobian(q), atol=1e-12)
        np.testing.assert_allclose(pin.rnea(via.model, d2, qv, vv, vv)[perm],
                                   pin.rnea(cassie.model, d1, q, v, v), atol=1e-10)
    # same effects: the URDF's <dynamics> carry the damping, the loops the springs
    perm_v = np.array([via.joint_v_index(n) for n in list(cassie.model.names)[1:]])
    for field in ("armature", "damping", "coulomb", "stiffness"):
        np.testing.assert_array_equal(getattr(via.effects, field)[perm_v],
                                      getattr(cassie.effects, field))
    urdf, _ = robots.cassie_urdf()
    assert urdf.count("<visual") == 23 and "np.float64" not in urdf
    geom = pin.buildGeomFromUrdfString(via.model, urdf, pin.GeometryType.VISUAL)
    assert len(geom.geometryObjects) == 23               # the STL meshes were found
