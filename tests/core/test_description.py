import numpy as np
import pinocchio as pin
import pytest
import yourdfpy
from conftest import TWO_LINKS

import hexapod_pin as hp
from hexapod_pin.hexapod.geometry import hexapod_urdf
from hexapod_pin.core.description import build_model, parse_loops, urdf_dir, validate_urdf
from hexapod_pin.errors import DescriptionError


@pytest.fixture(scope="module")
def urdf_text():
    return hexapod_urdf(hp.HexapodGeometry())


def test_xacro_expands_and_loads_in_yourdfpy(urdf_text, tmp_path):
    path = tmp_path / "hexapod.urdf"
    path.write_text(urdf_text)
    robot = yourdfpy.URDF.load(str(path), build_scene_graph=True, load_meshes=False)
    types = [j.type for j in robot.robot.joints]
    assert types.count("prismatic") == 6
    assert types.count("revolute") == 12
    assert types.count("floating") == 1
    # the leg of a rail is as long as the geometry says, in yourdfpy's own parse
    leg = robot.link_map["leg_0"]
    assert leg.inertial.mass == pytest.approx(0.3)
    tip = robot.joint_map["leg_0_tip_mount"].origin
    assert tip[2, 3] == pytest.approx(0.45)


def test_xacro_arguments_change_the_model():
    text = hexapod_urdf(hp.HexapodGeometry(leg_length=0.5, platform_mass=2.0))
    model = build_model(text)
    assert model.inertias[model.getJointId("platform_joint")].mass == pytest.approx(2.0)
    fid = model.getFrameId("leg_3_tip")
    assert model.frames[fid].placement.translation[2] == pytest.approx(0.5)


def test_pinocchio_tree_has_the_expected_joints(urdf_text):
    model = build_model(urdf_text)
    assert (model.nq, model.nv, model.njoints) == (25, 24, 20)
    assert model.check(model.createData())
    kinds = {model.names[j]: model.joints[j].shortname() for j in range(1, model.njoints)}
    for i in range(6):
        assert kinds[f"carriage_{i}"] == "JointModelPX"
        assert kinds[f"u_{i}_a"] == "JointModelRX"
        assert kinds[f"u_{i}_b"] == "JointModelRY"
        # depth-first: each leg chain is contiguous under its carriage
        jc = model.getJointId(f"carriage_{i}")
        assert model.parents[model.getJointId(f"u_{i}_a")] == jc
        assert model.parents[model.getJointId(f"u_{i}_b")] == jc + 1
    assert kinds["platform_joint"] == "JointModelFreeFlyer"
    # total mass of the tree = 6 carriages + 6 legs + platform
    data = model.createData()
    assert pin.computeTotalMass(model, data) == pytest.approx(6 * 0.5 + 6 * 0.3 + 1.5)


def test_carriage_joint_frames_follow_the_rails(urdf_text):
    model = build_model(urdf_text)
    g = hp.HexapodGeometry()
    for i in range(6):
        k = i // 2
        placement = model.jointPlacements[model.getJointId(f"carriage_{i}")]
        np.testing.assert_allclose(placement.translation, g.rail_midpoints[k], atol=1e-12)
        # the prismatic axis (local x) is the rail direction u_k
        np.testing.assert_allclose(placement.rotation[:, 0], g.rail_directions[k], atol=1e-12)


def test_loops_file_parses():
    spec = hp.load_loops(urdf_dir() / "hexapod.loops.yaml")
    assert len(spec.closures) == 6 and all(c.type == "point" for c in spec.closures)
    assert spec.actuated == tuple(f"carriage_{i}" for i in range(6))


@pytest.mark.parametrize("text,culprit", [
    ("closures: [", "line 1"),                 # the line the YAML parser names
    ("- a\n- b", None),
    ("closures: [{name: a, type: hinge, frame1: x, frame2: y}]", "a"),
    ("closures: [{name: a, type: point, frame1: x}]", "closures[0]"),
    ("closures: [{name: a, type: point, frame1: x, frame2: x}]", "a"),
    ("closures: [{name: a, type: point, frame1: x, frame2: y}, {name: a, type: point, frame1: x, frame2: z}]", "a"),
    ("closures: []\nactuated: [j, j]", "actuated"),
    ("closures: []\nbogus: 1", "bogus"),
    ("closures: [{name: a, type: point, frame1: x, frame2: y, offset1: {xyz: [1, 2]}}]", "a"),
])
def test_malformed_loops_raise(text, culprit):
    with pytest.raises(DescriptionError) as info:
        parse_loops(text, source="test.yaml")
    assert info.value.culprit == culprit


def test_missing_files_raise(tmp_path):
    with pytest.raises(hp.MissingFileError, match="not found") as err:
        hp.expand_xacro(tmp_path / "none.urdf.xacro")
    assert isinstance(err.value, FileNotFoundError) and err.value.path.endswith("none.urdf.xacro")
    with pytest.raises(hp.MissingFileError, match="not found"):
        hp.load_loops(tmp_path / "none.yaml")
    with pytest.raises(DescriptionError, match="child link='missing'> names no link"):
        build_model("<robot name='x'><link name='a'/><joint name='j' type='revolute'>"
                    "<parent link='a'/><child link='missing'/></joint></robot>")


# -- descriptions validated at load (Pinocchio alone only warns, or loads non-physics) ----------
def _two_links(mass="1.0", ixx="0.02", x="0", axis="0 0 1"):
    return TWO_LINKS.format(mass=mass, ixx=ixx, x=x, axis=axis)


def test_a_valid_description_loads():
    model = build_model(_two_links(), source="two")
    assert model.nq == 1 and model.inertias[1].mass == pytest.approx(1.0)


@pytest.mark.parametrize("changes, words", [
    ({"mass": "-1.0"}, "mass must be finite and >= 0"),
    ({"mass": "nan"}, "mass must be finite"),
    ({"mass": "abc"}, "malformed URDF"),
    ({"ixx": "-0.02"}, "not positive semi-definite"),
    ({"ixx": "0.001"}, "triangle inequality"),
    ({"mass": "0"}, "zero mass with a non-zero inertia"),
    ({"axis": "0 0 0"}, "axis must be finite and non-zero"),
    ({"x": "1e300"}, "joint origin beyond"),
    ({"x": "inf"}, "joint origin must be finite"),
])
def test_non_physical_descriptions_are_refused(changes, words):
    with pytest.raises(DescriptionError, match=words) as err:
        build_model(_two_links(**changes), source="two")
    assert err.value.source == "two"
    # Pinocchio alone accepts (or silently repairs) most of these: the check is ours
    assert err.value.culprit in ("link arm", "joint j", None)


def test_binary_and_missing_files_are_description_errors(tmp_path):
    binary = tmp_path / "robot.urdf"
    binary.write_bytes(bytes(range(256)) * 4)
    loops = tmp_path / "robot.loops.yaml"
    loops.write_bytes(b"\xff\xfe\x00closures")
    with pytest.raises(DescriptionError, match="not UTF-8"):
        hp.ClosedLoopModel.from_files(binary, urdf_dir() / "hexapod.loops.yaml")
    with pytest.raises(DescriptionError, match="not UTF-8"):
        hp.load_loops(loops)
    with pytest.raises(hp.MissingFileError, match="file not found"):
        hp.load_loops(tmp_path / "missing.yaml")


def test_unknown_xacro_arguments_are_refused():
    with pytest.raises(DescriptionError, match="unknown xacro argument"):
        hp.expand_xacro(urdf_dir() / "hexapod.urdf.xacro", {"leg_lenght": "0.5"})


def test_huge_closure_offsets_are_refused():
    text = ("closures:\n  - {name: c, type: point, frame1: a, frame2: b,\n"
            "     offset1: {xyz: [1.0e160, 0, 0]}}\nactuated: [j]\n")
    with pytest.raises(DescriptionError, match="offset xyz beyond"):
        parse_loops(text)


def test_inertia_check_is_shared_by_the_sdf_reader():
    from hexapod_pin.loaders.sdf import parse_sdf
    sdf = """<sdf version="1.9"><model name="m"><link name="a"><inertial><mass>1</mass>
      <inertia><ixx>0.001</ixx><iyy>0.02</iyy><izz>0.03</izz></inertia></inertial></link>
      </model></sdf>"""
    with pytest.raises(DescriptionError, match="triangle inequality"):
        parse_sdf(sdf)


def _run(code: str, env_extra: dict | None = None) -> str:
    import os
    import subprocess
    import sys
    env = dict(os.environ, **(env_extra or {}))
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env=env, timeout=300, check=False)
    assert done.returncode == 0, done.stderr[-3000:]
    return done.stdout.strip()


def test_importing_the_package_loads_no_urdf_parser():
    """``import hexapod_pin`` does not pay for yourdfpy / trimesh / networkx (0.6 s)."""
    out = _run("import sys, hexapod_pin; print(sorted(m for m in ('yourdfpy', 'trimesh', "
               "'networkx') if m in sys.modules))")
    assert out == "[]"


def test_a_validated_description_is_remembered_and_a_bad_one_never(tmp_path):
    """The second load of the same text under the same name skips the strict parse (no
    yourdfpy in that process); other text under that name, or a failing text, is parsed."""
    import uuid
    source = f"memo-test-{uuid.uuid4().hex}"
    good = TWO_LINKS.format(mass=1, ixx=0.01, x=0, axis="0 0 1")
    path = tmp_path / "two_links.urdf"
    path.write_text(good, encoding="utf-8")
    check = ("import sys; from hexapod_pin.core.description import validate_urdf; "
             f"validate_urdf(open({str(path)!r}).read(), {source!r}); "
             "print('yourdfpy' in sys.modules)")
    assert _run(check) == "True"            # parsed, then remembered
    assert _run(check) == "False"           # remembered: not parsed
    assert _run(check, {"HEXAPOD_PIN_NO_MEMO": "1"}) == "True"
    bad = TWO_LINKS.format(mass=-1, ixx=0.01, x=0, axis="0 0 1")
    for _ in range(2):                      # a failure is never remembered
        with pytest.raises(DescriptionError, match="mass"):
            validate_urdf(bad, source)
    assert _run(check) == "False"           # the good text is still the one remembered


@pytest.mark.parametrize("file_name, loops, args, culprit", [
    ("hexapod.urdf.xacro", "hexapod.loops.yaml", {"leg_length": "0"}, "leg_length"),
    ("hexapod.urdf.xacro", "hexapod.loops.yaml", {"leg_length": "-0.45"}, "leg_length"),
    ("hexapod.urdf.xacro", "hexapod.loops.yaml", {"leg_4_length": "0"}, "leg_4_length"),
    ("hexapod.urdf.xacro", "hexapod.loops.yaml", {"platform_izz": "-1"}, "platform_izz"),
    ("hexapod.urdf.xacro", "hexapod.loops.yaml", {"carriage_mass": "heavy"}, "carriage_mass"),
    ("planar_3prr.urdf.xacro", "planar_3prr.loops.yaml", {"link_length": "0"}, "link_length"),
    ("planar_3prr.urdf.xacro", "planar_3prr.loops.yaml", {"slider_mass": "-1"}, "slider_mass"),
])
def test_xacro_arguments_follow_the_geometry_rules(file_name, loops, args, culprit):
    """A xacro argument the robot's geometry would refuse (a zero or negative leg, a
    negative moment, text) is refused at expansion, naming the argument (before: the model
    loaded, with a singular mass matrix for a zero leg); the same geometry as a
    :class:`HexapodGeometry` is a GeometryError; valid arguments still load."""
    with pytest.raises(DescriptionError, match="xacro argument") as info:
        hp.ClosedLoopModel.from_files(urdf_dir() / file_name, urdf_dir() / loops,
                                      xacro_args=args)
    assert info.value.culprit == culprit
    good = {"leg_length": "0.5"} if file_name.startswith("hexapod") else {"link_length": "0.32"}
    model = hp.ClosedLoopModel.from_files(urdf_dir() / file_name, urdf_dir() / loops,
                                          xacro_args=good)
    assert model.model.nq > 0
    with pytest.raises(hp.GeometryError):
        hp.HexapodGeometry(leg_length=0.0)
