"""Results come with their conditioning (issue 16, "conditioning-aware answers").

The dynamics results of both robots carry ``singularity``: the robot's
:class:`~hexapod_pin.core.results.SingularityMeasures` at the result's pose and branch,
computed on first access (not before) under the robot's lock. Compared here with
``robot.singularity(pose, branch)`` at regular poses and at poses just above each
threshold, found by bisection on the measure itself. Also: the planar closed form's own
residual refusals carry a measure and its threshold, the type-II label is spelled as the
hexapod's, and overflowing motions name the user's argument.
"""

import math
import threading

import numpy as np
import pytest

import hexapod_pin as hp
from hexapod_pin.core.measures import TYPE_I_TOL, TYPE_II_TOL

TYPE_I_HEIGHT = math.sqrt(0.45 ** 2 - 0.23 ** 2)
HEX_TYPE_II = np.array([-0.020475341567368716, -0.013968434364764802, 0.31024850589967956,
                        0.2754338045906446, -0.7399207239621679, -0.13470940466330802])
PLANAR_TYPE_II = np.array([0.0020209507676428916, 0.002521242674892949, 0.5855816720810173])
# a planar forward-dynamics state that the closed form refuses on its own residual check
# (|cos| = 2.6e-3, just above TYPE_I_TOL)
PLANAR_RESIDUAL = (np.array([0.06889491514077074, 0.02066847454223122, 0.0]),
                   np.array([-0.05558657807935546, -0.1171156834025543, -0.6675054787796914]),
                   np.array([1.662879943381042, 0.5795828875355198, 0.6932742302361041]))


@pytest.fixture(scope="module")
def planar():
    return hp.Planar3PRR.default()


def bisect(robot, start, end, measure, target):
    """The pose on the segment ``start -> end`` where ``measure`` crosses ``target``, on
    its regular side (``measure >= target``); ``measure(start) < target <= measure(end)``."""
    lo, hi = 0.0, 1.0
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        try:
            value = measure(robot.singularity(start + mid * (end - start)))
        except hp.UnreachablePoseError:
            value = -1.0
        lo, hi = (mid, hi) if value < target else (lo, mid)
    return start + hi * (end - start)


def near_thresholds(robot):
    """A pose just above the type-I threshold and one just above the type-II threshold."""
    home = np.asarray(robot.home_pose, dtype=float)
    if robot.pose_dim == 6:
        low = home.copy()
        low[2] = TYPE_I_HEIGHT
        one = bisect(robot, low, home, lambda m: m.type_one, 1.05 * TYPE_I_TOL)
        two = bisect(robot, HEX_TYPE_II, home, lambda m: m.type_two, 3.0 * TYPE_II_TOL)
    else:
        far = home + 0.12 * np.array([1.0, 0.3, 0.0])      # beyond the reach boundary
        one = bisect(robot, far, home, lambda m: m.type_one, 1.05 * TYPE_I_TOL)
        two = bisect(robot, PLANAR_TYPE_II, home, lambda m: m.type_two, 3.0 * TYPE_II_TOL)
    m_one, m_two = robot.singularity(one), robot.singularity(two)
    assert TYPE_I_TOL <= m_one.type_one < 1.1 * TYPE_I_TOL and m_one.regular
    assert TYPE_II_TOL <= m_two.type_two < 4.0 * TYPE_II_TOL and m_two.regular
    return [one, two]


def same_measures(got, want):
    assert isinstance(got, hp.SingularityMeasures)
    for name in ("condition_number", "type_one", "type_one_actuator", "type_two",
                 "characteristic_length", "type_one_threshold", "type_two_threshold"):
        assert getattr(got, name) == getattr(want, name), name
    np.testing.assert_array_equal(got.type_two_singular_values, want.type_two_singular_values)
    if want.jacobian_singular_values is None:
        assert got.jacobian_singular_values is None
    else:
        np.testing.assert_array_equal(got.jacobian_singular_values,
                                      want.jacobian_singular_values)
    assert got.regular == want.regular


@pytest.mark.parametrize("which", ["hexapod", "planar"])
def test_results_carry_the_measures_of_their_pose(which, robot, planar):
    """``result.singularity == robot.singularity(pose)`` for every inverse and forward
    route, at regular poses and just above each threshold."""
    rob = robot if which == "hexapod" else planar
    dim = rob.pose_dim
    rng = np.random.default_rng(16)
    home = np.asarray(rob.home_pose, dtype=float)
    regular = [home, home + 0.01 * rng.normal(size=dim)]
    # every route at regular poses; the closed forms (the default routes) near the
    # thresholds (the generic tree solvers need not converge there)
    for pose, routes in [(p, (("kkt", "qp"), ("nullspace", "kkt", "pinocchio", "qp")))
                         for p in regular] + \
            [(p, (("kkt",), ("nullspace",))) for p in near_thresholds(rob)]:
        want = rob.singularity(pose)
        twist = np.zeros(dim)
        for method in routes[0]:
            res = rob.inverse_dynamics(pose, twist, np.zeros(dim), bounded=False,
                                       method=method)
            same_measures(res.singularity, want)
        tau = res.actuator_forces
        for method in routes[1]:
            same_measures(rob.forward_dynamics(pose, twist, tau, method=method).singularity,
                          want)
    # the thresholds the near poses were bisected against are the ones reported
    assert want.type_one_threshold == TYPE_I_TOL and want.type_two_threshold == TYPE_II_TOL


@pytest.mark.parametrize("which", ["hexapod", "planar"])
def test_measures_follow_the_result_branch(which, robot, planar):
    """A result on another branch carries that branch's measures (on the 3-PRR they
    differ from the home branch's; the hexapod's mirrored branch has the same), at the
    pose as given even if the caller's array changes later."""
    rob = robot if which == "hexapod" else planar
    dim = rob.pose_dim
    if dim == 6:
        branch = np.array([1.0, -1.0, 1.0, -1.0, 1.0, -1.0])     # every leg mirrored
        pose = np.array(rob.home_pose, dtype=float) + [0.005, -0.003, -0.01, 0.02, -0.01,
                                                       0.03]
    else:
        branch = np.array([-1.0, 1.0, 1.0])
        pose = np.array(rob.home_pose, dtype=float)
    res = rob.inverse_dynamics(pose, np.zeros(dim), np.zeros(dim), branch=branch,
                               bounded=False)
    fwd = rob.forward_dynamics(pose, np.zeros(dim), res.actuator_forces, branch=branch)
    want = rob.singularity(pose, branch)
    assert not np.array_equal(res.configuration, rob.inverse_dynamics(
        pose, np.zeros(dim), np.zeros(dim), bounded=False).configuration)
    if dim == 3:
        assert want.type_two != rob.singularity(pose).type_two
    pose += 0.05                                 # the caller's array, after the call
    same_measures(res.singularity, want)
    same_measures(fwd.singularity, want)


@pytest.mark.parametrize("which", ["hexapod", "planar"])
def test_measures_are_computed_on_first_access_only(which, robot, planar):
    """Computing a result does not compute its measures; the first read does, once."""
    rob = robot if which == "hexapod" else planar
    dim = rob.pose_dim
    pose = np.asarray(rob.home_pose, dtype=float)
    res = rob.inverse_dynamics(pose, np.zeros(dim), np.zeros(dim))
    fwd = rob.forward_dynamics(pose, np.zeros(dim), res.actuator_forces)
    for result in (res, fwd):
        assert "singularity" not in vars(result)
        assert result._conditioning.value is None
    first = res.singularity
    assert vars(res)["singularity"] is first and res._conditioning.value is first
    assert res.singularity is first
    assert fwd._conditioning.value is None               # its own, still not computed


def test_measures_of_results_read_from_several_threads(robot, planar):
    """Results read on other threads while the robots compute: each measure equals the
    one computed alone (the lazy part holds the robot's lock)."""
    rng = np.random.default_rng(7)
    cases = []
    for rob in (robot, planar):
        dim = rob.pose_dim
        for _ in range(4):
            pose = np.asarray(rob.home_pose, dtype=float) + 0.01 * rng.normal(size=dim)
            cases.append((rob, pose, rob.singularity(pose)))
    results = [rob.inverse_dynamics(pose, np.zeros(rob.pose_dim), np.zeros(rob.pose_dim))
               for rob, pose, _ in cases]
    errors = []

    def worker(k):
        try:
            for i in range(len(cases)):
                j = (i + k) % len(cases)
                rob, pose, want = cases[j]
                rob.inverse_dynamics(pose, np.ones(rob.pose_dim) * 0.01,
                                     np.zeros(rob.pose_dim))
                same_measures(results[j].singularity, want)
        except (AssertionError, hp.HexapodPinError) as exc:     # reported on the main thread
            errors.append(exc)

    threads = [threading.Thread(target=worker, args=(k,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors, errors


def test_planar_residual_refusals_carry_a_measure_and_threshold(planar):
    """The planar closed form's own residual check (before: a SingularityError without a
    threshold) reports the pose's measure nearer its threshold, with that threshold; the
    batch route says the same of the same state."""
    pose, twist, forces = PLANAR_RESIDUAL
    measures = planar.singularity(pose)
    with pytest.raises(hp.SingularityError, match="residual") as info:
        planar.forward_dynamics(pose, twist, forces)
    assert info.value.threshold == TYPE_I_TOL
    assert info.value.sigma_min == measures.type_one
    assert "type-I" in str(info.value) and "threshold" in str(info.value)
    home = np.asarray(planar.home_pose, dtype=float)
    with pytest.raises(hp.BatchSingularityError, match="residual") as batch:
        planar.forward_dynamics_batch(np.array([home, pose]), np.array([np.zeros(3), twist]),
                                      np.array([forces, forces]))
    assert batch.value.index == 1
    assert batch.value.threshold == TYPE_I_TOL
    assert batch.value.sigma_min == measures.type_one


def test_type_two_label_is_one_spelling(robot, planar):
    """Both robots call a type-II refusal "type-II"."""
    for rob, pose in ((robot, HEX_TYPE_II), (planar, PLANAR_TYPE_II)):
        dim = rob.pose_dim
        with pytest.raises(hp.SingularityError, match="type-II") as info:
            rob.inverse_dynamics(pose, np.zeros(dim), np.zeros(dim), bounded=False)
        assert "type II" not in str(info.value)
        assert info.value.threshold == TYPE_II_TOL


def test_planar_overflowing_motion_names_the_argument(planar):
    """A twist of 1e160 (its square overflows in the tree accelerations) is refused as an
    InputError naming ``twist`` (before: the internal ``a``); likewise ``twist_dot``."""
    zero = np.zeros(3)
    for method in ("kkt", "qp"):
        with pytest.raises(hp.InputError, match="twist") as info:
            planar.inverse_dynamics(zero, np.array([1e160, 0.0, 0.0]), zero, method=method)
        assert info.value.name == "twist"
        with pytest.raises(hp.InputError) as info:
            planar.inverse_dynamics(zero, zero, np.full(3, 1e308), method=method)
        assert info.value.name == "twist_dot"
