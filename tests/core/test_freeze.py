"""Freezing joints (core/freeze.py): a reduced ClosedLoopModel whose closures still hold.

Independent checks: the reduced closure residual equals the full model's at every
(unassembled) configuration with the locked values; the reduced forward dynamics equals a
numpy KKT solve of the FULL model written here, with rows ``a[locked] = 0`` added to the
closures; rigid closures are dropped only when they hold.
"""

import numpy as np
import pinocchio as pin
import pytest

import stress_robots
from conftest import random_pose
from hexapod_pin.core.dynamics import forward_dynamics_tree
from hexapod_pin.core.freeze import freeze_joints
from hexapod_pin.errors import AssemblyError, InputError
from hexapod_pin.loaders import robots

# robot -> joints to lock (actuated and passive ones)
LOCKS = {
    "five_bar_stiff": ["mot1"],
    "five_bar_massless": ["free2"],
    "delta_weld": ["motor_0", "elbow_1_Y"],
    "delta_massless": ["motor_2"],
    "ladder_mixed": ["bar_3"],
    "planar_ladder_weld": ["bar_2"],
}


def full_kkt_with_locked_joints(clm, q, v, tau, locked_v):
    """Reference: ``M a + h = tau - D v + J^T lambda`` with ``J = [J_c; S_locked]`` and
    ``J a = [-gamma; 0]``, least squares (redundant rows), written here (``D``: the joint
    damping of the description, as Pinocchio's parser stores it in ``model.damping``;
    ``crba`` adds ``model.armature``)."""
    tau = tau - np.asarray(clm.model.damping) * v
    data = clm.model.createData()
    mass = pin.crba(clm.model, data, q)
    mass = np.triu(mass) + np.triu(mass, 1).T
    bias = pin.nle(clm.model, data, q, v)
    sel = np.zeros((len(locked_v), clm.nv))
    sel[np.arange(len(locked_v)), locked_v] = 1.0
    jac = np.vstack([clm.constraint_jacobian(q), sel])
    rhs = np.concatenate([-clm.constraint_drift(q, v), np.zeros(len(locked_v))])
    n = jac.shape[0]
    kkt = np.block([[mass, -jac.T], [jac, np.zeros((n, n))]])
    sol = np.linalg.lstsq(kkt, np.concatenate([tau - bias, rhs]), rcond=None)[0]
    return sol[:clm.nv]


def _check_frozen_dynamics(frozen, q, rng, tau_full_extra=None):
    full, red = frozen.full, frozen.model
    q_red = frozen.reduced_configuration(q)
    assert np.max(np.abs(red.residual(q_red))) <= 1e-12
    v_red = red.project_velocity(q_red, rng.normal(size=red.nv), metric="euclidean")
    u = rng.normal(size=red.n_actuated)
    acc = frozen.full_velocity(forward_dynamics_tree(red, q_red, v_red, u, method="kkt").a)
    tau = np.zeros(full.nv)
    for joint, value in zip(red.actuated_joints, u):
        tau[full.joint_v_index(joint)] = value
    locked_v = np.setdiff1d(np.arange(full.nv), frozen.v_index)
    ref = full_kkt_with_locked_joints(full, q, frozen.full_velocity(v_red), tau, locked_v)
    np.testing.assert_allclose(acc, ref, atol=1e-9 * max(1.0, np.abs(ref).max()))


@pytest.mark.parametrize("name", sorted(LOCKS))
def test_frozen_dynamics_equal_the_full_model_with_locked_accelerations(name):
    stress = stress_robots.build(name)
    rng = np.random.default_rng(21)
    for _ in range(2):
        q, _ = stress.sample(rng)
        frozen = freeze_joints(stress.clm, LOCKS[name], q)
        assert frozen.model.nv == stress.clm.nv - len(LOCKS[name])
        assert set(frozen.model.actuated_joints) == set(stress.clm.actuated_joints) - set(LOCKS[name])
        _check_frozen_dynamics(frozen, q, rng)


@pytest.mark.parametrize("name", sorted(LOCKS))
def test_reduced_closures_are_the_full_closures(name):
    """At random (unassembled) configurations with the locked values: same residual."""
    stress = stress_robots.build(name)
    rng = np.random.default_rng(22)
    q_lock, _ = stress.sample(rng)
    frozen = freeze_joints(stress.clm, LOCKS[name], q_lock)
    for _ in range(3):
        q_red = pin.integrate(frozen.model.model, frozen.reduced_configuration(q_lock),
                              rng.uniform(-0.3, 0.3, frozen.model.nv))
        q_full = frozen.full_configuration(q_red)
        np.testing.assert_allclose(frozen.model.residual(q_red), stress.clm.residual(q_full),
                                   atol=1e-13)
        np.testing.assert_array_equal(frozen.reduced_configuration(q_full), q_red)


def test_hexapod_with_a_carriage_locked(robot, rng):
    """The hexapod's platform is a free flyer in the tree: lock one carriage, the reduced
    model has 5 actuators and 5 DoF, and its dynamics match the full KKT with the lock."""
    q = robot.configuration(random_pose(robot, rng))
    frozen = freeze_joints(robot.model, [robot.model.actuated_joints[0]], q)
    assert frozen.model.n_actuated == 5
    assert frozen.model.mobility(frozen.reduced_configuration(q)) == 5
    _check_frozen_dynamics(frozen, q, rng)


def test_cassie_with_rigid_springs():
    """Locking Cassie's knee and heel springs: the leg loops still hold on the reduced tree,
    the dynamics match the full model with the spring accelerations held at zero."""
    cassie = robots.cassie(root="fixed")
    q0 = pin.neutral(cassie.model)
    for side in ("left", "right"):
        q0[cassie.joint_q_index(f"{side}-pitch-op")] = 0.3
        q0[cassie.joint_q_index(f"{side}-foot-op")] = -0.4
    springs = [f"{side}-{j}" for side in ("left", "right")
               for j in ("knee-shin-joint", "tarsus-spring-joint")]
    q = cassie.assemble(q0, fixed=np.r_[cassie.actuated_v,
                                        [cassie.joint_v_index(s) for s in springs]]).q
    frozen = freeze_joints(cassie, springs, q)
    assert frozen.model.nv == cassie.nv - 4 and frozen.model.n_rows == cassie.n_rows
    _check_frozen_dynamics(frozen, q, np.random.default_rng(23))


def test_solo12_free_flyer_base_with_joints_locked():
    """Solo-12 standing (free-flyer base, feet held by point closures to the world): lock
    one knee, then a knee and a hip; the base stays free, the mobility drops by one each."""
    solo = robots.solo12()
    q = robots.solo12_stand(solo, [0.0, 0.0, 0.25]).q
    for lock, mobility in ((["FL_KFE"], 5), (["FL_KFE", "HR_HAA"], 4)):
        frozen = freeze_joints(solo, lock, q)
        assert frozen.model.mobility(frozen.reduced_configuration(q)) == mobility
        _check_frozen_dynamics(frozen, q, np.random.default_rng(26))


def test_a_loop_made_rigid_is_dropped_only_when_it_holds():
    five = stress_robots.build("five_bar_stiff")
    q, _ = five.sample(np.random.default_rng(24))
    all_joints = list(five.clm.model.names[1:])
    frozen = freeze_joints(five.clm, all_joints, q)
    assert frozen.dropped_closures == tuple(c.name for c in five.clm.closures)
    assert frozen.model.n_rows == 0
    broken = q.copy()
    broken[five.clm.joint_q_index("mot1")] += 0.1
    with pytest.raises(AssemblyError):
        freeze_joints(five.clm, all_joints, broken)


def test_input_errors():
    five = stress_robots.build("five_bar_stiff")
    q, _ = five.sample(np.random.default_rng(25))
    with pytest.raises(InputError):
        freeze_joints(five.clm, ["no_such_joint"], q)
    with pytest.raises(InputError):
        freeze_joints(five.clm, ["mot1", "mot1"], q)
    with pytest.raises(InputError):
        freeze_joints(five.clm, ["mot1"], q[:-1])
