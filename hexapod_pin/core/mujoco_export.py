"""MuJoCo export of any closed-loop model: the same tree as MJCF, closures as equalities.

:func:`closed_loop_mjcf` writes the MJCF text of a
:class:`~hexapod_pin.core.closed_loop.ClosedLoopModel`; :func:`to_mujoco` compiles it
(``mujoco`` is optional: the ``bench`` / ``test`` extras install it);
:func:`mujoco_state` and :func:`velocity_map` convert states and matrices.

Conventions of the export:

* one ``<body>`` per Pinocchio joint, nested as the tree, at the joint's placement in its
  parent (``model.jointPlacements``), named after the joint; bodies fixed to a joint are
  already merged into its inertia by Pinocchio (``model.inertias``: mass, centre of mass
  and the inertia about it in the joint frame, written as ``<inertial fullinertia>``);
* joints: 1-DoF revolute / prismatic (about a frame axis or an unaligned axis) as
  ``hinge`` / ``slide``, spherical as ``ball``, a free flyer (a child of the world with an
  identity placement) as ``freejoint``; other joint types raise
  :class:`~hexapod_pin.errors.InputError`. Pinocchio's joints are in depth-first order
  and the bodies are written in that order, so each joint has the same ``idx_q`` /
  ``idx_v`` in both. The coordinates differ in two places (:func:`mujoco_state` and
  :func:`velocity_map` convert): quaternions are ``(x, y, z, w)`` in Pinocchio and
  ``(w, x, y, z)`` in MuJoCo, and a free flyer's linear velocity is in the body frame
  in Pinocchio (``v_lin = R^T p'``) and in the world frame in MuJoCo (``p'``); angular
  velocities are in the body frame in both. With ``qvel = T v`` (:func:`velocity_map`),
  ``M_mj = T^-T M T^-1`` and generalised forces map as ``tau = T^T qfrc``;
* every closure anchor is a ``<site>`` (``<closure>__anchor1`` / ``__anchor2``) on its
  body; a point closure becomes ``<connect site1 site2>``, a weld ``<weld site1 site2>``
  (site frames kept coincident), both with the stiffest impedance MuJoCo allows
  (``solimp = 0.9999 0.9999 0.001 0.5 2``) and ``solref = (2 timestep, 1)``; a joint
  coupling (``clm.couplings``) becomes ``<joint joint1 joint2 polycoef>`` (the exported
  joints have no ``ref``: MuJoCo's ``qpos0`` is zero and its polynomial is ours);
* the joint and drive effects (``clm.effects``, :mod:`~hexapod_pin.core.effects`) are the
  joints' ``armature``, ``damping``, ``frictionloss`` (Coulomb friction), ``stiffness``
  and ``springref`` (the spring reference; MuJoCo's ``qpos_spring``); a ball joint takes
  one value per effect (equal on its three coordinates) and a spring relaxed at the
  identity; a free flyer takes none (MuJoCo's free-joint damping and friction act on the
  world-frame velocity, Pinocchio's on the body frame); otherwise
  :class:`~hexapod_pin.errors.InputError`. MuJoCo's friction loss is a soft constraint of
  its forward dynamics (not in ``qfrc_passive``; ``mjDSBL_FRICTIONLOSS`` turns it off);
  ``qfrc_passive`` is :func:`~hexapod_pin.core.effects.passive_forces`;
* contacts are disabled; no joint limits; gravity is Pinocchio's ``model.gravity``;
* padding: MuJoCo refuses a moving body whose mass or any principal moment of inertia is
  below ``mjMINVAL`` (1e-15): point masses (the hexapod's carriages, the planar robot's
  sliders), thin rods (zero axial inertia) and the massless bodies between the joints of
  a universal or planar chain. As the benchmark generators do (``benchmarks/mjcf.py``),
  a mass below ``tiny_inertia`` (kg; default 1e-12) is raised to it and each principal
  moment below ``tiny_inertia`` (kg m^2) is raised to it about the same principal axis;
  nothing else changes (a body that needs no padding is written exactly). Effect on the
  mass matrix: ``dM = sum_b (dm_b Jc_b^T Jc_b + Jw_b^T dI_b Jw_b)`` (``Jc_b``, ``Jw_b``:
  the body's centre-of-mass linear and angular Jacobians), with ``0 <= dm_b <= tiny`` and
  ``0 <= dI_b <= tiny``, so ``||dM||_2 <= tiny_inertia sum_b (||Jc_b||^2 + ||Jw_b||^2)``
  (of order ``tiny_inertia (n_bodies + sum of squared lever arms in m)``). Measured (export
  at ``tiny_inertia`` and at 1000 times it, ``tests/core/test_mujoco_export_reliability.py``):
  ``max |dM| / max |M|`` = 7e-13 on the built-in hexapod, 2e-12 on the planar robot,
  1.5e-11 on the delta of ``tests/data``, 0 on robots whose every body has a mass and a
  full inertia (the four-bar, five-bars and Stewart platform of ``tests/data``, Solo-12,
  Cassie);
* names (model, joints, closures, frames) are XML-escaped; a name with characters XML
  cannot carry (control characters) is refused;
* one ``<motor>`` per actuated joint, in ``clm.actuated_joints`` order, with the
  effects' ``gear``: ``ctrl`` is the motor torque, ``u / gear`` for the actuator force
  ``u`` of :func:`~hexapod_pin.core.dynamics.inverse_dynamics_tree`; a finite
  ``effort_limit`` becomes ``ctrlrange`` and ``forcerange`` ``+-effort_limit / |gear|``
  (MuJoCo limits the motor side), else the motor is unlimited.

MuJoCo's equality constraints are soft (regularised); its forward dynamics therefore
differs from the rigid one by the regulariser (relative ~1e-4 of the smallest
eigenvalue of ``J M^-1 J^T``). The mass matrix and the inverse dynamics reduced to the
actuators (``mj_inverse`` without equalities, projected on the null space of MuJoCo's
constraint Jacobian) are exact and agree with this library's to rounding.
"""

from __future__ import annotations

import math
import numbers
import re
from typing import Any, NamedTuple
from xml.sax.saxutils import escape

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..errors import InputError, MissingDependencyError
from .checks import real_number
from .closed_loop import ClosedLoopModel

#: inertia (kg, kg m^2) given to bodies that have none (MuJoCo needs > mjMINVAL = 1e-15)
TINY_INERTIA = 1e-12
#: impedance pinned at mujoco.mjMAXIMP (0.9999): the stiffest soft constraint
STIFF_SOLIMP = (0.9999, 0.9999, 0.001, 0.5, 2.0)
#: MuJoCo's mjMINVAL (masses and principal inertias below it are refused) and its
#: impedance range [mjMINIMP, mjMAXIMP] (solimp values outside are clipped silently)
_MJ_MINVAL, _MJ_MINIMP, _MJ_MAXIMP = 1e-15, 1e-4, 0.9999
#: characters XML 1.0 cannot carry, even escaped
_NOT_XML = re.compile("[\x00-\x08\x0b\x0c\x0e-\x1f\ufffe\uffff]")

_AXES = {"X": (1.0, 0.0, 0.0), "Y": (0.0, 1.0, 0.0), "Z": (0.0, 0.0, 1.0)}


def _f(x: float) -> str:
    return repr(float(x))


def _vec(values) -> str:
    return " ".join(_f(v) for v in values)


def _pose(placement: pin.SE3) -> str:
    quat = pin.Quaternion(placement.rotation)             # (x, y, z, w)
    return (f'pos="{_vec(placement.translation)}" '
            f'quat="{_vec((quat.w, quat.x, quat.y, quat.z))}"')


def _name(text: str, what: str) -> str:
    """``text`` escaped for an XML attribute value in double quotes.

    Raises:
        InputError: a character XML cannot carry (``what`` names the object).
    """
    if _NOT_XML.search(text):
        raise InputError(what, text, "a name MJCF can carry (no control characters)")
    return escape(text, {'"': "&quot;"})


def _site_name(frame_name: str) -> str:
    return _name(frame_name.replace("/", "__"), "frame name")


def _joint_kind(jmodel, name: str, parent: int,
                placement: pin.SE3) -> tuple[str, tuple[float, ...] | None]:
    """The MJCF joint type of a Pinocchio joint and its axis (None for free and ball)."""
    short = jmodel.shortname()
    if short == "JointModelFreeFlyer":
        if parent != 0 or not placement.isIdentity():
            raise InputError("clm", name, "the MuJoCo export supports a free flyer only as a "
                                          "child of the world with an identity placement")
        return "free", None
    if short == "JointModelSpherical":
        return "ball", None
    if short.startswith("JointModelR") and short[-1] in _AXES and len(short) == 12:
        kind, axis = "hinge", _AXES[short[-1]]
    elif short.startswith("JointModelP") and short[-1] in _AXES and len(short) == 12:
        kind, axis = "slide", _AXES[short[-1]]
    elif short == "JointModelRevoluteUnaligned":
        kind, axis = "hinge", tuple(jmodel.extract().axis)
    elif short == "JointModelPrismaticUnaligned":
        kind, axis = "slide", tuple(jmodel.extract().axis)
    else:
        raise InputError("clm", short, f"joint {name!r}: the MuJoCo export supports 1-DoF "
                                       "revolute and prismatic, spherical and free-flyer "
                                       "joints only")
    return kind, axis


def _joint_xml(clm: ClosedLoopModel, jid: int) -> str:
    """The ``<joint>`` (or ``<freejoint>``) element of joint ``jid``, with its effects."""
    model = clm.model
    name = model.names[jid]
    kind, axis = _joint_kind(model.joints[jid], name, model.parents[jid],
                             model.jointPlacements[jid])
    effects = _effects_xml(clm, jid, kind)
    if kind == "free":
        return f'<freejoint name="{_name(name, "joint name")}"/>'
    attributes = [f'name="{_name(name, "joint name")}"', f'type="{kind}"']
    attributes += [f'axis="{_vec(axis)}"'] if axis is not None else []
    attributes += [effects] if effects else []
    return f"<joint {' '.join(attributes)}/>"


def _effects_xml(clm: ClosedLoopModel, jid: int, kind: str) -> str:
    """The effect attributes of joint ``jid`` (``kind``: its MJCF type), "" when it has none.

    Raises:
        InputError: effects a MuJoCo joint of that kind cannot carry (see the module
            docstring).
    """
    model, effects = clm.model, clm.effects
    name, jm = model.names[jid], model.joints[jid]
    coords = slice(jm.idx_v, jm.idx_v + jm.nv)
    values = {attribute: getattr(effects, field)[coords] for attribute, field in
              (("armature", "armature"), ("damping", "damping"),
               ("frictionloss", "coulomb"), ("stiffness", "stiffness"))}
    if kind == "free":
        if any(v.any() for v in values.values()):
            raise InputError("clm.effects", name, "the MuJoCo export carries no joint effects "
                                                  "on a free flyer")
        return ""
    out = []
    for attribute, value in values.items():
        if np.any(value != value[0]):
            raise InputError("clm.effects", name, f"a MuJoCo {kind} joint takes one "
                                                  f"{attribute}, got {value.tolist()}")
        if value[0]:
            out.append(f'{attribute}="{_f(value[0])}"')
    reference = effects.spring_reference[jm.idx_q:jm.idx_q + jm.nq]
    if kind == "ball":
        relaxed = np.max(np.abs(pin.difference(model, pin.neutral(model),
                                               effects.spring_reference)[coords]))
        if values["stiffness"][0] and relaxed > 1e-12:
            raise InputError("clm.effects", name, "a MuJoCo ball joint's spring is relaxed "
                                                  "at the identity only")
    elif reference[0]:
        out.append(f'springref="{_f(reference[0])}"')
    return " ".join(out)


def _motor_xml(joint: str, gear: float, limit: float) -> str:
    """The ``<motor>`` of an actuated joint: its gear, its motor-side limit when finite."""
    escaped = _name(joint, "joint name")
    attributes = f'name="{escaped}" joint="{escaped}" gear="{_f(gear)}"'
    if np.isfinite(limit):
        bound = _f(limit / abs(gear))
        attributes += (f' ctrllimited="true" ctrlrange="-{bound} {bound}" forcelimited="true" '
                       f'forcerange="-{bound} {bound}"')
    return f"<motor {attributes}/>"


def _padded_inertia(inertia: pin.Inertia, tiny: float, body: str
                    ) -> tuple[float, np.ndarray]:
    """Mass (kg) and rotational inertia about the centre of mass (kg m^2) of a body as
    exported: a mass below ``tiny`` raised to it, each principal moment below ``tiny``
    raised to it about its own axis (the module docstring bounds the effect).

    Raises:
        InputError: an inertia with a negative principal moment beyond round-off.
    """
    mass = float(inertia.mass)
    rot = np.asarray(inertia.inertia, dtype=float)
    rot = 0.5 * (rot + rot.T)
    moments, axes = np.linalg.eigh(rot)
    if moments[0] < -1e-12 * max(abs(moments[-1]), tiny):
        raise InputError("clm", body, f"body {body!r}: the inertia has a negative principal "
                                      f"moment {moments[0]:.3e} kg m^2")
    pad = np.maximum(tiny - moments, 0.0)
    if pad.any():                                 # exact (unchanged) when nothing is padded
        rot = rot + (axes * pad) @ axes.T
    return max(mass, tiny), rot


def _inertial_xml(inertia: pin.Inertia, tiny: float, body: str) -> str:
    mass, rot = _padded_inertia(inertia, tiny, body)
    full = (rot[0, 0], rot[1, 1], rot[2, 2], rot[0, 1], rot[0, 2], rot[1, 2])
    return (f'<inertial pos="{_vec(inertia.lever)}" mass="{_f(mass)}" '
            f'fullinertia="{_vec(full)}"/>')


def _reals(value: Any, name: str, sizes: tuple[int, ...]) -> tuple[float, ...]:
    """A tuple of finite real numbers of one of the ``sizes``.

    Raises:
        InputError: not a sequence of that many real, finite numbers (bools refused).
    """
    expected = f"expected {' or '.join(map(str, sizes))} finite real numbers"
    if isinstance(value, (str, bytes)) or not hasattr(value, "__len__") \
            or len(value) not in sizes:
        raise InputError(name, value, expected)
    if any(isinstance(x, (bool, np.bool_)) or not isinstance(x, numbers.Real)
           or not math.isfinite(x) for x in value):
        raise InputError(name, value, expected)
    return tuple(float(x) for x in value)


def _check_solimp(solimp: Any) -> tuple[float, ...]:
    """MuJoCo's ``(dmin, dmax, width[, midpoint, power])``, in the ranges MuJoCo keeps
    (it clips values outside them without a word).

    Raises:
        InputError: see :func:`closed_loop_mjcf`.
    """
    values = _reals(solimp, "solimp", (3, 5))
    span = f"in [{_MJ_MINIMP:g}, {_MJ_MAXIMP:g}] (MuJoCo clips it there)"
    for k, part in ((0, "dmin"), (1, "dmax")) + (((3, "midpoint"),) if len(values) == 5
                                                  else ()):
        if not _MJ_MINIMP <= values[k] <= _MJ_MAXIMP:
            raise InputError("solimp", solimp, f"{part} = {values[k]:g} must be {span}")
    if values[2] <= 0.0:
        raise InputError("solimp", solimp, f"width = {values[2]:g} must be > 0")
    if len(values) == 5 and values[4] < 1.0:
        raise InputError("solimp", solimp, f"power = {values[4]:g} must be >= 1")
    return values


def _check_solref(solref: Any, timestep: float) -> tuple[float, ...]:
    """MuJoCo's ``(timeconst, dampratio)`` (both > 0 / >= 0) or ``(-stiffness, -damping)``
    (both < 0 / <= 0); a time constant below ``2 timestep`` refused (MuJoCo would raise
    it to that without a word).

    Raises:
        InputError: see :func:`closed_loop_mjcf`.
    """
    values = _reals(solref, "solref", (2,))
    first, second = values
    if first > 0.0 and second >= 0.0:
        if first < 2.0 * timestep * (1.0 - 1e-12):
            raise InputError("solref", solref, f"the time constant must be >= 2 timestep = "
                                               f"{2.0 * timestep:g} s (MuJoCo raises a "
                                               "smaller one to that)")
        return values
    if first < 0.0 and second <= 0.0:
        return values
    raise InputError("solref", solref, "expected (timeconst > 0, dampratio >= 0) or "
                                       "(-stiffness < 0, -damping <= 0)")


def closed_loop_mjcf(clm: ClosedLoopModel, timestep: float = 1e-3,
                     tiny_inertia: float = TINY_INERTIA,
                     solimp: tuple[float, ...] = STIFF_SOLIMP,
                     solref: tuple[float, float] | None = None) -> str:
    """MJCF text of ``clm`` (conventions in the module docstring).

    Args:
        clm: the closed-loop model.
        timestep: MuJoCo time step (s).
        tiny_inertia: mass (kg) and inertia (kg m^2) of bodies that have none.
        solimp: impedance of the closure equalities.
        solref: ``(timeconst, dampratio)`` of the closures; default ``(2 timestep, 1)``.

    Returns:
        The MJCF document (str).

    Raises:
        InputError: a joint type the export does not support, joint effects MuJoCo cannot
            carry (on a free flyer; unequal on a ball joint's coordinates; a ball spring not
            relaxed at the identity), a name XML cannot carry, a body inertia with a
            negative principal moment, or a bad option: ``timestep`` not a finite number
            > 0; ``tiny_inertia`` not a finite number > 1e-15 (MuJoCo's ``mjMINVAL``);
            ``solimp`` not 3 or 5 finite numbers with ``dmin``, ``dmax`` (and
            ``midpoint``) in [1e-4, 0.9999], ``width > 0`` and ``power >= 1``; ``solref``
            not 2 finite numbers ``(timeconst >= 2 timestep, dampratio >= 0)`` or
            ``(-stiffness < 0, -damping <= 0)``.
    """
    if not isinstance(clm, ClosedLoopModel):
        raise InputError("clm", clm, "expected a ClosedLoopModel")
    timestep = real_number(timestep, "timestep", minimum=0.0)
    tiny_inertia = real_number(tiny_inertia, "tiny_inertia", minimum=_MJ_MINVAL)
    solimp = _check_solimp(solimp)
    solref = (2.0 * timestep, 1.0) if solref is None else _check_solref(solref, timestep)
    model = clm.model
    sites: dict[int, list[str]] = {}
    for closure in clm.closures:
        for tag in ("anchor1", "anchor2"):
            frame = model.frames[model.getFrameId(f"{closure.name}/{tag}")]
            sites.setdefault(frame.parentJoint, []).append(
                f'<site name="{_site_name(frame.name)}" {_pose(frame.placement)}/>')
    children: dict[int, list[int]] = {}
    for jid in range(1, model.njoints):
        children.setdefault(model.parents[jid], []).append(jid)

    def body(jid: int, indent: str) -> list[str]:
        name, placement = model.names[jid], model.jointPlacements[jid]
        lines = [f'{indent}<body name="{_name(name, "joint name")}" {_pose(placement)}>',
                 f"{indent}  {_joint_xml(clm, jid)}",
                 f"{indent}  {_inertial_xml(model.inertias[jid], tiny_inertia, name)}"]
        lines += [f"{indent}  {site}" for site in sites.get(jid, [])]
        for child in children.get(jid, []):
            lines += body(child, indent + "  ")
        lines.append(f"{indent}</body>")
        return lines

    gravity = np.asarray(model.gravity.linear)
    lines = [
        f'<mujoco model="{_name(str(clm.name), "clm.name")}">',
        ('  <compiler angle="radian" autolimits="true" inertiafromgeom="false" '
        'balanceinertia="false"/>'),
        (f'  <option timestep="{_f(timestep)}" gravity="{_vec(gravity)}" integrator="Euler" '
        'solver="Newton" tolerance="1e-15" iterations="100" jacobian="dense">'
        '<flag contact="disable"/></option>'),
        '  <default><joint damping="0" armature="0" frictionloss="0" limited="false"/>',
        f'    <equality solref="{_vec(solref)}" solimp="{_vec(solimp)}"/>',
        '    <motor ctrllimited="false" forcelimited="false" gear="1"/></default>',
        '  <worldbody>',
    ]
    lines += [f"    {site}" for site in sites.get(0, [])]
    for child in children.get(0, []):
        lines += body(child, "    ")
    lines += ["  </worldbody>", "  <equality>"]
    for closure in clm.closures:
        kind = "connect" if closure.type == "point" else "weld"
        lines.append(f'    <{kind} name="{_name(closure.name, "closure name")}" '
                     f'site1="{_site_name(closure.name + "/anchor1")}" '
                     f'site2="{_site_name(closure.name + "/anchor2")}"/>')
    for coupling in clm.couplings:     # the joints have no ref: qpos0 = 0, absolute polycoef
        second = ("" if coupling.joint2 is None
                  else f'joint2="{_name(coupling.joint2, "joint name")}" ')
        lines.append(f'    <joint name="{_name(coupling.name, "coupling name")}" '
                     f'joint1="{_name(coupling.joint1, "joint name")}" {second}'
                     f'polycoef="{_vec(coupling.polycoef)}"/>')
    lines += ["  </equality>", "  <actuator>"]
    effects = clm.effects
    lines += [f"    {_motor_xml(j, effects.gear[k], effects.effort_limit[k])}"
              for k, j in enumerate(clm.actuated_joints)]
    lines += ["  </actuator>", "</mujoco>"]
    return "\n".join(lines) + "\n"


def to_mujoco(clm: ClosedLoopModel, **options: Any) -> Any:
    """Compile :func:`closed_loop_mjcf` into a ``mujoco.MjModel`` (same options).

    Raises:
        MissingDependencyError: ``mujoco`` is not installed (extra ``bench``).
        InputError: see :func:`closed_loop_mjcf`; also an actuated joint that is not
            1-DoF, or a model MuJoCo's compiler refuses (its message quoted: e.g. two
            names that coincide once a frame's ``/`` is written ``__``).
    """
    try:
        import mujoco
    except ImportError:
        raise MissingDependencyError("mujoco", "bench") from None
    text = closed_loop_mjcf(clm, **options)
    for name in clm.actuated_joints:
        if clm.model.joints[clm.model.getJointId(name)].nv != 1:
            raise InputError("clm", name, "the MuJoCo export actuates 1-DoF joints only")
    try:
        return mujoco.MjModel.from_xml_string(text)
    except ValueError as error:
        raise InputError("clm", clm.name, f"MuJoCo refused the export: {error}") from None


class MujocoState(NamedTuple):
    """MuJoCo coordinates of a Pinocchio state (see the module docstring).

    Attributes:
        qpos: (nq,) positions, quaternions ``(w, x, y, z)``.
        qvel: (nv,) velocities, free-flyer linear velocity in the world frame (m/s).
        qacc: (nv,) accelerations (their time derivative), or None when ``a`` was not given.
    """

    qpos: np.ndarray
    qvel: np.ndarray
    qacc: np.ndarray | None


def _quaternion_joints(model: pin.Model):
    """(idx_q, idx_v, is_free) of the free-flyer and spherical joints."""
    out = []
    for jid in range(1, model.njoints):
        short = model.joints[jid].shortname()
        if short in ("JointModelFreeFlyer", "JointModelSpherical"):
            out.append((model.idx_qs[jid], model.idx_vs[jid], short == "JointModelFreeFlyer"))
    return out


def mujoco_state(clm: ClosedLoopModel, q: npt.ArrayLike, v: npt.ArrayLike | None = None,
                 a: npt.ArrayLike | None = None) -> MujocoState:
    """MuJoCo's ``qpos`` / ``qvel`` / ``qacc`` for Pinocchio's ``q``, ``v``, ``a`` of ``clm``.

    Equal entry by entry on 1-DoF joints; quaternions reordered from ``(x, y, z, w)`` to
    ``(w, x, y, z)``; a free flyer's linear velocity ``p' = R v_lin`` and acceleration
    ``p'' = R (a_lin + omega x v_lin)`` (Pinocchio's ``a`` is the derivative of the
    body-frame velocity); angular parts unchanged (body frame in both).

    Args:
        clm: the closed-loop model.
        q: configuration (nq,).
        v: velocity (nv,), optional (zero when None).
        a: acceleration (nv,), optional (``qacc`` None when None).

    Raises:
        InputError: bad shapes or non-finite values.
    """
    q = clm.check_q(q)
    v = np.zeros(clm.nv) if v is None else clm.check_v(v)
    qpos, qvel = q.copy(), v.copy()
    acc = None if a is None else clm.check_v(a)
    qacc = None if acc is None else acc.copy()
    for iq, iv, free in _quaternion_joints(clm.model):
        quat = q[iq + 3:iq + 7] if free else q[iq:iq + 4]
        at = iq + 3 if free else iq
        qpos[at] = quat[3]
        qpos[at + 1:at + 4] = quat[:3]
        if free:
            rot = pin.Quaternion(quat).normalized().matrix()
            lin, ang = v[iv:iv + 3], v[iv + 3:iv + 6]
            qvel[iv:iv + 3] = rot @ lin
            if qacc is not None and acc is not None:
                qacc[iv:iv + 3] = rot @ (acc[iv:iv + 3] + np.cross(ang, lin))
    return MujocoState(qpos, qvel, qacc)


def velocity_map(clm: ClosedLoopModel, q: npt.ArrayLike) -> np.ndarray:
    """``T`` (nv, nv) with MuJoCo's ``qvel = T v`` at ``q``: identity but for each free
    flyer's linear block, the rotation ``R`` of its quaternion. Hence ``M_mj = T^-T M
    T^-1``, a constraint Jacobian ``J_mj = J T^-1`` and generalised forces
    ``tau = T^T qfrc`` (same power).

    Raises:
        InputError: bad shape or non-finite ``q``.
    """
    q = clm.check_q(q)
    out = np.eye(clm.nv)
    for iq, iv, free in _quaternion_joints(clm.model):
        if free:
            out[iv:iv + 3, iv:iv + 3] = pin.Quaternion(q[iq + 3:iq + 7]).normalized().matrix()
    return out
