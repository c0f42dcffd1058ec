"""The MuJoCo export of every model of the library compiles, with our mass matrix up to a
stated padding; its options are validated; its names are escaped (issue 31, item 5).

The peer is MuJoCo's compiler and ``mj_fullM``. Our side: Pinocchio's ``crba`` of the
rigid tree plus ``diag(armature)``. The padding (bodies without mass or with a principal
moment below ``tiny_inertia``, :mod:`hexapod_pin.core.mujoco_export`) is measured by a
second export at 1000 times ``tiny_inertia`` (the effect is linear in it), and its size is
checked against the a-priori bound ``tiny sum_b (||Jc_b||^2 + ||Jw_b||^2)`` computed here
from Pinocchio's body Jacobians.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import hexapod_pin as hp
from hexapod_pin.core.description import LoopsSpec
from hexapod_pin.errors import InputError
from hexapod_pin.loaders import robots as library_robots
from hexapod_pin.loaders.any_robot import load_model

mujoco = pytest.importorskip("mujoco")
import robot_registry

from hexapod_pin.core.mujoco_export import (
    TINY_INERTIA,
    closed_loop_mjcf,
    mujoco_state,
    to_mujoco,
    velocity_map,
)

DATA = Path(__file__).resolve().parents[1] / "data"

#: every model of the library: the built-in robots, the robots of the test registry,
#: the remaining test description and the library's loaders of upstream robots
BUILDERS = {
    "builtin-hexapod": lambda: hp.Hexapod.default().model,
    "builtin-planar": lambda: hp.Planar3PRR.default().model,
    "five-bar-6d": lambda: load_model(DATA / "parallel" / "five_bar_6d")[0],
    "solo12": library_robots.solo12,
    "cassie": library_robots.cassie,
    **{f"registry-{name}": (lambda name=name: robot_registry.get(name).model)
       for name in robot_registry.ROBOTS},
}


def _model(name):
    built = BUILDERS[name]()
    return built if isinstance(built, hp.ClosedLoopModel) else built.model


def _q(clm, rng):
    return pin.integrate(clm.model, pin.neutral(clm.model), 0.1 * rng.normal(size=clm.nv))


def _mass_matrices(clm, q, tiny):
    """Ours and MuJoCo's (mapped to Pinocchio's coordinates: ``T^T M_mj T``) at ``q``."""
    rigid = pin.Model(clm.tree_model)
    rigid.armature[:] = 0.0
    mass = pin.crba(rigid, rigid.createData(), q)
    mass = np.triu(mass) + np.triu(mass, 1).T + np.diag(clm.effects.armature)
    model = to_mujoco(clm, tiny_inertia=tiny)
    data = mujoco.MjData(model)
    data.qpos[:] = mujoco_state(clm, q).qpos
    mujoco.mj_forward(model, data)
    full = np.zeros((model.nv, model.nv))
    mujoco.mj_fullM(model, data, full)
    t_map = velocity_map(clm, q)
    return mass, t_map.T @ full @ t_map


def _padding_bound(clm, q):
    """``sum_b (||Jc_b||_2^2 + ||Jw_b||_2^2)`` over every body (kg -> the mass matrix's
    units per kg or kg m^2 of padding): an upper bound of the padding's effect per unit
    of ``tiny_inertia``."""
    model = clm.tree_model
    data = model.createData()
    pin.computeJointJacobians(model, data, q)
    total = 0.0
    for jid in range(1, model.njoints):
        jac = pin.getJointJacobian(model, data, jid, pin.ReferenceFrame.LOCAL)
        lever = model.inertias[jid].lever
        linear = jac[:3] - pin.skew(lever) @ jac[3:]          # v_c = v + w x c
        total += np.linalg.norm(linear, 2) ** 2 + np.linalg.norm(jac[3:], 2) ** 2
    return total


def _needs_padding(clm, tiny):
    for inertia in list(clm.tree_model.inertias)[1:]:
        if inertia.mass < tiny or np.linalg.eigvalsh(inertia.inertia)[0] < tiny:
            return True
    return False


@pytest.mark.parametrize("name", sorted(BUILDERS))
def test_mujoco_compiles_every_model_and_its_mass_matrix_is_ours(name):
    clm = _model(name)
    q = _q(clm, np.random.default_rng(3))
    mass, small = _mass_matrices(clm, q, TINY_INERTIA)
    _, big = _mass_matrices(clm, q, 1e3 * TINY_INERTIA)
    scale = np.max(np.abs(mass))
    # the padding's effect per unit of tiny_inertia, measured (linear in it)
    per_unit = (big - small) / (999.0 * TINY_INERTIA)
    effect = TINY_INERTIA * per_unit
    assert np.max(np.abs(small - mass - effect)) <= 1e-12 * scale
    # ... within the bound of the module docstring
    bound = TINY_INERTIA * _padding_bound(clm, q)
    assert np.linalg.norm(effect, 2) <= 1.01 * bound + 1e-12 * scale
    # ... small: below 1e-10 of the mass matrix on every model of the library
    assert np.max(np.abs(effect)) <= 1e-10 * scale
    if not _needs_padding(clm, 1e3 * TINY_INERTIA):
        assert closed_loop_mjcf(clm) == closed_loop_mjcf(clm, tiny_inertia=1e3 * TINY_INERTIA)
        assert np.max(np.abs(small - mass)) <= 1e-12 * scale


@pytest.mark.parametrize("name", ["builtin-hexapod", "builtin-planar"])
def test_the_built_in_robots_need_padding_and_only_their_deficient_moments_move(name):
    clm = _model(name)
    model = to_mujoco(clm)
    assert _needs_padding(clm, TINY_INERTIA)
    for jid in range(1, clm.model.njoints):
        inertia = clm.model.inertias[jid]
        body = model.body(clm.model.names[jid])
        ours = np.sort(np.linalg.eigvalsh(inertia.inertia))
        theirs = np.sort(body.inertia)
        np.testing.assert_allclose(theirs, np.maximum(ours, TINY_INERTIA), rtol=1e-12,
                                   atol=1e-18)
        assert body.mass[0] == max(inertia.mass, TINY_INERTIA)


OPTIONS = [
    ("timestep", math.inf), ("timestep", math.nan), ("timestep", 0.0), ("timestep", -1e-3),
    ("timestep", "1e-3"), ("timestep", None), ("timestep", True), ("timestep", 1e-3j),
    ("tiny_inertia", 0.0), ("tiny_inertia", 1e-16), ("tiny_inertia", math.inf),
    ("tiny_inertia", "x"),
    ("solref", (math.nan, 1.0)), ("solref", (0.02, math.inf)), ("solref", (0.02,)),
    ("solref", "0.02 1"), ("solref", 0.02), ("solref", (0.02, -1.0)), ("solref", (-1.0, 1.0)),
    ("solref", (0.0, 1.0)), ("solref", (1e-3, 1.0)), ("solref", (True, 1.0)),
    ("solimp", (0.9, 0.95)), ("solimp", (0.9, 0.95, 0.001, 0.5)), ("solimp", (1.0, 1.0, 0.001)),
    ("solimp", (0.9, 0.95, 0.0)), ("solimp", (0.9, 0.95, 0.001, 0.5, 0.5)),
    ("solimp", (0.9, 0.95, 0.001, 1.5, 2.0)), ("solimp", (math.nan, 0.9, 0.001)),
    ("solimp", None), ("solimp", "0.9 0.9 0.001"),
]


@pytest.mark.parametrize("option, value", OPTIONS)
def test_bad_export_options_are_refused_by_name(option, value):
    clm = robot_registry.get("four-bar").model
    with pytest.raises(InputError, match=option) as caught:
        closed_loop_mjcf(clm, **{option: value})
    assert caught.value.name == option
    with pytest.raises(InputError, match=option):
        to_mujoco(clm, **{option: value})


def test_good_options_reach_the_compiled_model():
    clm = robot_registry.get("four-bar").model
    model = to_mujoco(clm, timestep=2e-3, solref=(0.01, 0.5), solimp=(0.9, 0.95, 0.002),
                      tiny_inertia=1e-10)
    assert model.opt.timestep == 2e-3
    np.testing.assert_array_equal(model.eq_solref[0], [0.01, 0.5])
    np.testing.assert_array_equal(model.eq_solimp[0][:3], [0.9, 0.95, 0.002])
    direct = to_mujoco(clm, solref=(-1e4, -10.0))
    np.testing.assert_array_equal(direct.eq_solref[0], [-1e4, -10.0])


def test_a_non_model_is_refused():
    with pytest.raises(InputError, match="clm"):
        closed_loop_mjcf("four_bar.urdf")


def _renamed_four_bar(tmp_path, crank, closure="pin", robot="four_bar"):
    """The four-bar of tests/data with its actuated joint, its closure and its robot
    renamed (XML-escaped in the URDF, YAML-quoted in the loops file)."""
    from xml.sax.saxutils import escape

    urdf = (DATA / "four_bar" / "four_bar.urdf").read_text()
    urdf = urdf.replace('name="crank"', f'name="{escape(crank, {chr(34): "&quot;"})}"')
    urdf = urdf.replace('<robot name="four_bar">',
                        f'<robot name="{escape(robot, {chr(34): "&quot;"})}">')
    loops = (DATA / "four_bar" / "four_bar.loops.yaml").read_text()
    loops = loops.replace("actuated: [crank]", f"actuated: [{json.dumps(crank)}]")
    loops = loops.replace("{name: pin,", f"{{name: {json.dumps(closure)},")
    (tmp_path / "r.urdf").write_text(urdf)
    (tmp_path / "r.loops.yaml").write_text(loops)
    return load_model(tmp_path / "r.urdf")[0]


@pytest.mark.parametrize("crank", ['cr"ank', "cr<ank>", "a&b", "it's", "a b"])
def test_names_with_xml_characters_are_escaped(crank, tmp_path):
    clm = _renamed_four_bar(tmp_path, crank, closure=f"pin{crank}")
    assert crank in clm.actuated_joints
    model = to_mujoco(clm)
    assert model.joint(crank).id >= 0 and model.body(crank).id >= 0
    assert model.actuator(crank).trnid[0] == model.joint(crank).id
    assert model.equality(f"pin{crank}").id == 0
    assert mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, model.joint(crank).id) == crank


def test_a_name_xml_cannot_carry_is_refused_by_name():
    clm = robot_registry.get("four-bar").model
    tree = pin.Model(clm.tree_model)
    tree.names[1] = "crank\x01"
    bad = hp.ClosedLoopModel(tree, LoopsSpec(closures=clm.loops.closures,
                                             actuated=("crank\x01",)))
    with pytest.raises(InputError, match="joint name") as caught:
        closed_loop_mjcf(bad)
    assert caught.value.value == "crank\x01"
