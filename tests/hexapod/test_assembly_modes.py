"""Assembly modes: completeness against a brute-force search with an independent solver
(Newton in pose coordinates on the six leg-length equations, from many random starts),
the home count, mirror symmetry, IK of every mode, the Pinocchio tree closing, degeneracies."""

import numpy as np
import pinocchio as pin
import pytest

import hexapod_pin as hp
from hexapod_pin.hexapod import assembly_modes as am

from conftest import random_pose


def _leg_residuals(robot, pos, rot, q):
    """Six leg-length equations |P_k - c_i|^2 - L^2 (N, 6) for N poses (pos (N, 3), rot
    (N, 3, 3)), and their Jacobians (N, 6, 6) in world-axes increments: rows [2 n, 2 r x n]."""
    g = robot.geometry
    rail = np.array([0, 0, 1, 1, 2, 2])
    arms = np.einsum("nij,kj->nki", rot, g.platform_points[rail])
    legs = pos[:, None] + arms - (g.rail_midpoints[rail] + q[:, None] * g.rail_directions[rail])
    res = np.einsum("nki,nki->nk", legs, legs) - g.leg_length ** 2
    jac = 2 * np.concatenate([legs, np.cross(arms, legs)], axis=2)
    return res, jac


def _exp3(w):
    """Rodrigues' formula for many rotation vectors (N, 3) -> (N, 3, 3)."""
    angle = np.linalg.norm(w, axis=1)[:, None, None]
    k = np.zeros((w.shape[0], 3, 3))
    k[:, 0, 1], k[:, 0, 2], k[:, 1, 2] = -w[:, 2], w[:, 1], -w[:, 0]
    k = k - k.transpose(0, 2, 1)
    small = angle < 1e-8
    safe = np.where(small, 1.0, angle)
    a = np.where(small, 1.0, np.sin(safe) / safe)
    b = np.where(small, 0.5, (1 - np.cos(safe)) / safe ** 2)
    return np.eye(3) + a * k + b * k @ k


def brute_force_modes(robot, q, n_starts, rng):
    """Distinct platform-point triples (3, 3) of the assemblies found by damped Newton in
    pose coordinates (R <- exp(dw) R, world-axes increments) from random starts, all starts
    at once (an independent solver: no circles, no resultants)."""
    g = robot.geometry
    pos = rng.uniform(-1, 1, (n_starts, 3)) * g.leg_length
    quat = rng.normal(size=(n_starts, 4))
    rot = np.array([pin.Quaternion(*(v / np.linalg.norm(v))).toRotationMatrix() for v in quat])
    for _ in range(80):
        res, jac = _leg_residuals(robot, pos, rot, q)
        jt = jac.transpose(0, 2, 1)
        normal = jt @ jac + 1e-14 * np.eye(6)
        step = -np.linalg.solve(normal, (jt @ res[..., None]))[..., 0]
        norm = np.linalg.norm(step, axis=1)
        scale = np.minimum(1.0, 0.2 / np.maximum(norm, 1e-300))[:, None]  # damp wild steps
        pos = pos + scale * step[:, :3]
        rot = _exp3(scale * step[:, 3:]) @ rot
    res, _ = _leg_residuals(robot, pos, rot, q)
    found = []
    for n in np.flatnonzero(np.max(np.abs(res), axis=1) < 1e-12):
        points = pos[n] + g.platform_points @ rot[n].T
        if not any(np.max(np.abs(points - f)) < 1e-7 for f in found):
            found.append(points)
    return found


def _points(robot, pose):
    return robot.platform_points_world(pose)


def _same_sets(modes_points, brute_points, tol=1e-7):
    unmatched = [m for m in modes_points if not any(np.max(np.abs(m - b)) < tol
                                                    for b in brute_points)]
    extra = [b for b in brute_points if not any(np.max(np.abs(m - b)) < tol
                                                for m in modes_points)]
    return unmatched, extra


def test_home_has_eight_modes_sorted_and_mirrored(any_robot):
    q = any_robot.home_q
    modes = any_robot.assembly_modes(q)
    assert len(modes) == 8
    heights = [m[2] for m in modes]
    assert heights == sorted(heights, reverse=True)
    assert sum(h > 0 for h in heights) == 4
    np.testing.assert_allclose(modes[0], any_robot.home_pose, atol=1e-12)
    mirror = np.diag([1.0, 1.0, -1.0])
    points = [_points(any_robot, m) for m in modes]
    for p in points:                                  # the mirror image is an assembly too
        assert min(np.max(np.abs(p @ mirror - other)) for other in points) < 1e-12


def test_every_mode_closes_the_tree_and_has_the_same_ik(any_robot, rng):
    for q in (any_robot.home_q, any_robot.inverse_kinematics(random_pose(any_robot, rng))):
        modes = any_robot.assembly_modes(q)
        assert len(modes) >= 2 and len(modes) % 2 == 0 and len(modes) <= 16
        for mode in modes:
            branch = any_robot.branch_of(mode, q)
            np.testing.assert_allclose(any_robot.inverse_kinematics(mode, branch,
                                                                    check_limits=False),
                                       q, atol=1e-12)
            tree_q = any_robot.configuration(mode, branch=branch)
            assert np.max(np.abs(any_robot.model.residual(tree_q))) <= 1e-12
        # distinct
        for a in range(len(modes)):
            for b in range(a):
                gap = _points(any_robot, modes[a]) - _points(any_robot, modes[b])
                assert np.max(np.abs(gap)) > 1e-6


@pytest.mark.parametrize("which", ["home", "random"])
def test_modes_match_brute_force(any_robot, which):
    rng = np.random.default_rng(7)
    q = any_robot.home_q if which == "home" else any_robot.inverse_kinematics(
        random_pose(any_robot, rng, scale=1.5))
    modes = any_robot.assembly_modes(q)
    brute = brute_force_modes(any_robot, q, 400, rng)
    unmatched, extra = _same_sets([_points(any_robot, m) for m in modes], brute)
    assert not extra, "brute force found an assembly that assembly_modes missed"
    assert not unmatched, "assembly_modes returned a pose brute force never found"
    assert len(modes) == len(brute)


def test_modes_of_a_pose_include_it(robot, rng):
    for _ in range(3):
        pose = random_pose(robot, rng, scale=1.5)
        modes = robot.assembly_modes(robot.inverse_kinematics(pose))
        assert min(np.max(np.abs(m - pose)) for m in modes) < 1e-12


def test_eliminant_is_a_trigonometric_polynomial_of_degree_eight(any_robot, rng):
    """The sampled eliminant has no energy above frequency 8 (the degree-16 bound), and it
    vanishes at the theta_0 of every assembly."""
    q = any_robot.inverse_kinematics(random_pose(any_robot, rng))
    system = am.circle_system(any_robot.kinematics.circles, q)
    coeffs, roots, aliasing = am.eliminant_roots(system)
    assert aliasing < 1e-12
    assert roots.shape == (16,)
    scale = np.max(np.abs(coeffs))
    for mode in any_robot.assembly_modes(q):
        theta0 = system.angles_of(any_robot.platform_points_world(mode))[0]
        value = am.resultant_samples(system, np.array([theta0]))[0]
        assert abs(value) < 1e-9 * scale


def test_far_apart_carriages_have_no_assembly_and_coincident_ones_are_degenerate(robot):
    g = robot.geometry
    assert robot.assembly_modes([-g.leg_length - 1e-3, g.leg_length + 1e-3,
                                 -0.1, 0.1, -0.1, 0.1]).shape == (0, 6)
    with pytest.raises(hp.AssemblyError, match="coincide"):
        robot.assembly_modes([0.1, 0.1, -0.1, 0.1, -0.1, 0.1])
    with pytest.raises(hp.AssemblyError, match="stretched"):
        robot.assembly_modes([-g.leg_length, g.leg_length, -0.1, 0.1, -0.1, 0.1])
    with pytest.raises(hp.InputError):
        robot.assembly_modes([0.1, np.nan, -0.1, 0.1, -0.1, 0.1])
    with pytest.raises(hp.InputError):
        robot.assembly_modes(np.zeros(7))


def test_crossed_carriages_assemble_like_their_mirror_on_the_rail(robot):
    """Swapping the two carriages of every rail leaves each leg-sphere pair, hence every
    assembly, unchanged (only the legs' labels swap)."""
    q = robot.home_q + np.array([0.01, -0.02, 0.0, 0.03, -0.01, 0.0])
    swapped = q.reshape(3, 2)[:, ::-1].ravel()
    a, b = robot.assembly_modes(q), robot.assembly_modes(swapped)
    assert len(a) == len(b) == 8
    for x, y in zip(a, b):
        np.testing.assert_allclose(x, y, atol=1e-12)


def test_branch_of_rejects_a_pose_that_does_not_assemble(robot):
    with pytest.raises(hp.InputError):
        robot.branch_of(robot.home_pose + 0.01, robot.home_q)
