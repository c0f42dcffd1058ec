"""A URDF typo is a DescriptionError naming the element, the attribute and the line, raised
before Pinocchio's parser (which prints the cause on C++ stderr and raises a generic "XML
stream does not contain a valid URDF model") (issue 31, item 3).

Positions are found here independently of the validator: start tags by a regular
expression over the text (comments blanked), their lines by counting newlines.
"""

from __future__ import annotations

import re
import string
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import hexapod_pin as hp
from hexapod_pin.core.description import URDF_JOINT_TYPES, build_model, validate_urdf
from hexapod_pin.errors import DescriptionError
from hexapod_pin.hexapod.geometry import hexapod_urdf

DATA = Path(__file__).resolve().parents[1] / "data"
FOUR_BAR = (DATA / "four_bar" / "four_bar.urdf").read_text()
STEWART = (DATA / "stewart" / "stewart.urdf").read_text()
HEXAPOD = hexapod_urdf(hp.HexapodGeometry())
TEXTS = {"four_bar": FOUR_BAR, "stewart": STEWART, "hexapod": HEXAPOD}

#: the attributes of each element of the URDF specification
ATTRIBUTES = {
    "robot": {"name", "version"}, "link": {"name"}, "origin": {"xyz", "rpy"},
    "mass": {"value"}, "inertia": {"ixx", "ixy", "ixz", "iyy", "iyz", "izz"},
    "visual": {"name"}, "collision": {"name"}, "box": {"size"},
    "cylinder": {"radius", "length"}, "sphere": {"radius"}, "mesh": {"filename", "scale"},
    "material": {"name"}, "color": {"rgba"}, "texture": {"filename"},
    "joint": {"name", "type"}, "parent": {"link"}, "child": {"link"},
    "axis": {"xyz"}, "dynamics": {"damping", "friction"},
    "limit": {"lower", "upper", "effort", "velocity"},
}
#: the elements whose every unknown attribute is refused (elsewhere only near misses)
STRICT = {"origin", "mass", "inertia", "axis", "parent", "child"}

_TAG = re.compile(r"<([A-Za-z_]+)((?:\s+[\w:]+\s*=\s*\"[^\"]*\")*)\s*/?>")
_ATTRIBUTE = re.compile(r"([\w:]+)\s*=\s*\"([^\"]*)\"")


def _blank_comments(text):
    return re.sub(r"<!--.*?-->", lambda m: re.sub(r"[^\n]", " ", m.group()), text,
                  flags=re.DOTALL)


def _attributes(text):
    """(tag, line, attribute name, start, end) of every attribute of a known element."""
    out = []
    for tag in _TAG.finditer(_blank_comments(text)):
        if tag.group(1) not in ATTRIBUTES:
            continue
        line = text.count("\n", 0, tag.start()) + 1
        for attribute in _ATTRIBUTE.finditer(tag.group(2)):
            start = tag.start(2) + attribute.start(1)
            out.append((tag.group(1), line, attribute.group(1), start,
                        start + len(attribute.group(1))))
    return out


def _joint_types(text):
    """(joint name, line, start, end of the type's value) of every joint."""
    out = []
    for tag in _TAG.finditer(_blank_comments(text)):
        if tag.group(1) == "joint":
            attributes = {a.group(1): a for a in _ATTRIBUTE.finditer(tag.group(2))}
            kind = attributes["type"]
            out.append((attributes["name"].group(2), text.count("\n", 0, tag.start()) + 1,
                        tag.start(2) + kind.start(2), tag.start(2) + kind.end(2)))
    return out


def _refused(text, capfd=None):
    with pytest.raises(DescriptionError) as caught:
        build_model(text, source="typo.urdf")
    if capfd is not None:
        assert capfd.readouterr().err == ""          # nothing from Pinocchio's parser
    assert "valid URDF model" not in str(caught.value)
    return caught.value


def test_the_descriptions_used_here_pass():
    for text in TEXTS.values():
        validate_urdf(text, source="strictness-clean")
        assert _attributes(text) and _joint_types(text)


def test_an_unknown_joint_type_names_the_joint_its_line_and_the_type(capfd):
    text = FOUR_BAR.replace('name="rocker_pivot" type="revolute"',
                            'name="rocker_pivot" type="revolut"')
    error = _refused(text, capfd)
    line = FOUR_BAR.splitlines().index('  <joint name="rocker_pivot" type="revolute">') + 1
    assert error.culprit == f"joint rocker_pivot (line {line})"
    assert "type='revolut'" in str(error) and "did you mean 'revolute'" in str(error)


@pytest.mark.parametrize("role, typo", [("parent", "bas"), ("child", "rockr")])
def test_a_missing_parent_or_child_link_names_the_joint_and_the_link(role, typo, capfd):
    good = '<parent link="base"/><child link="rocker"/>'
    bad = good.replace('"base"' if role == "parent" else '"rocker"', f'"{typo}"')
    text = FOUR_BAR.replace(good, bad)
    error = _refused(text, capfd)
    assert error.culprit.startswith("joint rocker_pivot (line ")
    assert f"<{role} link='{typo}'> names no link" in str(error)


def test_a_joint_without_its_parent_element_is_refused():
    error = _refused(FOUR_BAR.replace('<parent link="base"/><child link="rocker"/>',
                                      '<child link="rocker"/>'))
    assert "exactly one <parent" in str(error) and "rocker_pivot" in error.culprit


def test_a_misspelt_inertia_attribute_names_the_link_the_attribute_and_the_line(capfd):
    text = FOUR_BAR.replace('iyy="3.0e-3"', 'iyyy="3.0e-3"')
    error = _refused(text, capfd)
    line = next(k for k, row in enumerate(FOUR_BAR.splitlines(), 1) if 'iyy="3.0e-3"' in row)
    assert error.culprit == f"link rocker/inertial/inertia (line {line})"
    assert "iyyy='3.0e-3'" in str(error) and "did you mean 'iyy'" in str(error)
    assert "triangle" not in str(error)                 # the old, misleading report


def test_a_missing_inertia_attribute_is_refused_not_defaulted():
    error = _refused(FOUR_BAR.replace(' iyy="3.0e-3"', ""))
    assert "needs the attribute 'iyy'" in str(error) and "link rocker" in error.culprit


@pytest.mark.parametrize("old, new, expected", [
    ('<link name="rocker_end"/>', '<link name="rocker"/>', "link name 'rocker' already used"),
    ('<child link="coupler_end"/>', '<child link="rocker"/>', "already the child of joint"),
    (('    <limit lower="-3.141592653589793" upper="3.141592653589793" effort="0" '
      'velocity="20"/>\n'), "", "a revolute joint needs a <limit"),
    ('effort="5" velocity="20"/>', 'effort="5" velocity="20"/><dynamics D="1"/>',
     "<dynamics> needs damping or friction"),
    ('effort="5" velocity="20"/>', 'velocity="20"/>', "needs the attribute 'effort'"),
    ("<inertial><origin xyz=\"0.15", "<inertial><orgin xyz=\"0.15",
     "unknown element <orgin>"),
    ('<link name="rocker_end"/>', '<lnk name="rocker_end"/>', "unknown element <lnk>"),
    ('effort="0" velocity="20"/>\n  </joint>\n  <link name="rocker">',
     'effort="0" velocty="20"/>\n  </joint>\n  <link name="rocker">', "velocty='20'"),
    ('<robot name="four_bar">', '<robot name="four_bar"><oops', "malformed XML"),
])
def test_other_typos_are_refused_by_name(old, new, expected):
    assert FOUR_BAR.count(old) == 1
    error = _refused(FOUR_BAR.replace(old, new))
    assert expected in str(error)
    assert "line" in (error.culprit or "")


def test_extensions_of_real_urdfs_pass():
    """Elements and attributes outside the specification that real URDFs carry (ANYmal's
    limit and self_filter, Panda's dynamics, gazebo and namespaced attributes)."""
    text = FOUR_BAR.replace(
        '<joint name="crank" type="revolute">',
        '<joint name="crank" type="revolute" dont_collapse="true" xacro:foo="1">'
    ).replace('effort="5" velocity="20"/>', 'effort="5" velocity="20" gear_velocity="3" '
              'command_effort="2"/><dynamics damping="0" D="1" K="2" mu_viscous="0"/>'
    ).replace('<link name="coupler_end"/>', '<link name="coupler_end"><self_filter/>'
              '<contact><lateral_friction value="1"/></contact></link>'
    ).replace("</robot>", '<gazebo reference="crank_link"><mu1>0.2</mu1></gazebo>'
              '<transmission name="t"><type>x</type></transmission></robot>')
    build_model(text.replace("<robot name", '<robot xmlns:xacro="x" name'), source="ext")


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(name=st.sampled_from(sorted(TEXTS)), data=st.data(),
       new=st.text(alphabet=string.ascii_letters + "_", min_size=1, max_size=12))
def test_any_unknown_joint_type_is_refused_naming_the_joint(name, data, new):
    text = TEXTS[name]
    joint, line, start, end = data.draw(st.sampled_from(_joint_types(text)))
    if new in URDF_JOINT_TYPES:
        return
    error = _refused(text[:start] + new + text[end:])
    assert error.culprit == f"joint {joint} (line {line})"
    assert f"type={new!r}" in str(error)


def _typo(data, word, strict):
    """A misspelling: in a strict element any other name, elsewhere one letter dropped or
    doubled (what a hand makes)."""
    if strict and data.draw(st.booleans()):
        return data.draw(st.text(alphabet=string.ascii_lowercase + "_", min_size=1,
                                 max_size=10))
    k = data.draw(st.integers(0, len(word) - 1))
    return word[:k] + word[k + 1:] if data.draw(st.booleans()) and len(word) > 2 \
        else word[:k + 1] + word[k:]


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(name=st.sampled_from(sorted(TEXTS)), data=st.data())
def test_any_misspelt_attribute_is_refused_naming_element_attribute_and_line(name, data):
    text = TEXTS[name]
    tag, line, attribute, start, end = data.draw(st.sampled_from(_attributes(text)))
    new = _typo(data, attribute, tag in STRICT)
    if new in ATTRIBUTES[tag] or not new:
        return
    error = _refused(text[:start] + new + text[end:])
    assert error.culprit.endswith(f"(line {line})") and tag in error.culprit
    assert f"unknown attribute {new}=" in str(error)
