"""``load_robot``: a parallel robot from any description the library reads.

One registry, :data:`FORMATS`, maps a description to the function that loads its
:class:`~hexapod_pin.core.closed_loop.ClosedLoopModel`; a new format is one loader plus
one line there. What makes the model a robot (the platform frame, the pose axes, the
home configuration, the force bounds) comes from the call's arguments, or else from the
optional ``robot:`` section of a loops file::

    robot:
      platform: coupler_point        # the frame whose placement is the pose
      pose_axes: [x, z]              # a subset of x, y, z, roll, pitch, yaw, in order
      home: [0.0, -0.948, -1.896]    # optional: a configuration (nq,) near home
      max_actuator_force: 5.0        # optional: N or N m, one or one per actuator
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy.typing as npt

from ..core.closed_loop import ClosedLoopModel
from ..core.description import RobotSection, load_loops
from ..core.robot import ClosedLoopRobot
from ..core.checks import existing_file
from ..errors import ArgumentTypeError, DescriptionError
from .mjcf import read_mjcf, robot_section
from .parallel_robots import load_parallel_robot
from .sdf import closed_loop_from_sdf, load_sdf


def loops_beside(path: Path) -> Path:
    """The loops file of a URDF or xacro: ``<name>.loops.yaml`` beside it (``name``: the
    file name without ``.urdf``, ``.xacro`` or ``.urdf.xacro``)."""
    name = path.name
    for suffix in (".urdf.xacro", ".xacro", ".urdf"):
        if name.endswith(suffix):
            name = name[: -len(suffix)]
            break
    return path.with_name(f"{name}.loops.yaml")


def _urdf(path: Path, actuated: tuple[str, ...]) -> tuple[ClosedLoopModel, RobotSection | None]:
    loops = loops_beside(path)
    if not loops.is_file():
        raise DescriptionError(str(path), f"no loops file beside it (expected {loops.name})",
                               loops.name)
    return ClosedLoopModel.from_files(path, loops), load_loops(loops).robot


def _sdf(path: Path, actuated: tuple[str, ...]) -> tuple[ClosedLoopModel, RobotSection | None]:
    return closed_loop_from_sdf(load_sdf(path), actuated=actuated), None


def _folder(path: Path, actuated: tuple[str, ...]
            ) -> tuple[ClosedLoopModel, RobotSection | None]:
    if (path / "robot.yaml").is_file():
        return load_parallel_robot(path), None
    urdfs = sorted(p for p in path.iterdir() if p.name.endswith((".urdf", ".urdf.xacro"))
                   and loops_beside(p).is_file())
    if len(urdfs) != 1:
        raise DescriptionError(str(path), "expected an example-parallel-robots folder "
                               "(robot.urdf + robot.yaml) or exactly one URDF with its "
                               f"loops file, found {[p.name for p in urdfs]}")
    return _urdf(urdfs[0], actuated)


def _mjcf(path: Path, actuated: tuple[str, ...]) -> tuple[ClosedLoopModel, RobotSection | None]:
    if actuated:
        raise DescriptionError(str(path), "an MJCF names its actuated joints (<actuator>); "
                               "actuated= is for SDF files", "actuated")
    result = read_mjcf(path)
    return result.model, robot_section(result)


#: description kinds -> (test on the path, loader returning the model and robot section)
FORMATS: dict[str, tuple[Callable[[Path], bool],
                         Callable[[Path, tuple[str, ...]],
                                  tuple[ClosedLoopModel, RobotSection | None]]]] = {
    "folder": (lambda p: p.is_dir(), _folder),
    "urdf": (lambda p: p.name.endswith((".urdf", ".xacro")), _urdf),
    "sdf": (lambda p: p.suffix == ".sdf", _sdf),
    "mjcf": (lambda p: p.suffix in (".xml", ".mjcf"), _mjcf),
}


def load_model(path: str | os.PathLike[str], actuated: tuple[str, ...] = ()
               ) -> tuple[ClosedLoopModel, RobotSection | None]:
    """The :class:`ClosedLoopModel` of a description and its ``robot:`` section (or None).

    Args:
        path: a URDF / xacro with ``<name>.loops.yaml`` beside it, an SDF, an MJCF
            (``.xml``, :func:`~hexapod_pin.loaders.mjcf.read_mjcf`; its ``home`` is the
            robot's default home), or a folder (example-parallel-robots format, or one
            URDF with its loops file).
        actuated: the actuated joints of an SDF (the other formats name them).

    Raises:
        MissingFileError: the path does not exist.
        DescriptionError: an unknown format, or a malformed description.
    """
    if not isinstance(path, (str, os.PathLike)):
        raise ArgumentTypeError("path", path, "expected a file or folder path, got "
                                f"{type(path).__name__}")
    path = Path(path)
    existing_file(path, folder=True)
    for test, loader in FORMATS.values():
        if test(path):
            return loader(path, tuple(actuated))
    raise DescriptionError(str(path), "unknown description format (expected a folder, "
                           ".urdf, .xacro, .sdf, .xml)")


def load_robot(path: str | os.PathLike[str], platform: str | None = None,
               pose_axes: object = None, *, home: npt.ArrayLike | None = None,
               actuated: tuple[str, ...] = (), **options: Any) -> ClosedLoopRobot:
    """A :class:`~hexapod_pin.core.robot.ClosedLoopRobot` from a description file.

    Args:
        path: see :func:`load_model`.
        platform: the platform frame; default the loops file's ``robot.platform``.
        pose_axes: the pose components; default the loops file's ``robot.pose_axes``,
            else all six.
        home: the home configuration (nq,); default the loops file's ``robot.home``, else
            the robot's own choice (see :class:`ClosedLoopRobot`).
        actuated: the actuated joints of an SDF.
        **options: ``max_actuator_force``, ``characteristic_length`` (see
            :class:`ClosedLoopRobot`).

    Raises:
        DescriptionError: see :func:`load_model`; no platform frame given or named; the
            robot cannot be built (see :class:`ClosedLoopRobot`).
        InputError: bad options.
        ArgumentTypeError: a path that is not a path, an unknown option.
    """
    unknown = sorted(set(options) - {"max_actuator_force", "characteristic_length"})
    if unknown:
        raise ArgumentTypeError(unknown[0], options[unknown[0]], "unknown option of "
                                "load_robot (max_actuator_force, characteristic_length)")
    model, section = load_model(path, actuated)
    section = section or RobotSection()
    platform = platform if platform is not None else section.platform
    if platform is None:
        raise DescriptionError(str(path), "no platform frame: pass platform= or write "
                               "'robot: {platform: <frame>}' in the loops file", "platform")
    axes = pose_axes if pose_axes is not None else (
        section.pose_axes or ("x", "y", "z", "roll", "pitch", "yaw"))
    if home is None and section.home is not None:
        home = section.home
    if "max_actuator_force" not in options and section.max_actuator_force is not None:
        options["max_actuator_force"] = section.max_actuator_force
    return ClosedLoopRobot(model, platform, axes, home=home, **options)
