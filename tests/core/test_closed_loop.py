"""The generic core: closures, Jacobian, drift, rank, assembly (checked by independent routes)."""

import numpy as np
import pinocchio as pin
import pytest

import hexapod_pin as hp
from hexapod_pin.core.closed_loop import ClosedLoopModel
from hexapod_pin.hexapod.geometry import hexapod_urdf
from hexapod_pin.core.description import build_model, parse_loops
from hexapod_pin.errors import AssemblyError, DescriptionError, InputError

from conftest import fd_constraint_jacobian, random_configuration, random_pose


def _random_q(model, rng, around=None, scale=1.0):
    """A random tree configuration (closures NOT satisfied)."""
    return random_configuration(model.model, rng, around, scale)



def test_home_closures_hold(any_robot):
    q = any_robot.home_configuration
    assert np.max(np.abs(any_robot.model.residual(q))) <= 1e-12
    assert any_robot.model.n_rows == 18


def test_second_geometry_home_closures_hold():
    robot = hp.Hexapod(hp.HexapodGeometry(rail_radius=0.40, platform_radius=0.10, leg_length=0.50,
                                          carriage_home=0.18))
    assert np.max(np.abs(robot.model.residual(robot.configuration(robot.home_pose)))) <= 1e-12


def test_residual_is_leg_tip_minus_platform_point(robot):
    """At a tree configuration, the residual rows are the world gap between leg tip and anchor,
    computed here from the joint values by hand."""
    rng = np.random.default_rng(0)
    model = robot.model
    q = _random_q(model, rng)
    g = robot.geometry
    res = model.residual(q)
    idx = robot.indices
    for i in range(6):
        k = i // 2
        a, b = q[idx.u_a_q[i]], q[idx.u_b_q[i]]
        rail = pin.rpy.rpyToMatrix(0, 0, np.pi / 2 + 2 * np.pi / 3 * k + np.pi / 2)
        leg_dir = rail @ pin.rpy.rpyToMatrix(a, 0, 0) @ pin.rpy.rpyToMatrix(0, b, 0) @ [0, 0, 1]
        tip = g.rail_midpoints[k] + q[idx.carriage_q[i]] * g.rail_directions[k] + g.leg_length * leg_dir
        ff = q[idx.platform_q]
        rot = pin.Quaternion(ff[6], ff[3], ff[4], ff[5]).normalized().toRotationMatrix()
        anchor = ff[:3] + rot @ g.platform_points[k]
        np.testing.assert_allclose(res[3 * i:3 * i + 3], tip - anchor, atol=1e-14)


def test_constraint_jacobian_matches_finite_differences(robot, rng):
    for _ in range(3):
        q = _random_q(robot.model, rng)
        np.testing.assert_allclose(robot.model.constraint_jacobian(q), fd_constraint_jacobian(robot.model, q),
                                   atol=1e-8)


def _weld_model(robot, q_ref):
    """The hexapod with leg 0's tip welded to the platform at its pose in q_ref."""
    model = robot.model
    pin.framesForwardKinematics(model.model, model.data, q_ref)
    tip = model.data.oMf[model.model.getFrameId("leg_0_tip")]
    anchor = model.data.oMf[model.model.getFrameId("platform_anchor_0")]
    rel = anchor.actInv(tip)
    xyz = rel.translation.tolist()
    rpy = pin.rpy.matrixToRpy(rel.rotation).tolist()
    text = f"""closures:
  - {{name: w, type: weld, frame1: leg_0_tip, frame2: platform_anchor_0,
     offset2: {{xyz: {xyz}, rpy: {rpy}}}}}
  - {{name: p, type: point, frame1: leg_3_tip, frame2: platform_anchor_3}}
actuated: [carriage_0]
"""
    tree = build_model(hexapod_urdf(robot.geometry))
    return ClosedLoopModel(tree, parse_loops(text))


def test_weld_jacobian_and_drift_match_finite_differences(robot, rng):
    q_ref = robot.configuration(random_pose(robot, rng))
    weld = _weld_model(robot, q_ref)
    assert np.max(np.abs(weld.residual(q_ref))) < 1e-12
    np.testing.assert_allclose(weld.constraint_jacobian(q_ref), fd_constraint_jacobian(weld, q_ref), atol=1e-8)
    # away from the closure, but with the weld's relative rotation well below pi (log6 and
    # its finite differences are ill-conditioned near pi)
    q = _random_q(weld, rng, around=q_ref, scale=0.5)
    np.testing.assert_allclose(weld.constraint_jacobian(q), fd_constraint_jacobian(weld, q), atol=1e-7)
    # drift = d^2/dt^2 residual(q (+) t v) at t = 0 (zero acceleration path), at the closure
    v = rng.normal(size=weld.nv)
    h = 1e-4
    second = (weld.residual(pin.integrate(weld.model, q_ref, h * v)) - 2 * weld.residual(q_ref)
              + weld.residual(pin.integrate(weld.model, q_ref, -h * v))) / h**2
    np.testing.assert_allclose(weld.constraint_drift(q_ref, v), second, atol=2e-5)


def test_closure_linear_forces_of_points_and_welds(robot, rng):
    """The force part of each closure's spatial force (what a result's closure_forces
    holds) against a reference written here: a point closure's multipliers are its force
    (world axes); a weld's six pair with its log6 rows, its force is ``R_1 (Jlog6(M21)^T
    lambda)[:3]`` (the spatial force in anchor-1 axes rotated to the world)."""
    from hexapod_pin.core.closure_forces import closure_linear_forces

    q_ref = robot.configuration(random_pose(robot, rng))
    weld = _weld_model(robot, q_ref)
    q = _random_q(weld, rng, around=q_ref, scale=0.3)      # away from the closure: M21 != I
    lam = rng.normal(size=weld.n_rows)
    data = weld.model.createData()
    got = closure_linear_forces(weld.model, data, weld.closure_frames, q, lam)
    pin.framesForwardKinematics(weld.model, data, q)
    want = []
    for frame in weld.closure_frames:
        part = lam[frame.rows]
        if frame.is_point:
            want.append(part)
        else:
            one, two = data.oMf[frame.frame1], data.oMf[frame.frame2]
            local = pin.Jlog6(two.actInv(one)).T @ part
            want.append(one.rotation @ local[:3])
    assert [f.is_point for f in weld.closure_frames] == [False, True]
    np.testing.assert_allclose(got, np.array(want), rtol=0, atol=1e-12)
    # points only: the multipliers themselves, no kinematics (a fresh data stays unplaced)
    fresh = robot.model.model.createData()
    lam = rng.normal(size=robot.model.n_rows)
    got = closure_linear_forces(robot.model.model, fresh, robot.model.closure_frames,
                                robot.home_configuration, lam)
    np.testing.assert_array_equal(got, lam.reshape(-1, 3))


def test_point_drift_matches_second_differences(robot, rng):
    q = _random_q(robot.model, rng)
    v = rng.normal(size=robot.model.nv)
    h = 1e-4
    m = robot.model
    second = (m.residual(pin.integrate(m.model, q, h * v)) - 2 * m.residual(q)
              + m.residual(pin.integrate(m.model, q, -h * v))) / h**2
    np.testing.assert_allclose(m.constraint_drift(q, v), second, atol=2e-5)


def test_rank_and_mobility_at_home(robot):
    info = robot.model.rank(robot.home_configuration)
    assert info.rank == 18 and info.redundant_rows.size == 0
    assert robot.model.mobility(robot.home_configuration) == 6


def test_redundant_closure_rows_are_detected(robot):
    """Closing leg 1 on leg 0's tip as well as on the platform adds 3 dependent rows."""
    text = (robot.model.closures and
            "closures:\n" + "".join(
                f"  - {{name: tip_{i}, type: point, frame1: leg_{i}_tip, frame2: platform_anchor_{i}}}\n"
                for i in range(6))
            + "  - {name: extra, type: point, frame1: leg_1_tip, frame2: leg_0_tip}\n"
            + "actuated: [carriage_0, carriage_1, carriage_2, carriage_3, carriage_4, carriage_5]\n")
    model = ClosedLoopModel(build_model(hexapod_urdf(robot.geometry)), parse_loops(text))
    q = robot.home_configuration
    info = model.rank(q)
    assert info.n_rows == 21 and info.rank == 18 and info.redundant_rows.size == 3
    # the independent rows alone have full rank
    jac = model.constraint_jacobian(q)[info.independent_rows]
    assert np.linalg.matrix_rank(jac) == 18
    # assembly still converges with the redundant rows present
    q0 = q.copy()
    q0[robot.indices.u_a_q] += 0.02
    res = model.assemble(q0)
    assert res.residual_norm <= 1e-12


def test_assembly_converges_from_perturbed_starts(any_robot, rng):
    """Perturb everything but the carriages; Newton must land on the closed-form configuration."""
    robot = any_robot
    for _ in range(5):
        pose = random_pose(robot, rng)
        q_exact = robot.configuration(pose)
        q0 = pin.integrate(robot.model.model, q_exact, 0.03 * rng.normal(size=robot.model.nv)
                           * np.isin(np.arange(robot.model.nv), robot.model.passive_v))
        result = robot.model.assemble(q0)
        assert result.residual_norm <= 1e-12
        np.testing.assert_array_equal(robot.carriage_positions(result.q), robot.carriage_positions(q0))
        np.testing.assert_allclose(robot.pose_from_configuration(result.q), pose, atol=1e-10)


def test_assembly_quadratic_convergence(robot, rng):
    q0 = pin.integrate(robot.model.model, robot.home_configuration,
                       1e-3 * rng.normal(size=24) * np.isin(np.arange(24), robot.model.passive_v))
    res = robot.model.assemble(q0)
    assert res.iterations <= 5


def test_assembly_failure_raises(robot):
    q0 = robot.home_configuration.copy()
    q0[robot.indices.carriage_q[0]] = -2.0  # leg 0 cannot reach its platform point any more
    with pytest.raises(AssemblyError) as info:
        robot.model.assemble(q0, max_iter=30)
    assert info.value.residual_norm > 1e-6


def test_complete_velocity_keeps_closures(robot, rng):
    q = robot.configuration(random_pose(robot, rng))
    qdot = rng.normal(size=6)
    v = robot.model.complete_velocity(q, robot.model.actuated_v, qdot)
    assert np.max(np.abs(robot.model.constraint_jacobian(q) @ v)) < 1e-12
    # first-order check along the motion: the closures stay closed to O(h^2)
    h = 1e-6
    assert np.max(np.abs(robot.model.residual(pin.integrate(robot.model.model, q, h * v)))) < 1e-10


def test_bad_descriptions_name_the_culprit(robot):
    tree = build_model(hexapod_urdf(robot.geometry))
    cases = {
        "closures: [{name: a, type: point, frame1: nowhere, frame2: platform}]": "a",
        "closures: [{name: b, type: point, frame1: leg_0, frame2: leg_0_tip}]": "b",
        "closures: []\nactuated: [no_such_joint]": "no_such_joint",
        "closures: []\nactuated: [platform_joint]": "platform_joint",
    }
    for text, culprit in cases.items():
        with pytest.raises(DescriptionError) as info:
            ClosedLoopModel(tree, parse_loops(text))
        assert info.value.culprit == culprit


def test_world_side_closure(robot):
    """A closure to the world: holding the platform origin at a fixed point."""
    text = "closures: [{name: hold, type: point, frame1: platform, frame2: world, offset2: {xyz: [0, 0, 0.3]}}]\n"
    model = ClosedLoopModel(build_model(hexapod_urdf(robot.geometry)), parse_loops(text))
    q = model.neutral()
    np.testing.assert_allclose(model.residual(q), [0, 0, -0.3], atol=1e-15)
    assert model.assemble(q).residual_norm <= 1e-12


def test_bad_inputs_raise(robot):
    with pytest.raises(InputError):
        robot.model.residual(np.zeros(3))
    q = robot.home_configuration.copy()
    q[0] = np.nan
    with pytest.raises(InputError):
        robot.model.constraint_jacobian(q)


# ------------------------------------------- residual / Jacobian against a per-closure route
_MIXED_LOOPS = """closures:
  - {name: w, type: weld, frame1: leg_0_tip, frame2: platform_anchor_0,
     offset1: {xyz: [0.01, -0.02, 0.03], rpy: [0.1, -0.2, 0.3]},
     offset2: {xyz: [-0.02, 0.01, 0.05], rpy: [-0.3, 0.2, 0.1]}}
  - {name: p, type: point, frame1: leg_1_tip, frame2: platform_anchor_1,
     offset1: {xyz: [0.0, 0.04, -0.01]}, offset2: {xyz: [0.03, 0.0, 0.02], rpy: [0.5, 0, 0]}}
  - {name: pw, type: point, frame1: platform, frame2: world, offset2: {xyz: [0.1, 0, 0.3]}}
  - {name: ww, type: weld, frame1: world, frame2: leg_2_tip,
     offset1: {xyz: [0.2, 0.1, 0.4], rpy: [0.2, 0.1, -0.4]}}
  - {name: p3, type: point, frame1: leg_3_tip, frame2: platform_anchor_3}
actuated: [carriage_0]
"""


def _reference_residual_and_jacobian(clm, q):
    """Per-closure reference: anchor placements by ``pin.updateFramePlacements`` and
    anchor Jacobians by ``pin.getFrameJacobian``, one closure at a time (module doc's
    formulas: point ``p1 - p2`` world axes, weld ``log6(oM2^-1 oM1)`` with the Jacobian
    ``Jlog6 (J1 - Ad(M21^-1) J2)`` in LOCAL axes)."""
    model, data = clm.model, clm.model.createData()
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    res, jac = [], []
    lwa, loc = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED, pin.ReferenceFrame.LOCAL
    for closure in clm.closures:
        f1 = model.getFrameId(f"{closure.name}/anchor1")
        f2 = model.getFrameId(f"{closure.name}/anchor2")
        m1, m2 = data.oMf[f1], data.oMf[f2]
        if closure.type == "point":
            res.append(m1.translation - m2.translation)
            jac.append(pin.getFrameJacobian(model, data, f1, lwa)[:3]
                       - pin.getFrameJacobian(model, data, f2, lwa)[:3])
        else:
            m21 = m2.actInv(m1)
            res.append(pin.log6(m21).vector)
            jac.append(pin.Jlog6(m21) @ (pin.getFrameJacobian(model, data, f1, loc)
                                         - m21.inverse().action
                                         @ pin.getFrameJacobian(model, data, f2, loc)))
    return np.concatenate(res), np.vstack(jac)


def _assert_same(value, ref, what):
    """Equal to 1e-15 relative to the largest entry of the reference (rounding only)."""
    assert value.shape == ref.shape, what
    scale = max(1.0, float(np.max(np.abs(ref), initial=0.0)))
    miss = float(np.max(np.abs(value - ref), initial=0.0))
    assert miss <= 1e-15 * scale, f"{what}: {miss:.3e} off (scale {scale:.3g})"


def test_residual_and_jacobian_match_a_per_closure_reference(robot, rng):
    """Point and weld closures, offsets on both anchors, closures to the world on either
    side: residual, J_c and the fused residual_and_jacobian equal the per-closure
    reference to rounding (1e-15 relative), away from the closure and at it."""
    import stress_robots

    mixed = ClosedLoopModel(build_model(hexapod_urdf(robot.geometry)),
                            parse_loops(_MIXED_LOOPS))
    models = [mixed, stress_robots.build("delta_weld").clm,
              stress_robots.build("ladder_mixed").clm,
              stress_robots.build("planar_ladder_weld").clm]
    for clm in models:
        for trial in range(3):
            q = _random_q(clm, rng, around=clm.neutral(), scale=0.3)
            if trial == 2:
                try:
                    q = clm.assemble(q).q
                except AssemblyError:
                    continue
            res_ref, jac_ref = _reference_residual_and_jacobian(clm, q)
            _assert_same(clm.residual(q), res_ref, f"{clm.name} residual")
            _assert_same(clm.constraint_jacobian(q), jac_ref, f"{clm.name} J_c")
            res, jac = clm.residual_and_jacobian(q)
            _assert_same(res, res_ref, f"{clm.name} fused residual")
            _assert_same(jac, jac_ref, f"{clm.name} fused J_c")
            assert np.max(np.abs(res_ref)) > 1e-3 or trial == 2   # the test sees non-zero rows
