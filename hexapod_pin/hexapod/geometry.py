"""Design parameters of the rail-driven hexapod (SI units, validated), ideal or as built.

The default numbers are documented placeholders: the dimensions of the real
Quanser 6-DoF Hexapod are not public. Every number is a parameter.

Ideal conventions (the drawing; world frame z up, rails in the plane z = 0):

* rail k (k = 0, 1, 2) has its midpoint at ``m_k = rail_radius (cos a_k, sin a_k, 0)``
  with ``a_k = 90 deg + 120 deg k`` and its direction ``u_k = (-sin a_k, cos a_k, 0)``;
* carriage i rides on rail ``k = i // 2`` at ``c_i = m_k + q_i u_k``;
* the platform point of rail k is ``p_k = platform_radius (cos a_k, sin a_k, 0)``
  in the platform frame, whose origin is the platform's centre of mass.

As-built conventions (:class:`ChainGeometry`, per chain ``i = 0..5``): the universal-joint
centre of chain ``i`` moves on the straight line through ``line_points[i]`` (world, m)
along the unit ``line_directions[i]``; at the actuator reading ``q_i`` (m) it sits at
``c_i = line_points[i] + (q_i + sensor_offsets[i]) line_directions[i]``; leg ``i`` has the
length ``leg_lengths[i]`` (m, joint centre to joint centre) and ends at its own platform
joint ``platform_joints[i]`` (platform frame, m; the two legs of a pair need not meet).
The ideal robot is ``line_points[i] = m_k``, ``line_directions[i] = u_k``, offsets 0,
lengths ``leg_length`` and ``platform_joints[i] = p_k`` (``k = i // 2``), which is what
``HexapodGeometry.chains = None`` means. The scalar fields (``rail_radius``, ...,
``leg_length``) stay the nominal design: the stroke limits (``rail_half_length``,
``carriage_min_gap``) apply to the readings ``q``, the type-II measure keeps the nominal
``platform_radius`` as its length scale, and the masses and inertias are the nominal ones
(each leg a uniform rod of its own length). An as-built home pose is the forward
kinematics of ``home_q`` on the home branch: the ideal home's assembly, moved by the rigid
motion that best fits the drawing's joint centres onto the as-built ones, followed from
the drawing to the as-built chains (:func:`continue_pose`, Newton's method at each step),
so that it is the same assembly mode as the drawing's home.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from ..core import layouts
from ..core.checks import validate_scalars
from ..core.description import expand_xacro, register_xacro_rules, urdf_dir
from ..core.pose import rotation_from_rpy, rpy_from_rotation
from ..errors import GeometryError

N_RAILS = 3
N_CARRIAGES = 6
#: the IK branch of the home pose: ``s_i = -sign(n_i . u_i)``, even carriages -1
HOME_SIGNS = np.array([-1.0, 1.0, -1.0, 1.0, -1.0, 1.0])
#: the fields of :class:`ChainGeometry` in the order of :meth:`ChainGeometry.as_vector`,
#: with their shapes
CHAIN_FIELDS = (("line_points", (6, 3)), ("line_directions", (6, 3)),
                ("sensor_offsets", (6,)), ("leg_lengths", (6,)),
                ("platform_joints", (6, 3)))
#: length of :meth:`ChainGeometry.as_vector` (18 + 18 + 6 + 6 + 18)
CHAIN_VECTOR_SIZE = 66
#: residual (m, relative to ``max(1, leg length)``) below which :func:`closure_pose` has
#: converged
CLOSURE_TOL = 1e-12
#: largest step and smallest step of :func:`continue_pose` (fractions of the path)
CONTINUATION_STEP = 1.0
CONTINUATION_MIN_STEP = 1.0 / 4096.0
#: largest move of the platform in one continuation step (m, and rad of rotation): a
#: larger one is a jump to another assembly, and the step is halved
CONTINUATION_MAX_MOVE = 0.02


def _frozen(value: np.ndarray) -> np.ndarray:
    value.setflags(write=False)
    return value


@dataclass(frozen=True, eq=False)
class ChainGeometry:
    """Per-chain kinematic geometry of an as-built hexapod (SI units, validated).

    Attributes:
        line_points: (6, 3) a point of each chain's universal-joint line, world frame (m).
        line_directions: (6, 3) unit direction of each line, world frame (normalised on
            construction; the actuator force ``tau_i`` acts along it).
        sensor_offsets: (6,) zero offset of each position sensor (m): the joint centre is
            at ``line_points[i] + (q_i + sensor_offsets[i]) line_directions[i]``.
        leg_lengths: (6,) universal-joint centre to platform-joint centre (m), > 0.
        platform_joints: (6, 3) each leg's platform-joint centre, platform frame (m).

    Arrays are stored as read-only float64 copies; equality and hashing compare values.

    Raises:
        GeometryError: a field of the wrong shape, non-finite, a zero direction or a
            non-positive leg length, naming the field.
    """

    line_points: np.ndarray
    line_directions: np.ndarray
    sensor_offsets: np.ndarray
    leg_lengths: np.ndarray
    platform_joints: np.ndarray

    def __post_init__(self) -> None:
        for name, shape in CHAIN_FIELDS:
            raw = getattr(self, name)
            try:
                value = np.array(raw, dtype=float)
            except (TypeError, ValueError):
                raise GeometryError(name, raw, "must be an array of real numbers") from None
            if np.iscomplexobj(np.asarray(raw)) or value.shape != shape:
                raise GeometryError(name, raw, f"must be real with shape {shape}")
            if not np.all(np.isfinite(value)):
                raise GeometryError(name, raw, "must be finite")
            object.__setattr__(self, name, value)
        if np.any(self.leg_lengths <= 0.0):
            raise GeometryError("leg_lengths", self.leg_lengths, "must be > 0")
        dirs = self.line_directions
        norms = np.linalg.norm(dirs, axis=1)
        if np.any(norms < 1e-9):
            raise GeometryError("line_directions", dirs,
                                f"rows must be non-zero (norms {norms})")
        for i in range(6):
            if abs(norms[i] - 1.0) > 4 * np.finfo(float).eps:
                dirs[i] = dirs[i] / norms[i]
        for name, _ in CHAIN_FIELDS:
            _frozen(getattr(self, name))

    @classmethod
    def ideal(cls, geometry: "HexapodGeometry") -> "ChainGeometry":
        """The drawing of ``geometry``: line points ``m_k``, directions ``u_k``, offsets 0,
        lengths ``leg_length``, platform joints ``p_k`` (``k = i // 2``)."""
        k = np.arange(N_CARRIAGES) // 2
        return cls(line_points=layouts.points_on_circle(geometry.rail_radius, 3)[k],
                   line_directions=layouts.rail_directions(3)[k],
                   sensor_offsets=np.zeros(N_CARRIAGES),
                   leg_lengths=np.full(N_CARRIAGES, geometry.leg_length),
                   platform_joints=layouts.points_on_circle(geometry.platform_radius, 3)[k])

    def as_vector(self) -> np.ndarray:
        """The five arrays flattened (row-major) and concatenated, shape
        (CHAIN_VECTOR_SIZE,) = (66,): ``line_points`` [0:18], ``line_directions`` [18:36],
        ``sensor_offsets`` [36:42], ``leg_lengths`` [42:48], ``platform_joints`` [48:66]."""
        return np.concatenate([getattr(self, name).ravel() for name, _ in CHAIN_FIELDS])

    @classmethod
    def from_vector(cls, vec) -> "ChainGeometry":
        """Inverse of :meth:`as_vector` (directions normalised, everything validated).

        Raises:
            GeometryError: ``vec`` not of shape (66,), or an invalid field.
        """
        vec = np.asarray(vec, dtype=float)
        if vec.shape != (CHAIN_VECTOR_SIZE,):
            raise GeometryError("chains", vec, f"vector must have shape ({CHAIN_VECTOR_SIZE},)")
        parts, start = {}, 0
        for name, shape in CHAIN_FIELDS:
            size = int(np.prod(shape))
            parts[name] = vec[start:start + size].reshape(shape)
            start += size
        return cls(**parts)

    def as_dict(self) -> dict[str, list]:
        """The five arrays as nested lists (for TOML/JSON files)."""
        return {name: getattr(self, name).tolist() for name, _ in CHAIN_FIELDS}

    def carriage_points(self, q) -> np.ndarray:
        """Universal-joint centres ``c_i`` (..., 6, 3), world frame (m), at readings ``q``
        (..., 6)."""
        q = np.asarray(q, dtype=float)
        return self.line_points + (q + self.sensor_offsets)[..., None] * self.line_directions

    def legs(self, rot, trans, q) -> tuple[np.ndarray, np.ndarray]:
        """The closure equations' vectors, written once: legs ``n_i = t + R p_i - c_i(q)``
        from each universal-joint centre to its platform joint, and arms ``R p_i``, both
        (..., 6, 3) in world axes (m), for platform rotations ``rot`` (..., 3, 3),
        translations ``trans`` (..., 3) (m) and readings ``q`` (..., 6) (m). A pose closes
        when ``|n_i| = leg_lengths[i]`` for every leg."""
        arms = np.einsum("...ab,ib->...ia", rot, self.platform_joints)
        legs = np.asarray(trans, dtype=float)[..., None, :] + arms - self.carriage_points(q)
        return legs, arms

    def __eq__(self, other) -> bool:
        if not isinstance(other, ChainGeometry):
            return NotImplemented
        return all(np.array_equal(getattr(self, name), getattr(other, name))
                   for name, _ in CHAIN_FIELDS)

    def __hash__(self) -> int:
        return hash(self.as_vector().tobytes())

    def __reduce__(self):
        # pickled by value, rebuilt (validated, read-only) by the constructor
        return (ChainGeometry, tuple(getattr(self, name) for name, _ in CHAIN_FIELDS))


def closure_pose(chains: ChainGeometry, q, start, *, max_iter: int = 50) -> np.ndarray:
    """Forward kinematics by Newton's method on the six closure equations
    ``|t + R platform_joints[i] - c_i(q)| = leg_lengths[i]``, from the pose ``start``.

    Args:
        chains: the per-chain geometry.
        q: (6,) actuator readings (m).
        start: (6,) starting pose ``(x, y, z, roll, pitch, yaw)`` (m, rad); the solution
            found is the one Newton's method reaches from it (the caller checks its
            branch and assembly mode).
        max_iter: Newton iterations at most.

    Returns:
        (6,) the pose, every leg within ``CLOSURE_TOL * max(1, leg length)`` m of its
        length, or None when Newton's method did not converge or met a singular
        Jacobian.
    """
    q = np.asarray(q, dtype=float)
    pts = chains.carriage_points(q)
    t = np.array(start[:3], dtype=float)
    rot = rotation_from_rpy(np.asarray(start[3:], dtype=float))
    tol = CLOSURE_TOL * max(1.0, float(np.max(chains.leg_lengths)))
    for _ in range(max_iter + 1):
        arms = chains.platform_joints @ rot.T
        legs = t + arms - pts
        norms = np.linalg.norm(legs, axis=1)
        res = norms - chains.leg_lengths
        if not np.all(np.isfinite(res)):
            return None
        if np.max(np.abs(res)) <= tol:
            return np.concatenate([t, rpy_from_rotation(rot)])
        unit = legs / norms[:, None]
        jac = np.hstack([unit, np.cross(arms, unit)])
        try:
            step = np.linalg.solve(jac, -res)
        except np.linalg.LinAlgError:
            return None
        t = t + step[:3]
        rot = pin.exp3(step[3:]) @ rot          # the rotation step, world axes
    return None


def rigid_fit(points, targets) -> tuple[np.ndarray, np.ndarray]:
    """The rotation ``R`` (3, 3) and translation ``t`` (3,) (m) minimising
    ``sum |R points_i + t - targets_i|^2`` (Kabsch; a proper rotation) for (n, 3) arrays."""
    points, targets = np.asarray(points, dtype=float), np.asarray(targets, dtype=float)
    p0, t0 = points.mean(axis=0), targets.mean(axis=0)
    u, _, vt = np.linalg.svd((targets - t0).T @ (points - p0))
    flip = np.diag([1.0, 1.0, np.sign(np.linalg.det(u @ vt)) or 1.0])
    rot = u @ flip @ vt
    return rot, t0 - rot @ p0


def continue_pose(start: ChainGeometry, stop: ChainGeometry, q, pose) -> np.ndarray | None:
    """Follow an assembly from the geometry ``start`` to ``stop`` at fixed readings.

    First ``start`` and ``pose`` are moved by the rigid motion that best fits ``start``'s
    joint centres at ``q`` onto ``stop``'s (least squares; the moved pose assembles the
    moved chains exactly, so a measuring instrument's frame far from the robot's costs
    nothing). Then the chains move on the straight line between the two
    :meth:`ChainGeometry.as_vector` (directions renormalised); at each step
    :func:`closure_pose` starts from the previous pose. A step is accepted when Newton's
    method converges and the platform moves by at most ``CONTINUATION_MAX_MOVE`` (m, and
    rad of rotation; a larger move is a jump to another assembly); otherwise it is halved,
    down to ``CONTINUATION_MIN_STEP`` of the path. Accepted steps double again up to
    ``CONTINUATION_STEP``.

    Args:
        start: the geometry the path starts from (``pose`` assembles it).
        stop: the geometry the path ends at.
        q: (6,) actuator readings (m).
        pose: (6,) an assembly of ``start`` at ``q`` (m, rad).

    Returns:
        (6,) the assembly of ``stop`` the path leads to (``closure_pose`` from ``pose``
        when the two geometries are equal), or None where the assembly is lost
        (it meets a fold, i.e. merges with another one and ceases to exist, or a
        type-II singularity).
    """
    if start == stop:
        return closure_pose(stop, q, pose)
    rot_fit, shift = rigid_fit(start.carriage_points(q), stop.carriage_points(q))
    start = ChainGeometry(line_points=start.line_points @ rot_fit.T + shift,
                          line_directions=start.line_directions @ rot_fit.T,
                          sensor_offsets=start.sensor_offsets, leg_lengths=start.leg_lengths,
                          platform_joints=start.platform_joints)
    pose = np.asarray(pose, dtype=float)
    rot = rot_fit @ rotation_from_rpy(pose[3:])
    pose = np.concatenate([rot_fit @ pose[:3] + shift, rpy_from_rotation(rot)])
    a, b = start.as_vector(), stop.as_vector()
    done, step = 0.0, CONTINUATION_STEP
    while done < 1.0:
        t = min(1.0, done + step)
        found = closure_pose(ChainGeometry.from_vector(a + t * (b - a)), q, pose)
        if found is not None:
            new_rot = rotation_from_rpy(found[3:])
            cosine = 0.5 * (np.trace(rot.T @ new_rot) - 1.0)
            turn = math.acos(min(1.0, max(-1.0, cosine)))
            if max(float(np.max(np.abs(found[:3] - pose[:3]))), turn) \
                    <= CONTINUATION_MAX_MOVE:
                done, pose, rot = t, found, new_rot
                step = min(2.0 * step, CONTINUATION_STEP)
                continue
        step /= 2.0
        if step < CONTINUATION_MIN_STEP:
            return None
    return pose


def leg_residuals(chains: ChainGeometry, q, pose) -> np.ndarray:
    """Closure residuals ``|t + R p_i - c_i(q)| - L_i`` (6,) (m) of a pose (6,) at the
    readings ``q`` (6,)."""
    legs, _ = chains.legs(rotation_from_rpy(np.asarray(pose[3:], dtype=float)), pose[:3], q)
    return np.linalg.norm(legs, axis=1) - chains.leg_lengths


def branch_of(chains: ChainGeometry, q, pose) -> np.ndarray:
    """IK branch signs ``s_i = -sign(n_i . u_i)`` (6,) of an assembled pose (6,) at the
    readings ``q`` (6,), ``n_i`` the leg from its joint centre to its platform joint."""
    legs, _ = chains.legs(rotation_from_rpy(np.asarray(pose[3:], dtype=float)), pose[:3], q)
    return -np.sign(np.einsum("ij,ij->i", legs, chains.line_directions))


def carriage_frames(chains: ChainGeometry) -> np.ndarray:
    """Orthonormal carriage frames (6, 3, 3), columns ``(u, l, w)``: ``u`` the line
    direction (the prismatic axis and the first universal-joint axis), ``l = normalize(z x
    u)`` (``z`` the world's vertical) and ``w = u x l`` (for a horizontal ``u``, ``w = z``).
    The carriage links of ``urdf/hexapod.urdf.xacro`` have these axes."""
    u = chains.line_directions
    z = np.array([0.0, 0.0, 1.0])
    lat = np.cross(z, u)
    norms = np.linalg.norm(lat, axis=1)
    lat = np.where(np.abs(norms - 1.0)[:, None] <= 4 * np.finfo(float).eps, lat,
                   lat / norms[:, None])
    up = np.cross(u, lat)
    up = up / np.linalg.norm(up, axis=1)[:, None]
    return np.stack([u, lat, up], axis=2)


@dataclass(frozen=True)
class HexapodGeometry:
    """Geometry, inertia and limits of the hexapod (SI units), ideal or as built.

    Attributes:
        rail_radius: distance from the world origin to each rail midpoint (m).
        platform_radius: distance from the platform origin to each spherical
            joint, in the platform plane (m); also the length scale of the type-II
            measure, as built too.
        leg_length: length of each leg, universal joint to spherical joint (m).
        carriage_home: ``abs(q_i)`` at home (m): even carriages at
            ``-carriage_home``, odd ones at ``+carriage_home``.
        rail_half_length: stroke, ``abs(q_i) <= rail_half_length`` (m).
        carriage_min_gap: ``q_{2k+1} - q_{2k} >= carriage_min_gap`` (m).
        carriage_mass: point mass of each carriage (kg).
        leg_mass: mass of each leg, a thin uniform rod (kg).
        platform_mass: mass of the platform (kg).
        platform_inertia: principal moments of inertia of the platform about
            its frame axes at its centre of mass (kg m^2), three values.
        gravity: magnitude of gravity, acting along -z (m/s^2).
        max_actuator_force: bound on ``abs(tau_i)`` (N); ``inf`` for none.
        chains: the as-built per-chain geometry (:class:`ChainGeometry`), or None for
            the ideal drawing (then :attr:`chain_geometry` is
            ``ChainGeometry.ideal(self)``). It is absolute: :meth:`replace` of a scalar
            keeps it as it is.

    Raises:
        GeometryError: on a non-finite, non-positive or inconsistent value, or an
            as-built geometry whose home does not assemble, naming the field and the value.
    """

    rail_radius: float = 0.35
    platform_radius: float = 0.12
    leg_length: float = 0.45
    carriage_home: float = 0.15
    rail_half_length: float = 0.30
    carriage_min_gap: float = 0.02
    carriage_mass: float = 0.5
    leg_mass: float = 0.3
    platform_mass: float = 1.5
    platform_inertia: tuple[float, float, float] = field(default=(0.004, 0.004, 0.008))
    gravity: float = 9.81
    max_actuator_force: float = 100.0
    chains: ChainGeometry | None = None

    def __post_init__(self) -> None:
        validate_scalars(self, skip=("platform_inertia", "chains"),
                         positive=("rail_radius", "platform_radius", "leg_length",
                                   "carriage_home", "rail_half_length", "carriage_mass",
                                   "leg_mass", "platform_mass", "max_actuator_force"),
                         non_negative=("carriage_min_gap", "gravity"))
        if self.chains is not None and not isinstance(self.chains, ChainGeometry):
            raise GeometryError("chains", self.chains, "must be a ChainGeometry or None")
        self._validate_inertia()
        self._validate_home()
        object.__setattr__(self, "_home_pose", _frozen(self._assemble_home()))

    def _validate_inertia(self) -> None:
        try:
            inertia = tuple(float(v) for v in self.platform_inertia)
        except (TypeError, ValueError):
            raise GeometryError("platform_inertia", self.platform_inertia,
                                "must be three real numbers") from None
        if len(inertia) != 3 or not all(math.isfinite(v) for v in inertia):
            raise GeometryError("platform_inertia", self.platform_inertia,
                                "must be three finite numbers")
        if min(inertia) <= 0.0:
            raise GeometryError("platform_inertia", inertia,
                                "principal moments must be > 0 (positive definite)")
        a, b, c = inertia
        tol = 1e-12 * (a + b + c)
        if a + b < c - tol or b + c < a - tol or a + c < b - tol:
            raise GeometryError("platform_inertia", inertia,
                                "violates the triangle inequality of a physical body")
        object.__setattr__(self, "platform_inertia", inertia)

    def _validate_home(self) -> None:
        if self.carriage_home > self.rail_half_length:
            raise GeometryError("carriage_home", self.carriage_home,
                                f"outside the stroke rail_half_length={self.rail_half_length}")
        if 2.0 * self.carriage_home < self.carriage_min_gap:
            raise GeometryError("carriage_home", self.carriage_home,
                                f"home gap {2 * self.carriage_home} < carriage_min_gap="
                                f"{self.carriage_min_gap}")
        if self.home_height_squared <= 0.0:
            raise GeometryError(
                "leg_length", self.leg_length,
                "home cannot be assembled: leg_length^2 must exceed "
                "(rail_radius - platform_radius)^2 + carriage_home^2 = "
                f"{self.leg_length ** 2 - self.home_height_squared:.6g}")

    def _assemble_home(self) -> np.ndarray:
        ideal = np.array([0.0, 0.0, math.sqrt(self.home_height_squared), 0.0, 0.0, 0.0])
        if self.chains is None:
            return ideal
        chains = self.chains
        frames = carriage_frames(chains)
        if np.any(np.abs(frames[:, 2, 0]) > 1.0 - 1e-6):
            raise GeometryError("chains.line_directions", chains.line_directions,
                                "a line along the vertical has no carriage frame")
        pose = continue_pose(ChainGeometry.ideal(self), chains, self.home_q, ideal)
        if pose is None or not np.array_equal(branch_of(chains, self.home_q, pose),
                                              HOME_SIGNS):
            raise GeometryError("chains", chains,
                                "home cannot be assembled: the ideal home's assembly, "
                                "followed to these chains at home_q, is lost (a fold or a "
                                "singularity on the way) or leaves the home branch")
        return pose

    @property
    def chain_geometry(self) -> ChainGeometry:
        """The explicit per-chain geometry: :attr:`chains`, or the ideal drawing."""
        return ChainGeometry.ideal(self) if self.chains is None else self.chains

    @property
    def is_ideal(self) -> bool:
        """True when :attr:`chains` is None (the drawing)."""
        return self.chains is None

    def with_chains(self, chains: ChainGeometry | None) -> "HexapodGeometry":
        """A copy with the per-chain geometry ``chains`` (None: the ideal drawing)."""
        return self.replace(chains=chains)

    def as_built(self, **deviations) -> "HexapodGeometry":
        """A copy whose chains are the ideal drawing plus ``deviations`` (m; any
        :class:`ChainGeometry` field by name, an array of that field's shape; directions
        renormalised).

        Raises:
            GeometryError: an unknown field, a deviation of the wrong shape, or an
                invalid result.
        """
        ideal = ChainGeometry.ideal(self)
        parts = {name: getattr(ideal, name) for name, _ in CHAIN_FIELDS}
        shapes = dict(CHAIN_FIELDS)
        for name, value in deviations.items():
            if name not in shapes:
                raise GeometryError(name, value, f"not a ChainGeometry field "
                                                 f"({', '.join(shapes)})")
            try:
                raw = np.asarray(value)
                if raw.dtype.kind not in "iuf":    # complex (its imaginary part), bool, text
                    raise TypeError(raw.dtype)
                delta = raw.astype(float)
            except (TypeError, ValueError):
                raise GeometryError(name, value, "must be an array of real numbers") from None
            if delta.shape != shapes[name]:
                raise GeometryError(name, value, f"deviation must have shape {shapes[name]}")
            parts[name] = parts[name] + delta
        return self.with_chains(ChainGeometry(**parts))

    @property
    def home_height_squared(self) -> float:
        """Square of the ideal home platform height (m^2); positive when the ideal home
        assembles."""
        radial = self.rail_radius - self.platform_radius
        return self.leg_length ** 2 - radial ** 2 - self.carriage_home ** 2

    @property
    def home_height(self) -> float:
        """Height z of the platform origin at home (m), about 0.3565 for the defaults
        (``home_pose[2]``)."""
        return float(self._home_pose[2])

    @property
    def home_q(self) -> np.ndarray:
        """Carriage positions at home (m), shape (6,): ``-h`` even, ``+h`` odd."""
        return np.tile([-self.carriage_home, self.carriage_home], N_RAILS)

    @property
    def home_pose(self) -> np.ndarray:
        """Home pose ``(x, y, z, roll, pitch, yaw)`` (m, rad), shape (6,): the level
        platform at the ideal home height, or, as built, the forward kinematics of
        :attr:`home_q` on the home branch."""
        return np.array(self._home_pose)

    @property
    def rail_midpoints(self) -> np.ndarray:
        """Nominal rail midpoints ``m_k`` in the world (m), shape (3, 3) (the drawing; as
        built, see :attr:`chain_geometry`)."""
        return layouts.points_on_circle(self.rail_radius, 3)

    @property
    def rail_directions(self) -> np.ndarray:
        """Nominal unit rail directions ``u_k`` in the world, shape (3, 3) (the drawing)."""
        return layouts.rail_directions(3)

    @property
    def platform_points(self) -> np.ndarray:
        """Nominal spherical-joint points ``p_k`` in the platform frame (m), shape (3, 3)
        (the drawing)."""
        return layouts.points_on_circle(self.platform_radius, 3)

    def xacro_args(self) -> dict[str, str]:
        """The xacro arguments of ``urdf/hexapod.urdf.xacro`` for this geometry: the
        scalars, and for an as-built geometry per chain ``i`` the carriage joint origin
        ``carriage_<i>_xyz`` (``line_points[i] + sensor_offsets[i] line_directions[i]``)
        and ``carriage_<i>_rpy`` (the frame of :func:`carriage_frames`), ``leg_<i>_length``
        and ``anchor_<i>_xyz`` (the platform joint)."""
        ixx, iyy, izz = self.platform_inertia
        values = {
            "rail_radius": self.rail_radius,
            "platform_radius": self.platform_radius,
            "leg_length": self.leg_length,
            "rail_half_length": self.rail_half_length,
            "carriage_mass": self.carriage_mass,
            "leg_mass": self.leg_mass,
            "platform_mass": self.platform_mass,
            "platform_ixx": ixx,
            "platform_iyy": iyy,
            "platform_izz": izz,
            "max_actuator_force": self.max_actuator_force
            if math.isfinite(self.max_actuator_force) else 1e30,
        }
        args = {k: repr(float(v)) for k, v in values.items()}
        if self.chains is not None:
            chains = self.chains
            origins = chains.line_points + chains.sensor_offsets[:, None] \
                * chains.line_directions
            rpys = rpy_from_rotation(carriage_frames(chains))
            for i in range(N_CARRIAGES):
                args[f"carriage_{i}_xyz"] = " ".join(repr(float(v)) for v in origins[i])
                args[f"carriage_{i}_rpy"] = " ".join(repr(float(v)) for v in rpys[i])
                args[f"leg_{i}_length"] = repr(float(chains.leg_lengths[i]))
                args[f"anchor_{i}_xyz"] = " ".join(repr(float(v))
                                                   for v in chains.platform_joints[i])
        return args

    def replace(self, **changes) -> "HexapodGeometry":
        """A copy with some fields changed (validated again).

        Raises:
            GeometryError: a name that is not a field (with the closest one), or an
                invalid value.
        """
        fields = [f.name for f in dataclasses.fields(self) if f.init]
        for name, value in changes.items():
            if name not in fields:
                close = difflib.get_close_matches(name, fields, n=1)
                hint = f"; did you mean {close[0]!r}?" if close else ""
                raise GeometryError(name, value, f"not a HexapodGeometry field{hint}")
        return dataclasses.replace(self, **changes)


#: the arguments of urdf/hexapod.urdf.xacro checked by the geometry's own rules when the
#: file is expanded with them (core.description.register_xacro_rules)
register_xacro_rules("hexapod.urdf.xacro", HexapodGeometry, {
    **{name: name for name in ("rail_radius", "platform_radius", "leg_length",
                               "rail_half_length", "carriage_mass", "leg_mass",
                               "platform_mass", "max_actuator_force")},
    "platform_ixx": "platform_inertia[0]", "platform_iyy": "platform_inertia[1]",
    "platform_izz": "platform_inertia[2]",
    **{f"leg_{i}_length": "leg_length" for i in range(6)}})


def hexapod_urdf(geometry: HexapodGeometry) -> str:
    """Expanded URDF text of the hexapod tree for a :class:`HexapodGeometry`."""
    return expand_xacro(urdf_dir() / "hexapod.urdf.xacro", geometry.xacro_args())
