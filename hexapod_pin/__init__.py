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
"""

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
                     BatchActuatorSaturationError, BatchSingularityError, BatchUnreachablePoseError, DescriptionError,
                     GeometryError, HexapodPinError, InconsistentMotionError,
                     InfeasiblePathError, InputError, MissingDependencyError, MissingFileError,
                     MotionSampleError, NonFiniteResultError, SingularityError, SolverError,
                     StrokeLimitError, UnreachablePoseError)
from .hexapod.geometry import ChainGeometry, HexapodGeometry
from .hexapod.kinematics import LegMotion
from .hexapod.robot import Hexapod
from .hexapod import compiled_backend  # noqa: F401  (registers simulate's backend="compiled")
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
