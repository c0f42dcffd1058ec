"""Base-parameter counts, confirmed by an SVD rank written here on many random states
(closures exact: the poses are reached by the robots' own inverse kinematics)."""

from __future__ import annotations

import numpy as np
import pytest
import robot_registry

from hexapod_pin.identification import ClosedLoopRegressor, base_parameters, random_states

#: drive columns of each count below, after the inertial ones
DRIVES = ((), ("armature",), ("viscous", "coulomb"), ("armature", "viscous", "coulomb"),
          ("armature", "viscous", "coulomb", "offset"))
#: (tree, then one count per entry of DRIVES). The issue's numbers are tree / closed loop /
#: with "viscous, Coulomb and offset terms per actuator" (carriage armature merged with
#: carriage mass): 76 / 46 / 58 (hexapod), 94 / 88 / 106 (Stewart), 17 / 14 / 22
#: (planar). Measured: its last count is the one with ARMATURE, viscous and Coulomb
#: columns (hexapod 46 + 0 + 6 + 6: its rails are horizontal, so a carriage's armature
#: column qdd is its chain's mass column; Stewart 88 + 6 + 6 + 6; planar 14 + 2 + 3 + 3:
#: slider 0's rail is horizontal, the other two are inclined). Offsets add 6 (hexapod),
#: 6 (Stewart) and 1 (planar: on an inclined rail the mass column is qdd + g sin(alpha),
#: the armature's qdd and the offset's 1 span it, so only the horizontal slider's offset
#: is new).
COUNTS = {"hexapod": (76, 46, 46, 58, 58, 64), "stewart": (94, 88, 94, 100, 106, 112),
          "planar": (17, 14, 16, 20, 22, 23)}
#: the issue's counts: (standard, tree, closed loop, with the drive terms)
ISSUE = {"hexapod": (190, 76, 46, 58), "stewart": (190, 94, 88, 106),
         "planar": (90, 17, 14, 22)}


def _svd_rank(mat: np.ndarray) -> tuple[int, float]:
    """Rank of ``mat`` with unit-norm columns (singular values > 1e-9 of the largest) and
    the gap: the ratio of the last kept singular value to the first dropped one."""
    norms = np.linalg.norm(mat, axis=0)
    sv = np.linalg.svd(mat[:, norms > 0] / norms[norms > 0], compute_uv=False)
    rank = int(np.sum(sv > 1e-9 * sv[0]))
    gap = sv[rank - 1] / sv[rank] if rank < sv.size else np.inf
    return rank, gap


@pytest.mark.parametrize("name", sorted(COUNTS))
def test_counts_confirmed_by_svd(name):
    robot = robot_registry.get(name)
    tree = COUNTS[name][0]
    poses, twists, twist_dots = random_states(robot, 80, seed=21)
    reg = ClosedLoopRegressor(robot, DRIVES[-1])
    # the tree's rank: Pinocchio's joint torque regressor, all nv rows, stacked
    tree_rows, closed_rows = [], []
    for p, t, d in zip(poses, twists, twist_dots):
        motion = reg.tree_motion(p, t, d)
        assert np.max(np.abs(robot.model.residual(motion.q))) < 1e-10
        assert np.max(np.abs(robot.model.constraint_jacobian(motion.q) @ motion.v)) < 1e-9
        tree_rows.append(reg.tree_regressor(motion.q, motion.v, motion.a))
        closed_rows.append(reg.rows_of(motion))
    full = np.vstack(closed_rows)
    n_in = reg.layout.n_inertial
    assert reg.layout.n_inertial == ISSUE[name][0]
    rank, gap = _svd_rank(np.vstack(tree_rows))
    assert rank == tree and gap > 1e6
    for drive, expected in zip(DRIVES, COUNTS[name][1:]):
        columns = list(range(n_in)) + [i for kind in drive
                                       for i in range(*reg.layout.drive_slice(kind).indices(
                                           reg.layout.size))]
        rank, gap = _svd_rank(full[:, columns])
        assert rank == expected
        assert gap > 1e6                       # a clear numerical rank
        base = base_parameters(robot, drive)
        assert base.count == expected == len(base.names) == len(base.rules())
    # the issue's numbers, exactly
    assert (tree, COUNTS[name][1], COUNTS[name][4]) == ISSUE[name][1:]


def test_regrouping_reproduces_the_regressor():
    """W pi = W_b (K pi) for any pi, on states the base was not found on; the rules name
    the parameters they regroup."""
    robot = robot_registry.get("planar")
    base = base_parameters(robot)
    reg = ClosedLoopRegressor(robot, base.layout.drive)
    full = reg.batch(*random_states(robot, 10, seed=99))
    pi = np.random.default_rng(0).normal(size=base.layout.size)
    assert np.allclose(full @ pi, base.regressor(full) @ base.values(pi), rtol=0, atol=1e-9)
    assert all(rule.split(" = ")[0] == name for rule, name in zip(base.rules(), base.names))
    assert any("m_slider_0" in rule for rule in base.rules())


def test_armature_merges_on_horizontal_rails_only():
    """The regrouping rules name the merges the counts imply: a hexapod carriage's
    armature with its chain's mass, the planar robot's slider 0 (horizontal rail) likewise,
    its inclined sliders' armature on its own and their offsets merged into it."""
    drive = ("armature", "viscous", "coulomb", "offset")
    hexapod = base_parameters(robot_registry.get("hexapod"), drive)
    rules = hexapod.rules()
    for k in range(6):
        assert any(f"Ia_carriage_{k}" in r and f"m_carriage_{k}" in r for r in rules)
    planar = base_parameters(robot_registry.get("planar"), drive)
    rules = planar.rules()
    assert any("Ia_slider_0" in r and "m_slider_0" in r for r in rules)
    for k in (1, 2):
        rule = next(r for r in rules if r.startswith(f"Ia_slider_{k} ="))
        assert "m_" not in rule and f"off_slider_{k}" in rule
