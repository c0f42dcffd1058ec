"""Robots nobody here designed, as :class:`~hexapod_pin.core.closed_loop.ClosedLoopModel` s.

* **Solo-12** (example-robot-data's ``solo12.urdf``): a free-flyer base, 12 actuated
  joints, the four feet held on the ground by 3-D point closures to the world
  (contacts as holonomic closures). :func:`solo12`, :func:`solo12_stand`.
* **Cassie** (example-robot-data's ``cassie_v2.sdf``, read by :mod:`hexapod_pin.loaders.sdf`):
  the achilles-rod and plantar-rod loops closed at their ball joints (3-D point
  closures), the pelvis fixed (hanging) or on a free-flyer. :func:`cassie`.
* :func:`actuation_report` for any closed-loop model: mobility from the constraint
  rank, actuated DoF, and whether the actuation is square, redundant or
  under-actuated.

The robot files are read from the installed ``example-robot-data`` package
(:func:`example_robot_data_dir`); nothing is downloaded.

Free-flyer conventions (Pinocchio's): ``q[:7] = (x, y, z, qx, qy, qz, qw)`` of the
base in the world; ``v[:6]`` the base velocity in the BODY frame (linear, angular);
``a[:6]`` the derivative of that body-frame velocity.
"""

from __future__ import annotations

import importlib.metadata
import os
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pinocchio as pin
import scipy.linalg

from ..core.closed_loop import AssemblyResult, ClosedLoopModel
from ..core.description import WORLD, ClosureSpec, LoopsSpec, build_model, read_text
from ..core.effects import spring_displacement
from ..errors import HexapodPinError, InputError

SOLO12_FEET = ("FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT")
SOLO12_JOINTS = tuple(f"{leg}_{j}" for leg in ("FL", "FR", "HL", "HR")
                      for j in ("HAA", "HFE", "KFE"))
#: Solo-12's motor torque limit (N m): 0.025 N m/A x 12 A x 9:1 gearing (open-dynamic-robot
#: -initiative figures). The URDF's effort="1000" is a placeholder.
SOLO12_TORQUE_LIMIT = 2.7
#: the "-op" joints of cassie_v2.sdf are the ones its Gazebo plugin drives (5 per leg)
CASSIE_ACTUATED = tuple(f"{side}-{j}-op" for side in ("left", "right")
                        for j in ("roll", "yaw", "pitch", "knee", "foot"))
FREE_FLYER_V = np.arange(6)


class RobotDataNotFoundError(HexapodPinError, FileNotFoundError):
    """The example-robot-data files cannot be found on this machine.

    Attributes:
        searched: the folders that were tried.
    """

    def __init__(self, what: str, searched: Sequence[str | os.PathLike[str]]) -> None:
        self.what = what
        self.searched = [str(s) for s in searched]
        super().__init__(f"cannot find {what}; searched: {', '.join(self.searched)}. "
                         "Install example-robot-data (pip install example-robot-data).")


# ------------------------------------------------------------------- data location
def example_robot_data_dir() -> Path:
    """The installed ``share/example-robot-data/robots`` folder (no network).

    Tried in order: the ``example_robot_data`` Python module's own path (when it is
    installed), the files of the ``example-robot-data`` distribution (the PyPI wheel
    installs them under ``cmeel.prefix``), ``sys.prefix``, and the prefixes in
    ``AMENT_PREFIX_PATH`` / ``CMAKE_PREFIX_PATH`` / ``ROS_PACKAGE_PATH``.

    Raises:
        RobotDataNotFoundError: none of them holds the robots.
    """
    candidates: list[Path] = []
    try:
        from example_robot_data.path import EXAMPLE_ROBOT_DATA_MODEL_DIR  # type: ignore

        candidates.append(Path(EXAMPLE_ROBOT_DATA_MODEL_DIR))
    except ImportError:  # the Python module is optional (the PyPI wheel has none)
        pass
    try:
        dist = importlib.metadata.distribution("example-robot-data")
        prefix = "cmeel.prefix/share/example-robot-data/robots"
        candidates.append(Path(str(dist.locate_file(prefix))))
        candidates.append(Path(str(dist.locate_file("share/example-robot-data/robots"))))
    except importlib.metadata.PackageNotFoundError:
        pass
    candidates.append(Path(sys.prefix) / "share" / "example-robot-data" / "robots")
    for var in ("AMENT_PREFIX_PATH", "CMAKE_PREFIX_PATH", "ROS_PACKAGE_PATH"):
        for prefix in os.environ.get(var, "").split(os.pathsep):
            if prefix:
                candidates.append(Path(prefix) / "share" / "example-robot-data" / "robots")
    for path in candidates:
        if (path / "solo_description").is_dir() or (path / "cassie_description").is_dir():
            return path
    raise RobotDataNotFoundError("example-robot-data's robots folder", candidates)


def package_dir() -> Path:
    """The ``share`` folder holding ``example-robot-data/``: pass it as a package dir to
    resolve ``package://example-robot-data/...`` mesh URIs (e.g. to draw Solo-12)."""
    return example_robot_data_dir().parent.parent


def robot_file(relative: str) -> Path:
    """A file under the example-robot-data robots folder, e.g.
    ``solo_description/robots/solo12.urdf``."""
    path = example_robot_data_dir() / relative
    if not path.is_file():
        raise RobotDataNotFoundError(relative, [path])
    return path


# ------------------------------------------------------------------------ Solo-12
def solo12_urdf_text() -> str:
    """Solo-12's URDF text (meshes as ``package://example-robot-data/...``, see
    :func:`package_dir`); the visual source for drawing :func:`solo12`."""
    return robot_file("solo_description/robots/solo12.urdf").read_text()


def solo12_tree() -> pin.Model:
    """Solo-12's tree with a free-flyer root (``root_joint``), from example-robot-data."""
    urdf = robot_file("solo_description/robots/solo12.urdf")
    model = build_model(read_text(urdf), source=str(urdf), root_joint=pin.JointModelFreeFlyer())
    srdf = example_robot_data_dir() / "solo_description" / "srdf" / "solo.srdf"
    if srdf.is_file():
        pin.loadReferenceConfigurations(model, str(srdf), False)
    return model


def solo12_reference_configuration(name: str = "standing") -> np.ndarray:
    """A configuration of the SRDF (``"standing"``, ``"straight_standing"``), shape (19,)."""
    model = solo12_tree()
    names = [entry.key() for entry in model.referenceConfigurations]
    if name not in names:
        raise InputError("name", name, f"not a Solo-12 reference configuration ({names})")
    return np.array(model.referenceConfigurations[name], dtype=float)


def solo12_default_foot_positions() -> np.ndarray:
    """Foot points (4, 3) in the world (m): the SRDF ``standing`` feet moved down to z = 0.

    Rows in :data:`SOLO12_FEET` order. The base of the ``standing`` configuration is
    then at ``z = 0.235 - 0.0191 = 0.2159`` m above the ground.
    """
    model = solo12_tree()
    data = model.createData()
    q = solo12_reference_configuration("standing")
    pin.framesForwardKinematics(model, data, q)
    feet = np.array([data.oMf[model.getFrameId(f)].translation for f in SOLO12_FEET])
    feet[:, 2] = 0.0
    return feet


def solo12(foot_positions: npt.ArrayLike | None = None) -> ClosedLoopModel:
    """Solo-12 standing: free-flyer base, four feet held at world points.

    Each foot frame (``FL_FOOT``, ...) is held by a 3-D point closure named
    ``<foot>_contact`` (``frame1`` = the foot, ``frame2`` = the world point). With
    the closure convention of :mod:`hexapod_pin.core.dynamics`, the closure multiplier of
    a foot is the force the ground exerts on that foot, world axes (N).

    Args:
        foot_positions: (4, 3) world points (m) in :data:`SOLO12_FEET` order;
            default :func:`solo12_default_foot_positions`.

    Returns:
        The model: nq = 19, nv = 18 (6 free-flyer + 12 joints), 12 closure rows,
        actuated = :data:`SOLO12_JOINTS` (the free-flyer is not actuated).
    """
    feet = (solo12_default_foot_positions() if foot_positions is None
            else np.asarray(foot_positions, dtype=float))
    if feet.shape != (4, 3) or not np.all(np.isfinite(feet)):
        raise InputError("foot_positions", foot_positions, "expected 4 x 3 finite numbers (m)")
    closures = tuple(ClosureSpec(f"{foot}_contact", "point", foot, WORLD, pin.SE3.Identity(),
                                 pin.SE3(np.eye(3), point))
                     for foot, point in zip(SOLO12_FEET, feet))
    return ClosedLoopModel(solo12_tree(), LoopsSpec(closures, SOLO12_JOINTS), name="solo12")


def base_configuration(position: npt.ArrayLike, rpy: npt.ArrayLike = (0.0, 0.0, 0.0)) -> np.ndarray:
    """Free-flyer part of ``q`` (7,) for a base at ``position`` (m) with ``R = Rz Ry Rx(rpy)``."""
    position = np.asarray(position, dtype=float)
    rpy = np.asarray(rpy, dtype=float)
    if position.shape != (3,) or rpy.shape != (3,):
        raise InputError("base pose", (position, rpy), "expected position (3,) and rpy (3,)")
    quat = pin.Quaternion(pin.rpy.rpyToMatrix(*rpy))
    return np.concatenate([position, quat.coeffs()])


def solo12_stand(clm: ClosedLoopModel, base_position: npt.ArrayLike,
                 base_rpy: npt.ArrayLike = (0.0, 0.0, 0.0),
                 q_guess: npt.ArrayLike | None = None) -> AssemblyResult:
    """Assemble Solo-12 with its base at a given pose and its feet on their points.

    The base pose (the 6 free-flyer velocity coordinates) is held; the 12 leg
    joints are solved by the generic Gauss-Newton assembly.

    Args:
        clm: the model from :func:`solo12`.
        base_position: base origin in the world (3,) (m).
        base_rpy: base orientation (roll, pitch, yaw) (rad), ``R = Rz Ry Rx``.
        q_guess: starting configuration (19,); default the SRDF ``standing`` legs
            (it picks the knee-backward / knee-forward branch of each leg).

    Raises:
        AssemblyError: a foot out of reach of its leg for that base pose.
    """
    q0 = (solo12_reference_configuration("standing") if q_guess is None
          else clm.check_q(q_guess, "q_guess").copy())
    q0[:7] = base_configuration(base_position, base_rpy)
    return clm.assemble(q0, fixed=FREE_FLYER_V)


def motion_with_base(clm: ClosedLoopModel, q: npt.ArrayLike, v_base: npt.ArrayLike,
                     a_base: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Tree velocity and acceleration keeping every closure, given the base motion.

    Args:
        clm: a model with a free-flyer first joint (e.g. :func:`solo12`).
        q: an assembled configuration (nq,).
        v_base: base velocity (6,), body frame (m/s, rad/s), Pinocchio convention.
        a_base: base acceleration (6,), derivative of the body-frame velocity.

    Returns:
        (v, a), each (nv,), with ``J_c v = 0`` and ``J_c a = -gamma(q, v)``; the leg
        joint rates are the least-squares (here unique) completion.
    """
    v = clm.complete_velocity(q, FREE_FLYER_V, v_base)
    a = clm.complete_acceleration(q, v, FREE_FLYER_V, a_base)
    return v, a


# ------------------------------------------------------------------------ Cassie
def cassie_sdf_path(name: str = "cassie_v2.sdf") -> Path:
    """Path of a Cassie SDF of example-robot-data (``cassie_v2.sdf`` by default)."""
    return robot_file(f"cassie_description/robots/{name}")


#: angles within this of a multiple of pi/2 are snapped when Cassie's SDF is read (its
#: files write pi/2 as 1.5708)
CASSIE_SNAP_ANGLES = 1e-4


def cassie(root: str = "fixed", sdf_name: str = "cassie_v2.sdf",
           snap_angles: float = CASSIE_SNAP_ANGLES, via_urdf: bool = False) -> ClosedLoopModel:
    """Cassie with its four rod loops closed, from example-robot-data's SDF.

    The SDF's loop joints are the ball joints ``{side}-pitch-rod-joint`` (achilles
    rod on the hip-pitch link) and ``{side}-plantar-foot-joint`` (plantar rod on the
    foot); each becomes a 3-D point closure named as the joint. The tree keeps the
    other 22 revolute joints. The plantar-rod loop is planar (its three revolute
    axes are parallel), so one of its three rows is redundant: exactly on the left
    leg, to ~1e-12 on the right leg, whose SDF poses mix pitch angles 1.3439 and
    1.364 with a roll of 1.5708 (not pi/2).

    Args:
        root: ``"fixed"`` (pelvis fixed at its SDF pose, 1.01 m up: the robot hangs)
            or ``"free_flyer"`` (``root_joint``; ``pin.neutral`` puts the pelvis at
            the world origin).
        sdf_name: which SDF of ``cassie_description/robots``.
        snap_angles: passed to :func:`hexapod_pin.loaders.sdf.load_sdf` (0: as written).
        via_urdf: build the tree from :func:`cassie_urdf`'s URDF with Pinocchio's URDF
            parser instead of directly (``root="fixed"`` only). Same mechanism;
            the link frames are then the URDF's (each link's frame is its joint's
            frame), which is what the URDF visuals are placed in: use this model,
            with ``urdf=cassie_urdf()[0]``, to draw Cassie. Pinocchio's URDF parser
            may order sibling subtrees differently: index ``q`` by joint name.

    Returns:
        The model; actuated = :data:`CASSIE_ACTUATED` (hip roll, yaw, pitch, knee and
        foot of each leg). The knee-shin and tarsus (heel) spring joints are passive.
        Its effects (``clm.effects``) are the SDF's joint dynamics: damping, and the
        springs of the knee-shin and heel joints (see :func:`cassie_spring_torques`),
        which every route applies.
    """
    from .sdf import build_tree, load_sdf

    if root not in ("fixed", "free_flyer"):
        raise InputError("root", root, "expected 'fixed' or 'free_flyer'")
    if via_urdf:
        if root != "fixed":
            raise InputError("root", root, "via_urdf supports root='fixed' only")
        urdf, loops = cassie_urdf(sdf_name, snap_angles)
        return ClosedLoopModel(build_model(urdf, source=f"cassie ({sdf_name}) via URDF"), loops,
                               name=f"cassie ({sdf_name}, fixed, via URDF)")
    sdf = load_sdf(cassie_sdf_path(sdf_name), snap_angles=snap_angles)
    tree = build_tree(sdf, root_joint=pin.JointModelFreeFlyer() if root == "free_flyer" else None,
                      actuated=CASSIE_ACTUATED)
    return ClosedLoopModel(tree.model, tree.loops, name=f"cassie ({sdf_name}, {root})")


def cassie_urdf(sdf_name: str = "cassie_v2.sdf",
                snap_angles: float = CASSIE_SNAP_ANGLES) -> tuple[str, LoopsSpec]:
    """Cassie's tree as URDF text (fixed pelvis) and its loops, via
    :func:`hexapod_pin.loaders.sdf.sdf_to_urdf`; mesh file names are resolved to the installed
    STL files. The URDF's ``<dynamics>`` carry the damping, the loops' ``effects`` the
    springs. Build the model to draw with ``cassie(via_urdf=True)``."""
    from .sdf import load_sdf, resolve_uri, sdf_to_urdf

    sdf = load_sdf(cassie_sdf_path(sdf_name), snap_angles=snap_angles)
    urdf, loops = sdf_to_urdf(sdf, mesh_resolver=lambda uri: resolve_uri(
        uri, sdf.base_dir, search=[package_dir()]) or uri)
    return urdf, LoopsSpec(loops.closures, CASSIE_ACTUATED, effects=loops.effects)


def cassie_spring_torques(clm: ClosedLoopModel, q: npt.ArrayLike) -> np.ndarray:
    """Generalised forces (nv,) of the model's joint springs (``clm.effects``):
    ``-stiffness * pin.difference(spring_reference, q)`` (N m), read from the SDF's
    ``<spring_stiffness>`` / ``<spring_reference>`` by :func:`cassie`.

    Zero on every joint without a spring (in ``cassie_v2.sdf``: springs on the knee-shin
    joints, 1500 N m/rad, and the heel joints, 1250 N m/rad, relaxed at 0). Every route
    already applies them (they are part of ``clm.effects``): this is what they contribute,
    for reports and checks, not a force to add to ``tau``.

    Raises:
        InputError: a ``q`` of the wrong shape or not finite.
    """
    q = clm.check_q(q)
    effects = clm.effects
    return -effects.stiffness * spring_displacement(clm.model, effects, q)


# ------------------------------------------------------------------ actuation report
@dataclass(frozen=True)
class ActuationReport:
    """Mobility and actuation of a closed-loop model at a configuration.

    With ``N`` a basis of the null space of ``J_c`` (the closure-consistent
    velocities) and ``S`` the selection of the actuated velocity coordinates:

    Attributes:
        nv: velocity DoF of the tree.
        n_rows: closure rows.
        rank: rank of ``J_c``.
        redundant_rows: ``n_rows - rank`` (closure rows implied by the others).
        mobility: DoF of the closed mechanism, ``nv - rank``.
        n_actuated: actuated joints.
        controlled: closed-mechanism DoF the actuators drive, ``rank(S N)``.
        unactuated_mobility: DoF left when the actuators are locked,
            ``mobility - controlled = nv - rank([J_c; S])``.
        actuation_redundancy: ``n_actuated - controlled``: the dimension of the
            actuator forces (with the multipliers) that move nothing (internal loads).
        status: ``"under-actuated"`` when ``unactuated_mobility > 0``, else
            ``"redundant"`` when ``actuation_redundancy > 0``, else ``"square"``.
        tolerance: the relative singular-value threshold used for every rank.
    """

    nv: int
    n_rows: int
    rank: int
    redundant_rows: int
    mobility: int
    n_actuated: int
    controlled: int
    unactuated_mobility: int
    actuation_redundancy: int
    status: str
    tolerance: float

    @property
    def sufficient(self) -> bool:
        """True when the actuators determine the motion (square or redundant)."""
        return self.unactuated_mobility == 0


def actuation_report(clm: ClosedLoopModel, q: npt.ArrayLike, rtol: float = 1e-9) -> ActuationReport:
    """Mobility (``nv - rank J_c``), actuated DoF and actuation sufficiency at ``q``.

    Args:
        clm: any closed-loop model.
        q: configuration (nq,), normally assembled (the report is first-order).
        rtol: singular values below ``rtol * max(1, sigma_max)`` count as zero. The
            default 1e-9 treats rows that are redundant up to the rounding of a
            description file (Cassie's SDF, ~1e-12) as redundant.

    Returns:
        :class:`ActuationReport`.
    """
    if not (np.isfinite(rtol) and 0 < rtol < 1):
        raise InputError("rtol", rtol, "expected 0 < rtol < 1")
    jac = clm.constraint_jacobian(q)
    nv = clm.nv
    rank = _rank(jac, rtol)
    if clm.n_rows:
        null = scipy.linalg.null_space(jac, rcond=rtol)
    else:
        null = np.eye(nv)
    # null_space uses rcond relative to sigma_max; keep its size consistent with rank
    if null.shape[1] != nv - rank:
        _, _, vt = np.linalg.svd(jac)
        null = vt[rank:].T
    sel = np.zeros((clm.n_actuated, nv))
    sel[np.arange(clm.n_actuated), clm.actuated_v] = 1.0
    controlled = _rank(sel @ null, rtol) if null.size and clm.n_actuated else 0
    mobility = nv - rank
    unactuated = mobility - controlled
    redundancy = clm.n_actuated - controlled
    status = "under-actuated" if unactuated > 0 else ("redundant" if redundancy > 0
                                                       else "square")
    return ActuationReport(nv, clm.n_rows, rank, clm.n_rows - rank, mobility, clm.n_actuated,
                           controlled, unactuated, redundancy, status, rtol)


def _rank(mat: np.ndarray, rtol: float) -> int:
    if mat.size == 0:
        return 0
    sv = np.linalg.svd(mat, compute_uv=False)
    return int(np.sum(sv > rtol * max(1.0, sv[0])))
