"""MJCF import (:mod:`hexapod_pin.loaders.mjcf`) against MuJoCo's own compiled model.

At closure-consistent states (random configurations projected on the closures by the
library's assembly, velocities projected on their null space), each model of
``tests/data/mjcf`` is compared with MuJoCo's rigid-body quantities, mapped to Pinocchio's
velocity convention by a map ``T`` written here (``qvel = T v``: a free joint's linear
velocity is in the world frame in MuJoCo, in the body frame in Pinocchio):

* the mass matrix with ``mj_fullM`` (``M = T^T M_mj T``), the bias with ``qfrc_bias``
  (``h = T^T (qfrc_bias + M_mj Tdot v)``), the joint effects with ``qfrc_passive``;
* the closure Jacobian's row space with the equality rows of MuJoCo's ``efc_J``;
* the constrained acceleration of the library's forward dynamics with a numpy KKT solve
  written here on MuJoCo's ``mj_fullM``, ``qfrc_bias``, ``qfrc_passive``,
  ``qfrc_actuator``, the friction loss ``-frictionloss sign(qvel)`` (MuJoCo's is a soft
  constraint row, not in ``qfrc_passive``) and the equality rows built from ``mj_jac`` at
  MuJoCo's anchors with their drift from ``mj_jacDot``, to 1e-10 relative.

MuJoCo's own ``qacc`` is soft and is not a reference (docs/tutorials/mujoco-model.md shows
the difference). The round trips with the exporter, the refusals and the reference
configurations follow.
"""

from __future__ import annotations

import builtins
import dataclasses
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from conftest import null_space_kkt

mujoco = pytest.importorskip("mujoco")

import hexapod_pin as hp
from hexapod_pin.core.dynamics import forward_dynamics_tree
from hexapod_pin.core.effects import passive_forces
from hexapod_pin.core.mujoco_export import closed_loop_mjcf, to_mujoco
from hexapod_pin.errors import DescriptionError, MissingDependencyError
from hexapod_pin.loaders import mjcf

DATA = Path(__file__).resolve().parents[1] / "data" / "mjcf"
MODELS = ["fourbar.xml", "spatial.xml", "agility_cassie/cassie.xml"]
RTOL = 1e-10


# -- MuJoCo's side, written independently of the loader -----------------------------------
def compile_mj(path):
    model = mujoco.MjModel.from_xml_path(str(path))
    model.opt.jacobian = mujoco.mjtJacobian.mjJAC_DENSE
    return model


def to_qpos(mj, q):
    """MuJoCo's qpos of a Pinocchio q: quaternions (x, y, z, w) -> (w, x, y, z)."""
    qpos = np.array(q, dtype=float)
    for j in range(mj.njnt):
        kind = int(mj.jnt_type[j])
        adr = mj.jnt_qposadr[j] + (3 if kind == mujoco.mjtJoint.mjJNT_FREE else 0)
        if kind in (mujoco.mjtJoint.mjJNT_FREE, mujoco.mjtJoint.mjJNT_BALL):
            qpos[adr] = q[adr + 3]
            qpos[adr + 1:adr + 4] = q[adr:adr + 3]
    return qpos


def velocity_maps(mj, q, v):
    """``T`` (nv, nv) with ``qvel = T v`` and ``Tdot v`` (nv,) at (q, v)."""
    T, Tdv = np.eye(mj.nv), np.zeros(mj.nv)
    for j in range(mj.njnt):
        if mj.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE:
            iq, iv = mj.jnt_qposadr[j], mj.jnt_dofadr[j]
            x, y, z, w = q[iq + 3:iq + 7]
            rot = pin.Quaternion(w, x, y, z).normalized().matrix()
            T[iv:iv + 3, iv:iv + 3] = rot
            Tdv[iv:iv + 3] = rot @ np.cross(v[iv + 3:iv + 6], v[iv:iv + 3])
    return T, Tdv


def equality_rows(mj, d):
    """MuJoCo's equality rows of efc_J (dense) at the state of ``d``."""
    rows = d.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY
    return d.efc_J.reshape(d.nefc, mj.nv)[rows]


def anchors(mj, d, i):
    """(point 1, body 1, point 2, body 2) of connect / weld ``i`` (MuJoCo's semantics)."""
    b1, b2, data = mj.eq_obj1id[i], mj.eq_obj2id[i], mj.eq_data[i]
    if mj.eq_objtype[i] == mujoco.mjtObj.mjOBJ_SITE:
        return d.site_xpos[b1], mj.site_bodyid[b1], d.site_xpos[b2], mj.site_bodyid[b2]
    first, second = (data[0:3], data[3:6]) if mj.eq_type[i] == mujoco.mjtEq.mjEQ_CONNECT \
        else (data[3:6], data[0:3])
    return (d.xpos[b1] + d.xmat[b1].reshape(3, 3) @ first, b1,
            d.xpos[b2] + d.xmat[b2].reshape(3, 3) @ second, b2)


def rigid_rows(mj, d):
    """Equality rows ``J`` (qvel coordinates) and drift ``Jdot qvel`` from mj_jac /
    mj_jacDot at the anchors: point velocity differences (and angular velocity
    differences for a weld), one block per active connect and weld."""
    jac, drift = [], []
    for i in range(mj.neq):
        if not d.eq_active[i]:
            continue
        p1, b1, p2, b2 = anchors(mj, d, i)
        blocks = []
        for fn in (mujoco.mj_jac, mujoco.mj_jacDot):
            out = []
            for p, b in ((p1, b1), (p2, b2)):
                jp, jr = np.zeros((3, mj.nv)), np.zeros((3, mj.nv))
                fn(mj, d, jp, jr, np.array(p), int(b))
                out.append(np.vstack([jp, jr]))
            diff = out[0] - out[1]
            blocks.append(diff[:3] if mj.eq_type[i] == mujoco.mjtEq.mjEQ_CONNECT else diff)
        jac.append(blocks[0])
        drift.append(blocks[1] @ d.qvel)
    return np.vstack(jac), np.concatenate(drift)


def projector(rows, rtol=1e-9):
    _, s, vt = np.linalg.svd(rows)
    rank = int(np.sum(s > rtol * s[0]))
    return vt[:rank].T @ vt[:rank], rank


def same_row_space(a, b):
    pa, ra = projector(a)
    pb, rb = projector(b)
    scale = max(np.abs(a).max(), np.abs(b).max())
    return ra == rb and np.abs(a - a @ pb).max() <= 1e-9 * scale \
        and np.abs(b - b @ pa).max() <= 1e-9 * scale


def close(a, b, rtol=RTOL):
    """``|a - b| <= rtol max|b|`` entry by entry (relative to the largest reference entry)."""
    scale = np.abs(np.asarray(b)).max()
    return np.abs(np.asarray(a) - np.asarray(b)).max() <= rtol * (scale if scale > 0 else 1.0)


# -- states ---------------------------------------------------------------------------------
def states(clm, n=3, seed=0):
    """(q, v) closure-consistent: random perturbations of qpos0 assembled by the library
    (every coordinate free), random velocities projected on ``J_c v = 0``."""
    rng = np.random.default_rng(seed)
    q0 = clm.reference_configurations["qpos0"]
    out = []
    while len(out) < n:
        start = pin.integrate(clm.model, q0, 0.2 * rng.standard_normal(clm.nv))
        q = clm.assemble(start, fixed=np.zeros(0, dtype=int)).q
        v = clm.project_velocity(q, rng.standard_normal(clm.nv), metric="euclidean")
        out.append((q, v))
    return out


def mujoco_at(mj, q, v, ctrl):
    d = mujoco.MjData(mj)
    d.qpos[:], d.qvel[:], d.ctrl[:] = to_qpos(mj, q), velocity_maps(mj, q, v)[0] @ v, ctrl
    mujoco.mj_forward(mj, d)
    full = np.zeros((mj.nv, mj.nv))
    mujoco.mj_fullM(mj, d, full)
    return d, full


@pytest.fixture(scope="module", params=MODELS)
def loaded(request):
    path = DATA / request.param
    return hp.load_mjcf(path), compile_mj(path)


def test_mass_bias_and_effects_equal_mujoco(loaded):
    clm, mj = loaded
    data = clm.model.createData()
    for q, v in states(clm):
        d, full = mujoco_at(mj, q, v, np.zeros(mj.nu))
        T, Tdv = velocity_maps(mj, q, v)
        mass = pin.crba(clm.model, data, q)
        mass = np.triu(mass) + np.triu(mass, 1).T
        assert close(mass, T.T @ full @ T)
        bias = pin.rnea(clm.model, data, q, v, np.zeros(clm.nv))
        assert close(bias, T.T @ (d.qfrc_bias + full @ Tdv))
        assert close(passive_forces(clm.model, clm.effects, q, v), T.T @ d.qfrc_passive)


def test_closure_rows_span_mujocos_equality_rows(loaded):
    clm, mj = loaded
    for q, v in states(clm):
        d, _ = mujoco_at(mj, q, v, np.zeros(mj.nu))
        T, _ = velocity_maps(mj, q, v)
        ours = clm.constraint_jacobian(q)
        assert same_row_space(ours, equality_rows(mj, d) @ T)
        assert same_row_space(rigid_rows(mj, d)[0], equality_rows(mj, d))
        assert np.abs(clm.residual(q)).max() < 1e-11


def test_constrained_acceleration_equals_a_kkt_solve_on_mujocos_terms(loaded):
    """To 1e-10 relative (1e-8 where ``cond(M)`` exceeds 1e6: Cassie's is ~1e7)."""
    clm, mj = loaded
    rng = np.random.default_rng(1)
    motors = [k for k in range(mj.nu) if mj.actuator_biastype[k] == 0]
    for q, v in states(clm, seed=2):
        ctrl = rng.uniform(-0.5, 0.5, mj.nu)                 # inside every ctrlrange
        d, full = mujoco_at(mj, q, v, ctrl)
        T, Tdv = velocity_maps(mj, q, v)
        force = d.qfrc_passive + d.qfrc_actuator - d.qfrc_bias \
            - mj.dof_frictionloss * np.sign(d.qvel)
        jac, drift = rigid_rows(mj, d)
        qacc = null_space_kkt(full, force, jac, -drift)
        # the joint force of each actuator as MuJoCo applied it (a servo's kp (ctrl - q)
        # is not imported); a plain motor's is the imported gear times ctrl
        u = d.actuator_force * mj.actuator_gear[:, 0]
        assert np.allclose(u[motors], (clm.effects.gear * ctrl)[motors], rtol=1e-15)
        rtol = RTOL if np.linalg.cond(full) <= 1e6 else 1e-8
        a = forward_dynamics_tree(clm, q, v, u, method="kkt").a
        assert close(T @ a + Tdv, qacc, rtol), np.abs(T @ a + Tdv - qacc).max()
        a = forward_dynamics_tree(clm, q, v, u).a
        assert close(T @ a + Tdv, qacc, max(rtol, 1e-8))


def test_bodies_and_sites_are_where_mujoco_puts_them(loaded):
    """Sibling root bodies, joint anchors, refs, a rotated joint-less root, free flyers."""
    clm, mj = loaded
    data = clm.model.createData()
    for q, v in states(clm, n=2, seed=3):
        d, _ = mujoco_at(mj, q, v, np.zeros(mj.nu))
        pin.framesForwardKinematics(clm.model, data, q)
        for b in range(1, mj.nbody):
            frame = data.oMf[clm.model.getFrameId(mj.body(b).name, pin.FrameType.BODY)]
            assert np.abs(frame.translation - d.xpos[b]).max() < 1e-12
            assert np.abs(frame.rotation - d.xmat[b].reshape(3, 3)).max() < 1e-12
        for s in range(mj.nsite):
            frame = data.oMf[clm.model.getFrameId(mj.site(s).name, pin.FrameType.OP_FRAME)]
            assert np.abs(frame.translation - d.site_xpos[s]).max() < 1e-12
            assert np.abs(frame.rotation - d.site_xmat[s].reshape(3, 3)).max() < 1e-12
    roots = [clm.model.idx_vs[j] for j in range(1, clm.model.njoints)
             if clm.model.parents[j] == 0]
    mj_roots = [mj.jnt_dofadr[j] for j in range(mj.njnt)     # no moving ancestor
                if mj.dof_parentid[mj.jnt_dofadr[j]] == -1]
    # sibling root bodies: two on the four-bar, a ball arm and two free bodies on the other
    assert roots == mj_roots
    assert len(roots) == {"fourbar.xml": 2, "spatial.xml": 3, "cassie.xml": 1}[clm.name]
    assert np.array_equal(clm.model.gravity.linear, mj.opt.gravity)


def test_the_comparisons_can_fail():
    """A 1e-6 heavier body, 1e-6 more damping, a closure anchor moved by 1 um: each is seen."""
    path = DATA / "spatial.xml"
    clm, mj = hp.load_mjcf(path), compile_mj(path)
    (q, v), = states(clm, n=1, seed=4)
    d, full = mujoco_at(mj, q, v, np.zeros(mj.nu))
    T, _ = velocity_maps(mj, q, v)
    heavier = pin.Model(clm.model)
    body = heavier.getJointId("elbow")                        # carries the forearm
    heavier.inertias[body] = pin.Inertia(heavier.inertias[body].mass * (1 + 1e-6),
                                         heavier.inertias[body].lever,
                                         heavier.inertias[body].inertia)
    mass = pin.crba(heavier, heavier.createData(), q)
    assert not close(np.triu(mass) + np.triu(mass, 1).T, T.T @ full @ T)
    damper = clm.with_effects(damping=clm.effects.damping * (1 + 1e-6))
    assert not close(passive_forces(clm.model, damper.effects, q, v), T.T @ d.qfrc_passive)
    closures = list(clm.closures)
    shift = pin.SE3(np.eye(3), np.array([1e-6, 0.0, 0.0]))
    closures[0] = dataclasses.replace(closures[0], offset1=closures[0].offset1 * shift)
    moved = hp.ClosedLoopModel(clm.tree_model, hp.LoopsSpec(tuple(closures), clm.actuated_joints),
                               effects=clm.effects)
    assert not same_row_space(moved.constraint_jacobian(q), equality_rows(mj, d) @ T)


# -- round trips with the exporter -------------------------------------------------------
@pytest.mark.parametrize("name", MODELS)
def test_the_export_of_a_loaded_model_compiles_to_the_same_dynamics(name):
    """``to_mujoco(load_mjcf(f))`` against ``f``: mass matrix, bias, passive forces and
    equality rows at the same qpos / qvel (the joints keep their order)."""
    path = DATA / name
    clm, mj = hp.load_mjcf(path), compile_mj(path)
    again = to_mujoco(clm)
    again.opt.jacobian = mujoco.mjtJacobian.mjJAC_DENSE
    assert (again.nq, again.nv, again.neq) == (mj.nq, mj.nv, int(mj.eq_active0.sum()))
    for q, v in states(clm, n=2, seed=5):
        d1, m1 = mujoco_at(mj, q, v, np.zeros(mj.nu))
        d2, m2 = mujoco_at(again, q, v, np.zeros(again.nu))
        assert close(m2, m1)
        assert close(d2.qfrc_bias, d1.qfrc_bias)
        assert close(d2.qfrc_passive, d1.qfrc_passive)
        assert np.array_equal(again.dof_frictionloss, mj.dof_frictionloss)
        assert same_row_space(equality_rows(again, d2), equality_rows(mj, d1))


def _four_bar_with_effects():
    four_bar = Path(__file__).resolve().parents[1] / "data" / "four_bar"
    clm = hp.ClosedLoopModel.from_files(four_bar / "four_bar.urdf",
                                        four_bar / "four_bar.loops.yaml")
    n = clm.nv
    return clm.with_effects(armature=np.linspace(0.01, 0.02, n), damping=np.full(n, 0.3),
                            coulomb=np.linspace(0.0, 0.1, n), stiffness=np.linspace(1, 2, n),
                            spring_reference=np.linspace(-0.2, 0.3, clm.nq),
                            gear=np.full(clm.n_actuated, 7.0),
                            effort_limit=np.full(clm.n_actuated, 21.0))


def test_loading_an_export_gives_back_the_model(tmp_path):
    """``load_mjcf(export(clm))``: the same mass matrix, bias, closure residual and
    Jacobian, actuated joints and effects as ``clm`` (a URDF model with every effect)."""
    clm = _four_bar_with_effects()
    path = tmp_path / "four_bar.xml"
    path.write_text(closed_loop_mjcf(clm), encoding="utf-8")
    back = hp.load_mjcf(path)
    assert back.actuated_joints == clm.actuated_joints
    for field in ("armature", "damping", "coulomb", "stiffness", "spring_reference", "gear",
                  "effort_limit"):
        assert np.allclose(getattr(back.effects, field), getattr(clm.effects, field),
                           rtol=1e-14, atol=1e-15), field
    d1, d2 = clm.model.createData(), back.model.createData()
    rng = np.random.default_rng(6)
    for _ in range(3):
        q = pin.integrate(clm.model, pin.neutral(clm.model), rng.standard_normal(clm.nv))
        v = rng.standard_normal(clm.nv)
        assert close(pin.crba(back.model, d2, q), pin.crba(clm.model, d1, q), 1e-12)
        assert close(pin.rnea(back.model, d2, q, v, 0 * v), pin.rnea(clm.model, d1, q, v, 0 * v),
                     1e-12)
        assert close(back.residual(q), clm.residual(q), 1e-12)
        assert close(back.constraint_jacobian(q), clm.constraint_jacobian(q), 1e-12)


# -- refusals, skipped equalities, reference configurations, load_robot --------------------
def test_unsupported_features_are_refused_by_name():
    with pytest.raises(DescriptionError) as caught:
        hp.load_mjcf(DATA / "refused.xml")
    message = str(caught.value)
    for part in ("tendon equality 'tie'", "actuator 'pull'", "tendon 'cable' (stiffness)"):
        assert part in message
    assert "'off'" not in message          # inactive: skipped, not refused
    assert "'gears'" not in message        # a hinge coupling: imported (test_couplings.py)
    assert caught.value.culprit == "tendon equality 'tie'"


def test_inactive_equalities_are_skipped_and_servos_noted():
    result = mjcf.read_mjcf(DATA / "spatial.xml")
    assert result.skipped == ("idle_coupling",)
    assert [c.name for c in result.model.closures] == ["reach", "glue", "glue_sites"]
    assert [c.type for c in result.model.closures] == ["point", "weld", "weld"]
    assert len(result.notes) == 1 and "elbow_servo" in result.notes[0]
    assert result.model.actuated_joints == ("extend", "elbow")
    # the motor's own armature and damping enter its joint as gear^2 times them
    mj = compile_mj(DATA / "spatial.xml")
    dof = mj.jnt_dofadr[mj.joint("extend").id]
    assert result.model.effects.armature[dof] == pytest.approx(0.002 + 4 * 0.003, rel=1e-15)
    assert result.model.effects.damping[dof] == pytest.approx(0.1 + 4 * 0.04, rel=1e-15)
    assert result.model.effects.effort_limit[0] == pytest.approx(2 * 5)


def test_reference_configurations_and_keyframe():
    mj = compile_mj(DATA / "fourbar.xml")
    clm = hp.load_mjcf(DATA / "fourbar.xml")
    refs = clm.reference_configurations
    assert set(refs) == {"qpos0", "start", "home"}
    assert np.array_equal(refs["qpos0"], mj.qpos0) and np.array_equal(refs["home"], mj.qpos0)
    assert refs["qpos0"][0] == pytest.approx(np.radians(10.0))   # ref="10" degrees
    assert np.abs(clm.residual(refs["qpos0"])).max() < 1e-15    # body connects close at qpos0
    keyed = mjcf.read_mjcf(DATA / "fourbar.xml", keyframe="start")
    assert np.array_equal(keyed.home, mj.key_qpos[0])
    assert np.array_equal(mjcf.read_mjcf(DATA / "fourbar.xml", keyframe=0).home, mj.key_qpos[0])
    with pytest.raises(DescriptionError, match="no keyframe 'missing'"):
        hp.load_mjcf(DATA / "fourbar.xml", keyframe="missing")
    spatial = mjcf.read_mjcf(DATA / "spatial.xml", keyframe="bent")
    qpos = compile_mj(DATA / "spatial.xml").key_qpos[0]
    assert np.array_equal(to_qpos(spatial.mj_model, spatial.home), qpos)   # (w,x,y,z) back


def test_load_robot_reads_mjcf():
    robot = hp.load_robot(DATA / "fourbar.xml", platform="coupler_end", pose_axes=("x",))
    assert isinstance(robot, hp.ClosedLoopRobot)
    with pytest.raises(DescriptionError, match="actuated= is for SDF"):
        hp.load_robot(DATA / "fourbar.xml", platform="coupler_end", actuated=("crank_joint",))


def test_missing_mujoco_names_the_extra(monkeypatch):
    real = builtins.__import__

    def without_mujoco(name, *args, **kwargs):
        if name == "mujoco":
            raise ImportError("no mujoco")
        return real(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", without_mujoco)
    with pytest.raises(MissingDependencyError, match=r"hexapod-pin\[mjcf\]"):
        hp.load_mjcf(DATA / "fourbar.xml")


def test_malformed_and_missing_files(tmp_path):
    with pytest.raises(hp.MissingFileError, match="file not found"):
        hp.load_mjcf(tmp_path / "absent.xml")
    bad = tmp_path / "bad.xml"
    bad.write_text("<mujoco><worldbody><body><joint type='nonsense'/></body></worldbody>"
                   "</mujoco>", encoding="utf-8")
    with pytest.raises(DescriptionError, match="MuJoCo could not compile it"):
        hp.load_mjcf(bad)


# -- a real model: MuJoCo Menagerie's Cassie (MIT), meshes removed ---------------------------
CASSIE = DATA / "agility_cassie" / "cassie.xml"


def test_cassie_inertials_are_the_written_ones():
    """The compiled inertials (mass, centre of mass, full inertia from ``body_inertia`` and
    ``body_iquat``) equal the file's explicit ``<inertial>`` elements, copied verbatim
    from the original: removing the (visual) meshes changed no inertial."""
    mj = compile_mj(CASSIE)
    written = {body.get("name"): body.find("inertial")
               for body in ET.parse(CASSIE).getroot().iter("body")}
    assert len(written) == mj.nbody - 1 and all(e is not None for e in written.values())
    for name, inertial in written.items():
        b = mj.body(name).id
        xx, yy, zz, xy, xz, yz = (float(x) for x in inertial.get("fullinertia").split())
        full = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
        w, x, y, z = mj.body_iquat[b]
        rot = pin.Quaternion(w, x, y, z).normalized().matrix()
        assert mj.body_mass[b] == float(inertial.get("mass"))
        assert np.allclose(mj.body_ipos[b], [float(c) for c in inertial.get("pos").split()],
                           rtol=0, atol=1e-15)
        assert np.abs(rot @ np.diag(mj.body_inertia[b]) @ rot.T - full).max() \
            <= 1e-12 * np.abs(full).max()
    assert (CASSIE.parent / "LICENSE").read_text(encoding="utf-8").startswith(
        "Copyright (c) 2022 Agility Robotics")


def test_cassie_closes_at_qpos0_not_at_pinocchios_neutral():
    clm = hp.load_mjcf(CASSIE)
    assert (clm.nq, clm.nv, clm.n_rows, clm.n_actuated) == (35, 32, 12, 10)
    refs = clm.reference_configurations
    assert np.abs(clm.residual(refs["qpos0"])).max() < 1e-12
    assert np.abs(clm.residual(clm.neutral())).max() > 0.1
    # the file's keyframe "home" is the home; written to 6 digits from MuJoCo's soft loops
    assert np.array_equal(refs["home"], mjcf.configuration_from_qpos(
        compile_mj(CASSIE), compile_mj(CASSIE).key_qpos[0]))
    assert np.abs(clm.residual(refs["home"])).max() < 2e-3
    assert clm.effects.gear.tolist() == [25, 25, 16, 16, 50] * 2
    assert clm.effects.effort_limit == pytest.approx([112.5, 112.5, 195.2, 195.2, 45.0] * 2)


REFUSED = {
    "gravity compensation of body 'lifted'":
        '<body name="lifted" gravcomp="1"><joint name="h"/><geom size=".1"/></body>',
    "fluid forces": '<body name="b"><joint name="h"/><geom size=".1"/></body>',
    "spring, frictionloss or armature of free joint 'loose'":
        '<body name="b"><joint name="loose" type="free" stiffness="2"/><geom size=".1"/></body>',
    "weld 'flat' with torquescale 0":
        '<body name="b"><joint name="h"/><geom size=".1"/></body>',
}


@pytest.mark.parametrize("expected", sorted(REFUSED))
def test_more_refusals_name_the_feature(tmp_path, expected):
    option = '<option density="1.2"/>' if "fluid" in expected else ""
    equality = ('<equality><weld name="flat" body1="b" torquescale="0"/></equality>'
                if "weld" in expected else "")
    path = tmp_path / "model.xml"
    path.write_text(f"<mujoco>{option}<worldbody>{REFUSED[expected]}</worldbody>{equality}"
                    "</mujoco>", encoding="utf-8")
    with pytest.raises(DescriptionError, match=expected.split(" '")[0]) as caught:
        hp.load_mjcf(path)
    assert expected in str(caught.value)


def test_from_mjmodel_reads_a_compiled_model():
    """The exporter's compiled MjModel read back directly (no file): the same tree."""
    clm = _four_bar_with_effects()
    back = mjcf.from_mjmodel(to_mujoco(clm)).model
    q = pin.integrate(clm.model, pin.neutral(clm.model), np.full(clm.nv, 0.3))
    assert close(pin.crba(back.model, back.model.createData(), q),
                 pin.crba(clm.model, clm.model.createData(), q), 1e-12)
    assert close(back.constraint_jacobian(q), clm.constraint_jacobian(q), 1e-12)


def test_free_joint_damping_maps_exactly_and_armature_is_refused(tmp_path):
    """Equal damping on a free joint's translations is the same on MuJoCo's world-frame
    linear velocity and Pinocchio's body-frame one (``T^T b T = b``); an armature is not
    (MuJoCo's acts on the world-frame acceleration: the bias would differ by
    ``armature omega x v``), and is refused."""
    body = ('<mujoco><worldbody><body name="b" pos="0.1 0.2 0.3" euler="0.3 0.2 0.1">'
            '<joint name="f" type="free" damping="0.7" {}/>'
            '<geom type="box" size="0.1 0.2 0.3"/></body></worldbody></mujoco>')
    path = tmp_path / "free.xml"
    path.write_text(body.format('armature="0.05"'), encoding="utf-8")
    with pytest.raises(DescriptionError, match="armature of free joint 'f'"):
        hp.load_mjcf(path)
    path.write_text(body.format(""), encoding="utf-8")
    clm, mj = hp.load_mjcf(path), compile_mj(path)
    rng = np.random.default_rng(7)
    q = pin.integrate(clm.model, clm.reference_configurations["qpos0"], rng.standard_normal(6))
    v = rng.standard_normal(6)
    d, full = mujoco_at(mj, q, v, np.zeros(0))
    T, Tdv = velocity_maps(mj, q, v)
    mass = pin.crba(clm.model, clm.model.createData(), q)
    assert close(np.triu(mass) + np.triu(mass, 1).T, T.T @ full @ T)
    assert close(passive_forces(clm.model, clm.effects, q, v), T.T @ d.qfrc_passive)
    assert close(pin.rnea(clm.model, clm.model.createData(), q, v, 0 * v),
                 T.T @ (d.qfrc_bias + full @ Tdv))
