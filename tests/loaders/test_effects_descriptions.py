"""Joint and drive effects read from the descriptions: a URDF's ``<dynamics damping
friction>``, the ``effects:`` section of a loops file, an SDF's ``<axis><dynamics>``
(damping, friction, spring reference and stiffness), and the loops file the SDF -> URDF
export writes.

References written here: the numbers of the files, and the inverse dynamics of the
rigid mechanism from raw Pinocchio (``crba``, ``nonLinearEffects`` on the tree without
armature) projected on the closures' null space (scipy), plus the effects' force
``D v + c sign(v) + K (q - q_ref)`` written out.
"""

from __future__ import annotations

import dataclasses
import math
import re
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import scipy.linalg
from conftest import TWO_LINKS
from test_sdf import FOUR_BAR

from hexapod_pin.core.closed_loop import ClosedLoopModel
from hexapod_pin.core.description import build_model, load_loops, parse_loops
from hexapod_pin.core.dynamics import inverse_dynamics_tree
from hexapod_pin.errors import DescriptionError
from hexapod_pin.loaders.sdf import closed_loop_from_sdf, loops_yaml, parse_sdf, sdf_to_urdf

DATA = Path(__file__).resolve().parents[1] / "data" / "four_bar"
URDF = (DATA / "four_bar.urdf").read_text()
LOOPS = (DATA / "four_bar.loops.yaml").read_text()


def _with_dynamics(urdf, **joints):
    """The URDF with ``<dynamics damping friction>`` added to the named joints."""
    for joint, (damping, friction) in joints.items():
        start = urdf.index(f'<joint name="{joint}"')
        end = urdf.index("</joint>", start)
        urdf = (urdf[:end] + f'<dynamics damping="{damping}" friction="{friction}"/>'
                + urdf[end:])
    return urdf


def _four_bar(folder, urdf=URDF, effects=""):
    """The four-bar of tests/data written to ``folder`` with another URDF / effects."""
    folder.mkdir(exist_ok=True)
    (folder / "four_bar.urdf").write_text(urdf)
    (folder / "four_bar.loops.yaml").write_text(LOOPS + effects)
    return ClosedLoopModel.from_files(folder / "four_bar.urdf", folder / "four_bar.loops.yaml")


def _array(clm, values):
    """(nv,) zeros but ``values`` ({index: value})."""
    out = np.zeros(clm.nv)
    out[list(values)] = list(values.values())
    return out


def _reference_u(clm, q, v, a, damping, coulomb, stiffness=None, q_ref=None, armature=None):
    """Actuator forces of ``(M + A) a + h + D v + c sign(v) + K (q - q_ref) = S^T u +
    J^T lambda`` on the null space of the closures (1-DoF joints, nq = nv)."""
    model = pin.Model(clm.tree_model)
    model.armature[:] = 0.0
    data = model.createData()
    mass = pin.crba(model, data, q)
    mass = np.triu(mass) + np.triu(mass, 1).T + np.diag(np.zeros(clm.nv) if armature is None
                                                       else armature)
    needed = mass @ a + pin.nonLinearEffects(model, data, q, v) + damping * v \
        + coulomb * np.sign(v)
    if stiffness is not None:
        needed += stiffness * (q - q_ref)
    selection = np.zeros((clm.nv, clm.n_actuated))
    selection[clm.actuated_v, np.arange(clm.n_actuated)] = 1.0
    null = scipy.linalg.null_space(clm.constraint_jacobian(q), rcond=1e-10) \
        if clm.n_rows else np.eye(clm.nv)
    return np.linalg.lstsq(null.T @ selection, null.T @ needed, rcond=None)[0]


def _motion(clm, q0, seed):
    rng = np.random.default_rng(seed)
    q = clm.assemble(q0).q
    v = clm.velocity_from_actuated(q, [1.3 + rng.uniform()])
    a = clm.acceleration_from_actuated(q, v, [rng.normal()])
    assert np.all(np.abs(v) > 1e-3)
    return q, v, a


HOME = np.array([0.3, -0.9, -1.8])


# ------------------------------------------------------------------------------- URDF
def test_urdf_damping_and_friction_enter_inverse_dynamics(tmp_path):
    """On the actuated crank alone: the rigid answer + d v + c sign(v); on every joint:
    the null-space reference with D v + c sign(v)."""
    rigid = _four_bar(tmp_path / "rigid")
    crank_only = _four_bar(tmp_path / "crank", _with_dynamics(URDF, crank=(0.7, 0.3)))
    np.testing.assert_array_equal(crank_only.effects.damping, [0.7, 0.0, 0.0])
    np.testing.assert_array_equal(crank_only.effects.coulomb, [0.3, 0.0, 0.0])
    for seed in (1, 2):
        q, v, a = _motion(rigid, HOME, seed)
        for sign in (1.0, -1.0):
            u_rigid = inverse_dynamics_tree(rigid, q, sign * v, a, method="kkt").actuator_forces
            u = inverse_dynamics_tree(crank_only, q, sign * v, a, method="kkt").actuator_forces
            expected = u_rigid + 0.7 * sign * v[0] + 0.3 * np.sign(sign * v[0])
            np.testing.assert_allclose(u, expected, rtol=0, atol=1e-12)
            np.testing.assert_allclose(u_rigid, _reference_u(rigid, q, sign * v, a, 0.0, 0.0),
                                       rtol=1e-10)
    every = _four_bar(tmp_path / "every", _with_dynamics(URDF, crank=(0.7, 0.3), coupler_pin=(
        0.2, 0.05), rocker_pivot=(1.1, 0.4)))
    damping, coulomb = np.array([0.7, 0.2, 1.1]), np.array([0.3, 0.05, 0.4])
    q, v, a = _motion(every, HOME, 3)
    for method in ("kkt", "qp"):
        u = inverse_dynamics_tree(every, q, v, a, method=method).actuator_forces
        np.testing.assert_allclose(u, _reference_u(every, q, v, a, damping, coulomb), rtol=1e-9)


@pytest.mark.parametrize("value", ["-0.5", "abc", "nan", "inf"])
@pytest.mark.parametrize("attribute", ["damping", "friction"])
def test_bad_urdf_dynamics_name_the_joint_and_its_line(attribute, value):
    values = {"damping": "0.1", "friction": "0.1"} | {attribute: value}
    urdf = _with_dynamics(URDF, coupler_pin=(values["damping"], values["friction"]))
    line = URDF[:URDF.index('<joint name="coupler_pin"')].count("\n") + 1
    with pytest.raises(DescriptionError, match=f"<dynamics {attribute}>") as info:
        build_model(urdf, source="four_bar.urdf")
    assert info.value.source == "four_bar.urdf"
    assert info.value.culprit == f"joint coupler_pin (line {line})"


# -------------------------------------------------------------------- loops effects
EFFECTS = """effects:
  velocity_threshold: 1.0e-6
  joints:
    crank: {armature: 0.02, damping: 1.1, stiffness: 3.0, spring_reference: 0.2, gear: 25,
            rotor_inertia: 1.0e-5, effort_limit: 100}
    coupler_pin: {damping: [0.4], coulomb: 0.1}
"""


def test_loops_file_effects_override_the_trees(tmp_path):
    clm = _four_bar(tmp_path, _with_dynamics(URDF, crank=(0.7, 0.3), rocker_pivot=(0.9, 0.2)),
                    EFFECTS)
    eff = clm.effects
    np.testing.assert_array_equal(eff.damping, [1.1, 0.4, 0.9])     # loops file, then URDF
    np.testing.assert_array_equal(eff.coulomb, [0.3, 0.1, 0.2])
    np.testing.assert_allclose(eff.armature, [0.02 + 25.0 ** 2 * 1e-5, 0.0, 0.0], rtol=1e-15)
    np.testing.assert_array_equal(eff.stiffness, [3.0, 0.0, 0.0])
    np.testing.assert_array_equal(eff.spring_reference, [0.2, 0.0, 0.0])
    np.testing.assert_array_equal(eff.gear, [25.0])
    np.testing.assert_array_equal(eff.effort_limit, [100.0])
    assert eff.velocity_threshold == 1e-6
    q, v, a = _motion(clm, HOME, 4)
    u = inverse_dynamics_tree(clm, q, v, a, method="kkt").actuator_forces
    ref = _reference_u(clm, q, v, a, np.array([1.1, 0.4, 0.9]), np.array([0.3, 0.1, 0.2]),
                       np.array([3.0, 0, 0]), np.array([0.2, 0, 0]),
                       np.array([0.02 + 625e-5, 0, 0]))
    np.testing.assert_allclose(u, ref, rtol=1e-10)
    # derived models keep them (with_effects starts from the record, not the file)
    assert clm.with_effects(damping={"rocker_pivot": 0.0}).effects.damping.tolist() == \
        [1.1, 0.4, 0.0]


def test_a_continuous_joints_spring_reference_is_an_angle():
    urdf = TWO_LINKS.format(mass=1.0, ixx=0.01, x=0.0, axis="0 1 0").replace(
        'type="revolute"', 'type="continuous"')
    text = "closures: []\nactuated: [j]\neffects:\n  joints:\n    j: {stiffness: 2.0, " \
        "spring_reference: 0.3}\n"
    clm = ClosedLoopModel(build_model(urdf), parse_loops(text))
    assert clm.nq == 2 and clm.nv == 1
    np.testing.assert_allclose(clm.effects.spring_reference, [math.cos(0.3), math.sin(0.3)],
                               rtol=1e-15)
    q = np.array([math.cos(1.0), math.sin(1.0)])
    v, a = np.array([0.0]), np.array([0.0])
    u = inverse_dynamics_tree(clm, q, v, a, method="kkt").actuator_forces
    gravity = pin.rnea(clm.tree_model, clm.tree_model.createData(), q, v, a)
    np.testing.assert_allclose(u, gravity + 2.0 * (1.0 - 0.3), rtol=1e-12)


def _at_line(culprit):
    """A culprit of the tables below with its ``line +k`` (k = 1: the ``effects:`` line,
    written after the four-bar's loops file) made absolute."""
    before = LOOPS.count("\n")
    return re.sub(r"line \+(\d+)", lambda m: f"line {before + int(m.group(1))}", culprit)


BAD_EFFECTS = [
    ("effects: [1, 2]\n", "must be a mapping", "effects (line +1)"),
    ("effects:\n  joint: {}\n", "unknown key 'joint'", "effects.joint (line +2)"),
    ("effects:\n  joints:\n    crank: {damp: 1.0}\n", "unknown key 'damp'",
     "effects.joints.crank.damp (line +3)"),
    ("effects:\n  joints:\n    crank: {damping: 1e-3}\n", "write 1.0e-9",
     "effects.joints.crank.damping (line +3)"),
    ("effects:\n  joints:\n    crank: {damping: [1, x]}\n", "a number or a list",
     "effects.joints.crank.damping (line +3)"),
    ("effects:\n  joints:\n    crank: 3\n", "must be a mapping", "effects.joints.crank (line +3)"),
    ("effects:\n  joints:\n    crank: {damping: 1}\n    crank: {coulomb: 1}\n", "twice",
     "effects.joints.crank (line +4)"),
    ("effects:\n  velocity_threshold: [1.0, 2.0]\n", "one number",
     "effects.velocity_threshold (line +2)"),
]
BAD_VALUES = [
    ("effects:\n  joints:\n    cranck: {damping: 1.0}\n", "not a joint of the tree",
     "effects.joints.cranck.damping (line +3)"),
    ("effects:\n  joints:\n    coupler_pin: {gear: 5}\n", "not an actuated joint",
     "effects.joints.coupler_pin.gear (line +3)"),
    ("effects:\n  joints:\n    crank: {damping: -1.0}\n", "must be >= 0",
     "effects.joints.crank.damping (line +3)"),
    ("effects:\n  joints:\n    crank:\n      coulomb: 0.1\n      armature: [0.1, 0.2]\n",
     "1 velocity coordinates", "effects.joints.crank.armature (line +5)"),
    ("effects:\n  joints:\n    crank: {gear: 0}\n", "nonzero", "effects.joints.crank.gear (line +3)"),
    ("effects:\n  joints:\n    crank: {effort_limit: 0.0}\n", "> 0",
     "effects.joints.crank.effort_limit (line +3)"),
    ("effects:\n  joints:\n    crank: {stiffness: .nan}\n", "NaN",
     "effects.joints.crank.stiffness (line +3)"),
    ("effects:\n  velocity_threshold: -1.0\n", "finite number >= 0",
     "effects.velocity_threshold (line +2)"),
]


@pytest.mark.parametrize("text, words, culprit", BAD_EFFECTS)
def test_a_malformed_effects_section_names_the_file_key_and_line(tmp_path, text, words, culprit):
    path = tmp_path / "four_bar.loops.yaml"
    path.write_text(LOOPS + text)
    with pytest.raises(DescriptionError, match=re.escape(words)) as info:
        load_loops(path)
    assert info.value.source == str(path) and info.value.culprit == _at_line(culprit)


@pytest.mark.parametrize("text, words, culprit", BAD_VALUES)
def test_effects_the_tree_refuses_name_the_file_key_and_line(tmp_path, text, words, culprit):
    """Names, sizes and ranges are checked when the model is built (against the tree)."""
    load_loops_ok = parse_loops(LOOPS + text)                   # the syntax is right
    assert load_loops_ok.effects is not None
    with pytest.raises(DescriptionError, match=re.escape(words)) as info:
        _four_bar(tmp_path, effects=text)
    assert info.value.source == str(tmp_path / "four_bar.loops.yaml")
    assert info.value.culprit == _at_line(culprit)


# -------------------------------------------------------------------------------- SDF
DYNAMICS = ("<dynamics><damping>0.3</damping><friction>0.2</friction>"
            "<spring_reference>0.1</spring_reference><spring_stiffness>4</spring_stiffness>"
            "</dynamics>")
FOUR_BAR_MOVED = FOUR_BAR.replace(
    '<joint name="rocker_joint" type="revolute"><parent>ground</parent><child>rocker</child>',
    '<joint name="rocker_joint" type="revolute"><parent>ground</parent><child>rocker</child>'
    '<pose>0 0 -0.25 0 0 0</pose>')
SPRUNG = FOUR_BAR_MOVED.replace(
    '<joint name="crank_joint" type="revolute"><parent>ground</parent><child>crank</child>'
    '<axis><xyz>0 1 0</xyz></axis>',
    '<joint name="crank_joint" type="revolute"><parent>ground</parent><child>crank</child>'
    f'<axis><xyz>0 1 0</xyz>{DYNAMICS}</axis>').replace(
    '<child>rocker</child><pose>0 0 -0.25 0 0 0</pose><axis><xyz>0 1 0</xyz>',
    '<child>rocker</child><pose>0 0 -0.25 0 0 0</pose><axis><xyz>0 1 0</xyz>'
    '<dynamics><damping>0.05</damping><spring_stiffness>2.5</spring_stiffness></dynamics>')


def test_sdf_joint_dynamics_become_the_models_effects():
    assert SPRUNG.count("<dynamics>") == 2
    clm = closed_loop_from_sdf(parse_sdf(SPRUNG), actuated=["crank_joint"])
    crank, rocker = clm.joint_v_index("crank_joint"), clm.joint_v_index("rocker_joint")
    eff = clm.effects
    expected = {"damping": {crank: 0.3, rocker: 0.05}, "coulomb": {crank: 0.2},
                "stiffness": {crank: 4.0, rocker: 2.5}, "spring_reference": {crank: 0.1}}
    for field, values in expected.items():
        np.testing.assert_array_equal(getattr(eff, field), _array(clm, values), err_msg=field)
    q0 = pin.neutral(clm.model)
    q0[clm.joint_q_index("crank_joint")] = 0.4
    q, v, a = _motion(clm, q0, 5)
    u = inverse_dynamics_tree(clm, q, v, a, method="kkt").actuator_forces
    ref = _reference_u(clm, q, v, a, _array(clm, expected["damping"]),
                       _array(clm, expected["coulomb"]), _array(clm, expected["stiffness"]),
                       _array(clm, expected["spring_reference"]))
    np.testing.assert_allclose(u, ref, rtol=1e-10)


def test_sdf_effects_survive_the_urdf_and_loops_files(tmp_path):
    """SDF -> URDF (<dynamics>) + loops file (effects: the springs) -> Pinocchio's own URDF
    parser: the same effects as the direct route."""
    sdf = parse_sdf(SPRUNG)
    urdf, loops = sdf_to_urdf(sdf)
    (tmp_path / "m.urdf").write_text(urdf)
    (tmp_path / "m.loops.yaml").write_text(loops_yaml(loops).replace("actuated: []",
                                                                    "actuated: [crank_joint]"))
    via = ClosedLoopModel.from_files(tmp_path / "m.urdf", tmp_path / "m.loops.yaml")
    direct = closed_loop_from_sdf(sdf, actuated=["crank_joint"])
    assert list(via.model.names) == list(direct.model.names)
    for field in ("armature", "damping", "coulomb", "stiffness", "spring_reference"):
        np.testing.assert_array_equal(getattr(via.effects, field), getattr(direct.effects, field),
                                      err_msg=field)
    assert "<dynamics damping=\"0.3\" friction=\"0.2\"/>" in urdf
    # the loops file reads back as written, a threshold and an infinite limit included
    section = dataclasses.replace(loops.effects, velocity_threshold=1e-7, joints=(
        *loops.effects.joints, ("coupler_joint", (("effort_limit", math.inf), ("gear", -3.0)))))
    back = parse_loops(loops_yaml(dataclasses.replace(loops, effects=section))).effects
    assert back.joints == section.joints and back.velocity_threshold == 1e-7


@pytest.mark.parametrize("tag, value", [("damping", "-1"), ("friction", "-0.2"),
                                        ("spring_stiffness", "-4"), ("damping", "inf"),
                                        ("spring_reference", "inf")])
def test_bad_sdf_dynamics_name_the_joint(tag, value):
    text = SPRUNG.replace(f"<{tag}>{re.search(f'<{tag}>([^<]*)</{tag}>', SPRUNG).group(1)}"
                          f"</{tag}>", f"<{tag}>{value}</{tag}>", 1)
    with pytest.raises(DescriptionError, match=tag) as info:
        parse_sdf(text, source="sprung.sdf")
    assert info.value.source == "sprung.sdf" and info.value.culprit == "crank_joint"
