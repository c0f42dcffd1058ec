"""``hexapod_pin.core.workspace_maps`` against references written here.

* reachability against closed forms: the five-bar's two annuli ``|L1 - L2| <= |tip - m_i|
  <= L1 + L2``, the Stewart platform's leg lengths ``|p + R b_i - a_i|`` against its
  strokes;
* the condition number and ``sigma_min`` against ``numpy.linalg`` on ``robot.jacobian``,
  the statics against ``robot.static_forces`` pose by pose, the force capability against
  ``scipy.optimize.linprog``;
* on the hexapod, agreement with its compiled maps (``hexapod_pin.hexapod.workspace``);
* rows outside the workspace carry zeros / inf / False, never NaN; bad inputs raise
  typed errors.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.optimize
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import hexapod_pin as hp
import robot_registry
from hexapod_pin.core import workspace_maps as wm
from hexapod_pin.core.pose import rotation_from_rpy
from hexapod_pin.errors import ArgumentTypeError, InputError, SolverError
from hexapod_pin.hexapod import workspace as hexapod_workspace

# the five-bar (tests/data/parallel/five_bar_3d): motors at x = -0.1, 0.1, links 0.25, 0.3
MOTORS = np.array([[-0.1, 0.0], [0.1, 0.0]])
L1, L2 = 0.25, 0.3
# the Stewart platform (tests/data/stewart/README.md)
ALPHA = np.deg2rad([-15, 15, 105, 135, 225, 255])
BETA = np.deg2rad([-45, 45, 75, 165, 195, 285])
BASE = 0.5 * np.c_[np.cos(ALPHA), np.sin(ALPHA), np.zeros(6)]
PLATFORM = 0.3 * np.c_[np.cos(BETA), np.sin(BETA), np.zeros(6)]
LEG_OFFSET, STROKE = 0.65, 0.15


@pytest.fixture(scope="module")
def five_bar():
    return robot_registry.get("five-bar")


@pytest.fixture(scope="module")
def delta():
    return robot_registry.get("delta")


@pytest.fixture(scope="module")
def stewart():
    return robot_registry.get("stewart")


@pytest.fixture(scope="module")
def robots(five_bar, delta, stewart):
    return {"five-bar": five_bar, "delta": delta, "stewart": stewart}


#: per robot: the half side of the sampled box about home (m, rad), chosen so that the
#: sample holds poses inside and outside the workspace
SPREAD = {"five-bar": 0.3, "delta": 0.12, "stewart": np.r_[0.1, 0.1, 0.1, 0.15, 0.15, 0.15]}


def sample(robot, name, n, seed):
    spread = SPREAD[name]
    return wm.sample_box(robot, n, robot.home_pose - spread, robot.home_pose + spread, seed)


@pytest.fixture(scope="module")
def maps(robots):
    """Each robot's map of 40 poses with a payload (evaluated once for the module)."""
    out = {}
    for name, robot in robots.items():
        poses = sample(robot, name, 40, seed=3)
        payload = np.linspace(-1.0, 1.0, robot.pose_dim)
        out[name] = (poses, payload, wm.evaluate(robot, poses, payload))
    return out


def assert_never_nan(m):
    for field in ("actuator_positions", "condition_number", "sigma_min", "type_one",
                  "type_two", "static_forces"):
        assert not np.isnan(getattr(m, field)).any(), field


def assert_outside_rows_are_empty(m):
    assert np.array_equal(m.ok, m.reachable & m.within_stroke & m.regular)
    out = ~m.ok
    assert np.all(np.isinf(m.condition_number[out]))
    assert np.all(m.sigma_min[out] == 0.0)
    assert np.all(m.static_forces[out] == 0.0)
    assert np.all(m.type_one[~m.reachable] == 0.0)
    assert np.all(m.type_two[~m.reachable] == 0.0)
    assert m.failures.get("unreachable", 0) == np.count_nonzero(~m.reachable)
    assert m.failures.get("stroke", 0) == np.count_nonzero(m.reachable & ~m.within_stroke)


# -- reachability against closed forms -------------------------------------------------------
def five_bar_angles(tip):
    """Both motor angles (mod 2 pi) of each arm that put its distal end at ``tip`` (x, z)
    (rotation about +y by theta turns the x axis to (cos theta, 0, -sin theta))."""
    out = []
    for m in MOTORS:
        d = np.linalg.norm(tip - m)
        along = (d ** 2 + L1 ** 2 - L2 ** 2) / (2 * d)
        h = np.sqrt(max(L1 ** 2 - along ** 2, 0.0))
        u = (tip - m) / d
        normal = np.array([-u[1], u[0]])
        elbows = [m + along * u + s * h * normal for s in (1.0, -1.0)]
        out.append([np.arctan2(-(e[1] - m[1]), e[0] - m[0]) for e in elbows])
    return np.array(out)


def test_five_bar_reachable_iff_both_tips_lie_in_their_annuli(five_bar, maps):
    poses = np.vstack([maps["five-bar"][0], sample(five_bar, "five-bar", 40, seed=4)])
    m = wm.evaluate(five_bar, poses, statics=False, singularity=False)
    dist = np.linalg.norm(poses[:, None, :] - MOTORS[None], axis=2)
    margin = np.minimum(np.abs(dist - abs(L1 - L2)), np.abs(dist - (L1 + L2))).min(axis=1)
    inside = np.all((dist >= abs(L1 - L2)) & (dist <= L1 + L2), axis=1)
    clear = margin > 1e-6
    assert 10 <= np.count_nonzero(inside & clear) and 10 <= np.count_nonzero(~inside & clear)
    np.testing.assert_array_equal(m.reachable[clear], inside[clear])
    for k in np.flatnonzero(m.reachable):              # one of the circle intersections
        roots = five_bar_angles(poses[k])
        for arm in range(2):
            gap = np.abs(np.angle(np.exp(1j * (roots[arm] - m.actuator_positions[k, arm]))))
            assert gap.min() < 1e-9
    lower, upper = five_bar.stroke_limits()
    within = np.all((m.actuator_positions >= lower) & (m.actuator_positions <= upper), axis=1)
    np.testing.assert_array_equal(m.within_stroke[m.reachable], within[m.reachable])
    assert_outside_rows_are_empty(m)


def test_stewart_strokes_are_the_leg_lengths(stewart):
    poses = sample(stewart, "stewart", 40, seed=5)
    m = wm.evaluate(stewart, poses, statics=False, singularity=False)
    legs = np.array([np.linalg.norm(p[:3] + PLATFORM @ rotation_from_rpy(p[3:]).T - BASE,
                                    axis=1) for p in poses]) - LEG_OFFSET
    assert m.reachable.all()
    np.testing.assert_allclose(m.actuator_positions, legs, rtol=0, atol=1e-12)
    clear = np.abs(np.abs(legs) - STROKE).min(axis=1) > 1e-9
    within = np.all(np.abs(legs) <= STROKE, axis=1)
    assert 0 < np.count_nonzero(~within) < len(poses)
    np.testing.assert_array_equal(m.within_stroke[clear], within[clear])
    assert_outside_rows_are_empty(m)


# -- every measure against the robot's own single-pose routes and numpy ----------------------
@pytest.mark.parametrize("name", ["five-bar", "delta", "stewart"])
def test_measures_against_numpy_and_single_pose_routes(robots, maps, name):
    robot = robots[name]
    poses, payload, m = maps[name]
    assert m.poses.shape == (len(poses), robot.pose_dim)
    assert m.static_forces.shape == m.actuator_positions.shape == (len(poses),
                                                                   robot.n_actuators)
    assert 5 <= np.count_nonzero(m.ok)
    assert_never_nan(m)
    assert_outside_rows_are_empty(m)
    for k in np.flatnonzero(m.ok):
        jac = robot.jacobian(poses[k])
        sv = np.linalg.svd(jac, compute_uv=False)
        np.testing.assert_allclose(m.condition_number[k], np.linalg.cond(jac), rtol=1e-9)
        np.testing.assert_allclose(m.sigma_min[k], sv[-1], rtol=1e-9)
        tau = robot.static_forces(poses[k], payload, bounded=False)
        np.testing.assert_allclose(m.static_forces[k], tau, rtol=0,
                                   atol=1e-9 * max(1.0, np.abs(tau).max()))
    for k in np.flatnonzero(m.reachable):
        meas = robot.singularity(poses[k])
        assert m.type_one[k] == pytest.approx(meas.type_one, rel=1e-12, abs=1e-15)
        assert m.type_two[k] == pytest.approx(meas.type_two, rel=1e-12, abs=1e-15)
    np.testing.assert_allclose(wm.dexterity(m), np.where(m.ok, 1.0 / m.condition_number, 0.0))


def test_payload_per_pose_and_flags(five_bar, maps):
    poses, payload, m = maps["five-bar"]
    per_pose = np.outer(np.arange(len(poses)) / 10.0, payload)
    mp = wm.evaluate(five_bar, poses, per_pose, singularity=False)
    for k in np.flatnonzero(mp.ok)[:5]:
        np.testing.assert_allclose(mp.static_forces[k],
                                   five_bar.static_forces(poses[k], per_pose[k], bounded=False),
                                   rtol=0, atol=1e-9)
    bare = wm.evaluate(five_bar, poses, statics=False, singularity=False)
    np.testing.assert_array_equal(bare.ok, m.ok)
    np.testing.assert_array_equal(bare.condition_number, m.condition_number)
    assert np.all(bare.static_forces == 0.0) and np.all(bare.type_one == 0.0)


# -- force capability against linprog --------------------------------------------------------
def linprog_scale(tau0, tau1, limit):
    """max s >= 0 s.t. -limit <= tau0 + s tau1 <= limit (scipy's HiGHS)."""
    res = scipy.optimize.linprog(
        c=[-1.0], A_ub=np.r_[tau1, -tau1][:, None], b_ub=np.r_[limit - tau0, limit + tau0],
        bounds=[(0, None)], method="highs")
    assert res.status == 0, res.message
    return res.x[0]


@pytest.mark.parametrize("name", ["five-bar", "delta", "stewart"])
def test_force_capability_against_linprog(robots, maps, name):
    robot = robots[name]
    poses = maps[name][0][:12]
    direction = np.zeros(robot.pose_dim)
    direction[robot.pose_dim - 1 if robot.pose_dim < 6 else 2] = -1.0     # down-ish
    cap = wm.force_capability(robot, poses, direction)
    limit = np.broadcast_to(robot.geometry.max_actuator_force, (robot.n_actuators,))
    checked = 0
    for k, pose in enumerate(poses):
        if not cap.ok[k]:
            assert cap.scale[k] == 0.0 and cap.limiting_actuator[k] == -1
            continue
        tau0 = robot.static_forces(pose, bounded=False)
        tau1 = robot.static_forces(pose, direction, bounded=False) - tau0
        np.testing.assert_allclose(cap.base_forces[k], tau0, atol=1e-9)
        np.testing.assert_allclose(cap.unit_forces[k], tau1, atol=1e-9)
        s = linprog_scale(tau0, tau1, limit)
        assert cap.scale[k] == pytest.approx(s, rel=1e-7)
        reach = np.abs(tau0 + s * tau1)[cap.limiting_actuator[k]]
        assert reach == pytest.approx(limit[cap.limiting_actuator[k]], rel=1e-7)
        checked += 1
    assert checked >= 3
    assert not np.isnan(cap.scale).any()


def test_force_capability_with_a_bound_per_actuator(five_bar, maps):
    limit = np.array([30.0, 70.0])
    robot = hp.ClosedLoopRobot(five_bar.model, "end_1", ("x", "z"),
                               home=five_bar.home_configuration, max_actuator_force=limit)
    poses = maps["five-bar"][0][:10]
    direction = np.array([0.3, -1.0])
    cap = wm.force_capability(robot, poses, direction)
    # the drives' effort limits (50 N m from the URDF) cap the second bound
    limit = wm.actuator_force_bounds(robot)
    np.testing.assert_array_equal(limit, [30.0, 50.0])
    for k in np.flatnonzero(cap.ok):
        tau0 = robot.static_forces(poses[k], bounded=False)
        tau1 = robot.static_forces(poses[k], direction, bounded=False) - tau0
        if np.all(np.abs(tau0) <= limit):
            assert cap.scale[k] == pytest.approx(linprog_scale(tau0, tau1, limit), rel=1e-7)
        else:
            assert cap.scale[k] == 0.0 and not cap.feasible_without_payload[k]


def test_force_capability_is_inf_without_bounds(five_bar, maps):
    robot = hp.ClosedLoopRobot(five_bar.model, "end_1", ("x", "z"),
                               home=five_bar.home_configuration, max_actuator_force=np.inf)
    # the drives' effort limits (the URDF's efforts) still bound it ...
    capped = wm.force_capability(robot, maps["five-bar"][0][:6], [0.0, -1.0])
    assert np.all(np.isfinite(capped.scale[capped.ok]))
    # ... and without them nothing does
    robot = robot.with_effects(effort_limit=np.full(2, np.inf))
    cap = wm.force_capability(robot, maps["five-bar"][0][:6], [0.0, -1.0])
    assert np.all(np.isinf(cap.scale[cap.ok])) and np.all(cap.scale[~cap.ok] == 0.0)
    assert np.all(cap.limiting_actuator == -1)


# -- the hexapod: the same numbers as its compiled maps --------------------------------------
@pytest.fixture(scope="module")
def hexapod():
    return robot_registry.get("hexapod")


def near_home_hexapod(robot, n, seed):
    rng = np.random.default_rng(seed)
    spread = np.r_[0.04, 0.04, 0.04, 0.15, 0.15, 0.15]
    return robot.home_pose + rng.uniform(-1, 1, (n, 6)) * spread


def test_hexapod_agrees_with_its_compiled_maps(hexapod):
    poses = near_home_hexapod(hexapod, 50, seed=6)
    payload = np.array([1.0, -2.0, -30.0, 0.1, 0.2, -0.3])
    ours = wm.evaluate(hexapod, poses, payload)
    ref = hexapod_workspace.evaluate(hexapod, poses, payload)
    assert 5 <= np.count_nonzero(ref.ok) < len(poses)
    for field in ("reachable", "within_stroke", "regular", "ok"):
        np.testing.assert_array_equal(getattr(ours, field), getattr(ref, field), field)
    np.testing.assert_array_equal(np.isinf(ours.condition_number), np.isinf(ref.condition_number))
    ok = ref.ok
    np.testing.assert_allclose(ours.condition_number[ok], ref.condition_number[ok], rtol=1e-9)
    np.testing.assert_allclose(ours.sigma_min, ref.sigma_min, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(ours.static_forces, ref.static_forces, rtol=0, atol=1e-9)
    np.testing.assert_allclose(ours.type_one, ref.type_one, rtol=0, atol=1e-12)
    np.testing.assert_allclose(ours.type_two, ref.type_two, rtol=0, atol=1e-12)
    np.testing.assert_allclose(ours.q, ref.q, rtol=0, atol=1e-12)
    direction = np.array([0.0, 0.0, -9.81, 0.0, 0.0, 0.0])
    cap, cap_ref = (f(hexapod, poses, direction) for f in (wm.force_capability,
                                                           hexapod_workspace.force_capability))
    np.testing.assert_allclose(cap.scale, cap_ref.scale, rtol=1e-9, atol=1e-12)
    np.testing.assert_array_equal(cap.limiting_actuator, cap_ref.limiting_actuator)


class Refusing:
    """A robot whose batch routes refuse every chunk: the per-pose fallbacks run."""

    def __init__(self, robot):
        self._robot = robot

    def __getattr__(self, name):
        return getattr(self._robot, name)

    def jacobian_batch(self, poses, branch=None):
        raise SolverError("jacobian_batch", "refused", "test double")

    def static_forces_batch(self, poses, wrenches=None, *, bounded=True):
        raise SolverError("static_forces_batch", "refused", "test double")


def test_per_pose_fallback_gives_the_batch_answers(hexapod):
    poses = near_home_hexapod(hexapod, 30, seed=7)
    batch, single = wm.evaluate(hexapod, poses), wm.evaluate(Refusing(hexapod), poses)
    for field in ("reachable", "within_stroke", "regular", "ok"):
        np.testing.assert_array_equal(getattr(single, field), getattr(batch, field), field)
    np.testing.assert_allclose(single.condition_number, batch.condition_number, rtol=1e-12)
    np.testing.assert_allclose(single.static_forces, batch.static_forces, atol=1e-9)
    assert_never_nan(single)


def test_volume_estimate_moved_to_core_stays_importable():
    assert hexapod_workspace.volume_estimate is wm.volume_estimate
    assert hexapod_workspace.VolumeEstimate is wm.VolumeEstimate


# -- sampling, grids, volumes, progress ------------------------------------------------------
def test_sample_box_and_grid(five_bar, stewart):
    low, high = np.array([0.1, -0.2]), np.array([0.3, 0.1])
    a, b = (wm.sample_box(five_bar, 500, low, high, seed=9) for _ in range(2))
    np.testing.assert_array_equal(a, b)
    assert a.shape == (500, 2) and np.all((a >= low) & (a <= high))
    g = wm.grid(five_bar, [0.2, 0.0], [0.1, 0.05], (3, 2))
    np.testing.assert_allclose(g, [[0.1, -0.05], [0.1, 0.05], [0.2, -0.05], [0.2, 0.05],
                                   [0.3, -0.05], [0.3, 0.05]])
    g6 = wm.grid(stewart, stewart.home_pose, [0.01, 0.01, 0.01, 0, 0, 0], [2, 2, 2, 1, 1, 1])
    assert g6.shape == (8, 6) and np.all(g6[:, 3:] == stewart.home_pose[3:])


def test_volume_is_the_fraction_of_ok_samples_times_the_box(five_bar):
    low, high = five_bar.home_pose - 0.2, five_bar.home_pose + 0.2
    est = wm.volume(five_bar, 60, low, high, seed=11)
    m = wm.evaluate(five_bar, wm.sample_box(five_bar, 60, low, high, seed=11),
                    statics=False, singularity=False)
    p = np.mean(m.ok)
    assert 0.0 < p < 1.0
    assert est.box_volume == pytest.approx(0.16) and est.n_samples == 60
    assert est.volume == pytest.approx(0.16 * p)
    assert est.std_error == pytest.approx(0.16 * np.sqrt(p * (1 - p) / 60))
    strict = wm.volume(five_bar, 60, low, high, seed=11, max_condition=5.0)
    expected = np.mean(m.ok & (m.condition_number <= 5.0)) * 0.16
    assert strict.volume == pytest.approx(expected) and strict.volume <= est.volume


def test_progress_reports_increasing_fractions(hexapod):
    seen = []
    wm.evaluate(hexapod, near_home_hexapod(hexapod, 2 * wm.CHUNK + 5, seed=12),
                progress=seen.append)
    assert seen == sorted(seen) and len(seen) == 3 and seen[-1] == 1.0


def test_works_on_the_planar_robot():
    robot = robot_registry.get("planar")
    poses = wm.grid(robot, robot.home_pose, [0.05, 0.05, 0.2], 3)
    m = wm.evaluate(robot, poses)
    assert m.ok.any()
    assert_never_nan(m)
    assert_outside_rows_are_empty(m)


# -- bad inputs ------------------------------------------------------------------------------
def test_bad_inputs_raise_typed_errors(five_bar):
    good = five_bar.home_pose[None]
    with pytest.raises(ArgumentTypeError):
        wm.evaluate("robot", good)
    with pytest.raises(InputError, match="poses"):
        wm.evaluate(five_bar, [[np.nan, 0.0]])
    with pytest.raises(InputError, match="payload"):
        wm.evaluate(five_bar, good, [1.0, 2.0, 3.0])
    with pytest.raises(InputError, match="payload"):
        wm.evaluate(five_bar, np.repeat(good, 3, axis=0), np.zeros((2, 2)))
    with pytest.raises(ArgumentTypeError):
        wm.evaluate(five_bar, good, progress=3)
    with pytest.raises(InputError, match="direction"):
        wm.force_capability(five_bar, good, [0.0, 0.0])
    with pytest.raises(InputError, match="high"):
        wm.sample_box(five_bar, 3, [0.0, 0.0], [1.0, -1.0])
    with pytest.raises(InputError, match="high"):
        wm.volume(five_bar, 3, [0.0, 0.0], [1.0, 0.0])
    with pytest.raises(InputError, match="n_samples|n"):
        wm.volume(five_bar, 0, [0.0, 0.0], [1.0, 1.0])
    with pytest.raises(InputError, match="max_condition"):
        wm.volume(five_bar, 3, [0.0, 0.0], [1.0, 1.0], max_condition=-1.0)
    with pytest.raises(InputError, match="seed"):
        wm.sample_box(five_bar, 3, [0.0, 0.0], [1.0, 1.0], seed=-1)
    with pytest.raises(InputError, match="n"):
        wm.grid(five_bar, [0.0, 0.0], [0.1, 0.1], (2, 2, 2))
    with pytest.raises(InputError, match="half_extent"):
        wm.grid(five_bar, [0.0, 0.0], [0.1, 0.0], 2)


@settings(max_examples=40, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(shape=st.lists(st.integers(0, 4), min_size=0, max_size=3))
def test_random_bad_shapes_raise_input_error(five_bar, shape):
    arr = np.zeros(shape)
    if arr.ndim == 2 and arr.shape[1] == five_bar.pose_dim:
        return                                    # a well-formed batch of poses
    with pytest.raises(InputError):
        wm.evaluate(five_bar, arr)
    with pytest.raises(InputError):
        wm.force_capability(five_bar, arr, [0.0, -1.0])
    if arr.shape != (five_bar.pose_dim,) and arr.shape != (1, five_bar.pose_dim):
        with pytest.raises(InputError):
            wm.evaluate(five_bar, five_bar.home_pose[None], arr)


# -- drive effects: effort limits, springs, friction at rest ----------------------------------
def _stewart_poses(stewart, maps):
    poses, _, m = maps["stewart"]
    return poses[m.ok][:6]


def test_effort_limits_and_springs_enter_the_force_capability(stewart, maps):
    poses = _stewart_poses(stewart, maps)
    act = stewart.model.actuated_joints
    sprung = stewart.with_effects(stiffness={j: 300.0 for j in act})
    held = np.max(np.abs(sprung.static_forces_batch(poses, bounded=False)))
    effort = np.linspace(1.5, 3.0, len(act)) * held
    sprung = sprung.with_effects(effort_limit=effort)
    np.testing.assert_allclose(wm.actuator_force_bounds(sprung), np.minimum(
        effort, np.broadcast_to(stewart.geometry.max_actuator_force, effort.shape)))
    direction = np.array([0.0, 0.0, -50.0, 0.0, 0.0, 0.0])
    cap = wm.force_capability(sprung, poses, direction)
    limit = wm.actuator_force_bounds(sprung)
    for k, pose in enumerate(poses):
        assert cap.ok[k]
        tau0 = sprung.static_forces(pose, bounded=False)
        tau1 = sprung.static_forces(pose, direction, bounded=False) - tau0
        assert np.max(np.abs(tau0 - stewart.static_forces(pose, bounded=False))) > 1e-3
        np.testing.assert_allclose(cap.base_forces[k], tau0, atol=1e-9)
        np.testing.assert_allclose(cap.unit_forces[k], tau1, atol=1e-9)
        assert cap.scale[k] == pytest.approx(linprog_scale(tau0, tau1, limit), rel=1e-7)


def test_friction_at_rest_shrinks_the_guaranteed_capability(stewart, maps):
    poses = _stewart_poses(stewart, maps)
    act = stewart.model.actuated_joints
    coulomb = np.linspace(2.0, 7.0, len(act))
    rubbing = stewart.with_effects(coulomb=dict(zip(act, coulomb)))
    direction = np.array([0.0, 0.0, -50.0, 0.0, 0.0, 0.0])
    limit = wm.actuator_force_bounds(rubbing)
    plain = wm.force_capability(stewart, poses, direction)
    sure = wm.force_capability(rubbing, poses, direction)
    helped = wm.force_capability(rubbing, poses, direction, friction="helping")
    for k, pose in enumerate(poses):
        tau0 = stewart.static_forces(pose, bounded=False)
        tau1 = stewart.static_forces(pose, direction, bounded=False) - tau0
        # friction on the actuated joints: the band is static +- coulomb (closed form)
        np.testing.assert_allclose(sure.band_below[k], coulomb, atol=1e-9)
        np.testing.assert_allclose(sure.band_above[k], coulomb, atol=1e-9)
        assert sure.scale[k] == pytest.approx(linprog_scale(tau0, tau1, limit - coulomb),
                                              rel=1e-7)
        assert helped.scale[k] == pytest.approx(linprog_scale(tau0, tau1, limit + coulomb),
                                                rel=1e-7)
        assert sure.scale[k] < plain.scale[k] < helped.scale[k]
    with pytest.raises(InputError):
        wm.force_capability(rubbing, poses, direction, friction="sometimes")


def test_guaranteed_capability_with_passive_friction_puts_the_band_on_the_bound(stewart,
                                                                                maps):
    poses = _stewart_poses(stewart, maps)[:3]
    rubbing = stewart.with_effects(coulomb={"u_0_a": 3.0, "u_2_b": 2.0, "u_4_a": 1.5,
                                            stewart.model.actuated_joints[1]: 2.5})
    direction = np.array([0.0, 0.0, -50.0, 0.0, 0.0, 0.0])
    cap = wm.force_capability(rubbing, poses, direction)
    limit = wm.actuator_force_bounds(rubbing)
    for k, pose in enumerate(poses):
        i, s = cap.limiting_actuator[k], cap.scale[k]
        # the band at the loaded pose: the same half-widths, its edge on the bound
        band = rubbing.holding_forces(pose, s * direction)
        np.testing.assert_allclose(band.static - band.lower, cap.band_below[k], atol=1e-8)
        np.testing.assert_allclose(band.upper - band.static, cap.band_above[k], atol=1e-8)
        assert np.all(band.upper <= limit * (1 + 1e-9)) and np.all(band.lower >= -limit *
                                                                    (1 + 1e-9))
        assert max(band.upper[i] - limit[i], -limit[i] - band.lower[i]) == \
            pytest.approx(0.0, abs=1e-7 * limit[i])


def test_the_hexapods_compiled_capability_refuses_effects_it_does_not_model(hexapod):
    poses = near_home_hexapod(hexapod, 4, seed=2)
    direction = [0.0, 0.0, -1.0, 0.0, 0.0, 0.0]
    for values in ({"coulomb": {"carriage_0": 1.0}}, {"effort_limit": np.full(6, 40.0)}):
        driven = hexapod.with_effects(**values)
        with pytest.raises(InputError, match="workspace_maps"):
            hexapod_workspace.force_capability(driven, poses, direction)
        cap = wm.force_capability(driven, poses, direction)        # the generic maps
        assert np.any(cap.ok) and np.all(np.isfinite(cap.scale))
    rigid = wm.force_capability(hexapod, poses, direction)
    compiled = hexapod_workspace.force_capability(hexapod, poses, direction)
    np.testing.assert_allclose(rigid.scale, compiled.scale, rtol=1e-9)


def test_the_hexapods_compiled_maps_hold_springs_on_every_joint(hexapod):
    """Springs on the carriages (in the compiled kernels) and on the universal joints (not
    in them: the statics go state by state through the tree routes): the compiled
    ``evaluate`` statics equal the robot's own static forces with the payload, and the
    compiled force capability the generic one."""
    poses = near_home_hexapod(hexapod, 6, seed=3)
    poses = poses[hexapod_workspace.evaluate(hexapod, poses).ok]
    assert len(poses) >= 3
    payload = np.array([1.0, -2.0, -5.0, 0.1, 0.2, -0.1])
    direction = [0.0, 0.0, -1.0, 0.0, 0.0, 0.0]
    for stiffness in ({"carriage_1": 50.0}, {"u_0_a": [3.0], "u_3_b": [2.0]}):
        sprung = hexapod.with_effects(stiffness=stiffness)
        measures = hexapod_workspace.evaluate(sprung, poses, payload)
        assert np.all(measures.ok)
        expected = np.array([sprung.static_forces(p, payload, bounded=False) for p in poses])
        rigid = np.array([hexapod.static_forces(p, payload, bounded=False) for p in poses])
        assert np.max(np.abs(expected - rigid)) > 1e-3          # the springs matter here
        np.testing.assert_allclose(measures.static_forces, expected, rtol=1e-12, atol=1e-12)
        compiled = hexapod_workspace.force_capability(sprung, poses, direction)
        generic = wm.force_capability(sprung, poses, direction)
        np.testing.assert_allclose(compiled.scale, generic.scale, rtol=1e-9)
