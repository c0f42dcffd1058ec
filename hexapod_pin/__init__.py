"""hexapod_pin: kinematics and dynamics of closed-loop mechanisms on Pinocchio and ProxSuite.

The rail-driven 6-DoF hexapod is the first and best-supported robot; any closed-loop
robot described as a URDF + loops file, an SDF, an MJCF or an example-parallel-robots folder gets
the same API with no code of its own (:class:`~hexapod_pin.core.robot.ClosedLoopRobot`):

```python
import hexapod_pin
robot = hexapod_pin.Hexapod.default()
q = robot.configuration(robot.home_pose)      # Pinocchio q, every closure holds
other = hexapod_pin.load_robot("stewart.urdf")        # its loops file names the platform
run = hexapod_pin.simulate(other, duration=0.5)       # any robot, one Trajectory
```

Layout: :mod:`hexapod_pin.core` (any tree + loop closures: description, closed-loop model,
dynamics, simulation, the shared robot API and result types), :mod:`hexapod_pin.loaders`
(robots and formats from elsewhere), :mod:`hexapod_pin.hexapod` and
:mod:`hexapod_pin.planar` (the two robots, one compiled closed form each),
:mod:`hexapod_pin.viz` (meshcat scenes, figures), :mod:`hexapod_pin.cli` (the command line).
The public names are ``hexapod_pin.__all__`` (listed with links on the API page of the
package); every robot implements
:class:`~hexapod_pin.core.robot_api.ParallelRobot` and returns the result types of
:mod:`hexapod_pin.core.results`.

The names are loaded on first use (PEP 562): ``import hexapod_pin`` imports none of its
modules, nor Pinocchio, numba or SciPy (``tests/test_startup.py``), and ``hexapod_pin.Hexapod``
imports :mod:`hexapod_pin.hexapod.robot` when it is first read. ``from hexapod_pin import X``,
``dir(hexapod_pin)`` and type checkers (the ``TYPE_CHECKING`` block) see every name.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .core.closed_loop import AssemblyResult, ClosedLoopModel, RankInfo
    from .core.controllers import ActuatorPID, ComputedTorque
    from .core.energy import model_energies
    from .core.simulate import Trajectory, simulate
    from .core.description import (ClosureSpec, LoopsSpec, expand_xacro, load_loops, parse_loops,
                                   urdf_dir)
    from .core.results import (BatchForwardDynamics, BatchInverseDynamics, BatchReducedDynamics,
                               Energies, ForwardDynamicsResult, InverseDynamicsDerivatives,
                               InverseDynamicsResult, InverseKinematicsBatch, JacobianBatch,
                               ReducedDynamics, SingularityMeasures)
    from .core.robot import ClosedLoopRobot, RobotSpec
    from .core.robot_api import ParallelRobot
    from .errors import (ActuatorSaturationError, ArgumentTypeError, AssemblyError,
                         BatchActuatorSaturationError, BatchSingularityError,
                         BatchUnreachablePoseError, DescriptionError,
                         GeometryError, HexapodPinError, InconsistentMotionError,
                         InfeasiblePathError, InputError, MissingDependencyError, MissingFileError,
                         MotionSampleError, NonFiniteResultError, SingularityError, SolverError,
                         StrokeLimitError, UnreachablePoseError)
    from .hexapod.geometry import ChainGeometry, HexapodGeometry
    from .hexapod.kinematics import LegMotion
    from .hexapod.robot import Hexapod
    from .loaders import robots
    from .loaders.any_robot import load_robot
    from .loaders.mjcf import load_mjcf
    from .loaders.parallel_robots import load_parallel_robot
    from .planar.assembly_modes import AssemblyPolynomial
    from .planar.geometry import PlanarGeometry
    from .planar.robot import Planar3PRR
    from .precompile import warmup

__version__ = "0.1.0"

__all__ = [
    # robots
    "Hexapod", "HexapodGeometry", "ChainGeometry", "LegMotion", "Planar3PRR", "PlanarGeometry",
    "AssemblyPolynomial", "ParallelRobot", "load_parallel_robot", "robots",
    "ClosedLoopRobot", "RobotSpec", "load_robot", "load_mjcf",
    # the generic core
    "ClosedLoopModel", "AssemblyResult", "RankInfo", "ClosureSpec", "LoopsSpec",
    "expand_xacro", "load_loops", "parse_loops", "urdf_dir",
    "simulate", "Trajectory", "ActuatorPID", "ComputedTorque", "model_energies",
    "warmup",
    # results shared by every robot
    "InverseDynamicsResult", "ForwardDynamicsResult", "ReducedDynamics", "Energies",
    "SingularityMeasures", "InverseDynamicsDerivatives", "InverseKinematicsBatch",
    "JacobianBatch", "BatchInverseDynamics", "BatchForwardDynamics", "BatchReducedDynamics",
    # errors
    "HexapodPinError", "ActuatorSaturationError", "AssemblyError", "DescriptionError",
    "GeometryError", "InputError", "SingularityError", "SolverError", "StrokeLimitError",
    "UnreachablePoseError", "BatchActuatorSaturationError", "BatchSingularityError",
    "BatchUnreachablePoseError", "MotionSampleError", "MissingDependencyError",
    "InconsistentMotionError", "InfeasiblePathError", "NonFiniteResultError",
    "ArgumentTypeError", "MissingFileError",
]

#: public name -> the module that defines it
_EXPORTS = {
    "AssemblyResult": "hexapod_pin.core.closed_loop",
    "ClosedLoopModel": "hexapod_pin.core.closed_loop",
    "RankInfo": "hexapod_pin.core.closed_loop",
    "ActuatorPID": "hexapod_pin.core.controllers",
    "ComputedTorque": "hexapod_pin.core.controllers",
    "model_energies": "hexapod_pin.core.energy",
    "Trajectory": "hexapod_pin.core.simulate",
    "simulate": "hexapod_pin.core.simulate",
    "ClosureSpec": "hexapod_pin.core.description",
    "LoopsSpec": "hexapod_pin.core.description",
    "expand_xacro": "hexapod_pin.core.description",
    "load_loops": "hexapod_pin.core.description",
    "parse_loops": "hexapod_pin.core.description",
    "urdf_dir": "hexapod_pin.core.description",
    "BatchForwardDynamics": "hexapod_pin.core.results",
    "BatchInverseDynamics": "hexapod_pin.core.results",
    "BatchReducedDynamics": "hexapod_pin.core.results",
    "Energies": "hexapod_pin.core.results",
    "ForwardDynamicsResult": "hexapod_pin.core.results",
    "InverseDynamicsDerivatives": "hexapod_pin.core.results",
    "InverseDynamicsResult": "hexapod_pin.core.results",
    "InverseKinematicsBatch": "hexapod_pin.core.results",
    "JacobianBatch": "hexapod_pin.core.results",
    "ReducedDynamics": "hexapod_pin.core.results",
    "SingularityMeasures": "hexapod_pin.core.results",
    "ClosedLoopRobot": "hexapod_pin.core.robot",
    "RobotSpec": "hexapod_pin.core.robot",
    "ParallelRobot": "hexapod_pin.core.robot_api",
    "ActuatorSaturationError": "hexapod_pin.errors",
    "ArgumentTypeError": "hexapod_pin.errors",
    "AssemblyError": "hexapod_pin.errors",
    "BatchActuatorSaturationError": "hexapod_pin.errors",
    "BatchSingularityError": "hexapod_pin.errors",
    "BatchUnreachablePoseError": "hexapod_pin.errors",
    "DescriptionError": "hexapod_pin.errors",
    "GeometryError": "hexapod_pin.errors",
    "HexapodPinError": "hexapod_pin.errors",
    "InconsistentMotionError": "hexapod_pin.errors",
    "InfeasiblePathError": "hexapod_pin.errors",
    "InputError": "hexapod_pin.errors",
    "MissingDependencyError": "hexapod_pin.errors",
    "MissingFileError": "hexapod_pin.errors",
    "MotionSampleError": "hexapod_pin.errors",
    "NonFiniteResultError": "hexapod_pin.errors",
    "SingularityError": "hexapod_pin.errors",
    "SolverError": "hexapod_pin.errors",
    "StrokeLimitError": "hexapod_pin.errors",
    "UnreachablePoseError": "hexapod_pin.errors",
    "ChainGeometry": "hexapod_pin.hexapod.geometry",
    "HexapodGeometry": "hexapod_pin.hexapod.geometry",
    "LegMotion": "hexapod_pin.hexapod.kinematics",
    "Hexapod": "hexapod_pin.hexapod.robot",
    "load_robot": "hexapod_pin.loaders.any_robot",
    "load_mjcf": "hexapod_pin.loaders.mjcf",
    "load_parallel_robot": "hexapod_pin.loaders.parallel_robots",
    "AssemblyPolynomial": "hexapod_pin.planar.assembly_modes",
    "PlanarGeometry": "hexapod_pin.planar.geometry",
    "Planar3PRR": "hexapod_pin.planar.robot",
    "warmup": "hexapod_pin.precompile",
}

#: public names that are modules
_MODULE_EXPORTS = {"robots": "hexapod_pin.loaders.robots"}

#: the package's subpackages and modules, reachable as attributes (``hexapod_pin.core``)
_SUBMODULES = frozenset({"core", "hexapod", "planar", "loaders", "viz", "cli", "calibration",
                         "planning", "identification", "motion", "files", "errors",
                         "precompile"})


def __getattr__(name: str) -> Any:
    """A public name (or subpackage) of the package, imported on first use and kept."""
    if name in _EXPORTS:
        value = getattr(importlib.import_module(_EXPORTS[name]), name)
    elif name in _MODULE_EXPORTS:
        value = importlib.import_module(_MODULE_EXPORTS[name])
    elif name in _SUBMODULES:
        value = importlib.import_module(f"{__name__}.{name}")
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__) | _SUBMODULES)
