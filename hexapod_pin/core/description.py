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

Nothing here is specific to the hexapod.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np
import pinocchio as pin
import yaml

from ..errors import DescriptionError

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
class LoopsSpec:
    """A parsed loops description: closures and actuated joint names."""

    closures: tuple[ClosureSpec, ...]
    actuated: tuple[str, ...]


def urdf_dir() -> Path:
    """Folder holding the packaged robot descriptions (``hexapod.urdf.xacro`` ...)."""
    packaged = resources.files("hexapod_pin") / "urdf"
    if packaged.is_dir():
        return Path(str(packaged))
    source_tree = Path(__file__).resolve().parents[2] / "urdf"
    if source_tree.is_dir():
        return source_tree
    raise DescriptionError("hexapod_pin", "cannot find the urdf/ folder of the package")


def expand_xacro(path: str | Path, args: dict[str, str] | None = None) -> str:
    """Expand a xacro (or plain URDF) file to a URDF string, in Python.

    Args:
        path: the ``.xacro`` or ``.urdf`` file.
        args: xacro arguments, name -> value as text.

    Raises:
        DescriptionError: when the file is missing or does not expand.
    """
    path = Path(path)
    if not path.is_file():
        raise DescriptionError(str(path), "file not found")
    args = dict(args or {})
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


def build_model(urdf_xml: str, source: str = "<urdf>") -> pin.Model:
    """Build the Pinocchio tree model from URDF text (no root joint added).

    Raises:
        DescriptionError: when Pinocchio cannot parse the URDF or the model fails
            Pinocchio's consistency check.
    """
    try:
        model = pin.buildModelFromXML(urdf_xml)
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
    return pin.SE3(pin.rpy.rpyToMatrix(*rpy), xyz)


def parse_loops(text: str, source: str = "<loops>") -> LoopsSpec:
    """Parse a loops description (YAML text) into a :class:`LoopsSpec`.

    Only the syntax is checked here; names are checked against the tree by
    :class:`hexapod_pin.closed_loop.ClosedLoopModel`.

    Raises:
        DescriptionError: malformed YAML, missing keys, unknown closure type,
            duplicate names, or a closure joining a frame to itself.
    """
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise DescriptionError(source, f"malformed YAML: {exc}") from None
    if not isinstance(data, dict):
        raise DescriptionError(source, "the loops description must be a YAML mapping")
    unknown = set(data) - {"closures", "actuated"}
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
    for index, entry in enumerate(raw_closures):
        label = f"closures[{index}]"
        if not isinstance(entry, dict):
            raise DescriptionError(source, "a closure must be a mapping", label)
        missing = {"name", "type", "frame1", "frame2"} - set(entry)
        if missing:
            raise DescriptionError(source, f"missing keys {sorted(missing)}", label)
        extra = set(entry) - {"name", "type", "frame1", "frame2", "offset1", "offset2"}
        if extra:
            raise DescriptionError(source, f"unknown keys {sorted(extra)}", label)
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
    return LoopsSpec(tuple(closures), tuple(actuated))


def load_loops(path: str | Path) -> LoopsSpec:
    """Read and parse a loops description file (see :func:`parse_loops`)."""
    path = Path(path)
    if not path.is_file():
        raise DescriptionError(str(path), "file not found")
    return parse_loops(path.read_text(), source=str(path))
