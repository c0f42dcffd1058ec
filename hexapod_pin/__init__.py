"""hexapod_pin: kinematics and dynamics of closed-loop mechanisms on Pinocchio and ProxSuite.

The rail-driven 6-DoF hexapod is the first and best-supported robot::

    import hexapod_pin
    robot = hexapod_pin.Hexapod.default()
    q = robot.configuration(robot.home_pose)      # Pinocchio q, every closure holds
"""

from .core.closed_loop import AssemblyResult, ClosedLoopModel, RankInfo
from .core.description import ClosureSpec, LoopsSpec, expand_xacro, load_loops, parse_loops, urdf_dir
from .errors import (ActuatorSaturationError, AssemblyError, DescriptionError, GeometryError,
                     HexapodPinError, InputError, SingularityError, SolverError,
                     StrokeLimitError, UnreachablePoseError)
from .hexapod.geometry import HexapodGeometry
from .hexapod.robot import Hexapod
from .hexapod.kinematics import InverseKinematicsBatch, JacobianBatch, LegMotion, SingularityMeasures
from .loaders.parallel_robots import load_parallel_robot
from .planar.assembly_modes import AssemblyPolynomial
from .planar.geometry import PlanarGeometry
from .planar.robot import Planar3PRR

__version__ = "0.1.0"

__all__ = [
    "ActuatorSaturationError", "AssemblyError", "AssemblyResult", "ClosedLoopModel",
    "ClosureSpec", "DescriptionError", "GeometryError", "Hexapod", "HexapodGeometry",
    "HexapodPinError", "InputError", "LoopsSpec", "RankInfo", "SingularityError",
    "SolverError", "StrokeLimitError", "UnreachablePoseError", "expand_xacro", "load_loops",
    "parse_loops", "urdf_dir", "AssemblyPolynomial", "Planar3PRR",
    "PlanarGeometry", "load_parallel_robot", "derivatives", "robots", "sdf",
    "workspace", "InverseKinematicsBatch", "JacobianBatch", "LegMotion", "SingularityMeasures",
]
from .hexapod import derivatives
from .loaders import robots
from .loaders import sdf
from .hexapod import workspace  # noqa: E402  (submodules as attributes)
