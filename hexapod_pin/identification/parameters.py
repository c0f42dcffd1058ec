"""The dynamic parameters of a closed-loop robot: their layout, names and values, and the
robot rebuilt with other values.

Inertial parameters: ten per body of the Pinocchio tree (the body of each joint
``1 .. njoints - 1``, in joint order), Pinocchio's convention
(``pin.Inertia.toDynamicParameters``)::

    pi_body = (m, m c_x, m c_y, m c_z, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz)

with ``m`` the mass (kg), ``c`` the centre of mass (m) and ``I`` the rotational inertia
about the body frame's ORIGIN (kg m^2), all in the body (joint) frame. Names:
``m_<body>``, ``mx_<body>``, ``my_<body>``, ``mz_<body>``, ``Ixx_<body>``, ... with
``<body>`` the name of the tree's joint that carries the body (unique in a Pinocchio
model; a link merged by a fixed joint is part of its parent's body).

Drive parameters: per actuator (``clm.actuated_joints`` order) and per kind of
:data:`DRIVE_KINDS`, the force each adds to the actuator force ``u_i`` (N or N m):

========== ======================== ============ =====================================
kind       name                     column       unit of the parameter
========== ======================== ============ =====================================
armature   ``Ia_<actuator>``        ``qdd_i``    kg or kg m^2 (``effects.armature``)
viscous    ``fv_<actuator>``        ``qd_i``     N s/m, N m s/rad (``effects.damping``)
coulomb    ``fc_<actuator>``        sign(qd_i)   N, N m (``effects.coulomb``)
offset     ``off_<actuator>``       1            N, N m (a constant force bias of the
                                                 drive or its force measurement; no field
                                                 of the robot model holds it)
========== ======================== ============ =====================================

(``qd_i``, ``qdd_i``: the actuated joint's velocity and acceleration). The full parameter
vector is the inertial parameters followed by the drive parameters, kind by kind in the
order asked for, actuator by actuator within a kind.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..core.checks import as_array
from ..core.closed_loop import ClosedLoopModel
from ..core.robot import ClosedLoopRobot
from ..errors import ArgumentTypeError, InputError

#: the drive parameter kinds, in their canonical order
DRIVE_KINDS = ("armature", "viscous", "coulomb", "offset")
#: the prefix of each drive kind's names
DRIVE_PREFIX = {"armature": "Ia", "viscous": "fv", "coulomb": "fc", "offset": "off"}
#: the default drive parameters of identification (armature is left out: on a horizontal
#: rail, the hexapod's, it cannot be told from the mass of the carriage; see
#: :mod:`.base` for which kinds merge on which robot)
DEFAULT_DRIVE = ("viscous", "coulomb", "offset")
#: the model's effect field of each drive kind that has one (offsets have none)
EFFECT_FIELDS = {"armature": "armature", "viscous": "damping", "coulomb": "coulomb"}
#: the ten inertial parameter names of a body, Pinocchio's order
INERTIAL_NAMES = ("m", "mx", "my", "mz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")
#: the unit of each inertial parameter
INERTIAL_UNITS = ("kg", "kg m", "kg m", "kg m", "kg m^2", "kg m^2", "kg m^2", "kg m^2",
                  "kg m^2", "kg m^2")


def check_drive(drive: object) -> tuple[str, ...]:
    """The drive kinds asked for, in the order given, each once.

    Raises:
        InputError: not a sequence of names of :data:`DRIVE_KINDS`, or a repeated one.
    """
    if isinstance(drive, str) or not isinstance(drive, Sequence):
        raise InputError("drive", drive, f"expected a sequence of names of {DRIVE_KINDS}")
    out = tuple(drive)
    for kind in out:
        if kind not in DRIVE_KINDS:
            raise InputError("drive", drive, f"unknown kind {kind!r}: expected names of "
                             f"{DRIVE_KINDS}")
    if len(set(out)) != len(out):
        raise InputError("drive", drive, "a kind is repeated")
    return out


@dataclass(frozen=True)
class ParameterLayout:
    """The full dynamic parameter vector of a robot (module docstring).

    Attributes:
        bodies: the body names (the tree's joints ``1 .. njoints - 1``).
        actuators: the actuated joints' names.
        drive: the drive kinds, in the vector's order.
    """

    bodies: tuple[str, ...]
    actuators: tuple[str, ...]
    drive: tuple[str, ...]

    @classmethod
    def of(cls, robot: object, drive: object = DEFAULT_DRIVE) -> ParameterLayout:
        """The layout of a robot (anything with a ``model``, a
        :class:`~hexapod_pin.core.closed_loop.ClosedLoopModel`).

        Raises:
            ArgumentTypeError: no closed-loop model.
            InputError: bad ``drive``.
        """
        return cls.of_model(closed_loop_model(robot), drive)

    @classmethod
    def of_model(cls, clm: ClosedLoopModel, drive: object = DEFAULT_DRIVE) -> ParameterLayout:
        """The layout of a closed-loop model (bodies of its tree, its actuated joints).

        Raises:
            InputError: bad ``drive``.
        """
        names = tuple(clm.model.names[j] for j in range(1, clm.model.njoints))
        return cls(names, tuple(clm.actuated_joints), check_drive(drive))

    @property
    def n_inertial(self) -> int:
        """Number of inertial parameters (10 per body)."""
        return 10 * len(self.bodies)

    @property
    def n_drive(self) -> int:
        """Number of drive parameters (one per kind and actuator)."""
        return len(self.drive) * len(self.actuators)

    @property
    def size(self) -> int:
        """Length of the full parameter vector."""
        return self.n_inertial + self.n_drive

    @property
    def names(self) -> tuple[str, ...]:
        """The name of every parameter, in the vector's order."""
        inertial = [f"{p}_{b}" for b in self.bodies for p in INERTIAL_NAMES]
        drive = [f"{DRIVE_PREFIX[k]}_{a}" for k in self.drive for a in self.actuators]
        return tuple(inertial + drive)

    @property
    def units(self) -> tuple[str, ...]:
        """The unit of every parameter (drive units for prismatic actuators; N m based
        ones for revolute actuators)."""
        drive_units = {"armature": "kg", "viscous": "N s/m", "coulomb": "N", "offset": "N"}
        return tuple(list(INERTIAL_UNITS) * len(self.bodies)
                     + [drive_units[k] for k in self.drive for _ in self.actuators])

    def drive_slice(self, kind: str) -> slice:
        """Where the parameters of one drive kind sit in the full vector."""
        k = self.drive.index(kind)
        n = len(self.actuators)
        return slice(self.n_inertial + k * n, self.n_inertial + (k + 1) * n)


def closed_loop_model(robot: object) -> ClosedLoopModel:
    """The :class:`ClosedLoopModel` of a robot.

    Raises:
        ArgumentTypeError: ``robot`` has none.
    """
    clm = getattr(robot, "model", None)
    if not isinstance(clm, ClosedLoopModel):
        raise ArgumentTypeError("robot", robot, "expected a robot of the library (with a "
                                "ClosedLoopModel as its model)")
    return clm


def nominal_parameters(robot: object, drive: object = DEFAULT_DRIVE) -> np.ndarray:
    """The full parameter vector of a robot's model (module docstring): its bodies'
    inertias and, per actuator, the armature, damping and Coulomb friction of its
    ``effects`` on the actuated coordinate (offsets 0).

    Raises:
        ArgumentTypeError: not a robot of the library.
        InputError: bad ``drive``.
    """
    clm = closed_loop_model(robot)
    layout = ParameterLayout.of(robot, drive)
    model = clm.model
    inertial = [np.asarray(model.inertias[j].toDynamicParameters(), dtype=float)
                for j in range(1, model.njoints)]
    eff, act = clm.effects, clm.actuated_v
    source = {"armature": eff.armature[act], "viscous": eff.damping[act],
              "coulomb": eff.coulomb[act], "offset": np.zeros(act.size)}
    return np.concatenate(inertial + [source[k] for k in layout.drive])


def robot_with_parameters(robot: object, parameters: np.ndarray,
                          drive: object = DEFAULT_DRIVE) -> ClosedLoopRobot:
    """The robot with other dynamic parameters, as a
    :class:`~hexapod_pin.core.robot.ClosedLoopRobot` (every route of the shared API: tree
    routes, no closed form) on a copy of its tree.

    The copy has the bodies' inertias of ``parameters``
    (``pin.Inertia.FromDynamicParameters``), the robot's gravity, closures, actuation and
    effects, with the armature, damping and Coulomb friction of the actuated coordinates
    replaced by the drive parameters present in ``drive`` (offsets have no field in the
    model and are left out: a robot model has no constant drive force). The new robot has
    the same platform frame, pose axes and home configuration, and no force bound. Its
    URDF text (drawing) is the original description's.

    Args:
        robot: a robot of the library (``Hexapod``, ``Planar3PRR``, ``ClosedLoopRobot``).
        parameters: the full parameter vector (:class:`ParameterLayout`).
        drive: the drive kinds of ``parameters``.

    Raises:
        ArgumentTypeError: not a robot of the library.
        InputError: a vector of the wrong length or not finite; negative armature,
            viscous or Coulomb parameters (the model's effects must be >= 0); a body
            with a mass <= 0 and other parameters not zero.
    """
    clm = closed_loop_model(robot)
    new = model_with_parameters(clm, parameters, drive)
    return ClosedLoopRobot(new, robot_platform_frame(robot), robot_pose_axes(robot),
                           home=robot_home(robot), max_actuator_force=np.inf)


def model_with_parameters(clm: ClosedLoopModel, parameters: npt.ArrayLike,
                          drive: object = DEFAULT_DRIVE) -> ClosedLoopModel:
    """A closed-loop model with other dynamic parameters: a copy of the tree of ``clm``
    with the bodies' inertias of ``parameters`` (:func:`tree_with_parameters`), the same
    closures, actuation, gravity and effects, with the armature, damping and Coulomb
    friction of the actuated coordinates replaced by the drive parameters present in
    ``drive`` (offsets have no model field and are left out). The tree-level route of
    :func:`robot_with_parameters`.

    Args:
        clm: the closed-loop model.
        parameters: the full parameter vector (``ParameterLayout.of_model(clm, drive)``).
        drive: the drive kinds of ``parameters``.

    Raises:
        InputError: bad ``drive``; a vector of the wrong length or not finite; negative
            armature, viscous or Coulomb parameters; a body with a mass <= 0 and other
            parameters not zero.
    """
    layout = ParameterLayout.of_model(clm, drive)
    values = as_array(parameters, (layout.size,), "parameters")
    tree = tree_with_parameters(clm, values)
    changes: dict[str, np.ndarray] = {}
    for kind, field in EFFECT_FIELDS.items():
        if kind not in layout.drive:
            continue
        per_act = values[layout.drive_slice(kind)]
        if (per_act < 0).any():
            raise InputError("parameters", per_act, f"negative {kind} parameters: a model's "
                             f"{field} must be >= 0")
        full = np.array(getattr(clm.effects, field), dtype=float)
        full[clm.actuated_v] = per_act
        changes[field] = full
    effects = clm.effects.replace(**changes) if changes else clm.effects
    return ClosedLoopModel(tree, clm.loops, name=clm.name, urdf_xml=clm.urdf_xml,
                           effects=effects)


def tree_with_parameters(clm: ClosedLoopModel, parameters: np.ndarray) -> pin.Model:
    """A copy of the tree of ``clm`` (its gravity included) with the bodies' inertias of
    a full parameter vector (its first ``10 nb`` entries; a body whose ten parameters
    are all zero gets ``pin.Inertia.Zero()``: a massless body).

    Raises:
        InputError: a body with a mass <= 0 but other parameters not zero (no inertia
            has them).
    """
    tree = pin.Model(clm.tree_model)
    tree.gravity = clm.model.gravity
    for j in range(1, tree.njoints):
        pi = parameters[10 * (j - 1):10 * j]
        if pi[0] > 0.0:
            tree.inertias[j] = pin.Inertia.FromDynamicParameters(pi)
        elif not np.any(pi):
            tree.inertias[j] = pin.Inertia.Zero()
        else:
            raise InputError("parameters", pi, f"body {tree.names[j]!r}: a mass <= 0 with "
                             "other inertial parameters not zero")
    return tree


def robot_platform_frame(robot: object) -> str:
    """The platform frame's name of a robot of the library."""
    return str(getattr(robot, "platform_frame"))


def robot_pose_axes(robot: object) -> tuple[str, ...]:
    """The pose axes of a robot of the library."""
    return tuple(getattr(robot, "pose_axes"))


def robot_home(robot: object) -> np.ndarray:
    """The home configuration (nq,) of a robot of the library."""
    return np.array(getattr(robot, "home_configuration"), dtype=float)
