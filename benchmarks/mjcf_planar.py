"""The planar 3-PRR in MuJoCo, generated as MJCF from a ``PlanarGeometry``.

The MJCF is the same tree as ``urdf/planar_3prr.urdf.xacro`` (the tree that
``hexapod_pin.planar.robot.Planar3PRR`` loads), with the same joint names:

* per rail k a body ``slider_k`` at the rail midpoint ``m_k``, rotated ``a_k + 90 deg``
  about z (x along ``u_k``), with a ``slide`` joint ``slider_k`` on x (actuated, one
  ``motor`` of gear 1); in it a body ``link_k`` with a ``hinge`` ``link_k_joint`` about z
  (angle measured from ``u_k``), the rod along its local x, site ``link_k_tip`` at
  ``(L, 0, 0)``;
* a body ``platform`` carrying three joints, applied in order as MuJoCo composes the joints
  of a body: ``slide`` ``platform_x`` (world x), ``slide`` ``platform_y`` (world y),
  ``hinge`` ``platform_theta`` (z): its qpos and qvel ARE the pose ``(x, y, theta)`` and
  the twist ``(vx, vy, omega)`` (world axes), as in Pinocchio; sites ``platform_anchor_k``
  at the platform points ``p_k``.

Every joint is 1-DoF and its velocity is the time derivative of its coordinate in both
tools, so the velocity map between MuJoCo and Pinocchio is a permutation of the dofs (by
joint name); no free-joint conversion is involved.

Closures. Each platform revolute joint is a site-based ``<equality><connect site1=
"link_k_tip" site2="platform_anchor_k">``, as for the hexapod. A connect always has 3 rows;
for this planar mechanism the out-of-plane (z) row is identically zero: zero Jacobian row
(slides in x-y, hinges about z), zero residual, zero reference acceleration, hence zero
force. MuJoCo has no 2-D point constraint, and it does not need one: its constraints are
regularised (``A + R`` is positive definite even when ``J`` is rank deficient), so the 3
redundant rows are harmless there, whereas Pinocchio's ``constraintDynamics`` needs
``mu > 0`` on them. Where we solve with ``J`` ourselves we say how:

* state completion (``qvel``, ``qacc`` from the platform twist / twist_dot) uses only the
  6 in-plane rows, a square 6 x 6 solve for the slider and link dofs;
* the reduction of ``mj_inverse`` to actuator forces, ``[S^T J_c^T] [tau; lambda] =
  qfrc_inverse - J_w^T w``: with the 6 in-plane rows of ``efc_J`` it is square (9 x 9,
  ``np.linalg.solve``, the default); with all 9 rows it is 9 equations in 12 unknowns,
  which ``mjcf.reduce_to_actuators`` solves by minimum-norm least squares (``lstsq``):
  zero on the 3 multipliers of the zero rows and the same unique ``tau`` (the system is
  consistent; the in-plane columns are independent away from singularities).

Stiffness (``solref``, ``solimp``, solver options) and the proximal refinement of the soft
forward dynamics are those of ``mjcf.py`` (its docstring and benchmarks/README.md).
Inertia: sliders are point masses and links thin rods (zero axial inertia) in our model;
MuJoCo rejects inertias below ``mjMINVAL`` on moving bodies, so those get
``mjcf.TINY_INERTIA``. Here they have NO effect on the dynamics: a slider only translates
and a link only turns about z, perpendicular to its axis, so neither value enters the mass
matrix (:func:`model_check` measures it with 1000x the value: 0 to round-off).
"""

from __future__ import annotations

import math

import mujoco
import numpy as np
from mjcf import STIFF_SOLIMP, TINY_INERTIA, _f, _vec, reduce_to_actuators, refine_forward

N_SLIDERS = 3
#: what :func:`model_check` measures: key -> (description, unit)
CHECKS = {
    "joints": ("joint values: MuJoCo-native closed form (qpos) vs Planar3PRR.configuration",
               "m, rad"),
    "sites": ("site positions vs Pinocchio frames link_k_tip / platform_anchor_k, same q",
              "m"),
    "closure": ("connect residual site1 - site2 in MuJoCo (all 3 rows)", "m"),
    "mass": ("mass matrix: mj_fullM (dofs permuted by name) vs Pinocchio crba, same q",
             "kg, kg m, kg m^2"),
    "bias": ("bias forces: qfrc_bias vs Pinocchio nonLinearEffects (gravity -g y), same q, v",
             "N, N m"),
    "velocity": ("qvel completion (in-plane rows of mj_jacSite) vs Planar3PRR.velocity",
                 "m/s, rad/s"),
    "acceleration": ("qacc completion (mj_jacDot drift) vs Planar3PRR.acceleration",
                     "m/s^2, rad/s^2"),
    "out-of-plane rows": ("efc_J and efc_force of the connect z rows (must be 0)",
                          "-, N"),
    "tiny inertia": ((f"mass matrix change due to the tiny inertia {TINY_INERTIA:g} kg m^2 "
                      "(sliders, link axis), measured with 1000x it (linear)"),
                     "kg, kg m, kg m^2"),
}


def _rail_angles() -> np.ndarray:
    return np.pi / 2 + 2 * np.pi / 3 * np.arange(N_SLIDERS)


def planar_mjcf(geometry, timestep: float = 1e-3, solref: tuple[float, float] | None = None,
                solimp: tuple[float, ...] = STIFF_SOLIMP, tiny_inertia: float = TINY_INERTIA,
                integrator: str = "Euler") -> str:
    """MJCF text of the planar 3-PRR of ``geometry`` (SI units), gravity ``-g`` along y.

    Args:
        geometry: a ``hexapod_pin.planar.robot.PlanarGeometry``.
        timestep: simulation time step (s).
        solref: ``(timeconst, dampratio)`` of the closures; default ``(2 timestep, 1)``.
        solimp: impedance of the closures, default ``mjcf.STIFF_SOLIMP``.
        tiny_inertia: inertia (kg m^2) for the sliders (all axes) and the links' axis.
        integrator: MuJoCo integrator name (``Euler`` is semi-implicit Euler).
    """
    g = geometry
    solref = (2.0 * timestep, 1.0) if solref is None else solref
    length, m_link = g.link_length, g.link_mass
    i_link = m_link * length ** 2 / 12.0
    option = {"timestep": _f(timestep), "gravity": _vec([0.0, -g.gravity, 0.0]),
              "integrator": integrator, "solver": "Newton", "tolerance": "1e-15",
              "iterations": "100", "jacobian": "dense"}
    out = ['<mujoco model="planar_3prr">',
           '  <compiler angle="radian" autolimits="true" inertiafromgeom="false"/>',
           "  <option " + " ".join(f'{k}="{v}"' for k, v in option.items()) + ">",
           '    <flag contact="disable"/>',
           "  </option>",
           "  <default>"]
    # contacts off; no damping, armature, friction loss or limits; stiff closures; bare motors
    defaults = {"geom": 'contype="0" conaffinity="0"',
                "joint": 'damping="0" armature="0" frictionloss="0" limited="false"',
                "equality": f'solref="{_vec(solref)}" solimp="{_vec(solimp)}"',
                "motor": 'ctrllimited="false" forcelimited="false" gear="1"'}
    out += [f"    <{tag} {attributes}/>" for tag, attributes in defaults.items()]
    out += ["  </default>", "  <worldbody>"]
    for k, a in enumerate(_rail_angles()):
        half = 0.5 * (a + math.pi / 2)
        mid = g.rail_radius * np.array([math.cos(a), math.sin(a), 0.0])
        quat = _vec([math.cos(half), 0.0, 0.0, math.sin(half)])
        out += [f'    <body name="slider_{k}" pos="{_vec(mid)}" quat="{quat}">',
                f'      <joint name="slider_{k}" type="slide" axis="1 0 0"/>',
                (f'      <inertial pos="0 0 0" mass="{_f(g.slider_mass)}" '
                 f'diaginertia="{_vec([tiny_inertia] * 3)}"/>'),
                f'      <body name="link_{k}">',
                f'        <joint name="link_{k}_joint" type="hinge" axis="0 0 1"/>',
                (f'        <inertial pos="{_f(length / 2)} 0 0" mass="{_f(m_link)}" '
                 f'diaginertia="{_vec([tiny_inertia, i_link, i_link])}"/>'),
                f'        <site name="link_{k}_tip" pos="{_f(length)} 0 0"/>',
                "      </body>",
                "    </body>"]
    out += ['    <body name="platform">',
            '      <joint name="platform_x" type="slide" axis="1 0 0"/>',
            '      <joint name="platform_y" type="slide" axis="0 1 0"/>',
            '      <joint name="platform_theta" type="hinge" axis="0 0 1"/>',
            (f'      <inertial pos="0 0 0" mass="{_f(g.platform_mass)}" diaginertia="'
             f'{_vec([g.platform_inertia / 2, g.platform_inertia / 2, g.platform_inertia])}"/>')]
    out += [f'      <site name="platform_anchor_{k}" pos="{_vec([*p, 0.0])}"/>'
            for k, p in enumerate(g.platform_points)]
    out += ["    </body>", "  </worldbody>", "  <equality>"]
    out += [f'    <connect name="pivot_{k}" site1="link_{k}_tip" site2="platform_anchor_{k}"/>'
            for k in range(N_SLIDERS)]
    out += ["  </equality>", "  <actuator>"]
    out += [f'    <motor name="slider_{k}" joint="slider_{k}"/>' for k in range(N_SLIDERS)]
    out += ["  </actuator>", "</mujoco>"]
    return "\n".join(out) + "\n"


class MujocoPlanar:
    """A compiled MuJoCo planar 3-PRR, its data, and the index maps of its state.

    States are MuJoCo's: ``qpos`` (9,) and ``qvel``, ``qacc`` (9,), every joint 1-DoF.
    Platform twist ``(vx, vy, omega)`` and wrench ``(fx, fy, mz)`` (force on the platform,
    moment about its origin = its centre of mass) are in world axes; actuator forces
    ``tau`` (3,) (N) act on slider k along ``+u_k``.

    Args:
        geometry: a ``PlanarGeometry``.
        **mjcf_options: passed to :func:`planar_mjcf`.
    """

    def __init__(self, geometry, **mjcf_options):
        self.geometry = geometry
        self.xml = planar_mjcf(geometry, **mjcf_options)
        self.model = mujoco.MjModel.from_xml_string(self.xml)
        self.data = mujoco.MjData(self.model)
        m = self.model
        dof = lambda name: int(m.joint(name).dofadr[0])
        adr = lambda name: int(m.joint(name).qposadr[0])
        self.slider_v = np.array([dof(f"slider_{k}") for k in range(N_SLIDERS)])
        self.slider_q = np.array([adr(f"slider_{k}") for k in range(N_SLIDERS)])
        self.link_q = np.array([adr(f"link_{k}_joint") for k in range(N_SLIDERS)])
        names = ("platform_x", "platform_y", "platform_theta")
        self.platform_v = np.array([dof(n) for n in names])
        self.platform_q = np.array([adr(n) for n in names])
        self.other_v = np.setdiff1d(np.arange(m.nv), self.platform_v)
        self.platform_body = m.body("platform").id
        self.slider_bodies = np.array([m.body(f"slider_{k}").id for k in range(N_SLIDERS)])
        self.pairs = [(m.site(f"link_{k}_tip").id, m.site(f"platform_anchor_{k}").id)
                      for k in range(N_SLIDERS)]
        #: rows of the 9 connect rows that lie in the plane (x, y of each pivot)
        self.in_plane = np.array([3 * k + i for k in range(N_SLIDERS) for i in (0, 1)])
        self.selection = np.zeros((m.nv, N_SLIDERS))     # S^T: actuator forces -> generalised
        self.selection[self.slider_v, np.arange(N_SLIDERS)] = 1.0
        self._buf = np.zeros((3, m.nv))
        self._qfrc = np.zeros(m.nv)
        self.refinements: list[int] = []

    # -- state ------------------------------------------------------------------------
    def qpos_from_pose(self, pose) -> np.ndarray:
        """qpos (9,) for a pose ``(x, y, theta)``, home IK branch (larger root per slider).

        A closed form in MuJoCo's own terms: rail midpoints and directions from the slider
        bodies (``body_pos``, ``body_quat``), link length and platform points from the
        sites. Slider k solves ``|P_k - m_k - s u_k| = L``; the link angle is the angle of
        ``P_k - c_k`` from ``u_k`` about z.

        Raises:
            ValueError: a link cannot reach its rail.
        """
        m = self.model
        pose = np.asarray(pose, dtype=float)
        c, s = math.cos(pose[2]), math.sin(pose[2])
        qpos = np.zeros(m.nq)
        qpos[self.platform_q] = pose
        for k, (tip, anchor) in enumerate(self.pairs):
            body = self.slider_bodies[k]
            rot = np.empty(9)
            mujoco.mju_quat2Mat(rot, m.body_quat[body])
            u, w = rot.reshape(3, 3)[:2, 0], rot.reshape(3, 3)[:2, 1]
            p = m.site_pos[anchor][:2]
            d = pose[:2] + np.array([c * p[0] - s * p[1], s * p[0] + c * p[1]]) \
                - m.body_pos[body][:2]
            along, length = u @ d, m.site_pos[tip][0]
            disc = length ** 2 - d @ d + along ** 2
            if disc < 0.0:
                raise ValueError(f"pose {pose} out of reach of link {k} (disc {disc:.3g})")
            qpos[self.slider_q[k]] = along + math.sqrt(disc)
            link = d - qpos[self.slider_q[k]] * u
            qpos[self.link_q[k]] = math.atan2(link @ w, link @ u)
        return qpos

    def pair_jacobian(self) -> np.ndarray:
        """``d(tip - anchor)/dqvel`` (9, nv), world axes, rows x, y, z per pivot
        (``mj_jacSite``; needs kinematics and comPos)."""
        m, d = self.model, self.data
        out = np.zeros((3 * N_SLIDERS, m.nv))
        for k, pair in enumerate(self.pairs):
            for sign, site in zip((1.0, -1.0), pair):
                mujoco.mj_jacSite(m, d, self._buf, None, site)
                out[3 * k:3 * k + 3] += sign * self._buf
        return out

    def pair_drift(self) -> np.ndarray:
        """``Jdot qvel`` (9,) of the pivots (``mj_jacDot``; needs comPos and comVel)."""
        m, d = self.model, self.data
        out = np.zeros(3 * N_SLIDERS)
        for k, pair in enumerate(self.pairs):
            for sign, site in zip((1.0, -1.0), pair):
                mujoco.mj_jacDot(m, d, self._buf, None, d.site_xpos[site], m.site_bodyid[site])
                out[3 * k:3 * k + 3] += sign * (self._buf @ d.qvel)
        return out

    def set_task_state(self, pose, twist, twist_dot=None):
        """Set qpos, qvel (and qacc) of ``data`` from a platform state, MuJoCo-native.

        qpos by :meth:`qpos_from_pose`; the platform dofs of qvel / qacc are the twist /
        twist_dot themselves; the 6 slider and link dofs solve the 6 in-plane pivot rows
        ``J v = 0`` and ``J a = -Jdot v`` (square solves).

        Returns:
            a tuple ``(qpos, qvel, qacc)`` of new arrays; ``qacc`` is None when
            ``twist_dot`` is.
        """
        m, d = self.model, self.data
        d.qpos[:] = self.qpos_from_pose(pose)
        d.qvel[:] = 0.0
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        jac = self.pair_jacobian()[self.in_plane]
        known, free = jac[:, self.platform_v], jac[:, self.other_v]

        def complete(platform_values, rhs):
            out = np.zeros(m.nv)
            out[self.platform_v] = platform_values
            out[self.other_v] = np.linalg.solve(free, rhs - known @ out[self.platform_v])
            return out

        d.qvel[:] = complete(twist, 0.0)
        if twist_dot is None:
            return d.qpos.copy(), d.qvel.copy(), None
        mujoco.mj_comVel(m, d)
        d.qacc[:] = complete(twist_dot, -self.pair_drift()[self.in_plane])
        return d.qpos.copy(), d.qvel.copy(), d.qacc.copy()

    def set_wrench(self, wrench) -> None:
        """Apply ``(fx, fy, mz)`` on the platform (``xfrc_applied`` at its centre of mass)."""
        fx, fy, mz = wrench
        self.data.xfrc_applied[self.platform_body] = (fx, fy, 0.0, 0.0, 0.0, mz)

    def wrench_qfrc(self, wrench) -> np.ndarray:
        """Generalised force (nv,) of a platform wrench (``mj_applyFT`` at its origin)."""
        d = self.data
        self._qfrc[:] = 0.0
        mujoco.mj_applyFT(self.model, d, np.array([wrench[0], wrench[1], 0.0]),
                          np.array([0.0, 0.0, wrench[2]]), d.xpos[self.platform_body],
                          self.platform_body, self._qfrc)
        return self._qfrc

    # -- dynamics ---------------------------------------------------------------------
    def inverse_tree_state(self, qpos, qvel, qacc, wrench, rows: str = "in_plane") -> np.ndarray:
        """Actuator forces (3,) from a consistent state: ``mj_inverse`` + reduction.

        Solves ``qfrc_inverse - J_w^T w = S^T tau + J_c^T lambda`` for ``tau`` with
        ``J_c`` = ``efc_J`` (the only constraints are the 3 connects, rows x, y, z each):
        ``rows="in_plane"``: the 6 in-plane rows, a square 9 x 9 solve (the z rows are
        identically zero, :func:`model_check` verifies it); ``rows="all"``: all 9 rows,
        minimum-norm least squares on the 9 x 12 system (zero multipliers on the z rows).
        Both give the same ``tau`` (to round-off); the square solve is the cheaper.
        """
        m, d = self.model, self.data
        d.qpos[:] = qpos
        d.qvel[:] = qvel
        d.qacc[:] = qacc
        mujoco.mj_inverse(m, d)
        jac = d.efc_J.reshape(d.nefc, m.nv)
        if rows == "in_plane":
            jac = jac[self.in_plane]
        rhs = d.qfrc_inverse - self.wrench_qfrc(wrench)
        return reduce_to_actuators(self.selection, rhs, jac)

    def inverse_task(self, pose, twist, twist_dot, wrench) -> np.ndarray:
        """Actuator forces (3,) from a platform state: completion + :meth:`inverse_tree_state`
        (in-plane rows)."""
        return self.inverse_tree_state(*self.set_task_state(pose, twist, twist_dot), wrench)

    def forward(self, qpos, qvel, tau, wrench, refine: bool = False) -> np.ndarray:
        """qacc (nv,) by ``mj_forward`` (soft closures), or made rigid by
        ``mjcf.refine_forward`` (``efc_aref`` holds ``-Jdot v`` since MuJoCo 3.7)."""
        m, d = self.model, self.data
        d.qpos[:], d.qvel[:], d.ctrl[:] = qpos, qvel, tau
        self.set_wrench(wrench)
        d.qacc_warmstart[:] = 0.0
        mujoco.mj_forward(m, d)
        if refine:
            self.refinements.append(refine_forward(m, d))
        return d.qacc.copy()

    def step(self, qpos, qvel, tau, wrench, refine: bool = False):
        """One semi-implicit Euler step (``v+ = v + dt a``, ``q+ = q + dt v+``).

        ``refine=False``: ``mj_step`` as is (soft closures). ``refine=True``: the refined
        :meth:`forward`, then ``mj_Euler`` (the same integrator on the rigid ``qacc``).

        Returns:
            ``(qpos, qvel)`` after the step (copies).
        """
        m, d = self.model, self.data
        if refine:
            self.forward(qpos, qvel, tau, wrench, refine=True)
            mujoco.mj_Euler(m, d)
        else:
            d.qpos[:], d.qvel[:], d.ctrl[:] = qpos, qvel, tau
            self.set_wrench(wrench)
            d.qacc_warmstart[:] = 0.0
            mujoco.mj_step(m, d)
        return d.qpos.copy(), d.qvel.copy()


# -- verification against the Pinocchio model ------------------------------------------------
def dof_permutation(mj: MujocoPlanar, pin_model) -> np.ndarray:
    """``perm[i]`` = MuJoCo dof of Pinocchio velocity index ``i`` (joints matched by name).

    Every joint is 1-DoF on both sides, so it maps ``q`` to ``qpos`` too.

    Raises:
        ValueError: a joint that is not 1-DoF, or whose qpos and dof addresses differ.
    """
    perm = np.empty(pin_model.nv, dtype=int)
    for j in range(1, pin_model.njoints):
        joint, mj_joint = pin_model.joints[j], mj.model.joint(pin_model.names[j])
        if joint.nq != 1 or joint.nv != 1 or joint.idx_q != joint.idx_v or \
                mj_joint.qposadr[0] != mj_joint.dofadr[0]:
            raise ValueError(f"joint {pin_model.names[j]} is not a plain 1-DoF joint")
        perm[joint.idx_v] = mj_joint.dofadr[0]
    return perm


def model_check(robot, mj: MujocoPlanar, poses, twists, twist_dots) -> dict[str, float]:
    """Max abs differences between the MJCF and ``robot`` (a ``Planar3PRR``), see
    :data:`CHECKS`, over the given platform states (arrays (n, 3)).

    Kinematic and inertial level only (no dynamics solve): joint values, site positions,
    closure residual, mass matrix, bias forces, velocity / acceleration completion, the
    redundant rows, and the effect of the tiny inertias. All should be ~1e-13 or 0.
    """
    import pinocchio as pin

    model = robot.model.model
    data = model.createData()
    m, d = mj.model, mj.data
    perm = dof_permutation(mj, model)
    big = type(mj)(mj.geometry, tiny_inertia=1e3 * TINY_INERTIA)
    worst = dict.fromkeys(CHECKS, 0.0)

    def keep(key, value):
        worst[key] = max(worst[key], float(np.max(np.abs(value))))

    full, full_big = np.zeros((m.nv, m.nv)), np.zeros((m.nv, m.nv))
    z_rows = np.arange(2, 3 * N_SLIDERS, 3)
    for pose, twist, twist_dot in zip(poses, twists, twist_dots):
        q, v = robot.configuration(pose), robot.velocity(pose, twist)
        # MuJoCo's own state: closed form and completion, then its closures
        qpos, qvel, qacc = mj.set_task_state(pose, twist, twist_dot)
        keep("joints", qpos[perm] - q)
        keep("velocity", qvel[perm] - v)
        keep("acceleration", qacc[perm] - robot.acceleration(pose, twist, twist_dot))
        d.ctrl[:], d.xfrc_applied[:] = 0.0, 0.0
        mujoco.mj_forward(m, d)
        for tip, anchor in mj.pairs:
            keep("closure", d.site_xpos[tip] - d.site_xpos[anchor])
        keep("out-of-plane rows", d.efc_J.reshape(d.nefc, m.nv)[z_rows])
        keep("out-of-plane rows", d.efc_force[z_rows])
        # sites, mass matrix and bias forces at Pinocchio's (q, v), in MuJoCo's dof order
        pin.framesForwardKinematics(model, data, q)
        mass = pin.crba(model, data, q)
        bias = pin.nonLinearEffects(model, data, q, v)
        for target in (mj, big):
            target.data.qpos[perm], target.data.qvel[perm] = q, v
            mujoco.mj_forward(target.model, target.data)
        for k, (tip, anchor) in enumerate(mj.pairs):
            for site, frame in ((tip, f"link_{k}_tip"), (anchor, f"platform_anchor_{k}")):
                keep("sites", d.site_xpos[site] - data.oMf[model.getFrameId(frame)].translation)
        mujoco.mj_fullM(m, d, full)
        keep("mass", full[np.ix_(perm, perm)] - (np.triu(mass) + np.triu(mass, 1).T))
        keep("bias", d.qfrc_bias[perm] - bias)
        mujoco.mj_fullM(big.model, big.data, full_big)
        keep("tiny inertia", (full_big - full) / (1e3 * TINY_INERTIA - TINY_INERTIA)
             * TINY_INERTIA)
    return worst
