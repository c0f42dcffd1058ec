"""Joint and drive effects in the closed forms of the hexapod and the planar 3-PRR.

Every check compares against an independent route: the rigid robot's answer plus the
terms written here (``u_i += a_i qdd_i + d_i qd_i + c_i sign(qd_i) + k_i (q_i - r_i)`` for
the actuated joints), the Pinocchio tree routes on ``robot.model``
(:func:`forward_dynamics_tree`, :func:`inverse_dynamics_tree`), the inverse dynamics
(stick / slip conditions of a forward answer) and central differences. The robots come
from ``tests/robot_registry.py`` (group "closed_form").
"""

from __future__ import annotations

import numpy as np
import pytest

import robot_registry
from hexapod_pin.core.dynamics import forward_dynamics_tree, inverse_dynamics_tree
from hexapod_pin.core.robot_api import FORWARD_DYNAMICS_METHODS
from hexapod_pin.errors import InputError

ROBOTS = robot_registry.names("closed_form")
#: a passive coordinate of each robot (a universal joint, a link)
PASSIVE_JOINT = {"hexapod": "u_0_a", "planar": "link_0_joint"}
CASES = ("armature", "damping", "coulomb", "springs", "all")


def close(got, want, tol):
    """``|got - want| <= tol max(1, |want|_max)`` elementwise."""
    got, want = np.asarray(got, dtype=float), np.asarray(want, dtype=float)
    np.testing.assert_allclose(got, want, rtol=0.0,
                               atol=tol * max(1.0, float(np.abs(want).max(initial=0.0))))


def per_actuator(robot, base, step):
    """``{actuated joint k: base + step k}``."""
    return {name: base + step * k for k, name in enumerate(robot.model.actuated_joints)}


def actuated_q(robot):
    """Indices into ``q`` of the actuated joints."""
    model = robot.model.model
    return np.array([model.joints[model.getJointId(j)].idx_q
                     for j in robot.model.actuated_joints])


def drive_fields(robot, case):
    """The ``with_effects`` fields of a case, on the actuated joints only."""
    home = robot.home_configuration[actuated_q(robot)]
    ref = {name: [home[k] + 0.003 * (k + 1)] for k, name in
           enumerate(robot.model.actuated_joints)}
    fields = {"armature": {"armature": per_actuator(robot, 0.3, 0.15)},
              "damping": {"damping": per_actuator(robot, 2.0, 1.5)},
              "coulomb": {"coulomb": per_actuator(robot, 0.4, 0.2)},
              "springs": {"stiffness": per_actuator(robot, 40.0, 15.0),
                          "spring_reference": ref}}
    if case == "all":
        return {k: v for part in fields.values() for k, v in part.items()}
    return fields[case]


_BUILT: dict = {}


def with_case(name, case):
    """The robot ``name`` with the drive effects of ``case`` (built once)."""
    key = (name, case)
    if key not in _BUILT:
        _BUILT[key] = robot_registry.get(name).with_effects(**drive_fields(
            robot_registry.get(name), case))
    return _BUILT[key]


def motion(robot, seed):
    """A state near home with every actuator sliding: pose, twist, twist_dot, wrench."""
    rng = np.random.default_rng(seed)
    dim = robot.pose_dim
    pose = robot.home_pose + rng.uniform(-0.004, 0.004, dim)
    twist, twist_dot = rng.uniform(-0.08, 0.08, dim), rng.uniform(-0.8, 0.8, dim)
    return pose, twist, twist_dot, rng.uniform(-1.0, 1.0, dim)


def drive_terms(robot, effects_robot, res):
    """``a qdd + d qd + c sign(qd) + k (q - r)`` (n_act,) written from the record."""
    eff, act = effects_robot.effects, robot.model.actuated_v
    q = res.configuration[actuated_q(robot)]
    qd, qdd = res.velocity[act], res.acceleration[act]
    ref = eff.spring_reference[actuated_q(robot)]
    return (eff.armature[act] * qdd + eff.damping[act] * qd + eff.coulomb[act] * np.sign(qd)
            + eff.stiffness[act] * (q - ref))


@pytest.mark.parametrize("case", CASES)
@pytest.mark.parametrize("name", ROBOTS)
def test_inverse_dynamics_adds_the_drive_terms(name, case):
    """Each effect alone and all together: the rigid forces plus the terms written here,
    the same in the single state ("kkt" and "qp"), the batch (1e-12) and the tree route on
    robot.model (1e-10, no wrench: the tree takes the drives from the same record)."""
    robot, eff = robot_registry.get(name), with_case(name, case)
    for seed in range(3):
        pose, twist, twist_dot, wrench = motion(robot, seed)
        rigid = robot.inverse_dynamics(pose, twist, twist_dot, wrench)
        want = rigid.actuator_forces + drive_terms(robot, eff, rigid)
        for method in ("kkt", "qp"):
            got = eff.inverse_dynamics(pose, twist, twist_dot, wrench, method=method)
            close(got.actuator_forces, want, 1e-10)
        batch = eff.inverse_dynamics_batch(pose[None], twist[None], twist_dot[None],
                                           wrench[None])
        close(batch.actuator_forces[0], got.actuator_forces, 1e-12)
        close(batch.closure_forces[0], got.closure_forces, 1e-10)
        plain = eff.inverse_dynamics(pose, twist, twist_dot)
        tree = inverse_dynamics_tree(eff.model, plain.configuration, plain.velocity,
                                     plain.acceleration)
        close(plain.actuator_forces, tree.actuator_forces, 1e-10)


@pytest.mark.parametrize("case", CASES)
@pytest.mark.parametrize("name", ROBOTS)
def test_forward_dynamics_inverts_inverse_dynamics(name, case):
    """``forward(inverse(x)) = x`` (1e-10) by every method and the batch (= single to
    1e-12); the closed form's tree acceleration equals the tree route's (1e-10)."""
    eff = with_case(name, case)
    for seed in range(2):
        pose, twist, twist_dot, wrench = motion(eff, seed)
        u = eff.inverse_dynamics(pose, twist, twist_dot, wrench).actuator_forces
        for method in FORWARD_DYNAMICS_METHODS:
            res = eff.forward_dynamics(pose, twist, u, wrench, method=method)
            close(res.twist_dot, twist_dot, 1e-10)
        single = eff.forward_dynamics(pose, twist, u, wrench)
        batch = eff.forward_dynamics_batch(pose[None], twist[None], u[None], wrench[None])
        close(batch.twist_dot[0], single.twist_dot, 1e-12)
        close(batch.actuator_accelerations[0], single.actuator_accelerations, 1e-12)
        close(batch.closure_forces[0], single.closure_forces, 1e-10)
        free = eff.forward_dynamics(pose, twist, u)
        state = eff.inverse_dynamics(pose, twist, twist_dot)      # the tree's q and v
        tree = forward_dynamics_tree(eff.model, state.configuration, state.velocity, u,
                                     method="kkt")
        close(free.tree_acceleration, tree.a, 1e-10)


@pytest.mark.parametrize("name", ROBOTS)
def test_reduced_dynamics_statics_and_energies_carry_the_drives(name):
    """``M_x += J^T diag(a) J``, ``h_x += J^T (a qdd0 + d qd + c sign(qd) + k dq)``,
    statics add the springs' ``k dq`` only, the kinetic energy the rotors' ``1/2 a qd^2``
    and the potential the springs' ``1/2 k dq^2``; batches equal single states."""
    robot, eff = robot_registry.get(name), with_case(name, "all")
    pose, twist, _, wrench = motion(robot, 5)
    zero = np.zeros(robot.pose_dim)
    drift = robot.inverse_dynamics(pose, twist, zero)      # the tree state at twist_dot = 0
    terms = drive_terms(robot, eff, drift)
    rigid, got = robot.reduced_dynamics(pose, twist), eff.reduced_dynamics(pose, twist)
    jac, arm = rigid.jacobian, eff.effects.armature[robot.model.actuated_v]
    close(got.mass_matrix, rigid.mass_matrix + jac.T @ (arm[:, None] * jac), 1e-12)
    close(got.bias, rigid.bias + jac.T @ terms, 1e-12)
    batch = eff.reduced_dynamics_batch(pose[None], twist[None])
    close(batch.mass_matrix[0], got.mass_matrix, 1e-12)
    close(batch.bias[0], got.bias, 1e-12)
    stretch = (drift.configuration[actuated_q(robot)]
               - eff.effects.spring_reference[actuated_q(robot)])
    springs = eff.effects.stiffness[robot.model.actuated_v] * stretch
    close(eff.static_forces(pose, wrench), robot.static_forces(pose, wrench) + springs, 1e-12)
    close(eff.static_forces_batch(pose[None], wrench[None])[0],
          eff.static_forces(pose, wrench), 1e-12)
    qd = drift.velocity[robot.model.actuated_v]
    e_rigid, e_got = robot.energies(pose, twist), eff.energies(pose, twist)
    close(e_got.kinetic, e_rigid.kinetic + 0.5 * np.dot(arm * qd, qd), 1e-12)
    close(e_got.potential, e_rigid.potential + 0.5 * np.dot(springs, stretch), 1e-12)


@pytest.mark.parametrize("name", ROBOTS)
def test_coulomb_friction_at_rest_sticks_below_breakaway_and_slips_above(name):
    """At rest (twist zero): a load within the friction band keeps every actuator at rest;
    one actuator loaded beyond its friction slides with the acceleration of the
    frictionless robot under ``u - c sign`` (the friction opposes the motion it starts);
    in a mixed case the answer meets stick / slip exactly (checked by inverse dynamics),
    and the closed form, its batch and the tree's stick / slip solve agree."""
    robot = robot_registry.get(name)
    act = robot.model.actuated_joints
    c = 0.8
    one = robot.with_effects(coulomb={act[0]: c})
    every = robot.with_effects(coulomb={j: c for j in act})
    pose, zero = robot.home_pose + 0.002, np.zeros(robot.pose_dim)
    hold = robot.static_forces(pose)
    signs = np.where(np.arange(len(act)) % 2, 1.0, -1.0)
    within = [signs * np.eye(len(act))[0], signs]        # one actuator loaded, or all
    for r, pattern in zip((one, every), within):
        load = hold + 0.6 * c * pattern
        for res in (r.forward_dynamics(pose, zero, load),
                    r.forward_dynamics(pose, zero, load, method="kkt")):
            close(res.twist_dot, zero, 1e-12)
            close(res.actuator_accelerations, np.zeros(len(act)), 1e-12)
        batch = r.forward_dynamics_batch(pose[None], zero[None], load[None])
        close(batch.twist_dot[0], zero, 1e-12)
    for direction in (1.0, -1.0):
        load = hold.copy()
        load[0] += direction * (c + 1.5)
        got = one.forward_dynamics(pose, zero, load)
        ref = load.copy()
        ref[0] -= direction * c                         # the friction opposes the slip
        want = robot.forward_dynamics(pose, zero, ref)
        close(got.twist_dot, want.twist_dot, 1e-10)
        assert np.sign(got.actuator_accelerations[0]) == direction
        batch = one.forward_dynamics_batch(pose[None], zero[None], load[None])
        close(batch.twist_dot[0], got.twist_dot, 1e-12)
    load = hold + np.linspace(-2.5, 2.5, len(act))       # some slip, some stick
    got = every.forward_dynamics(pose, zero, load)
    tree = every.forward_dynamics(pose, zero, load, method="kkt")
    close(got.twist_dot, tree.twist_dot, 1e-10)
    qdd = got.actuator_accelerations
    need = every.inverse_dynamics(pose, zero, got.twist_dot).actuator_forces
    slip = np.abs(qdd) > 1e-9
    assert slip.any() and not slip.all()
    close(load[slip], need[slip], 1e-9)                  # u = frictionless + c sign(qdd)
    assert np.all(np.abs(load[~slip] - need[~slip]) <= c * (1 + 1e-9))   # within the band
    # inverse dynamics at zero velocity: a joint that starts to move slides against c
    rigid_need = robot.inverse_dynamics(pose, zero, got.twist_dot).actuator_forces
    close(need - rigid_need, c * np.sign(qdd) * slip, 1e-10)


@pytest.mark.parametrize("name", ROBOTS)
def test_effects_on_passive_coordinates_answer_on_the_tree(name):
    """Armature, damping and a spring on a passive coordinate (with the drives): inverse
    dynamics equals the tree route, forward dynamics inverts it, batches equal single
    states and the reduced dynamics (the projection through the velocity map) hold the
    inverse dynamics' answer: ``J^T u + W = M_x twist_dot + h_x``."""
    base = with_case(name, "all")
    joint = PASSIVE_JOINT[name]
    eff = base.with_effects(armature={joint: 0.02}, damping={joint: 0.3},
                            stiffness={joint: 2.0})
    pose, twist, twist_dot, wrench = motion(eff, 7)
    res = eff.inverse_dynamics(pose, twist, twist_dot, wrench)
    plain = eff.inverse_dynamics(pose, twist, twist_dot)
    tree = inverse_dynamics_tree(eff.model, plain.configuration, plain.velocity,
                                 plain.acceleration)
    close(plain.actuator_forces, tree.actuator_forces, 1e-10)
    assert np.abs(res.actuator_forces - base.inverse_dynamics(
        pose, twist, twist_dot, wrench).actuator_forces).max() > 1e-6
    u = res.actuator_forces
    close(eff.forward_dynamics(pose, twist, u, wrench).twist_dot, twist_dot, 1e-10)
    close(eff.forward_dynamics_batch(pose[None], twist[None], u[None],
                                     wrench[None]).twist_dot[0], twist_dot, 1e-10)
    close(eff.inverse_dynamics_batch(pose[None], twist[None], twist_dot[None],
                                     wrench[None]).actuator_forces[0], u, 1e-12)
    red = eff.reduced_dynamics(pose, twist)
    close(red.jacobian.T @ u + wrench, red.mass_matrix @ twist_dot + red.bias, 1e-10)
    close(eff.reduced_dynamics_batch(pose[None], twist[None]).bias[0], red.bias, 1e-12)
    close(eff.static_forces_batch(pose[None])[0], eff.static_forces(pose), 1e-12)


@pytest.mark.parametrize("name", ROBOTS)
def test_inverse_dynamics_derivatives_with_drives_match_central_differences(name):
    """The analytic derivatives (pose, twist, twist_dot) with every drive effect and a
    passive damper, against central differences of the inverse dynamics (a sliding state:
    Coulomb friction is constant there)."""
    eff = with_case(name, "all").with_effects(damping={PASSIVE_JOINT[name]: 0.3})
    pose, twist, twist_dot, wrench = motion(eff, 9)
    der = eff.inverse_dynamics_derivatives(pose, twist, twist_dot, wrench)

    def tau(p, t, td):
        return eff.inverse_dynamics(p, t, td, wrench, bounded=False,
                                    joint_wrenches=False).actuator_forces

    eye, h = np.eye(eff.pose_dim), 1e-6
    for block, shift in ((der.d_pose, lambda e: (pose + e, twist, twist_dot)),
                         (der.d_twist, lambda e: (pose, twist + e, twist_dot)),
                         (der.d_twist_dot, lambda e: (pose, twist, twist_dot + e))):
        num = np.stack([(tau(*shift(h * eye[k])) - tau(*shift(-h * eye[k]))) / (2 * h)
                        for k in range(eff.pose_dim)], axis=1)
        close(block, num, 1e-6)


@pytest.mark.parametrize("name", ROBOTS)
def test_with_effects_and_the_constructor_build_the_same_robot(name):
    """``type(robot)(geometry, effects=record)`` equals ``robot.with_effects(...)``; an
    armature written into Pinocchio's model by hand is read by the closed forms at once;
    a record of another tree is refused."""
    robot, eff = robot_registry.get(name), with_case(name, "all")
    again = type(robot)(robot.geometry, effects=eff.effects)
    pose, twist, twist_dot, wrench = motion(robot, 11)
    close(again.inverse_dynamics_batch(pose[None], twist[None], twist_dot[None]).actuator_forces,
          eff.inverse_dynamics_batch(pose[None], twist[None], twist_dot[None]).actuator_forces,
          0.0)
    hand = type(robot)(robot.geometry)
    u = hand.static_forces(pose)
    hand.model.model.armature[hand.model.actuated_v] = 0.5
    batch = hand.forward_dynamics_batch(pose[None], twist[None], u[None]).twist_dot[0]
    single = hand.forward_dynamics(pose, twist, u, method="pinocchio").twist_dot
    close(batch, single, 1e-10)
    assert np.abs(batch - robot.forward_dynamics(pose, twist, u).twist_dot).max() > 1e-3
    other = robot_registry.get([n for n in ROBOTS if n != name][0])
    with pytest.raises(InputError):
        type(robot)(robot.geometry, effects=other.effects)
