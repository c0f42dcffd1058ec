"""Robot descriptions: xacro -> URDF -> ``pin.Model``, and loop-closure files.

A closed-loop robot is described by two files side by side:

* a URDF (or xacro) of the robot as a kinematic **tree**, the loops cut open;
* a loops description (YAML) naming the closures that join the cut ends again
  and the actuated joints.

The loops format (see ``urdf/hexapod.loops.yaml``)::

    closures:
      - name: tip_0            # unique
        type: point            # point (3 rows, ball joint) or weld (6 rows)
        frame1: leg_0_tip      # a frame of the tree, or "world"
        frame2: platform_anchor_0
        offset1: {xyz: [0, 0, 0], rpy: [0, 0, 0]}   # optional anchor in frame1
        offset2: {xyz: [0, 0, 0], rpy: [0, 0, 0]}   # optional anchor in frame2
    actuated: [carriage_0, ...]  # joint names
    effects:                     # optional: joint and drive effects by joint name
      velocity_threshold: 1.0e-9 # optional (m/s, rad/s): Coulomb's "at rest"
      joints:
        carriage_0: {armature: 0.02, damping: 1.5, coulomb: 0.8, stiffness: 100.0,
                     spring_reference: 0.0, gear: 25, rotor_inertia: 1.0e-5,
                     effort_limit: 100}
    couplings:                   # optional: joint couplings q1 = c0 + c1 q2 + ... + c4 q2^4
      - name: gear               # unique
        joint1: follower         # a revolute or prismatic joint (the driven one)
        joint2: driver           # optional: without it, q1 = c0
        polycoef: [0, 2, 0, 0, 0]   # c0 .. c4 (up to five numbers; missing ones are 0)

(the ``couplings:`` section: :class:`~hexapod_pin.core.couplings.JointCoupling`, one
constraint row each after the closure rows, for the revolute and prismatic joints of any
tree, a URDF's too; the ``effects:`` section: :class:`EffectsSection`; a ``robot:``
section: :class:`RobotSection`). The same ``effects:`` format, alone in a YAML or TOML file, is a
standalone effects file (:func:`read_effects_file`, the command line's ``--effects``).
Nothing here is specific to the hexapod.
"""

from __future__ import annotations

import difflib
import functools
import hashlib
import importlib.metadata
import io
import math
import os
import re
import threading
import warnings
import xml.parsers.expat
from collections.abc import Iterator
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import yaml

from .checks import existing_file
from ..errors import ArgumentTypeError, DescriptionError, GeometryError, InputError
from .couplings import JointCoupling
from .effects import JointEffects, resolve_effects
from .text_formats import load_structured, load_yaml

WORLD = "world"
CLOSURE_TYPES = {"point": 3, "weld": 6}


@dataclass(frozen=True)
class ClosureSpec:
    """One loop closure of a loops description.

    Attributes:
        name: unique name.
        type: ``"point"`` (3-D point-on-point, 3 rows) or ``"weld"`` (6 rows).
        frame1: frame name in the tree, or ``"world"``.
        frame2: frame name in the tree, or ``"world"``.
        offset1: anchor placement in frame1 (``pin.SE3``).
        offset2: anchor placement in frame2 (``pin.SE3``).
    """

    name: str
    type: str
    frame1: str
    frame2: str
    offset1: pin.SE3
    offset2: pin.SE3

    @property
    def n_rows(self) -> int:
        """Number of scalar constraint rows (3 or 6)."""
        return CLOSURE_TYPES[self.type]


@dataclass(frozen=True)
class RobotSection:
    """The optional ``robot:`` section of a loops file: how
    :func:`hexapod_pin.load_robot` makes the model a parallel robot (each entry may be
    overridden by the call's arguments).

    Attributes:
        platform: the platform frame's name, or None.
        pose_axes: the pose components (a subset of ``x, y, z, roll, pitch, yaw`` in that
            order), or None (all six).
        home: the home configuration (nq,) as numbers, or None.
        max_actuator_force: a bound (N or N m), a list of one per actuator, or None (the
            effort limits of the description).
    """

    platform: str | None = None
    pose_axes: tuple[str, ...] | None = None
    home: tuple[float, ...] | None = None
    max_actuator_force: float | tuple[float, ...] | None = None


#: the keys of a joint's entry in the ``effects:`` section of a loops file (the fields of
#: :func:`~hexapod_pin.core.effects.resolve_effects`; the last three on actuated joints only)
EFFECT_KEYS = ("armature", "damping", "coulomb", "stiffness", "spring_reference", "gear",
               "rotor_inertia", "effort_limit")
#: one value of the ``effects:`` section: a number or a list of numbers
EffectValue = float | tuple[float, ...]


@dataclass(frozen=True)
class EffectsSection:
    """The optional ``effects:`` section of a loops file: joint and drive effects by joint
    name, which replace those the tree carries (a URDF's ``<dynamics damping friction>``,
    Pinocchio's ``armature``) when the
    :class:`~hexapod_pin.core.closed_loop.ClosedLoopModel` is built.

    The format (every key optional)::

        effects:
          velocity_threshold: 1.0e-9          # m/s or rad/s (write 1.0e-9: YAML reads 1e-9 as text)
          joints:
            <joint name>:
              armature: 0.02                  # kg or kg m^2, >= 0
              damping: 1.5                    # N s/m or N m s/rad, >= 0
              coulomb: 0.8                    # N or N m, >= 0
              stiffness: 100.0                # N/m or N m/rad, >= 0
              spring_reference: 0.0           # m or rad (see below)
              gear: 25                        # actuated joints: force per motor torque, != 0
              rotor_inertia: 1.0e-5           # actuated joints: adds gear^2 rotor_inertia
                                              # to the armature
              effort_limit: 100               # actuated joints: N or N m, > 0 (.inf: none)

    Per-coordinate values are a number (every velocity coordinate of the joint) or a
    list of ``nv_joint`` numbers. ``spring_reference`` is the joint's ``nq_joint``
    configuration values or, for a joint whose ``nq`` differs from its ``nv`` (a
    continuous joint, a ball, a free flyer), its ``nv_joint`` displacement from the
    neutral configuration (an angle, a rotation vector); joints not named keep the
    neutral configuration as reference. Units and equations:
    :mod:`hexapod_pin.core.effects`.

    Attributes:
        joints: ``(joint name, ((key, value), ...))`` in file order; keys from
            :data:`EFFECT_KEYS`, values numbers or tuples of numbers (as written).
        velocity_threshold: the Coulomb rest threshold (m/s or rad/s), or None (the
            default of :mod:`~hexapod_pin.core.effects`).
        source: the file it came from, for messages.
        lines: ``(culprit, line)``: the 1-based line of the section, of each joint
            (``effects.joints.<joint>``) and of each key (``...<joint>.<key>``) when
            parsed from text.
    """

    joints: tuple[tuple[str, tuple[tuple[str, EffectValue], ...]], ...] = ()
    velocity_threshold: float | None = None
    source: str = "<loops>"
    lines: tuple[tuple[str, int], ...] = ()

    def culprit(self, joint: str | None = None, key: str | None = None) -> str:
        """``effects[.joints.<joint>[.<key>]]``, with ``(line n)`` when known."""
        name = "effects" if joint is None else f"effects.joints.{joint}"
        name = name if key is None else f"{name}.{key}"
        line = dict(self.lines).get(name)
        return name if line is None else f"{name} (line {line})"

    def apply(self, model: pin.Model, actuated: tuple[str, ...],
              base: JointEffects) -> JointEffects:
        """``base`` with this section's effects, joint by joint, checked by
        :func:`~hexapod_pin.core.effects.resolve_effects`.

        Args:
            model: the tree (joint names and sizes).
            actuated: its actuated joints' names.
            base: the effects the tree carries.

        Raises:
            DescriptionError: an unknown joint, an actuator key on a joint that is not
                actuated, a wrong number of values, NaN / inf, a negative coefficient, a
                zero gear, a non-positive effort limit, a spring reference that is not a
                configuration; naming :attr:`source`, the joint, the key and the line.
        """
        effects = base
        for joint, entries in self.joints:
            values = {key: {joint: _spring_configuration(model, joint, value)
                            if key == "spring_reference" else value}
                      for key, value in entries}
            effects = self._resolve(model, actuated, effects, values, joint)
        if self.velocity_threshold is not None:
            effects = self._resolve(model, actuated, effects,
                                    {"velocity_threshold": self.velocity_threshold}, None)
        return effects

    def _resolve(self, model: pin.Model, actuated: tuple[str, ...], base: JointEffects,
                 values: dict[str, Any], joint: str | None) -> JointEffects:
        try:
            return resolve_effects(model, actuated, base, **values)
        except InputError as exc:
            key = exc.name.split("[")[0]
            where = f"joint {joint!r}, {key}" if joint is not None else key
            raise DescriptionError(self.source, f"{where}: {exc.reason}",
                                   self.culprit(joint, key if key in values else None)
                                   ) from None


def _spring_configuration(model: pin.Model, joint: str, value: EffectValue) -> Any:
    """A joint's spring reference as configuration values: ``nv_joint`` values of a joint
    whose ``nq`` differs from its ``nv`` are a displacement from the neutral configuration
    (anything else is passed on as written, for :func:`resolve_effects` to check)."""
    if not model.existJointName(joint) or model.getJointId(joint) == 0:
        return value
    jmodel = model.joints[model.getJointId(joint)]
    arr = np.atleast_1d(np.asarray(value, dtype=float))
    if jmodel.nq == jmodel.nv or arr.shape != (jmodel.nv,):
        return value
    dv = np.zeros(model.nv)
    dv[jmodel.idx_v:jmodel.idx_v + jmodel.nv] = arr
    q = pin.integrate(model, pin.neutral(model), dv)
    return q[jmodel.idx_q:jmodel.idx_q + jmodel.nq]


@dataclass(frozen=True)
class LoopsSpec:
    """A parsed loops description: closures, actuated joint names, the optional
    ``robot:`` section (:class:`RobotSection`) and the optional ``effects:`` section
    (:class:`EffectsSection`)."""

    closures: tuple[ClosureSpec, ...]
    actuated: tuple[str, ...]
    robot: RobotSection | None = None
    effects: EffectsSection | None = None
    couplings: tuple[JointCoupling, ...] = ()


def urdf_dir() -> Path:
    """Folder holding the packaged robot descriptions (``hexapod.urdf.xacro`` ...)."""
    packaged = resources.files("hexapod_pin") / "urdf"
    if packaged.is_dir():
        return Path(str(packaged))
    source_tree = Path(__file__).resolve().parents[2] / "urdf"
    if source_tree.is_dir():
        return source_tree
    raise DescriptionError("hexapod_pin", "cannot find the urdf/ folder of the package")


#: the rules of the xacro arguments of known description files: file name -> a check of
#: the arguments given (name -> text) raising :class:`DescriptionError` naming the argument
#: (a robot package registers its file's: :func:`register_xacro_rules`)
_XACRO_RULES: dict[str, Any] = {}


def register_xacro_rules(file_name: str, build: Any, fields: dict[str, str]) -> None:
    """Check the xacro arguments of the files named ``file_name`` by the rules of a
    geometry: the arguments named in ``fields`` (xacro argument -> keyword of ``build``)
    are read as numbers and ``build(**keywords)`` (a geometry class, whose own checks raise
    :class:`~hexapod_pin.errors.GeometryError`) is called with them before the file is
    expanded; an argument whose keyword ends in ``[k]`` is entry ``k`` of a tuple keyword
    (the other entries: the class's default). A bad value is a :class:`DescriptionError`
    naming the argument, as a wrong geometry would be a :class:`GeometryError`."""
    _XACRO_RULES[file_name] = (build, dict(fields))


def _check_xacro_args(path: Path, args: dict[str, str]) -> None:
    """Apply the rules registered for ``path``'s file name to ``args`` (none: nothing)."""
    rules = _XACRO_RULES.get(path.name)
    if rules is None or not args:
        return
    build, fields = rules
    keywords: dict[str, Any] = {}
    owner: dict[str, str] = {}
    for name, text in args.items():
        field = fields.get(name)
        if field is None:
            continue
        try:
            value = float(text)
        except ValueError:
            raise DescriptionError(str(path), f"xacro argument {name}={text!r} is not a "
                                              "number", name) from None
        if "[" in field:
            key, index = field[:-1].split("[")
            default = getattr(build(), key)
            current = list(keywords.get(key, default))
            current[int(index)] = value
            keywords[key] = tuple(current)
            owner[key] = name
            continue
        if field in keywords:          # another argument of the same keyword: alone
            _build_one(path, build, {field: value}, name)
            continue
        keywords[field], owner[field] = value, name
    _build_one(path, build, keywords, None, owner)


def _build_one(path: Path, build: Any, keywords: dict[str, Any], name: str | None,
               owner: dict[str, str] | None = None) -> None:
    """``build(**keywords)``, its :class:`GeometryError` as a :class:`DescriptionError`
    naming the xacro argument (``name``, or the owner of the offending keyword)."""
    try:
        build(**keywords)
    except GeometryError as exc:
        culprit = name or (owner or {}).get(exc.field, exc.field)
        raise DescriptionError(str(path), f"xacro argument {culprit}: {exc.reason} "
                                          f"(got {exc.value!r})", culprit) from None


def expand_xacro(path: str | Path, args: dict[str, str] | None = None) -> str:
    """Expand a xacro (or plain URDF) file to a URDF string, in Python.

    Args:
        path: the ``.xacro`` or ``.urdf`` file.
        args: xacro arguments, name -> value as text.

    Raises:
        MissingFileError: the file does not exist.
        DescriptionError: when the file is not text, does not expand, an argument is not
            one the file declares (``<xacro:arg name=...>``), or breaks the rules registered
            for the file (:func:`register_xacro_rules`: the hexapod's and planar robot's
            files by their geometries' rules, e.g. ``leg_length`` > 0).
    """
    path = Path(path)
    text = read_text(path)
    args = {str(k): str(v) for k, v in (args or {}).items()}
    declared = set(re.findall(r"<xacro:arg\s+name\s*=\s*[\"']([^\"']+)[\"']", text))
    unknown = sorted(set(args) - declared)
    if unknown:
        raise DescriptionError(str(path), f"unknown xacro argument(s) {unknown}; the file "
                                          f"declares {sorted(declared)}")
    _check_xacro_args(path, args)
    return _expand_cached(str(path.resolve()), path.stat().st_mtime_ns,
                          tuple(sorted(args.items())))


@functools.lru_cache(maxsize=64)
def _expand_cached(path: str, mtime: int, args: tuple) -> str:
    from xacrodoc import XacroDoc  # heavy import, only when expanding

    try:
        doc = XacroDoc.from_file(path, subargs=dict(args), walk_up=False)
        return doc.to_urdf_string()
    except Exception as exc:  # xacro raises many unrelated types
        raise DescriptionError(path, f"xacro expansion failed: {exc}") from exc


#: relative tolerance of the inertia checks (positive semi-definiteness, triangle inequality)
INERTIA_RTOL = 1e-9
#: largest coordinate accepted in a description (m): far beyond any robot, far below overflow
MAX_COORDINATE = 1e6


def validate_urdf(urdf_xml: str, source: str = "<urdf>") -> None:
    """Parse URDF text strictly (``yourdfpy``) and check its physics before Pinocchio loads it.

    First a strict pre-parse with line numbers (:func:`_check_urdf_elements`: unknown
    joint types, parent / child links that do not exist, misspelt or unknown attributes
    and elements, missing required attributes), so that a typo names its element,
    attribute and line instead of Pinocchio's "does not contain a valid URDF model" (whose
    cause goes to C++ stderr). Pinocchio's parser only warns about (and then drops) a
    malformed inertial, and accepts non-physical values; this check refuses them. Every
    link's inertial: mass finite and
    ``>= 0`` (a zero mass only with a zero inertia: a massless link); inertia tensor
    finite, symmetric positive semi-definite and satisfying the triangle inequality of
    its principal moments (``I1 + I2 >= I3``), to ``INERTIA_RTOL`` relative to its
    largest moment. Every joint: a finite origin within ``MAX_COORDINATE``; a finite,
    non-zero axis for revolute, continuous and prismatic joints; finite limits with
    ``lower <= upper``; ``<dynamics damping friction>`` finite and ``>= 0``.

    The last text that passed under each ``source`` name is remembered on disk (its
    SHA-256 with the validator's), so loading an unchanged description again skips the
    parse (:class:`_ValidationMemo`; ``HEXAPOD_PIN_NO_MEMO=1`` turns that off).

    Raises:
        DescriptionError: naming the source, the element at fault and the problem.
    """
    if not isinstance(urdf_xml, str):
        raise DescriptionError(source, f"URDF must be text, got {type(urdf_xml).__name__}")
    memo = _ValidationMemo(urdf_xml, source)
    if memo.known():
        return
    _validate_urdf(urdf_xml, source)
    memo.remember()


class _ValidationMemo:
    """Remembers, on disk, the last URDF text that passed :func:`validate_urdf` under each
    ``source`` name, so that loading the same description again (every ``Hexapod()``,
    every command-line call) skips the strict parse and its 0.4-0.6 s import of
    ``yourdfpy`` / ``trimesh``. The key is the SHA-256 of the text, this module's own
    source (a changed validator validates again) and the ``yourdfpy`` version; one small
    file per source name, next to numba's kernel cache (``__pycache__`` of this package,
    else the user cache directory). Anything that fails (a read-only disk) only means
    validating again; text that fails validation is never remembered."""

    def __init__(self, urdf_xml: str, source: str) -> None:
        digest = hashlib.sha256(_validator_stamp().encode())
        digest.update(urdf_xml.encode("utf-8", "surrogatepass"))
        self.digest = digest.hexdigest()
        name = hashlib.sha256(source.encode("utf-8", "surrogatepass")).hexdigest()[:32]
        self.paths = [folder / name for folder in _memo_folders()]

    def known(self) -> bool:
        for path in self.paths:
            try:
                if path.read_text(encoding="ascii") == self.digest:
                    return True
            except (OSError, ValueError):
                continue
        return False

    def remember(self) -> None:
        for path in self.paths:
            try:
                path.parent.mkdir(parents=True, exist_ok=True)
                tmp = path.with_suffix(f".{os.getpid()}.{threading.get_ident()}.tmp")
                tmp.write_text(self.digest, encoding="ascii")
                os.replace(tmp, path)
                return
            except OSError:
                continue


def _memo_folders() -> list[Path]:
    """Where :class:`_ValidationMemo` keeps its files (``HEXAPOD_PIN_NO_MEMO=1``: none)."""
    if os.environ.get("HEXAPOD_PIN_NO_MEMO"):
        return []
    user = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return [Path(__file__).resolve().parent / "__pycache__" / "validated_urdf",
            user / "hexapod_pin" / "validated_urdf"]


@functools.lru_cache(maxsize=1)
def _validator_stamp() -> str:
    try:
        version = importlib.metadata.version("yourdfpy")
    except importlib.metadata.PackageNotFoundError:
        version = "?"
    return hashlib.sha256(Path(__file__).read_bytes()).hexdigest() + version


def _validate_urdf(urdf_xml: str, source: str) -> None:
    """:func:`validate_urdf` without its memo."""
    _check_urdf_elements(urdf_xml, source)
    try:
        # non-finite numbers are reported below; the parser's own arithmetic on them
        # (trimesh's transforms) must not warn
        import yourdfpy  # here, not at import: it loads trimesh and networkx (0.6 s)

        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore", RuntimeWarning)
            robot = yourdfpy.URDF.load(io.StringIO(urdf_xml), build_scene_graph=False,
                                       build_collision_scene_graph=False, load_meshes=False,
                                       load_collision_meshes=False).robot
    except Exception as exc:  # yourdfpy / lxml raise ValueError, KeyError, XMLSyntaxError...
        raise DescriptionError(source, f"malformed URDF: {exc}") from exc
    for link in robot.links:
        if link.inertial is not None:
            _check_inertial(link.inertial, source, f"link {link.name}")
    for joint in robot.joints:
        _check_joint(joint, source)
        _check_dynamics(joint, urdf_xml, source)


#: the URDF elements read here: attributes (a trailing ``*``: required) and children. An
#: element of another namespace (``xacro:``, ``gazebo:``) and its content are not checked;
#: neither is an unknown attribute or child of an element outside :data:`_URDF_STRICT`
#: unless it is a near miss of a known name (a misspelling: ``limit effrot``), for real
#: URDFs carry extensions (``<link><self_filter>``, ``<dynamics D K>``, ``<gazebo>``).
_URDF_ELEMENTS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "robot": (("name*", "version"), ("link", "joint", "material")),
    "link": (("name*",), ("inertial", "visual", "collision")),
    "inertial": ((), ("origin", "mass", "inertia")),
    "origin": (("xyz", "rpy"), ()),
    "mass": (("value*",), ()),
    "inertia": (("ixx*", "ixy*", "ixz*", "iyy*", "iyz*", "izz*"), ()),
    "visual": (("name",), ("origin", "geometry", "material")),
    "collision": (("name",), ("origin", "geometry")),
    "geometry": ((), ("box", "cylinder", "sphere", "mesh", "capsule")),
    "box": (("size*",), ()),
    "cylinder": (("radius*", "length*"), ()),
    "capsule": (("radius*", "length*"), ()),
    "sphere": (("radius*",), ()),
    "mesh": (("filename*", "scale"), ()),
    "material": (("name",), ("color", "texture")),
    "color": (("rgba*",), ()),
    "texture": (("filename",), ()),
    "joint": (("name*", "type*"), ("origin", "parent", "child", "axis", "calibration",
                                   "dynamics", "limit", "mimic", "safety_controller")),
    "parent": (("link*",), ()),
    "child": (("link*",), ()),
    "axis": (("xyz",), ()),
    "calibration": (("rising", "falling", "reference_position"), ()),
    "dynamics": (("damping", "friction"), ()),
    "limit": (("lower", "upper", "effort*", "velocity*"), ()),
    "mimic": (("joint*", "multiplier", "offset"), ()),
    "safety_controller": (("soft_lower_limit", "soft_upper_limit", "k_position",
                           "k_velocity"), ()),
}
#: the elements of the inertial parameters and the kinematic tree: every unknown attribute
#: or child refused
_URDF_STRICT = frozenset({"inertial", "origin", "mass", "inertia", "axis", "parent", "child"})
#: how close an unknown name must be to a known one to count as its misspelling
#: (``difflib`` ratio, lengths within 2: one letter dropped or doubled in a name of 3
#: letters or more; not ``gear_velocity`` for ``velocity``)
_NEAR_MISS = 0.75
#: the joint types of the URDF specification
URDF_JOINT_TYPES = ("revolute", "continuous", "prismatic", "fixed", "floating", "planar")


class _UrdfElement:
    """One element of a URDF as the strict pre-parse sees it: tag, attributes, line,
    children."""

    def __init__(self, tag: str, attributes: dict[str, str], line: int,
                 parent: _UrdfElement | None = None) -> None:
        self.tag, self.attributes, self.line = tag, attributes, line
        self.children: list[_UrdfElement] = []
        name = attributes.get("name")
        here = tag if name is None else f"{tag} {name}"
        #: the element and its ancestors below <robot>: ``link rocker/inertial/inertia``
        self.path: str = here if parent is None or parent.tag in ("", "robot") \
            else f"{parent.path}/{here}"

    def culprit(self) -> str:
        """``<path> (line n)``, e.g. ``joint rocker (line 84)`` or
        ``link rocker/inertial/inertia (line 95)``."""
        return f"{self.path} (line {self.line})"


def _urdf_tree(urdf_xml: str, source: str) -> _UrdfElement:
    """The element tree of URDF text, with line numbers (standard library ``expat``).

    Raises:
        DescriptionError: not well-formed XML (the line and column of the fault).
    """
    parser = xml.parsers.expat.ParserCreate()
    stack: list[_UrdfElement] = [_UrdfElement("", {}, 0)]

    def start(tag: str, attributes: dict[str, str]) -> None:
        element = _UrdfElement(tag, attributes, parser.CurrentLineNumber, stack[-1])
        stack[-1].children.append(element)
        stack.append(element)

    parser.StartElementHandler = start
    parser.EndElementHandler = lambda tag: stack.pop()
    try:
        parser.Parse(urdf_xml, True)
    except xml.parsers.expat.ExpatError as exc:
        raise DescriptionError(source, f"malformed XML: {exc}",
                               f"line {exc.lineno}, column {exc.offset}") from None
    roots = stack[0].children
    if len(roots) != 1 or roots[0].tag != "robot":
        raise DescriptionError(source, "a URDF holds one <robot> element, got "
                                       f"{[r.tag for r in roots]}")
    return roots[0]


def suggest(word: str, known: Any, cutoff: float = 0.6) -> str:
    """`` (did you mean 'x'?)`` for the closest of ``known`` (``difflib`` ratio at least
    ``cutoff``), or ""."""
    close = difflib.get_close_matches(word, list(known), n=1, cutoff=cutoff)
    if cutoff >= _NEAR_MISS:               # a misspelling, not a longer extension name
        close = [c for c in close if abs(len(c) - len(word)) <= 2]
    return f" (did you mean {close[0]!r}?)" if close else ""


def _check_element(element: _UrdfElement, source: str) -> None:
    """Attributes and children of one element of :data:`_URDF_ELEMENTS`, recursively."""
    declared, children = _URDF_ELEMENTS[element.tag]
    allowed = {a.rstrip("*") for a in declared}
    strict = element.tag in _URDF_STRICT
    for attribute, value in element.attributes.items():
        if ":" in attribute or attribute in allowed or not (
                strict or suggest(attribute, allowed, _NEAR_MISS)):
            continue
        raise DescriptionError(source, f"unknown attribute {attribute}={value!r} of "
                                       f"<{element.tag}>{suggest(attribute, allowed)}; "
                                       f"expected {sorted(allowed) or 'none'}",
                               element.culprit())
    for attribute in declared:
        if attribute.endswith("*") and attribute[:-1] not in element.attributes:
            raise DescriptionError(source, f"<{element.tag}> needs the attribute "
                                           f"{attribute[:-1]!r}", element.culprit())
    for child in element.children:
        if ":" in child.tag:
            continue
        if child.tag in children:
            _check_element(child, source)
        elif strict or suggest(child.tag, children, _NEAR_MISS):
            raise DescriptionError(source, f"unknown element <{child.tag}> in <{element.tag}>"
                                           f"{suggest(child.tag, children)}; expected one of "
                                           f"{list(children) or 'none'}", child.culprit())


def _check_urdf_elements(urdf_xml: str, source: str) -> None:
    """The strict pre-parse of :func:`validate_urdf`: well-formed XML; every element this
    library reads with known attributes only and its required ones; joint types of the
    URDF specification, a ``<limit>`` on revolute and prismatic joints, damping or friction
    in a ``<dynamics>``; link and joint names unique; each joint's parent and child links defined,
    a link the child of one joint at most. Line numbers are those of ``urdf_xml`` (of the
    expanded text for a xacro).

    Raises:
        DescriptionError: naming the element (``joint rocker (line 84)``), the attribute
            and its value.
    """
    robot = _urdf_tree(urdf_xml, source)
    _check_element(robot, source)
    links: dict[str, _UrdfElement] = {}
    for link in (e for e in robot.children if e.tag == "link"):
        name = link.attributes["name"]
        if name in links:
            raise DescriptionError(source, f"link name {name!r} already used at line "
                                           f"{links[name].line}", link.culprit())
        links[name] = link
    parents: dict[str, _UrdfElement] = {}
    joints: dict[str, _UrdfElement] = {}
    for joint in (e for e in robot.children if e.tag == "joint"):
        name, kind = joint.attributes["name"], joint.attributes["type"]
        if name in joints:
            raise DescriptionError(source, f"joint name {name!r} already used at line "
                                           f"{joints[name].line}", joint.culprit())
        joints[name] = joint
        if kind not in URDF_JOINT_TYPES:
            raise DescriptionError(source, f"attribute type={kind!r} is not a URDF joint type"
                                           f"{suggest(kind, URDF_JOINT_TYPES)}; expected one "
                                           f"of {list(URDF_JOINT_TYPES)}", joint.culprit())
        for role in ("parent", "child"):
            found = [e for e in joint.children if e.tag == role]
            if len(found) != 1:
                raise DescriptionError(source, f"a joint needs exactly one <{role} link=...>, "
                                               f"got {len(found)}", joint.culprit())
            link = found[0].attributes["link"]
            if link not in links:
                raise DescriptionError(source, f"<{role} link={link!r}> names no link of the "
                                               f"URDF{suggest(link, links)}", joint.culprit())
            if role == "child" and link in parents:
                raise DescriptionError(source, f"link {link!r} is already the child of "
                                               f"{parents[link].culprit()}", joint.culprit())
            if role == "child":
                parents[link] = joint
        tags = [e.tag for e in joint.children]
        if kind in ("revolute", "prismatic") and "limit" not in tags:
            raise DescriptionError(source, f"a {kind} joint needs a <limit effort velocity>",
                                   joint.culprit())
        for dynamics in (e for e in joint.children if e.tag == "dynamics"):
            if not {"damping", "friction"} & set(dynamics.attributes):
                raise DescriptionError(source, "<dynamics> needs damping or friction",
                                       dynamics.culprit())


def _check_inertial(inertial, source: str, where: str) -> None:
    mass = float(inertial.mass) if inertial.mass is not None else 0.0
    inertia = np.zeros((3, 3)) if inertial.inertia is None else np.asarray(inertial.inertia,
                                                                             dtype=float)
    origin = np.eye(4) if inertial.origin is None else np.asarray(inertial.origin, dtype=float)
    if not np.isfinite(origin).all() or np.abs(origin[:3, 3]).max() > MAX_COORDINATE:
        raise DescriptionError(source, f"inertial origin must be finite and within "
                                       f"{MAX_COORDINATE:g} m", where)
    check_inertia(mass, inertia, source, where)


def check_inertia(mass: float, inertia: np.ndarray, source: str, where: str) -> None:
    """Check one body's inertial parameters (every description format uses this check).

    Args:
        mass: kg; finite and ``>= 0``; zero only with a zero inertia (a massless body).
        inertia: 3x3 rotational inertia about the centre of mass (kg m^2): finite,
            symmetric, positive semi-definite, its principal moments satisfying the
            triangle inequality ``I1 + I2 >= I3``, all to ``INERTIA_RTOL`` relative to its
            largest entry.
        source: the description, for the error message.
        where: the element, for the error message.

    Raises:
        DescriptionError: naming the source, the element and the violated condition.
    """
    mass = float(mass)
    inertia = np.asarray(inertia, dtype=float)
    if not np.isfinite(mass) or mass < 0.0:
        raise DescriptionError(source, f"mass must be finite and >= 0, got {mass!r}", where)
    if inertia.shape != (3, 3) or not np.isfinite(inertia).all():
        raise DescriptionError(source, "inertia must be a finite 3x3 tensor", where)
    scale = float(np.abs(inertia).max())
    if mass == 0.0 and scale > 0.0:
        raise DescriptionError(source, "zero mass with a non-zero inertia", where)
    if scale == 0.0:
        return
    tol = INERTIA_RTOL * scale
    if np.abs(inertia - inertia.T).max() > tol:
        raise DescriptionError(source, "inertia tensor is not symmetric", where)
    moments = np.linalg.eigvalsh(0.5 * (inertia + inertia.T))
    if moments[0] < -tol:
        raise DescriptionError(source, "inertia tensor is not positive semi-definite "
                                       f"(principal moments {moments.tolist()})", where)
    if moments[0] + moments[1] < moments[2] - tol:
        raise DescriptionError(source, "principal moments violate the triangle inequality "
                                       f"I1 + I2 >= I3 ({moments.tolist()})", where)


def _check_joint(joint, source: str) -> None:
    where = f"joint {joint.name}"
    origin = np.eye(4) if joint.origin is None else np.asarray(joint.origin, dtype=float)
    if not np.isfinite(origin).all():
        raise DescriptionError(source, "joint origin must be finite", where)
    if np.abs(origin[:3, 3]).max() > MAX_COORDINATE:
        raise DescriptionError(source, f"joint origin beyond {MAX_COORDINATE:g} m", where)
    if joint.type in ("revolute", "continuous", "prismatic"):
        axis = np.asarray(joint.axis if joint.axis is not None else (1.0, 0.0, 0.0),
                          dtype=float)
        if not np.isfinite(axis).all() or np.linalg.norm(axis) == 0.0:
            raise DescriptionError(source, f"joint axis must be finite and non-zero, got "
                                           f"{axis.tolist()}", where)
    limit = joint.limit
    if limit is not None and joint.type in ("revolute", "prismatic"):
        low, high = limit.lower, limit.upper
        if low is not None and high is not None:
            if not (np.isfinite(low) and np.isfinite(high)) or low > high:
                raise DescriptionError(source, f"joint limits must be finite with lower <= "
                                               f"upper, got [{low}, {high}]", where)


def _check_dynamics(joint: Any, urdf_xml: str, source: str) -> None:
    """A joint's ``<dynamics damping friction>``: finite numbers ``>= 0`` (they become the
    joint's viscous damping and Coulomb friction, :mod:`~hexapod_pin.core.effects`)."""
    dynamics = joint.dynamics
    if dynamics is None:
        return
    for attribute in ("damping", "friction"):
        raw = getattr(dynamics, attribute, None)
        if raw is None:
            continue
        try:
            value = float(raw)
        except (TypeError, ValueError):
            value = math.nan
        if not (math.isfinite(value) and value >= 0.0):
            raise DescriptionError(source, f"<dynamics {attribute}> must be a finite number "
                                           f">= 0, got {raw!r}",
                                   _joint_culprit(joint.name, urdf_xml))


def _joint_culprit(name: str, urdf_xml: str) -> str:
    """``joint <name>``, with ``(line n)`` of its ``<joint>`` element when found."""
    match = re.search(r"<joint\s[^>]*name\s*=\s*[\"']" + re.escape(name) + r"[\"']", urdf_xml)
    if match is None:
        return f"joint {name}"
    line = urdf_xml.count("\n", 0, match.start()) + 1
    return f"joint {name} (line {line})"


def build_model(urdf_xml: str, source: str = "<urdf>", root_joint=None) -> pin.Model:
    """Build the Pinocchio tree model from URDF text, validated first (:func:`validate_urdf`).

    Args:
        urdf_xml: the URDF text.
        source: the file or description it came from (for error messages).
        root_joint: a Pinocchio root joint (e.g. ``pin.JointModelFreeFlyer()``); None: the
            URDF's root link is fixed to the world.

    Raises:
        DescriptionError: the URDF is malformed or non-physical (:func:`validate_urdf`),
            Pinocchio cannot parse it, or the model fails Pinocchio's consistency check.
    """
    validate_urdf(urdf_xml, source)
    try:
        model = (pin.buildModelFromXML(urdf_xml) if root_joint is None
                 else pin.buildModelFromXML(urdf_xml, root_joint))
    except Exception as exc:
        raise DescriptionError(source, f"Pinocchio could not parse the URDF: {exc}") from exc
    if not model.check(model.createData()):
        raise DescriptionError(source, "model fails Pinocchio's consistency check "
                                       "(joints must be in depth-first order)")
    return model


def _placement(entry, source: str, culprit: str) -> pin.SE3:
    if entry is None:
        return pin.SE3.Identity()
    if not isinstance(entry, dict) or not set(entry) <= {"xyz", "rpy"}:
        raise DescriptionError(source, "an offset must be a mapping with keys xyz and rpy",
                               culprit)
    try:
        xyz = np.array(entry.get("xyz", [0.0, 0.0, 0.0]), dtype=float)
        rpy = np.array(entry.get("rpy", [0.0, 0.0, 0.0]), dtype=float)
    except (TypeError, ValueError) as exc:
        raise DescriptionError(source, f"offset is not numeric: {exc}", culprit) from None
    if xyz.shape != (3,) or rpy.shape != (3,) or not (np.all(np.isfinite(xyz))
                                                      and np.all(np.isfinite(rpy))):
        raise DescriptionError(source, "offset xyz and rpy must be 3 finite numbers each",
                               culprit)
    if np.abs(xyz).max() > MAX_COORDINATE:
        raise DescriptionError(source, f"offset xyz beyond {MAX_COORDINATE:g} m: "
                                       f"{xyz.tolist()}", culprit)
    return pin.SE3(pin.rpy.rpyToMatrix(*rpy), xyz)


def parse_loops(text: str, source: str = "<loops>") -> LoopsSpec:
    """Parse a loops description (YAML text) into a :class:`LoopsSpec`.

    Only the syntax is checked here; names are checked against the tree by
    :class:`hexapod_pin.core.closed_loop.ClosedLoopModel`.

    Raises:
        DescriptionError: malformed YAML, missing keys, unknown closure type,
            duplicate names, or a closure joining a frame to itself.
    """
    if not isinstance(text, str):
        raise ArgumentTypeError("text", text, "expected the YAML text (str), got "
                                f"{type(text).__name__}")
    data = load_yaml(text, source)
    if not isinstance(data, dict):
        raise DescriptionError(source, "the loops description must be a YAML mapping")
    unknown = set(data) - {"closures", "actuated", "robot", "effects", "couplings"}
    if unknown:
        raise DescriptionError(source, f"unknown keys {sorted(unknown)}", sorted(unknown)[0])
    raw_closures = data.get("closures", [])
    actuated = data.get("actuated", [])
    if not isinstance(raw_closures, list):
        raise DescriptionError(source, "'closures' must be a list", "closures")
    if not isinstance(actuated, list) or not all(isinstance(a, str) for a in actuated):
        raise DescriptionError(source, "'actuated' must be a list of joint names", "actuated")
    if len(set(actuated)) != len(actuated):
        raise DescriptionError(source, "duplicate actuated joint", "actuated")
    closures = []
    for entry in _list_entries(raw_closures, "closures", "closure", source,
                               ("name", "type", "frame1", "frame2"), ("offset1", "offset2")):
        name = str(entry["name"])
        ctype = str(entry["type"])
        if ctype not in CLOSURE_TYPES:
            raise DescriptionError(source, f"closure type {ctype!r} is not one of "
                                           f"{sorted(CLOSURE_TYPES)}", name)
        frame1, frame2 = str(entry["frame1"]), str(entry["frame2"])
        if frame1 == frame2:
            raise DescriptionError(source, f"closure joins frame {frame1!r} to itself", name)
        closures.append(ClosureSpec(name, ctype, frame1, frame2,
                                    _placement(entry.get("offset1"), source, name),
                                    _placement(entry.get("offset2"), source, name)))
    names = [c.name for c in closures]
    duplicated = sorted({n for n in names if names.count(n) > 1})
    if duplicated:
        raise DescriptionError(source, "duplicate closure names", duplicated[0])
    effects = None if data.get("effects") is None else \
        _effects_section(data["effects"], _effect_lines(text, source), source)
    return LoopsSpec(tuple(closures), tuple(actuated), _robot_section(data.get("robot"), source),
                     effects, _couplings(data.get("couplings"), source))


def _list_entries(raw: Any, section: str, what: str, source: str,
                  required: tuple[str, ...], optional: tuple[str, ...]) -> Iterator[dict]:
    """The mappings of a list section of the loops file (``closures:``, ``couplings:``),
    each checked as it is reached (so the first bad entry is the one reported): a mapping
    (else "a <what> must be a mapping"), with the ``required`` keys and no key beyond them
    and the ``optional`` ones (missing keys reported first).

    Raises:
        DescriptionError: naming ``<section>[index]``.
    """
    if not isinstance(raw, list):
        raise DescriptionError(source, f"'{section}' must be a list", section)
    for index, entry in enumerate(raw):
        label = f"{section}[{index}]"
        if not isinstance(entry, dict):
            raise DescriptionError(source, f"a {what} must be a mapping", label)
        missing = set(required) - set(entry)
        if missing:
            raise DescriptionError(source, f"missing keys {sorted(missing)}", label)
        extra = set(entry) - set(required) - set(optional)
        if extra:
            raise DescriptionError(source, f"unknown keys {sorted(extra)}", label)
        yield entry


def _couplings(raw: Any, source: str) -> tuple[JointCoupling, ...]:
    """The ``couplings:`` section (a list of mappings name, joint1, joint2, polycoef)."""
    if raw is None:
        return ()
    out = []
    for index, entry in enumerate(_list_entries(raw, "couplings", "coupling", source,
                                                ("name", "joint1", "polycoef"), ("joint2",))):
        label = f"couplings[{index}]"
        coef = entry["polycoef"]
        if not isinstance(coef, list) or not all(
                isinstance(c, (int, float)) and not isinstance(c, bool) for c in coef):
            raise DescriptionError(source, "'polycoef' must be a list of up to five numbers",
                                   label)
        joint2 = entry.get("joint2")
        out.append(JointCoupling(str(entry["name"]), str(entry["joint1"]),
                                 None if joint2 is None else str(joint2), tuple(coef)))
    names = [c.name for c in out]
    if len(set(names)) != len(names):
        raise DescriptionError(source, "duplicate coupling names", "couplings")
    return tuple(out)


def _effect_lines(text: str, source: str, nested: bool = True) -> dict[str, int]:
    """The 1-based line of the ``effects:`` section, its keys, joints and their keys (see
    :meth:`EffectsSection.culprit`; a key written twice was refused by
    :func:`~hexapod_pin.core.text_formats.load_yaml`). ``nested``: the section is the
    top-level ``effects`` key (a loops file), else the whole document (a standalone
    effects file)."""
    lines: dict[str, int] = {}

    def walk(node: Any, prefix: str, depth: int) -> None:
        if not isinstance(node, yaml.MappingNode):
            return
        for key_node, value_node in node.value:
            name, line = f"{prefix}.{key_node.value}", key_node.start_mark.line + 1
            lines[name] = line
            if depth < 3:                             # effects.joints.<joint>.<key>
                walk(value_node, name, depth + 1)

    root = yaml.compose(text)
    if not nested:
        walk(root, "effects", 1)
        return lines
    for key_node, value_node in root.value if isinstance(root, yaml.MappingNode) else ():
        if key_node.value == "effects":
            lines["effects"] = key_node.start_mark.line + 1
            walk(value_node, "effects", 1)
    return lines


def _is_number(value: object) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _effect_value(value: object, source: str, culprit: str) -> EffectValue:
    """A number or a non-empty list of numbers (DescriptionError otherwise)."""
    if _is_number(value):
        return float(value)  # type: ignore[arg-type]
    if isinstance(value, list) and value and all(_is_number(x) for x in value):
        return tuple(float(x) for x in value)
    hint = ""
    if isinstance(value, str):
        try:
            float(value)
            hint = " (YAML reads a number like 1e-9 as text: write 1.0e-9)"
        except ValueError:
            pass
    raise DescriptionError(source, f"expected a number or a list of numbers, got {value!r}"
                                   f"{hint}", culprit)


def _effects_section(raw: object, lines: dict[str, int], source: str) -> EffectsSection:
    """Check the ``effects:`` mapping of a loops file (types only; joint names, sizes and
    ranges are checked against the tree by :meth:`EffectsSection.apply`)."""
    section = EffectsSection(source=source, lines=tuple(lines.items()))
    if not isinstance(raw, dict):
        raise DescriptionError(source, "'effects' must be a mapping (keys joints, "
                                       "velocity_threshold)", section.culprit())
    unknown = sorted(set(map(str, raw)) - {"joints", "velocity_threshold"})
    if unknown:
        raise DescriptionError(source, f"unknown key {unknown[0]!r} in 'effects' (expected "
                                       "joints, velocity_threshold)",
                               section.culprit(key=unknown[0]))
    threshold = raw.get("velocity_threshold")
    if threshold is not None:
        threshold = _effect_value(threshold, source, section.culprit(key="velocity_threshold"))
        if isinstance(threshold, tuple):
            raise DescriptionError(source, "expected one number",
                                   section.culprit(key="velocity_threshold"))
    joints = raw.get("joints") or {}
    if not isinstance(joints, dict):
        raise DescriptionError(source, "'effects.joints' must be a mapping {joint name: "
                                       "{key: value}}", section.culprit(key="joints"))
    out = []
    for joint, entry in joints.items():
        if not isinstance(joint, str):
            raise DescriptionError(source, f"a joint name must be text, got {joint!r}",
                                   section.culprit(key="joints"))
        if not isinstance(entry, dict) or not entry:
            raise DescriptionError(source, f"the effects of joint {joint!r} must be a "
                                           f"mapping of {list(EFFECT_KEYS)}",
                                   section.culprit(joint))
        for key in entry:
            if key not in EFFECT_KEYS:
                raise DescriptionError(source, f"unknown key {key!r} (expected one of "
                                               f"{list(EFFECT_KEYS)})",
                                       section.culprit(joint, str(key)))
        out.append((joint, tuple((key, _effect_value(value, source, section.culprit(joint, key)))
                                 for key, value in entry.items())))
    return EffectsSection(tuple(out), threshold, source, section.lines)


#: the suffixes of a standalone effects file and their format (:func:`read_effects_file`)
EFFECTS_SUFFIXES = {".yaml": "yaml", ".yml": "yaml", ".toml": "toml"}


def parse_effects(text: str, source: str = "<effects>", *, kind: str = "yaml"
                  ) -> EffectsSection:
    """Parse a standalone effects file: the format of a loops file's ``effects:`` section
    (:class:`EffectsSection`: keys ``joints`` and ``velocity_threshold``), at the top
    level or under one ``effects`` key, written in YAML or TOML, e.g.::

        # drives.toml                          # drives.yaml
        velocity_threshold = 1e-6              velocity_threshold: 1.0e-6
        [joints.crank]                         joints:
        damping = 0.5                            crank: {damping: 0.5, gear: 20}
        gear = 20

    Only the syntax is checked here; :meth:`EffectsSection.apply` checks the joint names,
    sizes and ranges against a tree. Messages name ``source``, the key
    (``effects.joints.<joint>.<key>``, the prefix ``effects`` also for a file without
    that key) and its line.

    Args:
        text: the file's text.
        source: the file it came from, for messages.
        kind: ``"yaml"`` or ``"toml"``.

    Raises:
        DescriptionError: malformed YAML / TOML, a document that is not a mapping or is
            empty, a key beside ``effects``, an unknown key, a value that is not a number
            or a list of numbers (e.g. YAML's ``1e-9``, which it reads as text), a key
            written twice.
    """
    if kind not in ("yaml", "toml"):
        raise DescriptionError(source, f"unknown effects format {kind!r} (yaml or toml)")
    data: Any = load_structured(text, source, kind)
    if not isinstance(data, dict) or not data:
        raise DescriptionError(source, "an effects file must be a mapping with the keys "
                                       "joints and velocity_threshold (or one effects: "
                                       "section holding them)")
    nested = "effects" in data
    if nested and len(data) > 1:
        other = next(str(key) for key in data if key != "effects")
        raise DescriptionError(source, f"unknown key {other!r} beside 'effects' (an effects "
                                       "file holds joints and velocity_threshold, at the top "
                                       "level or under effects)", other)
    lines = _toml_lines(text, nested) if kind == "toml" else _effect_lines(text, source,
                                                                           nested)
    return _effects_section(data["effects"] if nested else data, lines, source)


def read_effects_file(path: str | Path) -> EffectsSection:
    """Read a standalone effects file (:func:`parse_effects`), YAML (``.yaml``, ``.yml``)
    or TOML (``.toml``) by its suffix. Apply it to a robot with
    ``robot.with_effects(section.apply(robot.model.tree_model,
    robot.model.actuated_joints, robot.effects))``.

    Raises:
        MissingFileError: the file does not exist.
        DescriptionError: another suffix, an unreadable file, or a malformed
            one (:func:`parse_effects`).
    """
    path = Path(path)
    kind = EFFECTS_SUFFIXES.get(path.suffix.lower())
    if kind is None:
        raise DescriptionError(str(path), f"an effects file ends in "
                                          f"{', '.join(EFFECTS_SUFFIXES)} (YAML or TOML)")
    return parse_effects(read_text(path), str(path), kind=kind)


#: a TOML key (bare, or quoted), and a dotted one
_TOML_PART = r"(?:[A-Za-z0-9_-]+|\"[^\"]*\"|'[^']*')"
_TOML_DOTTED = rf"{_TOML_PART}(?:\s*\.\s*{_TOML_PART})*"
_TOML_HEADER = re.compile(rf"^\s*\[\s*({_TOML_DOTTED})\s*\]\s*(?:#.*)?$")
_TOML_ASSIGN = re.compile(rf"^\s*({_TOML_DOTTED})\s*=(.*)$")
_TOML_INLINE = re.compile(rf"[{{,]\s*({_TOML_DOTTED})\s*=")


def _toml_key(text: str) -> list[str]:
    """The parts of a TOML (dotted, maybe quoted) key."""
    return [next(g for g in m.groups() if g is not None)
            for m in re.finditer(r"\"([^\"]*)\"|'([^']*)'|([A-Za-z0-9_-]+)", text)]


def _toml_lines(text: str, nested: bool) -> dict[str, int]:
    """The 1-based line of each table, key and inline-table key of an effects file in TOML
    (as :func:`_effect_lines` for YAML; tomllib has refused keys written twice already).
    A line scan of headers ``[a.b]`` and assignments ``a.b = ...`` (``{k = ...}`` inline
    tables on one line), enough for the flat files of this format."""
    lines: dict[str, int] = {}

    def record(path: list[str], number: int) -> None:
        path = path if nested else ["effects", *path]
        for end in range(1 if nested else 2, len(path) + 1):
            if path[0] == "effects":
                lines.setdefault(".".join(path[:end]), number)

    table: list[str] = []
    for number, line in enumerate(text.splitlines(), 1):
        header = _TOML_HEADER.match(line)
        if header is not None:
            table = _toml_key(header.group(1))
            record(table, number)
            continue
        assign = _TOML_ASSIGN.match(line)
        if assign is None:
            continue
        path = table + _toml_key(assign.group(1))
        record(path, number)
        value = assign.group(2).strip()
        if value.startswith("{"):
            for inner in _TOML_INLINE.finditer(value):
                record(path + _toml_key(inner.group(1)), number)
    return lines


def _numbers(value: object, source: str, key: str) -> tuple[float, ...]:
    """A list of real numbers, as floats (DescriptionError otherwise)."""
    if not isinstance(value, list) or not value or not all(
            isinstance(x, (int, float)) and not isinstance(x, bool) for x in value):
        raise DescriptionError(source, f"robot.{key} must be a list of numbers", f"robot.{key}")
    return tuple(float(x) for x in value)


def _robot_section(raw: object, source: str) -> RobotSection | None:
    """Check the ``robot:`` mapping of a loops file (types only; the names and sizes are
    checked when the robot is built)."""
    if raw is None:
        return None
    if not isinstance(raw, dict):
        raise DescriptionError(source, "'robot' must be a mapping", "robot")
    unknown = set(raw) - {"platform", "pose_axes", "home", "max_actuator_force"}
    if unknown:
        raise DescriptionError(source, f"unknown keys {sorted(unknown)} in 'robot'",
                               f"robot.{sorted(unknown)[0]}")
    platform = raw.get("platform")
    if platform is not None and not isinstance(platform, str):
        raise DescriptionError(source, "robot.platform must be a frame name", "robot.platform")
    axes = raw.get("pose_axes")
    if isinstance(axes, str):
        axes = [a.strip() for a in axes.split(",")]
    if axes is not None and (not isinstance(axes, list)
                             or not all(isinstance(a, str) for a in axes)):
        raise DescriptionError(source, "robot.pose_axes must be a list of axis names",
                               "robot.pose_axes")
    home = raw.get("home")
    force = raw.get("max_actuator_force")
    if force is not None and not (isinstance(force, (int, float)) and not isinstance(force, bool)):
        force = _numbers(force, source, "max_actuator_force")
    bound = force if force is None or isinstance(force, tuple) else float(force)
    return RobotSection(platform, None if axes is None else tuple(axes),
                        None if home is None else _numbers(home, source, "home"), bound)


def file_path(path: object, name: str = "path") -> str | os.PathLike[str]:
    """``path`` after checking that it is a path (a non-empty string or an
    ``os.PathLike``).

    Raises:
        ArgumentTypeError: anything else (None, a number, bytes, a list), naming ``name``.
    """
    if isinstance(path, os.PathLike) or (isinstance(path, str) and path):
        return path
    raise ArgumentTypeError(name, path, "expected a file path (str or os.PathLike), got "
                            f"{type(path).__name__}")


def read_text(path: str | os.PathLike[str], what: str = "file") -> str:
    """The UTF-8 text of a file the library reads (a description, geometry, motion,
    waypoint or measurement file: ``what``, named by the errors).

    Raises:
        ArgumentTypeError: ``path`` is not a path (None, a number).
        MissingFileError: the file does not exist.
        DescriptionError: a folder, an unreadable file, or not UTF-8 text (binary).
    """
    path = Path(file_path(path))
    if path.is_dir():
        raise DescriptionError(str(path), "is a folder, expected a file")
    existing_file(path, what)
    try:
        return path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise DescriptionError(str(path), f"not UTF-8 text ({exc.reason} at byte "
                                          f"{exc.start})") from None
    except OSError as exc:
        raise DescriptionError(str(path), f"cannot be read: {exc.strerror}") from None


def load_loops(path: str | Path) -> LoopsSpec:
    """Read and parse a loops description file (see :func:`parse_loops`)."""
    return parse_loops(read_text(path), source=str(path))
