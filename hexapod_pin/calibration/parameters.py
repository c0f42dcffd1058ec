"""The calibration parameters: a minimal coordinate set of the as-built chains and the two
frames of a measurement, and their names, units and scales.

The parameter vector ``theta`` (:data:`N_PARAMETERS` = 66 values) holds DEVIATIONS from a
start model (the nominal robot and the guessed frames), in this order:

* per chain ``i = 0..5`` (9 each, chain-major, 54 in all): two components of the line
  point normal to the nominal line (``line_point_n1``, ``line_point_n2``, m), two tangent
  perturbations of the line direction (``line_direction_t1``, ``line_direction_t2``,
  rad), the sensor zero (``sensor_offset``, m), the leg length (``leg_length``, m) and
  the platform joint (``platform_joint_x/y/z``, platform frame, m);
* the instrument frame (``instrument.x .. instrument.yaw``, m and rad): the pose of the
  measuring instrument's frame in the robot's world frame;
* the target frame (``target.x .. target.yaw``): the pose of the measured target's frame
  in the platform frame.

With the nominal line ``(a0, u0)`` of a chain and the unit normals ``v1 = normalize(u0 x
e)``, ``v2 = u0 x v1`` (``e`` the world axis least aligned with ``u0``), the chain is::

    line point  a = a0 + n1 v1 + n2 v2
    direction   u = w / |w|,  w = u0 + t1 v1 + t2 v2
    sensor zero o = o0 + d_o,  leg length L = L0 + d_L,  platform joint p = p0 + d_p

The line point has no component along the line: a shift along the line trades exactly
with the sensor zero (``c = a + (q + o) u``), so that coordinate is left out by
construction. Frames are poses ``(x, y, z, roll, pitch, yaw)``, ``R = Rz Ry Rx``, and their
deviations add to the guessed pose componentwise.

Scales (:attr:`ParameterModel.scales`): 1 mm for lengths and 1 mrad for angles, so that
the scaled identification Jacobian compares a millimetre with a milliradian.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ..core.checks import as_array
from ..core.pose import rotation_from_rpy
from ..errors import InputError
from ..hexapod.geometry import ChainGeometry

#: parameters per chain, in order (unit of each)
CHAIN_PARAMETERS = (("line_point_n1", "m"), ("line_point_n2", "m"),
                    ("line_direction_t1", "rad"), ("line_direction_t2", "rad"),
                    ("sensor_offset", "m"), ("leg_length", "m"),
                    ("platform_joint_x", "m"), ("platform_joint_y", "m"),
                    ("platform_joint_z", "m"))
#: coordinates of a frame (unit of each)
FRAME_PARAMETERS = (("x", "m"), ("y", "m"), ("z", "m"),
                    ("roll", "rad"), ("pitch", "rad"), ("yaw", "rad"))
N_CHAIN = len(CHAIN_PARAMETERS)
#: first index of the instrument and of the target frame in ``theta``
INSTRUMENT = 6 * N_CHAIN
TARGET = INSTRUMENT + 6
N_PARAMETERS = TARGET + 6
#: the chain groups and the chain parameters each holds (indices into a chain's 9)
CHAIN_GROUPS = {"line_points": (0, 1), "line_directions": (2, 3), "sensor_offsets": (4,),
                "leg_lengths": (5,), "platform_joints": (6, 7, 8)}
#: every group name :func:`parameter_indices` accepts; "chains" is all five chain groups
GROUPS = (*CHAIN_GROUPS, "instrument", "target")
#: what :func:`hexapod_pin.calibration.identify.calibrate` identifies by default
DEFAULT_IDENTIFY = ("chains", "instrument", "target")
#: scale of a length (m) and of an angle (rad) parameter
LENGTH_SCALE = 1e-3
ANGLE_SCALE = 1e-3


def _names_units() -> tuple[tuple[str, ...], tuple[str, ...], tuple[str, ...]]:
    names, units, groups = [], [], []
    by_index = {j: g for g, idx in CHAIN_GROUPS.items() for j in idx}
    for i in range(6):
        for j, (name, unit) in enumerate(CHAIN_PARAMETERS):
            names.append(f"chain{i}.{name}")
            units.append(unit)
            groups.append(by_index[j])
    for frame in ("instrument", "target"):
        for name, unit in FRAME_PARAMETERS:
            names.append(f"{frame}.{name}")
            units.append(unit)
            groups.append(frame)
    return tuple(names), tuple(units), tuple(groups)


#: name, unit and group of every parameter, in the order of ``theta``
NAMES, UNITS, PARAMETER_GROUPS = _names_units()


def parameter_indices(identify: Sequence[str] | str) -> np.ndarray:
    """Indices into ``theta`` of the parameter groups in ``identify``, ascending.

    Args:
        identify: group names from :data:`GROUPS` or ``"chains"`` (all five chain
            groups); a single string is one group.

    Raises:
        InputError: not a name or a list / tuple of names (None, a number), an unknown
            group name (with the closest known one), a name given twice, or no group at
            all.
    """
    if isinstance(identify, str):
        identify = (identify,)
    if not isinstance(identify, (list, tuple)) or not all(isinstance(i, str) for i in identify):
        raise InputError("identify", identify, "expected a parameter group name or a list of "
                                               f"them (chains, {', '.join(GROUPS)})")
    repeated = sorted({item for item in identify if list(identify).count(item) > 1})
    if repeated:
        raise InputError("identify", identify, f"names {repeated} more than once")
    wanted: set[str] = set()
    for item in identify:
        if item == "chains":
            wanted.update(CHAIN_GROUPS)
        elif item in GROUPS:
            wanted.add(item)
        else:
            raise InputError("identify", item,
                             f"unknown parameter group; known: chains, {', '.join(GROUPS)}")
    if not wanted:
        raise InputError("identify", identify, "names no parameter group")
    return np.array([k for k, g in enumerate(PARAMETER_GROUPS) if g in wanted], dtype=int)


def normal_basis(directions: np.ndarray) -> np.ndarray:
    """Unit normals ``(v1, v2)`` of each line direction, shape (6, 2, 3): ``v1 =
    normalize(u x e)`` with ``e`` the world axis least aligned with ``u``, ``v2 = u x v1``."""
    out = np.empty((directions.shape[0], 2, 3))
    for i, u in enumerate(directions):
        axis = np.zeros(3)
        axis[int(np.argmin(np.abs(u)))] = 1.0
        v1 = np.cross(u, axis)
        v1 /= np.linalg.norm(v1)
        out[i, 0], out[i, 1] = v1, np.cross(u, v1)
    return out


@dataclass(frozen=True)
class Frames:
    """The two frames of a measurement as rotations and translations.

    Attributes:
        instrument_rotation: rotation (3, 3) of the instrument frame in the robot's world,
            ``x_world = R x_instrument + t``.
        instrument_translation: its translation ``t`` (3,) (m).
        target_rotation: rotation (3, 3) of the target frame in the platform frame,
            ``x_platform = R x_target + t``.
        target_translation: its translation ``t`` (3,) (m).
    """

    instrument_rotation: np.ndarray
    instrument_translation: np.ndarray
    target_rotation: np.ndarray
    target_translation: np.ndarray


class ParameterModel:
    """The map from the deviations ``theta`` (66,) to the chains and the frames.

    Args:
        chains: the start (nominal) chain geometry, robot world and platform frames.
        instrument: guessed pose of the instrument frame in the world (6,) (m, rad).
        target: guessed pose of the target frame in the platform frame (6,) (m, rad).

    Attributes:
        start: the start :class:`ChainGeometry`.
        instrument: the guessed instrument pose (6,) (m, rad).
        target: the guessed target pose (6,) (m, rad).
        basis: the normals of each nominal line (6, 2, 3) (:func:`normal_basis`).
        scales: (66,) the scale of each parameter (1 mm, 1 mrad).

    Raises:
        InputError: a frame pose of the wrong shape or not finite.
    """

    def __init__(self, chains: ChainGeometry, instrument: npt.ArrayLike | None = None,
                 target: npt.ArrayLike | None = None):
        self.start = chains
        self.instrument = (np.zeros(6) if instrument is None
                           else as_array(instrument, (6,), "instrument").copy())
        self.target = np.zeros(6) if target is None else as_array(target, (6,), "target").copy()
        self.basis = normal_basis(chains.line_directions)
        self.scales = np.array([LENGTH_SCALE if u == "m" else ANGLE_SCALE for u in UNITS])

    def chains(self, theta: np.ndarray) -> ChainGeometry:
        """The chain geometry at the deviations ``theta`` (robot world / platform frame)."""
        dev = theta[:INSTRUMENT].reshape(6, N_CHAIN)
        s = self.start
        v1, v2 = self.basis[:, 0], self.basis[:, 1]
        points = s.line_points + dev[:, 0:1] * v1 + dev[:, 1:2] * v2
        raw = s.line_directions + dev[:, 2:3] * v1 + dev[:, 3:4] * v2
        return ChainGeometry(line_points=points,
                             line_directions=raw / np.linalg.norm(raw, axis=1)[:, None],
                             sensor_offsets=s.sensor_offsets + dev[:, 4],
                             leg_lengths=s.leg_lengths + dev[:, 5],
                             platform_joints=s.platform_joints + dev[:, 6:9])

    def frame_poses(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The instrument and target poses (6,), (6,) at the deviations ``theta``."""
        return (self.instrument + theta[INSTRUMENT:TARGET],
                self.target + theta[TARGET:N_PARAMETERS])

    def frames(self, theta: np.ndarray) -> Frames:
        """The two frames at ``theta`` as rotations and translations."""
        inst, targ = self.frame_poses(theta)
        return Frames(rotation_from_rpy(inst[3:]), inst[:3].copy(),
                      rotation_from_rpy(targ[3:]), targ[:3].copy())

    def direction_norms(self, theta: np.ndarray) -> np.ndarray:
        """``|w|`` of each chain (6,), the norm of the unnormalised direction."""
        dev = theta[:INSTRUMENT].reshape(6, N_CHAIN)
        raw = (self.start.line_directions + dev[:, 2:3] * self.basis[:, 0]
               + dev[:, 3:4] * self.basis[:, 1])
        return np.linalg.norm(raw, axis=1)

    def deviations_of(self, chains: ChainGeometry, instrument: npt.ArrayLike | None = None,
                      target: npt.ArrayLike | None = None) -> np.ndarray:
        """The deviations ``theta`` (66,) of given chains and frames: the inverse of
        :meth:`chains` and :meth:`frame_poses` (a line point is moved along its line onto
        the plane normal to the nominal line, its sensor zero taking the shift).

        Raises:
            InputError: a line at 90 degrees or more from its nominal direction.
        """
        theta = np.zeros(N_PARAMETERS)
        dev = theta[:INSTRUMENT].reshape(6, N_CHAIN)
        s = self.start
        for i in range(6):
            u, u0 = chains.line_directions[i], s.line_directions[i]
            v1, v2 = self.basis[i]
            along = float(u @ u0)
            if not along > 0.0:
                raise InputError("chains.line_directions", u,
                                 f"chain {i} is 90 degrees or more from its nominal line")
            n1, n2, shift = np.linalg.solve(np.column_stack([v1, v2, -u]),
                                            chains.line_points[i] - s.line_points[i])
            dev[i, 0:2] = n1, n2
            dev[i, 2:4] = u @ v1 / along, u @ v2 / along
            dev[i, 4] = chains.sensor_offsets[i] - shift - s.sensor_offsets[i]
            dev[i, 5] = chains.leg_lengths[i] - s.leg_lengths[i]
            dev[i, 6:9] = chains.platform_joints[i] - s.platform_joints[i]
        if instrument is not None:
            theta[INSTRUMENT:TARGET] = as_array(instrument, (6,), "instrument") - self.instrument
        if target is not None:
            theta[TARGET:] = as_array(target, (6,), "target") - self.target
        return theta
