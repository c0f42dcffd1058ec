"""Time-optimal motion of parallel robots within their closed-loop limits.

:func:`time_optimal` retimes a path through platform waypoints as fast as the actuator
forces, velocities and accelerations, the platform speeds and the strokes allow (TOPP-RA
on the robot's own closed-loop inverse dynamics); :func:`check_feasibility` measures the
margins of a timed motion against the same limits. Both take any robot with the shared
API (:mod:`hexapod_pin.core.robot_api`), with its drive effects (armature, damping, Coulomb
friction, springs, effort limits: ``docs/drives.md``, "Planning with drives").

Modules: :mod:`.path` (C2 paths, rotations on SO(3)), :mod:`.limits` (limits, payload,
their coefficients along a path), :mod:`.solver` (compiled TOPP-RA),
:mod:`.trajectory` (:func:`time_optimal`, :class:`TimedTrajectory`), :mod:`.feasibility`
(:func:`check_feasibility`, :class:`FeasibilityReport`).
"""

from .feasibility import FeasibilityReport, Violation, check_feasibility
from .limits import Limits, Payload
from .path import GeometricPath, PathSamples, read_waypoints
from .trajectory import PhaseProfile, TimedTrajectory, time_optimal

__all__ = ["FeasibilityReport", "GeometricPath", "Limits", "PathSamples", "Payload",
           "PhaseProfile", "TimedTrajectory", "Violation", "check_feasibility",
           "read_waypoints", "time_optimal"]
