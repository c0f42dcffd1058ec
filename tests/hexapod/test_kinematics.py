"""Hexapod kinematics: IK / FK, Jacobian and its derivative, qddot, leg motion, singularities,
batch forms and errors, each checked against an independent route (finite differences built
with proper rotation perturbations, a second algorithm, or the reference states)."""

import numpy as np
import pinocchio as pin
import pytest

import hexapod_pin as hp
from hexapod_pin.hexapod import assembly_modes as am
from hexapod_pin.hexapod.kinematics import TYPE_I_TOL

from conftest import geometry_from_reference, load_reference, random_pose

# a type-II singular pose of the default geometry (found by minimising the smallest singular
# value of the normalised closure Jacobian with Nelder-Mead from random starts; it is regular
# for type I: every leg at least 0.05 in cosine from perpendicular to its rail)
TYPE_II_POSE = np.array([-0.020475341567368716, -0.013968434364764802, 0.31024850589967956,
                         0.2754338045906446, -0.7399207239621679, -0.13470940466330802])


def moved(pose, twist, t, accel=(0.0, 0.0, 0.0), beta=0.0):
    """Pose at time t of a motion with x(t) = x0 + v t + a t^2/2 and R(t) = exp(s(t) [w]) R0,
    s(t) = t + beta t^2/2: a fixed world axis, so the angular velocity is exactly w s'(t) and
    the twist at t = 0 is (v, w), its derivative (a, beta w). Rotations via Pinocchio."""
    pose = np.asarray(pose, float)
    twist = np.asarray(twist, float)
    pos = pose[:3] + twist[:3] * t + 0.5 * np.asarray(accel) * t * t
    s = t + 0.5 * beta * t * t
    rot = pin.exp3(twist[3:] * s) @ pin.rpy.rpyToMatrix(*pose[3:])
    return np.concatenate([pos, pin.rpy.matrixToRpy(rot)])


def regular_pose(robot, rng):
    """A random reachable pose at least 0.15 in cosine from type I and 0.1 from type II, so
    that IK is analytic well beyond the finite-difference steps (near a type-I singularity
    q(pose) has a square-root branch point and differences of step h are meaningless)."""
    for _ in range(200):
        pose = random_pose(robot, rng)
        measures = robot.singularity(pose)
        if measures.type_one > 0.15 and measures.type_two > 0.1:
            return pose
    raise RuntimeError("no regular pose found")


def derivative(f, h):
    """First derivative at 0 of f(t): central differences with one Richardson step (O(h^4))."""
    d = lambda s: (f(s) - f(-s)) / (2 * s)
    return (4 * d(h / 2) - d(h)) / 3


def second_derivative(f, h):
    """Second derivative at 0 of f(t): second differences with one Richardson step (O(h^4))."""
    f0 = f(0.0)
    d = lambda s: (f(s) - 2 * f0 + f(-s)) / (s * s)
    return (4 * d(h / 2) - d(h)) / 3


# -- reference states and conventions -------------------------------------------------------------
def test_reference_states_velocity_and_acceleration():
    for entry in load_reference()["hexapod"]:
        robot = hp.Hexapod(geometry_from_reference(entry))
        pose, twist, twist_dot = (np.array(entry[k]) for k in ("pose", "twist", "twist_dot"))
        np.testing.assert_allclose(robot.jacobian(pose), entry["jacobian"], rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(robot.qddot(pose, twist, twist_dot), entry["qddot"],
                                   rtol=1e-9, atol=1e-12)
        motion = robot.leg_motion(pose, twist, twist_dot)
        np.testing.assert_allclose(motion.qdot, entry["qdot"], rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(motion.qddot, entry["qddot"], rtol=1e-9, atol=1e-12)
        if np.any(twist):
            np.testing.assert_allclose(robot.twist_from_qdot(pose, entry["qdot"]), twist,
                                       rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(robot.forward_kinematics(entry["q"]), pose, atol=1e-12)


# -- inverse / forward kinematics -----------------------------------------------------------------
def test_forward_of_inverse_is_identity(any_robot, rng):
    for _ in range(25):
        pose = random_pose(any_robot, rng)
        q = any_robot.inverse_kinematics(pose)
        np.testing.assert_allclose(any_robot.forward_kinematics(q), pose, atol=1e-12)
        guess = pose + rng.normal(scale=1e-3, size=6)
        np.testing.assert_allclose(any_robot.forward_kinematics(q, guess), pose, atol=1e-12)


def test_forward_kinematics_closes_the_pinocchio_tree(any_robot, rng):
    """The FK pose closes the 18 closure equations of the URDF tree (an independent model)."""
    q = any_robot.inverse_kinematics(random_pose(any_robot, rng))
    pose = any_robot.forward_kinematics(q)
    tree_q = any_robot.configuration(pose)
    assert np.max(np.abs(any_robot.model.residual(tree_q))) <= 1e-12
    np.testing.assert_allclose(any_robot.carriage_positions(tree_q), q, atol=1e-12)


def test_forward_kinematics_converges_quadratically(robot, rng):
    """Side errors of successive Newton iterates: e_{k+1} <= C e_k^2 (read off by capping
    the iterations with tol = 0, which makes the solver report its last error)."""
    pose = random_pose(robot, rng)
    q = robot.inverse_kinematics(pose)
    system = am.circle_system(robot.kinematics.circles, q)
    start = system.angles_of(robot.platform_points_world(pose + np.r_[0.01, -0.01, 0.01,
                                                                      0.05, 0.03, -0.04]))
    errors = []
    for n in range(1, 9):
        with pytest.raises(hp.AssemblyError) as info:
            am.newton_circles(system, start, max_iter=n, tol=0.0)
        errors.append(info.value.residual_norm)
        if errors[-1] < 1e-13:
            break
    assert errors[-1] < 1e-13 and 3 <= len(errors) <= 6, errors
    # e_{k+1} / e_k^2 stays bounded (while e_{k+1} is above the rounding floor ~1e-16)
    ratios = [errors[k + 1] / errors[k] ** 2 for k in range(len(errors) - 1)
              if errors[k + 1] > 1e-14]
    assert len(ratios) >= 2 and max(ratios) < 1e3, (errors, ratios)


def test_forward_kinematics_follows_the_guess_to_another_mode(robot):
    modes = robot.assembly_modes(robot.home_q)
    for mode in modes:
        np.testing.assert_allclose(robot.forward_kinematics(robot.home_q, mode + 1e-3), mode,
                                   atol=1e-12)


def test_forward_kinematics_errors(robot):
    g = robot.geometry
    with pytest.raises(hp.AssemblyError, match="2 leg_length"):
        robot.forward_kinematics([-g.leg_length - 0.01, g.leg_length + 0.01, -0.1, 0.1, -0.1, 0.1])
    with pytest.raises(hp.AssemblyError, match="coincide"):
        robot.forward_kinematics([0.05, 0.05, -0.1, 0.1, -0.1, 0.1])
    with pytest.raises(hp.InputError):
        robot.forward_kinematics([0.0] * 5)
    with pytest.raises(hp.InputError):
        robot.forward_kinematics([np.nan, 0.1, -0.1, 0.1, -0.1, 0.1])
    with pytest.raises(hp.InputError):
        robot.forward_kinematics(robot.home_q, guess=[0.0, 0.0, np.inf, 0.0, 0.0, 0.0])
    with pytest.raises(hp.InputError):
        robot.forward_kinematics(robot.home_q, guess=[0.0, 0.0, 0.3])


def test_forward_kinematics_at_type_two_singularity_never_returns_a_wrong_pose(robot,
                                                                              monkeypatch):
    """At a type-II singularity Newton's convergence is no longer quadratic: with few
    iterations FK raises instead of returning the unconverged iterate; whatever it
    returns closes the loops."""
    assert robot.singularity(TYPE_II_POSE).type_two < 1e-6
    q = robot.inverse_kinematics(TYPE_II_POSE, check_limits=False)
    guess = TYPE_II_POSE + np.r_[2e-3, -2e-3, 1e-3, 1e-2, -1e-2, 1e-2]
    with monkeypatch.context() as patch:
        patch.setattr(hp.hexapod.kinematics, "FK_MAX_ITER", 4)
        with pytest.raises(hp.AssemblyError):
            robot.forward_kinematics(q, guess)
        regular = random_pose(robot, np.random.default_rng(3))
        robot.forward_kinematics(robot.inverse_kinematics(regular),
                                 regular + np.r_[2e-3, -2e-3, 1e-3, 1e-2, -1e-2, 1e-2])
    for guess in (TYPE_II_POSE + 1e-3, TYPE_II_POSE - 1e-3, robot.home_pose):
        try:
            pose = robot.forward_kinematics(q, guess)
        except hp.AssemblyError:
            continue
        tree_q = robot.configuration(pose, branch=robot.branch_of(pose, q))
        assert np.max(np.abs(robot.model.residual(tree_q))) <= 1e-12


def test_inverse_kinematics_branches(robot, rng):
    pose = random_pose(robot, rng)
    home = robot.inverse_kinematics(pose)
    flipped = np.array([1.0, -1.0, -1.0, 1.0, -1.0, 1.0])
    q = robot.inverse_kinematics(pose, branch=flipped, check_limits=False)
    np.testing.assert_allclose(q[2:], home[2:], atol=0)
    # both roots put the carriage at leg_length from the platform point
    tips = robot.platform_points_world(pose)
    g = robot.geometry
    for qq in (home, q):
        for i in range(6):
            c = g.rail_midpoints[i // 2] + qq[i] * g.rail_directions[i // 2]
            assert np.linalg.norm(tips[i // 2] - c) == pytest.approx(g.leg_length, abs=1e-14)
    np.testing.assert_array_equal(robot.branch_of(pose, q), flipped)


# -- errors ---------------------------------------------------------------------------------------
def test_unreachable_pose_names_the_carriages(robot):
    pose = robot.home_pose + np.r_[0.0, 0.0, 0.2, 0.0, 0.0, 0.0]
    with pytest.raises(hp.UnreachablePoseError) as info:
        robot.inverse_kinematics(pose)
    assert info.value.carriages == [0, 1, 2, 3, 4, 5]
    g = robot.geometry
    expected = np.hypot(g.rail_radius - g.platform_radius, pose[2]) - g.leg_length
    np.testing.assert_allclose(info.value.shortfall, expected, rtol=1e-12)
    for call in (robot.jacobian, robot.singularity, lambda p: robot.qddot(p, np.zeros(6),
                                                                           np.zeros(6))):
        with pytest.raises(hp.UnreachablePoseError):
            call(pose)


def test_stroke_limit_and_crossing_carriages(robot):
    pose = robot.home_pose + np.r_[0.0, 0.0, -0.25, 0.0, 0.0, 0.0]   # low: carriages far out
    q = robot.inverse_kinematics(pose, check_limits=False)
    assert np.max(np.abs(q)) > robot.geometry.rail_half_length
    with pytest.raises(hp.StrokeLimitError, match="rail_half_length") as info:
        robot.inverse_kinematics(pose)
    np.testing.assert_array_equal(info.value.q, q)
    crossed = np.array([1.0, -1.0, -1.0, 1.0, -1.0, 1.0])
    with pytest.raises(hp.StrokeLimitError, match="cross"):
        robot.inverse_kinematics(robot.home_pose, branch=crossed)
    high = robot.home_pose.copy()
    high[2] = np.sqrt(robot.geometry.home_height_squared + robot.geometry.carriage_home ** 2
                      - 0.005 ** 2)                                   # gap 0.01 < 0.02
    with pytest.raises(hp.StrokeLimitError, match="too close"):
        robot.inverse_kinematics(high)


@pytest.mark.parametrize("bad", [np.zeros(5), np.zeros((6, 1)), [0, 0, np.nan, 0, 0, 0],
                                 [0, 0, 0.3, np.inf, 0, 0], "pose", None])
def test_bad_pose_input(robot, bad):
    for call in (robot.inverse_kinematics, robot.jacobian, robot.singularity,
                 lambda p: robot.jacobian_derivative(p, np.zeros(6)),
                 lambda p: robot.leg_motion(p, np.zeros(6))):
        with pytest.raises(hp.InputError):
            call(bad)


def test_bad_twist_and_branch_input(robot):
    pose = robot.home_pose
    with pytest.raises(hp.InputError):
        robot.jacobian_derivative(pose, np.zeros(5))
    with pytest.raises(hp.InputError):
        robot.qddot(pose, np.zeros(6), [0, 0, 0, 0, 0, np.nan])
    with pytest.raises(hp.InputError):
        robot.leg_motion(pose, np.zeros(6), np.zeros(7))
    with pytest.raises(hp.InputError):
        robot.twist_from_qdot(pose, np.zeros(3))
    for branch in ([1, 1, 1], [1, 0, 1, 1, 1, 1], [2, -1, 1, -1, 1, -1], "abcdef"):
        with pytest.raises(hp.InputError):
            robot.inverse_kinematics(pose, branch=branch)
        with pytest.raises(hp.InputError):
            robot.inverse_kinematics_batch(pose[None], branch=branch)


def test_type_one_singularity_raises_instead_of_inf(robot):
    """All six legs perpendicular to their rails: platform raised until each carriage pair
    meets; cosine 5e-8 (below TYPE_I_TOL but above the rounding noise of the quadratic)."""
    g = robot.geometry
    cosine = 5e-8
    z = np.sqrt(g.leg_length ** 2 - (g.rail_radius - g.platform_radius) ** 2
                - (cosine * g.leg_length) ** 2)
    pose = np.array([0.0, 0.0, z, 0.0, 0.0, 0.0])
    with pytest.raises(hp.SingularityError) as info:
        robot.jacobian(pose)
    assert info.value.sigma_min < TYPE_I_TOL
    for call in (lambda: robot.twist_from_qdot(pose, np.ones(6)),
                 lambda: robot.jacobian_derivative(pose, np.ones(6)),
                 lambda: robot.qddot(pose, np.ones(6), np.ones(6)),
                 lambda: robot.leg_motion(pose, np.ones(6))):
        with pytest.raises(hp.SingularityError):
            call()
    measures = robot.singularity(pose)
    assert measures.type_one == pytest.approx(cosine, rel=0.5)
    assert measures.condition_number == np.inf and measures.jacobian_singular_values is None
    batch = robot.jacobian_batch(pose[None])
    assert batch.reachable[0] and not batch.regular[0] and not batch.ok[0]
    assert np.all(batch.jacobian[0] == 0.0)
    # a little lower, the Jacobian is finite
    pose[2] -= 1e-3
    assert np.all(np.isfinite(robot.jacobian(pose)))


def test_twist_from_qdot_type_two(robot):
    with pytest.raises(hp.SingularityError, match="type-II"):
        robot.twist_from_qdot(TYPE_II_POSE, np.ones(6))


# -- velocity and acceleration level: finite differences ------------------------------------------
def test_jacobian_matches_finite_differences_of_ik(any_robot, rng):
    """Column j: central difference of IK along twist e_j, rotations left-multiplied by
    exp(t [w]) (world-axes increments), built with Pinocchio's exp3 / rpy."""
    for _ in range(5):
        pose = regular_pose(any_robot, rng)
        fd = np.empty((6, 6))
        for j in range(6):
            fd[:, j] = derivative(lambda t: any_robot.inverse_kinematics(
                moved(pose, np.eye(6)[j], t), check_limits=False), 1e-4)
        np.testing.assert_allclose(any_robot.jacobian(pose), fd, rtol=1e-8, atol=1e-9)


def test_jacobian_of_other_branch_matches_finite_differences(robot, rng):
    pose = regular_pose(robot, rng)
    branch = -np.asarray(hp.hexapod.kinematics.HOME_BRANCH)
    fd = np.empty((6, 6))
    for j in range(6):
        fd[:, j] = derivative(lambda t: robot.inverse_kinematics(
            moved(pose, np.eye(6)[j], t), branch, check_limits=False), 1e-4)
    np.testing.assert_allclose(robot.jacobian(pose, branch), fd, rtol=1e-8, atol=1e-9)


def test_jacobian_derivative_matches_finite_differences(any_robot, rng):
    for _ in range(5):
        pose = regular_pose(any_robot, rng)
        twist = rng.normal(scale=0.2, size=6)
        fd = derivative(lambda t: any_robot.jacobian(moved(pose, twist, t)), 1e-4)
        np.testing.assert_allclose(any_robot.jacobian_derivative(pose, twist), fd, rtol=1e-7,
                                   atol=1e-8)


def test_qddot_matches_second_differences(any_robot, rng):
    for _ in range(5):
        pose = regular_pose(any_robot, rng)
        twist = rng.normal(scale=0.2, size=6)
        accel, beta = rng.normal(size=3), rng.normal()
        twist_dot = np.concatenate([accel, beta * twist[3:]])
        q_of = lambda t: any_robot.inverse_kinematics(
            moved(pose, twist, t, accel, beta), check_limits=False)
        np.testing.assert_allclose(any_robot.qddot(pose, twist, twist_dot),
                                   second_derivative(q_of, 2e-3), rtol=1e-6, atol=1e-7)
        np.testing.assert_allclose(any_robot.jacobian(pose) @ twist, derivative(q_of, 1e-4),
                                   rtol=1e-8, atol=1e-9)


def test_twist_from_qdot_inverts_jacobian(any_robot, rng):
    pose = random_pose(any_robot, rng)
    twist = rng.normal(size=6)
    qdot = any_robot.jacobian(pose) @ twist
    np.testing.assert_allclose(any_robot.twist_from_qdot(pose, qdot), twist, rtol=1e-10,
                               atol=1e-12)


# -- leg motion -----------------------------------------------------------------------------------
def _leg_bodies(robot, pose):
    """World rotation of each leg body and the U-joint centre, from the Pinocchio tree."""
    tree_q = robot.configuration(pose)
    model, data = robot.model.model, robot.model.data
    pin.framesForwardKinematics(model, data, tree_q)
    frames = [data.oMf[model.getFrameId(f"leg_{i}")] for i in range(6)]
    return [f.rotation.copy() for f in frames]


def test_leg_motion_matches_finite_differences(any_robot, rng):
    length = any_robot.geometry.leg_length
    g = any_robot.geometry
    rail = hp.hexapod.kinematics.RAIL_OF
    for _ in range(3):
        pose = regular_pose(any_robot, rng)
        twist = rng.normal(scale=0.3, size=6)
        accel, beta = rng.normal(size=3), rng.normal()
        twist_dot = np.concatenate([accel, beta * twist[3:]])
        motion = any_robot.leg_motion(pose, twist, twist_dot)

        def state(t):
            return any_robot.leg_motion(moved(pose, twist, t, accel, beta),
                                        np.concatenate([twist[:3] + accel * t,
                                                        twist[3:] * (1 + beta * t)]))

        # direction is the unit leg vector from carriage to platform point
        q = any_robot.inverse_kinematics(pose, check_limits=False)
        tips = any_robot.platform_points_world(pose)[rail]
        carriages = g.rail_midpoints[rail] + q[:, None] * g.rail_directions[rail]
        np.testing.assert_allclose(motion.direction, (tips - carriages) / length, atol=1e-14)
        np.testing.assert_allclose(motion.com_position, 0.5 * (tips + carriages), atol=1e-14)
        h = 1e-4
        # de/dt = w x e, and the centre-of-mass velocity and accelerations
        np.testing.assert_allclose(np.cross(motion.angular_velocity, motion.direction),
                                   derivative(lambda t: state(t).direction, h), rtol=1e-8,
                                   atol=1e-9)
        np.testing.assert_allclose(motion.com_velocity,
                                   derivative(lambda t: state(t).com_position, h), rtol=1e-8,
                                   atol=1e-9)
        np.testing.assert_allclose(motion.com_acceleration,
                                   derivative(lambda t: state(t).com_velocity, h), rtol=1e-7,
                                   atol=1e-8)
        np.testing.assert_allclose(motion.angular_acceleration,
                                   derivative(lambda t: state(t).angular_velocity, h), rtol=1e-7,
                                   atol=1e-8)
        # full angular velocity (spin included): log of the leg bodies' relative rotation in
        # the Pinocchio tree (universal-joint angles from Hexapod.configuration)
        def rotation_log(t):
            before = _leg_bodies(any_robot, moved(pose, twist, -t, accel, beta))
            after = _leg_bodies(any_robot, moved(pose, twist, t, accel, beta))
            return np.array([pin.log3(a @ b.T) for a, b in zip(after, before)]) / (2 * t)

        omega = (4 * rotation_log(h / 2) - rotation_log(h)) / 3
        np.testing.assert_allclose(motion.angular_velocity, omega, rtol=1e-8, atol=1e-9)
        assert motion.angular_acceleration is not None
        assert state(0.0).angular_acceleration is None and state(0.0).qddot is None


def test_leg_angular_velocity_lies_in_the_universal_joint_axes(robot, rng):
    """w is a combination of the rail direction and the second axis (perpendicular to both)."""
    pose = random_pose(robot, rng)
    motion = robot.leg_motion(pose, rng.normal(size=6))
    dirs = robot.geometry.rail_directions[hp.hexapod.kinematics.RAIL_OF]
    normal = np.cross(dirs, np.cross(dirs, motion.direction))      # perpendicular to both axes
    np.testing.assert_allclose(np.einsum("ij,ij->i", motion.angular_velocity, normal), 0.0,
                               atol=1e-12)


# -- singularity measures -------------------------------------------------------------------------
def test_singularity_measures(robot, rng):
    pose = random_pose(robot, rng)
    s = robot.singularity(pose)
    jac = robot.jacobian(pose)
    sv = np.linalg.svd(jac, compute_uv=False)
    np.testing.assert_allclose(s.jacobian_singular_values, sv, rtol=1e-10)
    assert s.condition_number == pytest.approx(sv[0] / sv[-1], rel=1e-10)
    # type one: the smallest cosine between a leg and its rail, from the leg directions
    motion = robot.leg_motion(pose, np.zeros(6))
    cos = np.abs(np.einsum("ij,ij->i", motion.direction,
                           robot.geometry.rail_directions[hp.hexapod.kinematics.RAIL_OF]))
    assert s.type_one == pytest.approx(cos.min(), rel=1e-12)
    assert s.type_one_actuator == int(np.argmin(cos))
    assert 0.0 < s.type_two <= 1.0 + 1e-12
    assert s.type_two_singular_values.shape == (6,)


def test_type_two_measure_vanishes_where_the_platform_moves_with_locked_carriages(robot):
    """At TYPE_II_POSE a platform motion leaves every carriage still to first order: IK
    changes at second order along the null twist, at first order along another twist."""
    s = robot.singularity(TYPE_II_POSE)
    assert s.type_two < 1e-8 and s.type_one > 0.04
    _, _, vt = np.linalg.svd(robot.jacobian(TYPE_II_POSE))
    null, other = vt[-1], vt[0]
    q0 = robot.inverse_kinematics(TYPE_II_POSE, check_limits=False)
    for eps in (1e-3, 1e-4):
        dq_null = robot.inverse_kinematics(moved(TYPE_II_POSE, null, eps), check_limits=False) - q0
        dq_other = robot.inverse_kinematics(moved(TYPE_II_POSE, other, eps),
                                            check_limits=False) - q0
        assert np.max(np.abs(dq_null)) < 5 * eps ** 2 * 10
        assert np.max(np.abs(dq_other)) > 0.1 * eps
    assert robot.singularity(robot.home_pose).type_two > 0.3


# -- batch ----------------------------------------------------------------------------------------
def _mixed_poses(robot, rng, n=300):
    """Poses around home: reachable, out of stroke, unreachable, singular."""
    spread = np.where(np.arange(n)[:, None] < n // 2, 0.25, 1.0)
    poses = robot.home_pose + spread * np.concatenate([rng.uniform(-0.08, 0.08, (n, 3)),
                                                       rng.uniform(-0.5, 0.5, (n, 3))], axis=1)
    g = robot.geometry
    top = np.sqrt(g.leg_length ** 2 - (g.rail_radius - g.platform_radius) ** 2
                  - (5e-8 * g.leg_length) ** 2)
    poses[0] = [0, 0, top, 0, 0, 0]                 # type I
    poses[1] = robot.home_pose
    return poses


def test_batch_matches_single_pose_results(any_robot, rng):
    poses = _mixed_poses(any_robot, rng)
    branch = np.where(rng.uniform(size=6) < 0.5, -1.0, 1.0)
    for br in (None, branch):
        ik = any_robot.inverse_kinematics_batch(poses, branch=br)
        jb = any_robot.jacobian_batch(poses, branch=br)
        np.testing.assert_array_equal(ik.actuator_positions, jb.actuator_positions)
        np.testing.assert_array_equal(ik.within_stroke, jb.within_stroke)
        kinds = set()
        for n, pose in enumerate(poses):
            try:
                any_robot.inverse_kinematics(pose, branch=br)
                outcome = "ok"
            except hp.UnreachablePoseError:
                outcome = "unreachable"
            except hp.StrokeLimitError:
                outcome = "stroke"
            kinds.add(outcome)
            assert ik.ok[n] == (outcome == "ok")
            assert ik.reachable[n] == (outcome != "unreachable")
            if outcome != "unreachable":
                assert ik.within_stroke[n] == (outcome == "ok")
                np.testing.assert_allclose(ik.actuator_positions[n], any_robot.inverse_kinematics(
                    pose, branch=br, check_limits=False), rtol=1e-13, atol=1e-15)
            try:
                jac = any_robot.jacobian(pose, branch=br)
                assert jb.ok[n]
                np.testing.assert_allclose(jb.jacobian[n], jac, rtol=1e-11, atol=1e-13)
            except (hp.UnreachablePoseError, hp.SingularityError):
                assert not jb.ok[n]
                assert np.all(jb.jacobian[n] == 0.0)
        assert kinds == ({"ok", "unreachable", "stroke"} if br is None
                         else {"unreachable", "stroke"} | kinds)
        assert np.all(np.isfinite(ik.actuator_positions)) and np.all(np.isfinite(jb.jacobian))


def test_batch_per_row_branches_and_chunks(robot, rng):
    chunk = hp.hexapod.batch.CHUNK
    n = chunk + 100
    poses = np.tile(robot.home_pose, (n, 1)) + rng.normal(scale=0.01, size=(n, 6))
    branches = np.where(rng.uniform(size=(n, 6)) < 0.5, -1.0, 1.0)
    out = robot.jacobian_batch(poses, branch=branches)
    for k in (0, chunk - 1, chunk, n - 1):
        np.testing.assert_allclose(out.actuator_positions[k], robot.inverse_kinematics(
            poses[k], branch=branches[k], check_limits=False), atol=1e-15)
        np.testing.assert_allclose(out.jacobian[k], robot.jacobian(poses[k], branches[k]),
                                   rtol=1e-11, atol=1e-13)
    empty = robot.jacobian_batch(np.zeros((0, 6)))
    assert empty.jacobian.shape == (0, 6, 6) and empty.ok.shape == (0,)


def test_batch_input_errors(robot):
    with pytest.raises(hp.InputError):
        robot.inverse_kinematics_batch(np.zeros(6))
    with pytest.raises(hp.InputError):
        robot.jacobian_batch(np.zeros((3, 5)))
    poses = np.tile(robot.home_pose, (3, 1))
    poses[1, 4] = np.nan
    with pytest.raises(hp.InputError):
        robot.jacobian_batch(poses)
    with pytest.raises(hp.InputError):
        robot.inverse_kinematics_batch(poses[:1], branch=np.ones((2, 6)))


def test_leg_along_its_rail_is_a_universal_joint_gimbal_lock(robot):
    """Platform point 0 on the line of rail 0: both legs of rail 0 lie along the rail. J is
    regular there (|cos| = 1), but the legs' spin about themselves is undefined."""
    g = robot.geometry
    pose = np.array([0.0, g.rail_radius - g.platform_radius, 0.0, 0.0, 0.0, 0.0])
    np.testing.assert_allclose(np.abs(robot.jacobian(pose)[:2, 0]), 1.0, atol=1e-12)
    assert robot.singularity(pose).type_one < 1.0
    with pytest.raises(hp.SingularityError, match="along its rail"):
        robot.leg_motion(pose, np.ones(6))
    pose[1] -= 1e-3
    assert np.all(np.isfinite(robot.leg_motion(pose, np.ones(6), np.ones(6)).angular_velocity))
