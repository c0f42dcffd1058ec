"""Frame-target inverse kinematics with the closures held (core/frame_ik.py).

Targets are generated from assembled configurations (so they are reachable) and must be
reached to 1e-10 with the closures to 1e-12 from perturbed starts, on every seeded trial,
on the hard-class robots of tests/stress_robots.py, the hexapod and Cassie. Independent
checks: the hexapod's closed-form inverse kinematics, targets whose closest reachable
placement is known in closed form (out of a planar mechanism's plane, a rotation a delta
cannot make, two weighted targets for one point), a stationarity test written here with
an SVD null space, and the two routes (ProxSuite QP, null-space least squares) against
each other where the solution is unique.
"""

import numpy as np
import pinocchio as pin
import pytest
import scipy.linalg

import stress_robots
from conftest import random_pose
from hexapod_pin.errors import AssemblyError, InputError
from hexapod_pin.loaders import robots
from hexapod_pin.loaders.parallel_robots import load_parallel_robot

# robot -> (end-effector frame, placement target (True) or position target (False))
EFFECTORS = {
    "delta_weld": ("platform_center", False),
    "delta_massless": ("platform_center", False),
    "five_bar_stiff": ("pin", False),
    "five_bar_massless": ("pin", False),
    "ladder_mixed": ("bar_6_tip", False),
    "ladder_massless": ("bar_4_tip", True),
    "planar_ladder_weld": ("bar_5_tip", True),
    "ladder_long": ("bar_24_tip", False),
}
TRIALS = 4


def _placement(clm, q, frame):
    data = clm.model.createData()
    pin.framesForwardKinematics(clm.model, data, q)
    return pin.SE3(data.oMf[clm.frame_id(frame)])


def _perturbed(clm, q, rng, scale):
    return pin.integrate(clm.model, q, scale * rng.uniform(-1, 1, clm.nv))


@pytest.fixture(scope="module", params=sorted(EFFECTORS))
def stress(request):
    return stress_robots.build(request.param)


@pytest.mark.parametrize("method", ["qp", "lstsq"])
def test_targets_from_assembled_configurations_are_reached(stress, method):
    clm = stress.clm
    frame, full = EFFECTORS[stress.name]
    rng = np.random.default_rng(7)
    for _ in range(TRIALS):
        q_goal, _ = stress.sample(rng)
        goal = _placement(clm, q_goal, frame)
        start, _ = stress.sample(rng)
        target = goal if full else goal.translation
        # the samples wrap some joints past their +-3.2 rad limits: limits off here
        res = clm.frame_inverse_kinematics(frame, target, _perturbed(clm, start, rng, 0.02),
                                           position_only=not full, method=method,
                                           limits=False)
        assert res.reachable, (stress.name, res.target_residual)
        assert res.target_residual <= 1e-10 and res.closure_residual <= 1e-12
        # independent of the result's own numbers
        assert np.max(np.abs(clm.residual(res.q))) <= 1e-12
        reached = _placement(clm, res.q, frame)
        if full:
            assert np.max(np.abs(pin.log6(goal.actInv(reached)).vector)) <= 1e-10
        else:
            assert np.max(np.abs(reached.translation - goal.translation)) <= 1e-10
        assert res.iterations <= 25


def test_hexapod_platform_matches_the_closed_form(robot, rng):
    """Every random pose: the generic route places the platform and its carriages equal the
    hexapod's closed-form inverse kinematics; both routes give the same configuration."""
    clm = robot.model
    home = robot.home_configuration
    for _ in range(5):
        pose = random_pose(robot, rng)
        rot = pin.rpy.rpyToMatrix(*pose[3:])
        target = pin.SE3(rot, pose[:3])
        out = {}
        for method in ("qp", "lstsq"):
            res = clm.frame_inverse_kinematics("platform", target, _perturbed(clm, home, rng, 0.01),
                                               method=method)
            assert res.reachable and res.target_residual <= 1e-10
            assert res.closure_residual <= 1e-12
            np.testing.assert_allclose(res.q[robot.indices.carriage_q],
                                       robot.inverse_kinematics(pose), atol=1e-10)
            out[method] = res.q
        np.testing.assert_allclose(out["qp"], out["lstsq"], atol=1e-10)


def test_convergence_is_quadratic_near_the_solution(robot, rng):
    """Once the task error is below 1e-4, each step squares it (up to a constant and the
    rounding floor): the damping vanishes with the error."""
    for _ in range(3):
        pose = random_pose(robot, rng)
        target = pin.SE3(pin.rpy.rpyToMatrix(*pose[3:]), pose[:3])
        for method in ("qp", "lstsq"):
            res = robot.model.frame_inverse_kinematics("platform", target,
                                                       robot.home_configuration, method=method)
            assert res.reachable and res.history[-1] == res.target_residual
            pairs = [(a, b) for a, b in zip(res.history, res.history[1:]) if a < 1e-4]
            assert pairs
            for before, after in pairs:
                assert after <= max(1e3 * before ** 2, 1e-13), res.history


def test_routes_agree_on_the_delta(rng):
    delta = stress_robots.build("delta_weld")
    for _ in range(3):
        q_goal, _ = delta.sample(rng)
        goal = _placement(delta.clm, q_goal, "platform_center").translation
        start = _perturbed(delta.clm, q_goal, rng, 0.05)
        a = delta.clm.frame_inverse_kinematics("platform_center", goal, start, position_only=True)
        b = delta.clm.frame_inverse_kinematics("platform_center", goal, start, position_only=True,
                                               method="lstsq")
        np.testing.assert_allclose(a.q, b.q, atol=1e-10)


def test_cassie_both_feet_with_the_leg_loops(rng):
    cassie = robots.cassie(root="fixed")
    q0 = pin.neutral(cassie.model)
    for side in ("left", "right"):
        q0[cassie.joint_q_index(f"{side}-pitch-op")] = 0.3
        q0[cassie.joint_q_index(f"{side}-foot-op")] = -0.4
    springs = [f"{side}-{j}" for side in ("left", "right")
               for j in ("knee-shin-joint", "tarsus-spring-joint")]
    spring_v = [cassie.joint_v_index(name) for name in springs]
    q_home = cassie.assemble(q0, fixed=np.r_[cassie.actuated_v, spring_v]).q
    feet = ["left-foot", "right-foot"]
    for _ in range(3):
        q_goal = q_home.copy()
        # with rigid springs the achilles loop holds the knee: move the other motors
        moved = [j for j in cassie.actuated_joints if "knee" not in j]
        q_goal[[cassie.joint_q_index(j) for j in moved]] += rng.uniform(-0.1, 0.1, len(moved))
        q_goal = cassie.assemble(q_goal, fixed=np.r_[cassie.actuated_v, spring_v]).q
        targets = [_placement(cassie, q_goal, f) for f in feet]
        # the foot motors of this start sit outside the SDF's ranges: limits off
        res = cassie.frame_inverse_kinematics(feet, targets, q_home, fixed=springs,
                                              weights=[1.0, 2.0], limits=False)
        assert res.reachable and res.target_residual <= 1e-10
        assert res.closure_residual <= 1e-12
        np.testing.assert_array_equal(res.q[[cassie.joint_q_index(s) for s in springs]],
                                      q_home[[cassie.joint_q_index(s) for s in springs]])


# ----------------------------------------------------------------- unreachable targets
def test_out_of_plane_target_gives_the_projection_flagged():
    """The five-bar moves in the x-z plane: the closest reachable point of a target off the
    plane is its projection, and it is flagged unreachable."""
    five = stress_robots.build("five_bar_stiff")
    rng = np.random.default_rng(3)
    q_goal, _ = five.sample(rng)
    goal = _placement(five.clm, q_goal, "pin").translation
    target = goal + np.array([0.0, 0.05, 0.0])
    for method in ("qp", "lstsq"):
        res = five.clm.frame_inverse_kinematics("pin", target, five.sample(rng)[0],
                                                position_only=True, method=method, limits=False)
        assert not res.reachable and res.closure_residual <= 1e-12
        np.testing.assert_allclose(res.placements[0].translation, goal, atol=1e-10)
        assert res.target_residual == pytest.approx(0.05, abs=1e-10)


def test_rotation_a_delta_cannot_make_reaches_the_position():
    delta = stress_robots.build("delta_weld")
    rng = np.random.default_rng(4)
    q_goal, _ = delta.sample(rng)
    goal = _placement(delta.clm, q_goal, "platform_center")
    tilted = pin.SE3(goal.rotation @ pin.rpy.rpyToMatrix(0.1, -0.05, 0.0), goal.translation)
    res = delta.clm.frame_inverse_kinematics("platform_center", tilted,
                                             _perturbed(delta.clm, q_goal, rng, 0.05))
    assert not res.reachable and res.closure_residual <= 1e-12
    np.testing.assert_allclose(res.placements[0].translation, goal.translation, atol=1e-10)
    np.testing.assert_allclose(res.placements[0].rotation, goal.rotation, atol=1e-10)
    # stationarity, computed here: the task gradient has no component along the closures
    clm, q = delta.clm, res.q
    null = scipy.linalg.null_space(clm.constraint_jacobian(q))
    data = clm.model.createData()
    pin.computeJointJacobians(clm.model, data, q)
    pin.updateFramePlacements(clm.model, data)
    fid = clm.frame_id("platform_center")
    rel = tilted.actInv(data.oMf[fid])
    jac = pin.Jlog6(rel) @ pin.getFrameJacobian(clm.model, data, fid, pin.ReferenceFrame.LOCAL)
    assert np.max(np.abs(null.T @ jac.T @ pin.log6(rel).vector)) <= 1e-10


def test_two_weighted_targets_for_one_point_meet_at_the_weighted_mean():
    """The five-bar's weld holds its two closure anchors together: targets p1 (weight 1) and
    p2 (weight 3) for them give the point (p1 + 3 p2) / 4, flagged unreachable."""
    five = stress_robots.build("five_bar_stiff")
    rng = np.random.default_rng(5)
    q_goal, _ = five.sample(rng)
    anchor = five.clm.closures[0].name
    frames = [f"{anchor}/anchor1", f"{anchor}/anchor2"]
    p0 = _placement(five.clm, q_goal, frames[0]).translation
    p1, p2 = p0 + [0.01, 0.0, 0.0], p0 + [0.0, 0.0, 0.02]
    res = five.clm.frame_inverse_kinematics(frames, [p1, p2], q_goal, position_only=True,
                                            weights=[1.0, 3.0], limits=False)
    assert not res.reachable and res.closure_residual <= 1e-12
    for placement in res.placements:
        np.testing.assert_allclose(placement.translation, (p1 + 3 * p2) / 4, atol=1e-10)


def test_joint_limits_stop_the_step_and_flag_the_target():
    """A delta target that needs motor_0 past a limit placed just beyond the start: with
    limits the motor stops at the limit (unreachable, closures held); without, reached."""
    delta = stress_robots.build("delta_weld")
    clm = delta.clm
    rng = np.random.default_rng(6)
    q_start, _ = delta.sample(rng)
    iq = clm.joint_q_index("motor_0")
    q_goal = q_start.copy()
    q_goal[iq] += 0.1
    q_goal = clm.assemble(q_goal).q
    goal = _placement(clm, q_goal, "platform_center").translation
    saved = clm.model.upperPositionLimit.copy()
    try:
        upper = saved.copy()
        upper[iq] = q_start[iq] + 0.05
        clm.model.upperPositionLimit = upper
        res = clm.frame_inverse_kinematics("platform_center", goal, q_start, position_only=True)
        free = clm.frame_inverse_kinematics("platform_center", goal, q_start, position_only=True,
                                            limits=False)
    finally:
        clm.model.upperPositionLimit = saved
    assert not res.reachable and res.closure_residual <= 1e-12
    assert res.q[iq] == pytest.approx(q_start[iq] + 0.05, abs=1e-9)
    assert free.reachable and free.target_residual <= 1e-10


# ------------------------------------------------------- folded delta: reach or closest
# The delta of tests/data/parallel/delta in its translating mode: base radius 0.2 m, upper
# arms 0.25 m, forearms 0.5 m, platform radius 0.05 m, motor k at 120 k deg. Leg k can hold
# the platform centre p iff the distance from its wrist point to the circle of its elbow
# reaches the forearm length: with u = R_z(-phi_k) p + (r - R, 0, 0), rho = |(u_x, u_z)|,
# |u|^2 + L1^2 - 2 L1 rho <= L2^2 <= |u|^2 + L1^2 + 2 L1 rho (written here, independent of
# the library's kinematics).
DELTA_DIR = stress_robots.DATA / "delta"
DELTA_R, DELTA_L1, DELTA_L2, DELTA_r = 0.2, 0.25, 0.5, 0.05


def delta_margins(p):
    """Per leg, the signed slack (m^2) of the reach condition, shape ``p.shape[:-1] + (3,)``;
    all >= 0: reachable."""
    p = np.asarray(p, dtype=float)
    out = []
    for k in range(3):
        phi = 2 * np.pi * k / 3
        c, s = np.cos(phi), np.sin(phi)
        ux = c * p[..., 0] + s * p[..., 1] + DELTA_r - DELTA_R
        uy = -s * p[..., 0] + c * p[..., 1]
        uz = p[..., 2]
        rho = np.hypot(ux, uz)
        base = ux ** 2 + uy ** 2 + uz ** 2 + DELTA_L1 ** 2
        out.append(np.minimum(DELTA_L2 ** 2 - (base - 2 * DELTA_L1 * rho),
                              base + 2 * DELTA_L1 * rho - DELTA_L2 ** 2))
    return np.stack(out, axis=-1)


def folded_delta_problems(delta, seed, n_starts, n_targets):
    """Folded starts (elbows near pi: the platform high, at the top of the workspace) in the
    translating mode, and targets 2 cm away in random directions."""
    rng = np.random.default_rng(seed)
    fid = delta.frame_id("platform_center")
    data = delta.model.createData()
    problems = []
    while len(problems) < n_starts * n_targets:
        q0 = delta.neutral()
        motor, elbow, wrist = rng.uniform(0.6, 1.5), rng.uniform(2.0, 3.1), rng.uniform(-3.1, -2.5)
        for k in range(3):
            q0[delta.joint_q_index(f"motor_{k}")] = motor + rng.uniform(-0.2, 0.2)
            q0[delta.joint_q_index(f"elbow_{k}_Y")] = elbow
            q0[delta.joint_q_index(f"wrist_{k}_Y")] = wrist
        try:
            q = delta.assemble(q0).q
        except AssemblyError:
            continue
        pin.framesForwardKinematics(delta.model, data, q)
        if np.max(np.abs(data.oMf[fid].rotation - np.eye(3))) > 1e-9:
            continue                                  # another assembly mode: tilted platform
        centre = data.oMf[fid].translation.copy()
        for _ in range(n_targets):
            d = rng.normal(size=3)
            problems.append((q, centre + 0.02 * d / np.linalg.norm(d)))
    return problems


def test_closed_form_reach_condition_holds_on_assembled_deltas():
    """The test's reach condition is itself right: at assembled states each leg's wrist
    lies at the forearm length from its elbow, and the slack is non-negative."""
    delta = load_parallel_robot(DELTA_DIR)
    fid = delta.frame_id("platform_center")
    for q, _ in folded_delta_problems(delta, 11, 3, 1):
        pin.framesForwardKinematics(delta.model, delta.data, q)
        p = delta.data.oMf[fid].translation
        assert np.all(delta_margins(p) >= -1e-12)
        for k in range(3):
            phi, th = 2 * np.pi * k / 3, q[delta.joint_q_index(f"motor_{k}")]
            u = np.array([np.cos(phi) * p[0] + np.sin(phi) * p[1] + DELTA_r - DELTA_R,
                          -np.sin(phi) * p[0] + np.cos(phi) * p[1], p[2]])
            elbow = DELTA_L1 * np.array([np.cos(th), 0.0, -np.sin(th)])
            assert np.linalg.norm(u - elbow) == pytest.approx(DELTA_L2, abs=1e-12)


@pytest.mark.parametrize("method", ["qp", "lstsq"])
def test_folded_delta_targets_are_reached_or_give_the_closest_placement(method):
    """From folded starts, 2 cm targets: each reachable one (closed form) is reached to 1e-10
    in few steps; each unreachable one gives, within a bounded number of steps, a placement
    on the workspace boundary that no nearby reachable point beats (sampled with the closed
    form), flagged unreachable. Never an error: the closures hold everywhere."""
    delta = load_parallel_robot(DELTA_DIR)
    rng = np.random.default_rng(0)
    seen = {True: 0, False: 0}
    for q, target in folded_delta_problems(delta, 2, 6, 6):
        margin = float(np.min(delta_margins(target)))
        if abs(margin) < 1e-4:
            continue                                    # too close to the boundary to judge
        res = delta.frame_inverse_kinematics("platform_center", target, q, position_only=True,
                                             method=method)
        assert res.closure_residual <= 1e-12
        assert np.max(np.abs(delta.residual(res.q))) <= 1e-12
        placed = res.placements[0]
        assert np.max(np.abs(placed.rotation - np.eye(3))) <= 1e-9     # still translating
        reachable = margin > 0
        seen[reachable] += 1
        assert res.reachable == reachable, (margin, res.target_residual, res.iterations)
        if reachable:
            assert res.target_residual <= 1e-10 and res.iterations <= 10
            for before, after in zip(res.history, res.history[1:]):
                if before < 1e-4:                        # quadratic near the solution
                    assert after <= max(1e3 * before ** 2, 1e-13), res.history
            continue
        assert res.iterations <= 40, res.history
        p = placed.translation
        slack = delta_margins(p)
        assert np.all(slack >= -1e-10) and np.min(slack) <= 1e-8     # on the boundary
        distance = np.linalg.norm(p - target)
        assert distance == pytest.approx(np.linalg.norm(res.errors), abs=1e-12)
        near = p + rng.uniform(-2e-3, 2e-3, (4000, 3))
        inside = near[np.all(delta_margins(near) >= 0.0, axis=1)]
        assert inside.size
        assert np.min(np.linalg.norm(inside - target, axis=1)) >= distance - 1e-9
    assert seen[True] >= 5 and seen[False] >= 5, seen


def test_proxsuite_stopping_early_falls_back_to_the_null_space_step(monkeypatch):
    """Where ProxSuite stops at its iteration cap (here forced to 1) the QP route takes the
    null-space step: same answers as route "lstsq"; with a joint limit that step would
    cross, the route raises SolverError instead of leaving the range."""
    from hexapod_pin.core import frame_ik
    from hexapod_pin.errors import SolverError

    monkeypatch.setattr(frame_ik, "QP_MAX_ITER", 1)
    delta = stress_robots.build("delta_weld")
    clm = delta.clm
    rng = np.random.default_rng(8)
    for _ in range(3):
        q_goal, _ = delta.sample(rng)
        goal = _placement(clm, q_goal, "platform_center").translation
        start = clm.assemble(_perturbed(clm, q_goal, rng, 0.05)).q
        a = clm.frame_inverse_kinematics("platform_center", goal, start, position_only=True,
                                         limits=False)
        b = clm.frame_inverse_kinematics("platform_center", goal, start, position_only=True,
                                         method="lstsq")
        assert a.reachable and a.target_residual <= 1e-10 and a.closure_residual <= 1e-12
        np.testing.assert_allclose(a.q, b.q, atol=1e-10)
    q_start, _ = delta.sample(np.random.default_rng(6))
    iq = clm.joint_q_index("motor_0")
    q_goal = q_start.copy()
    q_goal[iq] += 0.1
    goal = _placement(clm, clm.assemble(q_goal).q, "platform_center").translation
    saved = clm.model.upperPositionLimit.copy()
    try:
        upper = saved.copy()
        upper[iq] = q_start[iq] + 0.05
        clm.model.upperPositionLimit = upper
        with pytest.raises(SolverError):
            clm.frame_inverse_kinematics("platform_center", goal, q_start, position_only=True)
    finally:
        clm.model.upperPositionLimit = saved


@pytest.mark.parametrize("relax", [1e-2, 1.0, 1e2])
def test_relaxed_intermediate_closures_still_give_exact_answers(monkeypatch, relax):
    """However loosely the intermediate iterates close the loops (frame_ik.RELAX), every
    answer keeps them to 1e-12 and reaches its target (checked with the model's own
    residual and placements, not the result's numbers)."""
    from hexapod_pin.core import frame_ik

    monkeypatch.setattr(frame_ik, "RELAX", relax)
    rng = np.random.default_rng(12)
    for name, frame in (("delta_weld", "platform_center"), ("five_bar_stiff", "pin")):
        robot = stress_robots.build(name)
        clm = robot.clm
        for _ in range(3):
            q_goal, _ = robot.sample(rng)
            goal = _placement(clm, q_goal, frame).translation
            start = _perturbed(clm, robot.sample(rng)[0], rng, 0.02)
            res = clm.frame_inverse_kinematics(frame, goal, start, position_only=True,
                                               limits=False)
            assert res.reachable and res.iterations <= 30
            assert np.max(np.abs(clm.residual(res.q))) <= 1e-12
            np.testing.assert_allclose(_placement(clm, res.q, frame).translation, goal,
                                       atol=1e-10)


# ------------------------------------------------------------------------- errors
def test_closures_that_cannot_hold_raise():
    five = stress_robots.build("five_bar_stiff")
    q = five.clm.neutral()
    q[five.clm.joint_q_index("mot1")] = np.pi       # motors pointing away from each other
    q[five.clm.joint_q_index("mot2")] = 0.0
    with pytest.raises(AssemblyError):
        five.clm.frame_inverse_kinematics("pin", [0.0, 0.0, -0.3], q, position_only=True,
                                          fixed=["mot1", "mot2"])


def test_input_errors():
    delta = stress_robots.build("delta_weld")
    clm = delta.clm
    q, _ = delta.sample(np.random.default_rng(0))
    target = _placement(clm, q, "platform_center")
    with pytest.raises(InputError):
        clm.frame_inverse_kinematics("no_such_frame", target, q)
    with pytest.raises(InputError):
        clm.frame_inverse_kinematics("platform_center", np.zeros(2), q, position_only=True)
    with pytest.raises(InputError):
        clm.frame_inverse_kinematics("platform_center", np.eye(4) * 2, q)
    with pytest.raises(InputError):
        clm.frame_inverse_kinematics("platform_center", target, q, method="newton")
    with pytest.raises(InputError):
        clm.frame_inverse_kinematics("platform_center", target, q, weights=-1.0)
    with pytest.raises(InputError):
        clm.frame_inverse_kinematics("platform_center", target, q, fixed=["no_such_joint"])
    with pytest.raises(InputError):
        clm.frame_inverse_kinematics(["platform_center"], [target, target], q)
    with pytest.raises(InputError):
        clm.frame_inverse_kinematics("platform_center", target, q[:-1])


# ------------------------------------------------------------------------- examples
@pytest.mark.parametrize("script, expected", [
    ("delta_end_effector.py", "reachable=True"),
    ("cassie_foot_placement.py", "both feet placed: reachable=True"),
    ("hexapod_platform_generic_ik.py", "generic route: reachable=True"),
])
def test_example_runs(script, expected, capsys):
    import runpy
    from pathlib import Path

    runpy.run_path(str(Path(__file__).resolve().parents[2] / "examples" / script),
                   run_name="__main__")
    out = capsys.readouterr().out
    assert expected in out
    if script == "delta_end_effector.py":
        line = next(l for l in out.splitlines() if l.startswith("folded legs"))
        assert "reachable=False" in line
    if script == "hexapod_platform_generic_ik.py":
        line = next(l for l in out.splitlines() if l.startswith("largest difference"))
        assert float(line.split()[2]) <= 1e-10
