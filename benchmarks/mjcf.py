"""Peer 1: the hexapod in MuJoCo, generated as MJCF from a ``HexapodGeometry``.

The MJCF is the same tree as ``urdf/hexapod.urdf.xacro``: per carriage a body on the rail
frame (x along ``u_k``) with a slide joint, a leg body with the universal joint as two
hinges (about the carriage x axis, then about the rotated y axis: the same axes as
``u_i_a`` / ``u_i_b``), and a free-joint platform. The six spherical joints are site-based
``<equality><connect>`` constraints between ``leg_i_tip`` and ``platform_anchor_k``.
Contacts are off, joints have no damping, armature, friction or limits; gravity is
``-g z``. Inertia: carriages are point masses and legs have zero axial inertia in our
model; MuJoCo rejects inertias below ``mjMINVAL`` on moving bodies, so those get
``TINY_INERTIA`` (kg m^2); benchmarks/README.md quantifies its effect.

Stiffness of the closures (soft constraints are MuJoCo's model, there is no hard mode):

* ``solimp = (0.9999, 0.9999, 0.001, 0.5, 2)``: impedance ``d`` pinned at ``mjMAXIMP``
  whatever the violation, so the regulariser is the smallest MuJoCo allows:
  ``R_ii = (1 - d) / d * A_ii ~ 1e-4 A_ii`` (``A = J M^-1 J^T``);
* ``solref = (2 dt, 1)``: time constant two time steps (the smallest that MuJoCo's
  ``refsafe`` keeps), critically damped: the Baumgarte-like reference acceleration
  ``-b J v - k r`` that pulls drift back;
* ``<option solver="Newton" tolerance="1e-15" iterations="100" jacobian="dense">``.

Even so, MuJoCo's forward dynamics is not the rigid one: the regulariser ``R`` makes the
closures give a little (``J qacc = aref - R f``), an error of ~1e-4 relative to the
smallest eigenvalue of ``A`` in the accelerations (measured: up to ~0.2 m/s^2, rad/s^2
here). Since MuJoCo 3.7.0 the reference acceleration of connect/weld constraints includes
the drift ``-Jdot v`` (commit 412cee20); before, it was omitted.
:meth:`MujocoHexapod.forward_refined` removes the regulariser (proximal-point refinement
of the soft solution) and, on MuJoCo < 3.7, adds the drift, to show that what remains is
the same physics.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

import numpy_hexapod as nh

#: inertia given to bodies that have none in our model (MuJoCo needs > mjMINVAL = 1e-15)
TINY_INERTIA = 1e-12
#: impedance pinned at mujoco.mjMAXIMP (0.9999): the stiffest soft constraint
STIFF_SOLIMP = (0.9999, 0.9999, 0.001, 0.5, 2.0)
#: MuJoCo >= 3.7.0 puts the closure drift -Jdot v into efc_aref itself
AREF_HAS_DRIFT = tuple(int(x) for x in mujoco.__version__.split(".")[:2]) >= (3, 7)


def _f(x: float) -> str:
    return repr(float(x))


def _vec(values) -> str:
    return " ".join(_f(v) for v in values)


def hexapod_mjcf(geometry, timestep: float = 1e-3, solref: tuple[float, float] | None = None,
                 solimp: tuple[float, ...] = STIFF_SOLIMP, tiny_inertia: float = TINY_INERTIA,
                 integrator: str = "Euler") -> str:
    """MJCF text of the hexapod of ``geometry`` (SI units), platform at its home pose.

    Args:
        geometry: a ``HexapodGeometry``.
        timestep: simulation time step (s).
        solref: ``(timeconst, dampratio)`` of the closures; default ``(2 timestep, 1)``.
        solimp: impedance of the closures, default :data:`STIFF_SOLIMP`.
        tiny_inertia: inertia (kg m^2) for the carriages (all axes) and the legs' axis.
        integrator: MuJoCo integrator name (``Euler`` is semi-implicit Euler).
    """
    g = geometry
    if solref is None:
        solref = (2.0 * timestep, 1.0)
    angles = np.pi / 2 + 2 * np.pi / 3 * np.arange(3)
    length, m_leg = g.leg_length, g.leg_mass
    i_leg = m_leg * length ** 2 / 12.0
    lines = [
        '<mujoco model="hexapod">',
        '  <compiler angle="radian" autolimits="true" inertiafromgeom="false"/>',
        f'  <option timestep="{_f(timestep)}" gravity="0 0 {_f(-g.gravity)}" '
        f'integrator="{integrator}" solver="Newton" tolerance="1e-15" iterations="100" '
        'jacobian="dense">',
        '    <flag contact="disable"/>',
        '  </option>',
        '  <default>',
        '    <geom contype="0" conaffinity="0"/>',
        '    <joint damping="0" armature="0" frictionloss="0" limited="false"/>',
        f'    <equality solref="{_vec(solref)}" solimp="{_vec(solimp)}"/>',
        '    <motor ctrllimited="false" forcelimited="false" gear="1"/>',
        '  </default>',
        '  <worldbody>',
    ]
    for i in range(6):
        a = angles[i // 2]
        mid = g.rail_radius * np.array([math.cos(a), math.sin(a), 0.0])
        half = 0.5 * (a + math.pi / 2)
        lines += [
            f'    <body name="carriage_{i}" pos="{_vec(mid)}" '
            f'quat="{_vec([math.cos(half), 0, 0, math.sin(half)])}">',
            f'      <joint name="carriage_{i}" type="slide" axis="1 0 0"/>',
            f'      <inertial pos="0 0 0" mass="{_f(g.carriage_mass)}" '
            f'diaginertia="{_vec([tiny_inertia] * 3)}"/>',
            f'      <body name="leg_{i}">',
            f'        <joint name="u_{i}_a" type="hinge" axis="1 0 0"/>',
            f'        <joint name="u_{i}_b" type="hinge" axis="0 1 0"/>',
            f'        <inertial pos="0 0 {_f(length / 2)}" mass="{_f(m_leg)}" '
            f'diaginertia="{_vec([i_leg, i_leg, tiny_inertia])}"/>',
            f'        <site name="leg_{i}_tip" pos="0 0 {_f(length)}"/>',
            '      </body>',
            '    </body>',
        ]
    pts = g.platform_points
    lines += [
        f'    <body name="platform" pos="0 0 {_f(g.home_height)}">',
        '      <freejoint name="platform_joint"/>',
        f'      <inertial pos="0 0 0" mass="{_f(g.platform_mass)}" '
        f'diaginertia="{_vec(g.platform_inertia)}"/>',
    ]
    lines += [f'      <site name="platform_anchor_{k}" pos="{_vec(pts[k])}"/>' for k in range(3)]
    lines += ['    </body>', '  </worldbody>', '  <equality>']
    lines += [f'    <connect name="tip_{i}" site1="leg_{i}_tip" site2="platform_anchor_{i // 2}"/>'
              for i in range(6)]
    lines += ['  </equality>', '  <actuator>']
    lines += [f'    <motor name="carriage_{i}" joint="carriage_{i}"/>' for i in range(6)]
    lines += ['  </actuator>', '</mujoco>']
    return "\n".join(lines) + "\n"


def refine_forward(model, data, max_refinements: int = 100, tol: float = 1e-12) -> int:
    """Make the soft solution in ``data`` (after ``mj_forward``) rigid, in place.

    MuJoCo solves ``min 1/2 |a - a0|_M^2 + 1/2 |J a - aref|_{R^-1}^2``, i.e.
    ``J a = aref - R f``. Re-solving with ``aref_k = aref* + R f_{k-1}`` (proximal point)
    converges to ``J a = aref*``, the rigid closure at acceleration level
    (``aref* = efc_aref``, which holds ``-Jdot v`` since MuJoCo 3.7 and is ~0 from the
    position and velocity terms at a consistent state). The error contracts by
    ``R / (lambda + R)`` per refinement over the eigenvalues ``lambda`` of
    ``A = J M^-1 J^T``: ~1e-2 for most hexapod states, much slower near singular ones.
    Stops when ``max |qacc_k - qacc_{k-1}| <= tol * max(1, max |qacc|)``.

    Returns:
        the number of refinements done.
    """
    target = data.efc_aref.copy()
    previous = data.qacc.copy()
    for k in range(1, max_refinements + 1):
        data.efc_aref[:] = target + data.efc_R * data.efc_force
        mujoco.mj_forwardSkip(model, data, mujoco.mjtStage.mjSTAGE_VEL, 1)
        change = float(np.max(np.abs(data.qacc - previous)))
        if change <= tol * max(1.0, float(np.max(np.abs(data.qacc)))):
            return k
        previous[:] = data.qacc
    return max_refinements


def reduce_to_actuators(selection: np.ndarray, qfrc: np.ndarray, jac: np.ndarray) -> np.ndarray:
    """Solve ``qfrc = S^T tau + J_c^T lambda`` for the actuator forces ``tau``.

    Args:
        selection: ``S^T`` (nv, n_act), columns the actuated dofs.
        qfrc: generalised force the actuators and closures must supply (nv,).
        jac: closure Jacobian (rows, nv), any row basis (``efc_J``).

    Square systems are solved exactly, others by least squares.
    """
    mat = np.hstack([selection, jac.T])
    if mat.shape[0] == mat.shape[1]:
        return np.linalg.solve(mat, qfrc)[:selection.shape[1]]
    return np.linalg.lstsq(mat, qfrc, rcond=None)[0][:selection.shape[1]]


class MujocoHexapod:
    """A compiled MuJoCo hexapod, its data, and the index maps of its state.

    Args:
        geometry: a ``HexapodGeometry``.
        **mjcf_options: passed to :func:`hexapod_mjcf`.
    """

    def __init__(self, geometry, **mjcf_options):
        self.geometry = geometry
        self.params = nh.params_from_geometry(geometry)
        self.xml = hexapod_mjcf(geometry, **mjcf_options)
        self.model = mujoco.MjModel.from_xml_string(self.xml)
        self.data = mujoco.MjData(self.model)
        m = self.model
        jq = lambda name: m.joint(name).qposadr[0]  # noqa: E731
        jv = lambda name: m.joint(name).dofadr[0]  # noqa: E731
        self.carriage_q = np.array([jq(f"carriage_{i}") for i in range(6)])
        self.carriage_v = np.array([jv(f"carriage_{i}") for i in range(6)])
        self.u_a_q = np.array([jq(f"u_{i}_a") for i in range(6)])
        self.u_b_q = np.array([jq(f"u_{i}_b") for i in range(6)])
        self.free_q = jq("platform_joint")
        self.free_v = jv("platform_joint")
        self.platform_body = m.body("platform").id
        self.tip_sites = np.array([m.site(f"leg_{i}_tip").id for i in range(6)])
        self.anchor_sites = np.array([m.site(f"platform_anchor_{i // 2}").id for i in range(6)])
        tree = np.ones(m.nv, dtype=bool)
        tree[self.free_v:self.free_v + 6] = False
        self.tree_v = np.flatnonzero(tree)            # the 18 non-free dofs
        self.selection = np.zeros((m.nv, 6))          # S^T: actuator forces -> generalised
        self.selection[self.carriage_v, np.arange(6)] = 1.0
        self._jacp = np.zeros((3, m.nv))
        self._jacp2 = np.zeros((3, m.nv))
        self._wrench_qfrc = np.zeros(m.nv)
        self.refinements: list[int] = []      # passes of each forward_refined call

    # -- state ------------------------------------------------------------------------
    def qpos_from_pose(self, pose: np.ndarray) -> np.ndarray:
        """MuJoCo qpos (nq,) for a pose (6,), every closure satisfied (closed form)."""
        q, u_a, u_b, rot = nh.tree_coordinates_one(self.params, pose)
        qpos = np.empty(self.model.nq)
        qpos[self.carriage_q], qpos[self.u_a_q], qpos[self.u_b_q] = q, u_a, u_b
        qpos[self.free_q:self.free_q + 3] = pose[:3]
        mujoco.mju_mat2Quat(qpos[self.free_q + 3:self.free_q + 7], rot.ravel())
        return qpos

    def closure_jacobian(self) -> np.ndarray:
        """``d(tip - anchor)/dqvel`` (18, nv) from ``mj_jacSite`` (needs kinematics + comPos)."""
        m, d = self.model, self.data
        out = np.empty((18, m.nv))
        for i in range(6):
            mujoco.mj_jacSite(m, d, self._jacp, None, self.tip_sites[i])
            mujoco.mj_jacSite(m, d, self._jacp2, None, self.anchor_sites[i])
            out[3 * i:3 * i + 3] = self._jacp - self._jacp2
        return out

    def closure_drift(self) -> np.ndarray:
        """``Jdot qvel`` (18,) of the closures (needs kinematics, comPos and comVel)."""
        m, d = self.model, self.data
        out = np.empty(18)
        for i in range(6):
            for sign, site in ((1.0, self.tip_sites[i]), (-1.0, self.anchor_sites[i])):
                mujoco.mj_jacDot(m, d, self._jacp, None, d.site_xpos[site], m.site_bodyid[site])
                if sign > 0:
                    out[3 * i:3 * i + 3] = self._jacp @ d.qvel
                else:
                    out[3 * i:3 * i + 3] -= self._jacp @ d.qvel
        return out

    def set_task_state(self, pose, twist, twist_dot=None):
        """Set qpos, qvel (and qacc) of ``data`` from a platform state, MuJoCo-native.

        qpos by closed form; qvel and qacc complete the free-joint values by solving the
        closures ``J v = 0`` and ``J a = -Jdot v`` for the 18 other dofs (``mj_jacSite``,
        ``mj_jacDot``). Free joint: ``qvel = (v, R^T w)``, ``qacc = (v_dot, R^T w_dot)``.
        Leaves kinematics, comPos and comVel computed.

        Returns:
            ``(qpos, qvel, qacc)`` copies (qacc None without ``twist_dot``).
        """
        m, d = self.model, self.data
        pose, twist = np.asarray(pose, float), np.asarray(twist, float)
        d.qpos[:] = self.qpos_from_pose(pose)
        rot = nh.rotation_one(pose[3:])
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        jac = self.closure_jacobian()
        fv = slice(self.free_v, self.free_v + 6)
        free_vel = np.concatenate([twist[:3], rot.T @ twist[3:]])
        qvel = np.zeros(m.nv)
        qvel[fv] = free_vel
        qvel[self.tree_v] = np.linalg.solve(jac[:, self.tree_v], -jac[:, fv] @ free_vel)
        d.qvel[:] = qvel
        mujoco.mj_comVel(m, d)
        qacc = None
        if twist_dot is not None:
            twist_dot = np.asarray(twist_dot, float)
            free_acc = np.concatenate([twist_dot[:3], rot.T @ twist_dot[3:]])
            qacc = np.zeros(m.nv)
            qacc[fv] = free_acc
            qacc[self.tree_v] = np.linalg.solve(
                jac[:, self.tree_v], -self.closure_drift() - jac[:, fv] @ free_acc)
            d.qacc[:] = qacc
        return d.qpos.copy(), qvel, qacc

    def platform_rotation(self) -> np.ndarray:
        """Rotation matrix of the platform at the current ``data`` (after kinematics)."""
        return self.data.xmat[self.platform_body].reshape(3, 3)

    def twist_dot_from_qacc(self, qacc: np.ndarray) -> np.ndarray:
        """Platform ``twist_dot`` (6,) (world axes) from a MuJoCo qacc."""
        fa = qacc[self.free_v:self.free_v + 6]
        return np.concatenate([fa[:3], self.platform_rotation() @ fa[3:]])

    def set_wrench(self, wrench) -> None:
        """Apply ``(f, m)`` (world axes, moment about the platform origin = its CoM)."""
        self.data.xfrc_applied[self.platform_body] = wrench

    def wrench_qfrc(self, wrench) -> np.ndarray:
        """Generalised force (nv,) of a platform wrench, by ``mj_applyFT`` at the origin."""
        d = self.data
        self._wrench_qfrc[:] = 0.0
        mujoco.mj_applyFT(self.model, d, wrench[:3], wrench[3:], d.xpos[self.platform_body],
                          self.platform_body, self._wrench_qfrc)
        return self._wrench_qfrc

    # -- dynamics ---------------------------------------------------------------------
    def inverse_tree_state(self, qpos, qvel, qacc, wrench) -> np.ndarray:
        """Actuator forces (6,) from a consistent tree state: ``mj_inverse`` + reduction.

        ``mj_inverse`` returns ``qfrc_inverse = M qacc + c - J^T f_soft``: the generalised
        force the actuators, the wrench and the closures must supply together (the soft
        constraint force lies in the range of ``J^T``, so the reduction removes it).
        """
        m, d = self.model, self.data
        d.qpos[:], d.qvel[:], d.qacc[:] = qpos, qvel, qacc
        mujoco.mj_inverse(m, d)
        jac = d.efc_J.reshape(d.nefc, m.nv)
        return reduce_to_actuators(self.selection, d.qfrc_inverse - self.wrench_qfrc(wrench),
                                   jac)

    def inverse_task(self, pose, twist, twist_dot, wrench) -> np.ndarray:
        """Actuator forces (6,) from a platform state: completion + ``mj_inverse`` + reduction."""
        qpos, qvel, qacc = self.set_task_state(pose, twist, twist_dot)
        return self.inverse_tree_state(qpos, qvel, qacc, wrench)

    def forward(self, qpos, qvel, tau, wrench):
        """``mj_forward`` as is: ``(twist_dot (6,), carriage qddot (6,), qacc (nv,))``."""
        m, d = self.model, self.data
        d.qpos[:], d.qvel[:], d.ctrl[:] = qpos, qvel, tau
        d.xfrc_applied[self.platform_body] = wrench
        mujoco.mj_forward(m, d)
        return self.twist_dot_from_qacc(d.qacc), d.qacc[self.carriage_v].copy(), d.qacc.copy()

    def forward_refined(self, qpos, qvel, tau, wrench, max_refinements: int = 100):
        """:meth:`forward` made rigid by :func:`refine_forward` (on MuJoCo < 3.7 the drift
        ``-Jdot v`` is first added to ``efc_aref``)."""
        m, d = self.model, self.data
        self.forward(qpos, qvel, tau, wrench)
        if not AREF_HAS_DRIFT:
            d.efc_aref[:] -= self.closure_drift()
        self.refinements.append(refine_forward(m, d, max_refinements))
        return self.twist_dot_from_qacc(d.qacc), d.qacc[self.carriage_v].copy(), d.qacc.copy()
