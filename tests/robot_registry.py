"""The robots of the test suites, in one registry: name -> how to build it, each built once.

Every suite that runs over several robots takes them from here: the shared API suite
(``tests/test_shared_api.py``) over the group ``"shared"``, the property, planning,
energy and simulation suites over ``"closed_form"``, the workspace and planning suites of
loaded robots by name. A new robot joins every shared suite with one line in
:data:`ROBOTS`. Fixtures: ``shared_robot`` (each robot of ``"shared"`` in turn) and
``robot`` / ``robot2`` (the two hexapod geometries) in ``tests/conftest.py``; a hypothesis
strategy draws from :func:`names` and builds with :func:`get`.

Groups: ``"shared"`` (every robot of the shared API suite), ``"closed_form"`` (the
hexapod and the planar 3-PRR, default geometries), ``"other_geometry"`` (the same robots
with other numbers), ``"loaded"`` (:class:`hexapod_pin.ClosedLoopRobot` loaded from the
descriptions of ``tests/data``).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any, Callable, NamedTuple

import hexapod_pin as hp

DATA = Path(__file__).resolve().parent / "data"
#: a second hexapod geometry (the ``robot2`` fixture, the kinematics properties)
SECOND_GEOMETRY = dict(rail_radius=0.40, platform_radius=0.10, leg_length=0.50, carriage_home=0.18)


class Entry(NamedTuple):
    """One robot: ``build()`` makes it; ``group`` names its kind; ``shared``: whether the
    shared API suite runs over it."""

    build: Callable[[], Any]
    group: str
    shared: bool = True


def _loaded(path: str, **options: Any) -> Callable[[], hp.ClosedLoopRobot]:
    """A builder of the robot described at ``tests/data/<path>`` (``hp.load_robot``)."""
    return lambda: hp.load_robot(DATA / path, **options)


ROBOTS: dict[str, Entry] = {
    "hexapod": Entry(hp.Hexapod.default, "closed_form"),
    "hexapod-other": Entry(lambda: hp.Hexapod(dataclasses.replace(
        hp.HexapodGeometry(), platform_mass=1.7, leg_mass=0.15)), "other_geometry"),
    "hexapod-second": Entry(lambda: hp.Hexapod(hp.HexapodGeometry(**SECOND_GEOMETRY)),
                            "other_geometry", shared=False),
    "planar": Entry(hp.Planar3PRR.default, "closed_form"),
    "planar-other": Entry(lambda: hp.Planar3PRR(hp.PlanarGeometry(
        rail_radius=0.4, platform_radius=0.15, link_length=0.33, slider_mass=0.7,
        link_mass=0.35, platform_mass=1.6, platform_inertia=0.005, gravity=9.5)),
        "other_geometry"),
    "stewart": Entry(_loaded("stewart/stewart.urdf"), "loaded"),
    "five-bar": Entry(_loaded("parallel/five_bar_3d", platform="end_1", pose_axes=("x", "z")),
                      "loaded"),
    "delta": Entry(_loaded("parallel/delta", platform="platform_center",
                           pose_axes=("x", "y", "z")), "loaded"),
    "four-bar": Entry(_loaded("four_bar/four_bar.urdf"), "loaded"),
}
_BUILT: dict[str, Any] = {}


def names(group: str = "shared") -> list[str]:
    """The sorted names of a group: ``"shared"`` or an :attr:`Entry.group`."""
    if group == "shared":
        return sorted(name for name, entry in ROBOTS.items() if entry.shared)
    found = sorted(name for name, entry in ROBOTS.items() if entry.group == group)
    if not found:
        raise KeyError(f"no robot in group {group!r}")
    return found


def get(name: str) -> Any:
    """The robot ``name``, built on first use and the same object afterwards (the suites
    only read their robots)."""
    if name not in _BUILT:
        _BUILT[name] = ROBOTS[name].build()
    return _BUILT[name]
