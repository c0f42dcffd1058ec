"""The MuJoCo export carries the joint and drive effects (armature, damping, Coulomb friction
as frictionloss, springs with their reference, the motors' gear and effort limits).

MuJoCo is the peer: its compiled fields (``dof_armature``, ``dof_damping``,
``jnt_stiffness``, ``qpos_spring``, ``dof_frictionloss``, ``actuator_gear``,
``actuator_forcerange``), its mass matrix (``mj_fullM``), its passive force
(``qfrc_passive``), its actuator force (``qfrc_actuator`` of ``ctrl``) and its inverse
dynamics (``mj_inverse`` without the equalities and the friction loss, projected on the
null space of MuJoCo's own equality rows, plus ``c sign(v)`` written here) against ours on
loaded robots with every effect set. Free-flyer coordinates are mapped with ``qvel = T v``,
``T`` built here from MuJoCo's own body rotation.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import scipy.linalg

import hexapod_pin as hp
from hexapod_pin.core.dynamics import forward_dynamics_tree, inverse_dynamics_tree
from hexapod_pin.core.effects import passive_forces
from hexapod_pin.errors import InputError

mujoco = pytest.importorskip("mujoco")
from hexapod_pin.core.mujoco_export import closed_loop_mjcf, mujoco_state, to_mujoco  # noqa: E402
from test_hard_classes import _delta_with_ball_wrists  # noqa: E402 (the delta, ball wrists)

DATA = Path(__file__).resolve().parents[1] / "data"


def _model(name, tmp_path):
    if name == "delta_ball_wrists":
        return _delta_with_ball_wrists(tmp_path)
    return hp.load_robot(DATA / name / f"{name}.urdf").model


def _kinds(clm):
    return {j: clm.model.joints[j].shortname() for j in range(1, clm.model.njoints)}


def _every_effect(clm, rng):
    """Every effect on every coordinate but a free flyer's (one value per ball joint, its
    spring relaxed at the identity); springs of 1-DoF joints relaxed away from zero."""
    model = clm.tree_model
    fields = {"armature": 0.05, "damping": 2.0, "coulomb": 0.5, "stiffness": 30.0}
    values = {f: np.zeros(clm.nv) for f in fields}
    shift = np.zeros(clm.nv)
    for jid, kind in _kinds(clm).items():
        jm = model.joints[jid]
        if kind == "JointModelFreeFlyer":
            continue
        coords = slice(jm.idx_v, jm.idx_v + jm.nv)
        for field, scale in fields.items():
            values[field][coords] = scale * rng.uniform(0.2, 1.0)
        if jm.nv == 1:
            shift[coords] = rng.uniform(-0.3, 0.3)
    reference = pin.integrate(model, pin.neutral(model), shift)
    gear = rng.uniform(5.0, 30.0, clm.n_actuated) * rng.choice([-1.0, 1.0], clm.n_actuated)
    return clm.with_effects(spring_reference=reference, gear=gear,
                            effort_limit=np.full(clm.n_actuated, 1e6), **values)


def _state(clm, rng):
    """An assembled q away from neutral, a velocity keeping the loops (every coordinate
    moving: Coulomb's sign is defined) and the acceleration of some actuator forces (the
    delta with ball wrists is under-actuated: not every acceleration is reachable)."""
    dq = np.zeros(clm.nv)
    dq[clm.actuated_v] = 0.05 * rng.normal(size=clm.n_actuated)
    section = clm.loops.robot
    home = pin.neutral(clm.model) if section is None else np.array(section.home)
    q = clm.assemble(pin.integrate(clm.model, home, dq)).q
    v = scipy.linalg.null_space(clm.constraint_jacobian(q), rcond=1e-10) @ rng.normal(
        size=clm.nv - clm.rank(q).rank)
    v *= 2.0 / np.max(np.abs(v))                                  # up to 2 rad/s or m/s
    assert np.all(np.abs(v) > 1e-6)
    a = forward_dynamics_tree(clm, q, v, rng.normal(size=clm.n_actuated), method="kkt").a
    return q, v, a


def _t_map(clm, model, data):
    """MuJoCo's ``qvel = T v`` from its own body rotations."""
    t_map = np.eye(clm.nv)
    for jid, kind in _kinds(clm).items():
        if kind == "JointModelFreeFlyer":
            iv = clm.model.joints[jid].idx_v
            t_map[iv:iv + 3, iv:iv + 3] = data.xmat[model.body(clm.model.names[jid]).id
                                                    ].reshape(3, 3)
    return t_map


ROBOTS = ["four_bar", "stewart", "delta_ball_wrists"]


@pytest.mark.parametrize("name", ROBOTS)
def test_mujoco_compiles_our_effects(name, tmp_path):
    clm = _every_effect(_model(name, tmp_path), np.random.default_rng(1))
    eff = clm.effects
    model = to_mujoco(clm)
    np.testing.assert_array_equal(model.dof_armature, eff.armature)
    np.testing.assert_array_equal(model.dof_damping, eff.damping)
    np.testing.assert_array_equal(model.dof_frictionloss, eff.coulomb)
    for jid in range(1, clm.model.njoints):
        mj_joint = model.joint(clm.model.names[jid]).id
        assert model.jnt_stiffness[mj_joint] == eff.stiffness[clm.model.joints[jid].idx_v]
    np.testing.assert_allclose(model.qpos_spring, mujoco_state(clm, eff.spring_reference).qpos,
                               rtol=0, atol=1e-15)
    assert np.any(eff.spring_reference != pin.neutral(clm.model))
    np.testing.assert_array_equal(model.actuator_gear[:, 0], eff.gear)
    bound = eff.effort_limit / np.abs(eff.gear)
    np.testing.assert_allclose(model.actuator_forcerange, np.c_[-bound, bound], rtol=1e-15)
    np.testing.assert_allclose(model.actuator_ctrlrange, np.c_[-bound, bound], rtol=1e-15)
    assert model.actuator_forcelimited.all() and model.actuator_ctrllimited.all()


@pytest.mark.parametrize("name", ROBOTS)
def test_mass_matrix_passive_forces_gear_and_inverse_dynamics_agree_with_mujoco(name, tmp_path):
    rng = np.random.default_rng(2)
    clm = _every_effect(_model(name, tmp_path), rng)
    eff = clm.effects
    q, v, a = _state(clm, rng)
    model = to_mujoco(clm)
    data = mujoco.MjData(model)
    state = mujoco_state(clm, q, v, a)
    data.qpos[:], data.qvel[:] = state.qpos, state.qvel
    mujoco.mj_forward(model, data)
    equality = data.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY
    assert np.max(np.abs(data.efc_pos[equality])) < 1e-12            # closures hold at q
    t_map = _t_map(clm, model, data)
    t_inv = np.linalg.inv(t_map)
    # mass matrix: Pinocchio's crba of the rigid tree + diag(armature), written here
    rigid = pin.Model(clm.tree_model)
    rigid.armature[:] = 0.0
    mass = pin.crba(rigid, rigid.createData(), q)
    mass = np.triu(mass) + np.triu(mass, 1).T + np.diag(eff.armature)
    mass_mj = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, mass_mj)
    assert np.max(np.abs(mass_mj - t_inv.T @ mass @ t_inv)) <= 1e-8 * np.max(np.abs(mass))
    # passive force: -D v - K dq, written here, = ours = MuJoCo's (tau = T^T qfrc)
    spring = -eff.stiffness * pin.difference(rigid, eff.spring_reference, q)
    written = -eff.damping * v + spring
    assert np.max(np.abs(spring)) > 0.1 and np.max(np.abs(eff.damping * v)) > 0.1
    ours = passive_forces(clm.model, eff, q, v)
    scale = np.max(np.abs(written))
    assert np.max(np.abs(ours - written)) <= 1e-12 * scale
    assert np.max(np.abs(t_map.T @ data.qfrc_passive - written)) <= 1e-10 * scale
    # inverse dynamics: MuJoCo without equalities and friction loss, + c sign(v) written here,
    # on the null space of MuJoCo's equality rows
    inv = inverse_dynamics_tree(clm, q, v, a, method="kkt")
    jac = data.efc_J.reshape(data.nefc, model.nv)[equality] @ t_map
    _, sv, vt = np.linalg.svd(jac)
    basis = vt[int(np.sum(sv > 1e-10 * sv[0])):].T
    model.opt.disableflags = int(mujoco.mjtDisableBit.mjDSBL_EQUALITY
                                 | mujoco.mjtDisableBit.mjDSBL_FRICTIONLOSS)
    data.qacc[:] = state.qacc
    mujoco.mj_inverse(model, data)
    needed = t_map.T @ data.qfrc_inverse + eff.coulomb * np.sign(v)
    selection = np.zeros((clm.nv, clm.n_actuated))
    selection[clm.actuated_v, np.arange(clm.n_actuated)] = 1.0
    u_mj, *_ = np.linalg.lstsq(basis.T @ selection, basis.T @ needed, rcond=None)
    assert np.max(np.abs(u_mj - inv.actuator_forces)) <= 1e-8 * np.max(np.abs(u_mj))
    # gear: ctrl = u / gear (the motor torque) gives the actuator force u on the joint
    data.ctrl[:] = inv.actuator_forces / eff.gear
    mujoco.mj_forward(model, data)
    np.testing.assert_allclose(t_map.T @ data.qfrc_actuator, selection @ inv.actuator_forces,
                               rtol=0, atol=1e-12 * np.max(np.abs(inv.actuator_forces)))


def test_a_rigid_model_exports_no_effect_and_unlimited_unit_motors():
    clm = hp.load_robot(DATA / "four_bar" / "four_bar.urdf").model.with_effects(
        effort_limit=[np.inf])
    assert clm.effects.is_rigid
    text = closed_loop_mjcf(clm)
    for attribute in ("armature=\"0.", "stiffness", "springref", "ctrlrange", "forcerange"):
        assert attribute not in text.split("</default>")[1]
    model = to_mujoco(clm)
    assert not model.dof_damping.any() and not model.jnt_stiffness.any()
    assert model.actuator_gear[0, 0] == 1.0 and not model.actuator_forcelimited.any()


def test_effects_mujoco_cannot_carry_are_refused(tmp_path):
    delta = _delta_with_ball_wrists(tmp_path)
    ball = next(j for j, k in _kinds(delta).items() if k == "JointModelSpherical")
    name, iv = delta.model.names[ball], delta.model.joints[ball].idx_v
    damping = np.zeros(delta.nv)
    damping[iv:iv + 3] = [1.0, 2.0, 3.0]
    with pytest.raises(InputError, match="takes one damping"):
        closed_loop_mjcf(delta.with_effects(damping=damping))
    turned = pin.neutral(delta.model)
    dv = np.zeros(delta.nv)
    dv[iv] = 0.2
    turned = pin.integrate(delta.model, turned, dv)
    with pytest.raises(InputError, match="identity"):
        closed_loop_mjcf(delta.with_effects(stiffness={name: 5.0}, spring_reference=turned))
    stewart = hp.load_robot(DATA / "stewart" / "stewart.urdf").model
    with pytest.raises(InputError, match="free flyer"):
        closed_loop_mjcf(stewart.with_effects(damping={"platform_joint": 1.0}))
