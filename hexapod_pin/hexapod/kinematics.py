"""Kinematics of the rail-driven hexapod: the public methods over the compiled closed form.

Carriage i rides on rail ``k = i // 2``; it sits at ``c_i = m_k + q_i u_k`` and its
leg reaches the platform point ``P_k = t + R p_k`` (world). The leg vector is
``n_i = P_k - c_i`` and the loop closes when ``|n_i| = leg_length``. As built
(:class:`~hexapod_pin.hexapod.geometry.ChainGeometry`) every chain has its own line
``M_i + q_i u_i`` (``M_i`` the line point with the sensor offset folded in), length
``L_i`` and platform joint ``p_i``: read ``m_k, u_k, p_k, leg_length`` as ``M_i, u_i,
p_i, L_i`` below.

Inverse kinematics is the quadratic along the rail
``q_i = u_k . d_i + s_i sqrt(leg_length^2 - |d_i - (u_k . d_i) u_k|^2)``,
``d_i = P_k - m_k``, with the root sign ``s_i = branch[i]``; the home branch is
``(-1, +1, -1, +1, -1, +1)`` (even carriages on the smaller root).

Workspace Jacobian (``qdot = J @ twist``, twist = (v, w) in world axes)::

    J[i] = [n_i, r_k x n_i] / (n_i . u_k)

i.e. ``J = B^-1 A`` with ``A[i] = [n_i, r_k x n_i]`` and ``B = diag(n_i . u_k)``: type I
where a leg is perpendicular to its rail (``B`` singular), type II where ``A`` is.

Every formula is written once, in the compiled kernels of
:mod:`hexapod_pin.hexapod.kernels` (single states) and :mod:`hexapod_pin.hexapod.batch`
(N states); this module validates the inputs, runs them and raises the library's
exceptions. Forward kinematics and the assembly modes use the three-circle formulation of
:mod:`hexapod_pin.hexapod.assembly_modes` (as built: Newton on the six closure equations,
and continuation of the drawing's modes); the singularity measures are those of
:mod:`hexapod_pin.core.measures`.

Units: m, rad, s; every vector in world axes unless stated.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ..core.checks import as_array, check_signs, flag, required, vec6
from ..core.measures import singularity_measures
from ..core.results import InverseKinematicsBatch, JacobianBatch, SingularityMeasures
from ..errors import AssemblyError, GeometryError, InputError, StrokeLimitError
from . import assembly_modes as am
from . import batch
from . import kernels as K
from .geometry import HexapodGeometry
from .kernels import GIMBAL_TOL, HOME_BRANCH, RAIL_OF, TYPE_I_TOL, TYPE_II_TOL  # noqa: F401

__all__ = ["HexapodKinematics", "LegMotion", "check_branch"]

#: Newton iteration limit of :meth:`HexapodKinematics.forward_kinematics`
FK_MAX_ITER = 50


def check_branch(branch: npt.ArrayLike) -> np.ndarray:
    """Validate a branch (six values, each +1 or -1); ``None`` -> the home branch."""
    return check_signs(branch, HOME_BRANCH)


@dataclass(frozen=True)
class LegMotion:
    """Motion of the six legs (rigid rods) for a platform motion; arrays in carriage order.

    The angular velocity is that of the rigid leg body of the tree: a
    universal joint (first axis along the rail ``u_k``, second axis ``b``
    perpendicular to the rail and to the leg) lets the leg turn only about
    ``u_k`` and ``b``. With the unit direction ``e`` and ``c = u_k . e``::

        w = e x de/dt + lambda e,    lambda = c (e x de/dt) . u_k / (1 - c^2)

    (``e x de/dt`` is the part perpendicular to the leg; ``lambda e`` the spin
    about the leg that the universal joint imposes). It equals Pinocchio's
    ``LOCAL_WORLD_ALIGNED`` angular velocity of the ``leg_i`` body.

    Attributes:
        direction: unit leg directions ``e_i = n_i / L``, from carriage to platform (6, 3).
        com_position: leg centres of mass ``c_i + L/2 e_i`` (6, 3) (m).
        angular_velocity: leg angular velocities ``w_i`` (6, 3) (rad/s).
        com_velocity: velocities of the centres of mass (6, 3) (m/s).
        qdot: carriage velocities (6,) (m/s).
        angular_acceleration: ``dw_i/dt`` (6, 3) (rad/s^2), None without ``twist_dot``.
        com_acceleration: accelerations of the centres of mass (6, 3) (m/s^2), None
            without ``twist_dot``.
        qddot: carriage accelerations (6,) (m/s^2), None without ``twist_dot``.
    """

    direction: np.ndarray
    com_position: np.ndarray
    angular_velocity: np.ndarray
    com_velocity: np.ndarray
    qdot: np.ndarray
    angular_acceleration: np.ndarray | None = None
    com_acceleration: np.ndarray | None = None
    qddot: np.ndarray | None = None


class HexapodKinematics:
    """The hexapod's kinematics: the component that :class:`~hexapod_pin.hexapod.robot.Hexapod`
    delegates its kinematics methods to.

    Args:
        geometry: the :class:`~hexapod_pin.hexapod.geometry.HexapodGeometry`.
        closed_form: the robot's :class:`~hexapod_pin.hexapod.kernels.ClosedForm` (its
            packed geometry and per-thread scratch); default a new one.

    Attributes:
        geometry: the geometry. geo: its packed vector (:func:`kernels.pack_geometry`).
        circles: the :class:`~hexapod_pin.hexapod.assembly_modes.CircleGeometry` of the
            forward kinematics (of the drawing for an as-built geometry).
        chains: the per-chain geometry (``geometry.chain_geometry``).
    """

    def __init__(self, geometry: HexapodGeometry, closed_form: K.ClosedForm | None = None) -> None:
        self.geometry = geometry
        self.closed_form = K.ClosedForm(geometry) if closed_form is None else closed_form
        self.geo = self.closed_form.geo
        self.circles = am.CircleGeometry.from_geometry(geometry)
        self.chains = geometry.chain_geometry
        self._home_list = geometry.home_pose.tolist()

    @property
    def _scratch(self) -> K.Scratch:
        return self.closed_form.scratch

    # -- the kernels of one pose ------------------------------------------------------
    def _signs(self, branch) -> np.ndarray:
        return HOME_BRANCH if branch is None else check_branch(branch)

    def _legs(self, pose, branch, refuse=(K.UNREACHABLE, K.TYPE_I)) -> np.ndarray:
        """Run the leg kernel on a pose; raise for the codes in ``refuse``; return ``wk``."""
        s = self._scratch
        code = K.leg_state(self.geo, self._signs(branch), vec6(pose, "pose"), s.rot, s.wk)
        if code == K.NONFINITE:
            as_array(pose, (6,), "pose")
        if code in refuse:
            raise K.error_of(code, self.geo, s.wk, s.mats[1])
        return s.wk

    def _moving_legs(self, pose, twist, twist_dot, branch, refuse=(K.UNREACHABLE, K.TYPE_I)):
        """:meth:`_legs`, then the rates of ``twist`` and (when given) the accelerations of
        ``twist_dot``."""
        twist = vec6(twist, "twist")
        if twist_dot is not None:
            twist_dot = vec6(twist_dot, "twist_dot")
        wk = self._legs(pose, branch, refuse)
        if not K.all_finite(twist):
            as_array(twist, (6,), "twist")
        K.rates(self.geo, twist, wk, True)
        if twist_dot is not None:
            if not K.all_finite(twist_dot):
                as_array(twist_dot, (6,), "twist_dot")
            K.tip_accelerations(wk, twist_dot)
        return wk

    def platform_points_world(self, pose: npt.ArrayLike) -> np.ndarray:
        """World positions ``P_k`` of the three spherical joints (m), shape (3, 3), of the
        ideal geometry (a pair's two legs meet at one point).

        Raises:
            InputError: bad shape or values.
            GeometryError: an as-built geometry (use :meth:`platform_joints_world`).
        """
        if not self.geometry.is_ideal:
            raise GeometryError("chains", "as built", "the two legs of a pair need not meet "
                                "at one point: use platform_joints_world")
        return self.platform_joints_world(pose)[0::2]

    def platform_joints_world(self, pose: npt.ArrayLike) -> np.ndarray:
        """World positions ``t + R p_i`` of the six legs' platform joints (m), shape (6, 3)."""
        pose = as_array(pose, (6,), "pose")
        wk = self._legs(pose, None, refuse=())
        return pose[:3] + wk[[K.RX, K.RY, K.RZ]].T

    # -- inverse kinematics -----------------------------------------------------------
    def inverse_kinematics(self, pose: npt.ArrayLike, branch: npt.ArrayLike | None = None,
                           check_limits: bool = True) -> npt.NDArray[np.float64]:
        """Carriage positions for a platform pose (closed form).

        Args:
            pose: ``(x, y, z, roll, pitch, yaw)`` (m, rad), shape (6,).
            branch: six signs ``+1`` / ``-1`` choosing the root of each carriage's
                quadratic (``+1``: the larger q); default the home branch
                ``(-1, +1, -1, +1, -1, +1)``.
            check_limits: check ``abs(q_i) <= rail_half_length`` and
                ``q_{2k+1} - q_{2k} >= carriage_min_gap``.

        Returns:
            q, shape (6,) (m along ``u_k`` from the rail midpoint).

        Raises:
            InputError: wrong shape, NaN / inf, or a malformed branch.
            UnreachablePoseError: a leg cannot reach (which carriage, how short).
            StrokeLimitError: with ``check_limits``, a stroke or gap violation
                (including carriages of a rail that cross).
        """
        check_limits = flag(check_limits, "check_limits")
        wk = self._legs(pose, branch, refuse=(K.UNREACHABLE,))
        q = wk[K.Q].copy()
        if check_limits and K.limits(self.geo, wk) != K.OK:
            self.check_stroke(q)
        return q

    def stroke_violations(self, q: npt.ArrayLike) -> list[str]:
        """Human-readable stroke and gap violations of carriage positions ``q`` (6,)."""
        g = self.geometry
        q = as_array(q, (6,), "q")
        out = [f"carriage {i}: |q|={abs(q[i]):.6g} > rail_half_length={g.rail_half_length:g}"
               for i in range(6) if abs(q[i]) > g.rail_half_length]
        for k in range(3):
            gap = q[2 * k + 1] - q[2 * k]
            if gap < g.carriage_min_gap:
                what = "cross" if gap < 0 else "are too close"
                out.append(f"rail {k}: carriages {2 * k} and {2 * k + 1} {what} "
                           f"(gap {gap:.6g} < carriage_min_gap={g.carriage_min_gap:g})")
        return out

    def check_stroke(self, q: npt.ArrayLike) -> None:
        """Raise :class:`StrokeLimitError` when ``q`` violates a stroke or gap limit."""
        violations = self.stroke_violations(q)
        if violations:
            raise StrokeLimitError(q, violations)

    def branch_of(self, pose: npt.ArrayLike, q: npt.ArrayLike) -> np.ndarray:
        """The branch (six signs) on which ``q`` solves the inverse kinematics of ``pose``.

        ``s_i = sign(q_i - u_k . d_i)``, so that
        ``inverse_kinematics(pose, branch_of(pose, q)) == q``; a carriage exactly
        at the double root (leg perpendicular to its rail) gets ``+1``.

        Raises:
            InputError: bad shapes, or ``q`` does not assemble at ``pose`` (a leg
                length off by more than 1e-9 m, times the leg length above 1 m).
        """
        q = as_array(q, (6,), "q")
        wk = self._legs(as_array(pose, (6,), "pose"), None, refuse=())
        # home-branch legs: d = n + q_home u, u . d = q_home - s_home sqrt(disc)
        shift = (wk[K.Q] - q)[:, None] * self.chains.line_directions
        rel = wk[[K.NX, K.NY, K.NZ]].T + shift
        err = np.abs(np.linalg.norm(rel, axis=1) - self.chains.leg_lengths)
        if not np.max(err) <= 1e-9 * max(1.0, float(np.max(self.chains.leg_lengths))):
            raise InputError("q", q, f"does not assemble at the pose (leg length errors {err})")
        along = wk[K.Q] - HOME_BRANCH * np.sqrt(np.maximum(wk[K.DISC], 0.0))
        return np.where(q - along >= 0.0, 1.0, -1.0)

    # -- batch ------------------------------------------------------------------------------
    def inverse_kinematics_batch(self, poses: npt.ArrayLike,
                                 branch: npt.ArrayLike | None = None) -> InverseKinematicsBatch:
        """Inverse kinematics of many poses at once, with masks instead of exceptions.

        Args:
            poses: (N, 6) poses ``(x, y, z, roll, pitch, yaw)`` (m, rad).
            branch: None (home branch), six signs for every pose, or (N, 6) signs.

        Returns:
            :class:`~hexapod_pin.core.results.InverseKinematicsBatch`
            (``actuator_positions`` (N, 6), masks (N,)); the kernels of
            :meth:`inverse_kinematics`, run over the poses.

        Raises:
            InputError: wrong shape, NaN / inf anywhere, or a malformed branch.
        """
        poses = as_array(poses, (6,), "poses", batch=True)
        signs = batch.batch_signs(branch, poses.shape[0])
        return batch.kinematics_batch(self.geo, poses, signs, with_jacobian=False)

    def jacobian_batch(self, poses: npt.ArrayLike,
                       branch: npt.ArrayLike | None = None) -> JacobianBatch:
        """Inverse kinematics and workspace Jacobians of many poses.

        Args:
            poses: (N, 6) poses (m, rad).
            branch: None (home branch), six signs, or (N, 6) signs.

        Returns:
            :class:`~hexapod_pin.core.results.JacobianBatch`: ``jacobian`` (N, 6, 6) with
            ``qdot = J @ twist`` (twist ``(v, w)`` in world axes; zeros where not ``ok``),
            ``actuator_positions`` (N, 6) and the masks.

        Raises:
            InputError: wrong shape, NaN / inf anywhere, or a malformed branch.
        """
        poses = as_array(poses, (6,), "poses", batch=True)
        signs = batch.batch_signs(branch, poses.shape[0])
        return batch.kinematics_batch(self.geo, poses, signs, with_jacobian=True)

    # -- velocity level ---------------------------------------------------------------
    def jacobian(self, pose: npt.ArrayLike,
                 branch: npt.ArrayLike | None = None) -> npt.NDArray[np.float64]:
        """Workspace Jacobian ``J`` (6, 6) with ``qdot = J @ twist``.

        Rows in carriage order, ``J[i] = [n_i, r_k x n_i] / (n_i . u_k)``; columns
        ``(v, w)`` of the world-axes twist of the platform origin (m/s, rad/s).
        The legs are those of :meth:`inverse_kinematics` on ``branch`` (default
        the home branch), stroke limits not checked.

        Raises:
            InputError: wrong shape, NaN / inf, malformed branch.
            UnreachablePoseError: the pose cannot be reached.
            SingularityError: type-I singularity, a leg perpendicular to its rail
                (``|cos| < TYPE_I_TOL``): J is unbounded there.
        """
        out = np.empty((6, 6))
        K.jacobian(self._legs(pose, branch), out)
        return out

    def twist_from_actuator_velocities(self, pose: npt.ArrayLike,
                                       actuator_velocities: npt.ArrayLike,
                                       branch: npt.ArrayLike | None = None
                                       ) -> npt.NDArray[np.float64]:
        """Platform twist (6,) from carriage velocities (6,): solves ``J @ twist = qdot``.

        Twist ``(v, w)``: velocity of the platform origin and angular velocity,
        world axes (m/s, rad/s).

        Raises:
            InputError: bad shapes or values.
            UnreachablePoseError: the pose cannot be reached.
            SingularityError: type I (from :meth:`jacobian`) or type II
                (``sigma_min(A_hat) < TYPE_II_TOL``, the test of every route).
        """
        return self._twist_from(pose, actuator_velocities, branch, "actuator_velocities")

    def _twist_from(self, pose, velocities, branch, name: str) -> npt.NDArray[np.float64]:
        """:meth:`twist_from_actuator_velocities`, its errors naming ``velocities``
        ``name``."""
        qdot = as_array(velocities, (6,), name)
        wk = self._legs(pose, branch)
        jac = np.empty((6, 6))
        K.jacobian(wk, jac)
        code = K.factor_legs(self.geo, wk, self._scratch.mats)
        if code != K.OK:
            raise K.error_of(code, self.geo, wk, self._scratch.mats[1])
        return np.linalg.solve(jac, qdot)

    def twist_from_qdot(self, pose: npt.ArrayLike, qdot: npt.ArrayLike,
                        branch: npt.ArrayLike | None = None) -> np.ndarray:
        """:meth:`twist_from_actuator_velocities` (the carriage velocities ``qdot``)."""
        return self._twist_from(pose, qdot, branch, "qdot")

    def jacobian_derivative(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
                            branch: npt.ArrayLike | None = None) -> npt.NDArray[np.float64]:
        """Time derivative ``dJ/dt`` (6, 6) of the workspace Jacobian along a twist.

        With ``dn_i/dt = v + w x r_k - qdot_i u_k`` and ``dr_k/dt = w x r_k``::

            dJ[i]/dt = [dn_i, (w x r_k) x n_i + r_k x dn_i] / (n_i . u_k)
                       - J[i] (dn_i . u_k) / (n_i . u_k)

        Args:
            pose: (6,) (m, rad).
            twist: ``(v, w)`` (6,), world axes (m/s, rad/s).
            branch: IK branch, default the home branch.

        Returns:
            dJ/dt, shape (6, 6) (units of J per second).

        Raises:
            InputError: bad shape, non-finite or non-real values (as :meth:`jacobian`).
            UnreachablePoseError: a leg cannot reach the pose (as :meth:`jacobian`).
            SingularityError: at a singular configuration (as :meth:`jacobian`).
        """
        twist = vec6(twist, "twist")
        wk = self._moving_legs(pose, twist, None, branch)
        out = np.empty((6, 6))
        K.jacobian_derivative(self.geo, wk, twist, out)
        return out

    def qddot(self, pose: npt.ArrayLike, twist: npt.ArrayLike, twist_dot: npt.ArrayLike,
              branch: npt.ArrayLike | None = None) -> np.ndarray:
        """Carriage accelerations (6,) (m/s^2): ``qddot = J twist_dot + dJ/dt twist``.

        Evaluated in the equivalent form obtained by differentiating
        ``n_i . dn_i/dt = 0`` once more::

            qddot_i = (|dn_i/dt|^2 + n_i . d2P_k/dt2) / (n_i . u_k),
            d2P_k/dt2 = vdot + wdot x r_k + w x (w x r_k)

        (:meth:`jacobian_derivative` gives the other form; the tests check both).

        Args:
            pose: (6,) (m, rad).
            twist: ``(v, w)`` (6,) world axes (m/s, rad/s).
            twist_dot: plain time derivative of ``twist`` (6,) (m/s^2, rad/s^2).
            branch: IK branch, default the home branch.

        Raises:
            InputError: bad shape, non-finite or non-real values (as :meth:`jacobian`).
            UnreachablePoseError: a leg cannot reach the pose (as :meth:`jacobian`).
            SingularityError: at a singular configuration (as :meth:`jacobian`).
        """
        required(twist_dot=twist_dot)      # without it the kernels leave QDD unwritten
        return self._moving_legs(pose, twist, twist_dot, branch)[K.QDD].copy()

    def leg_motion(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
                   twist_dot: npt.ArrayLike | None = None,
                   branch: npt.ArrayLike | None = None) -> LegMotion:
        """Direction, angular velocity / acceleration and centre-of-mass motion of each leg.

        See :class:`LegMotion` for the definitions (the angular velocity is the
        true one of the rigid leg behind its universal joint; computed by
        :func:`~hexapod_pin.hexapod.kernels.leg_motion`).

        Args:
            pose: (6,) (m, rad).
            twist: ``(v, w)`` (6,) world axes (m/s, rad/s).
            twist_dot: its time derivative (6,), or None (no accelerations).
            branch: IK branch, default the home branch.

        Raises:
            InputError: bad shape, non-finite or non-real values (as :meth:`jacobian`).
            UnreachablePoseError: a leg cannot reach the pose (as :meth:`jacobian`).
            SingularityError: at a singular configuration (as :meth:`jacobian`), and where a
                leg lies along its rail (the universal joint's gimbal lock: the leg's spin is
                undefined).
        """
        wk = self._moving_legs(pose, twist, twist_dot, branch)
        out = np.empty((6, 6, 3))
        code = K.leg_motion(self.geo, wk, twist_dot is not None, out)
        if code != K.OK:
            raise K.error_of(code, self.geo, wk)
        qdot = wk[K.QD].copy()
        if twist_dot is None:
            return LegMotion(out[0], out[1], out[2], out[3], qdot)
        return LegMotion(out[0], out[1], out[2], out[3], qdot, out[4], out[5],
                         wk[K.QDD].copy())

    # -- singularities ----------------------------------------------------------------------
    def singularity(self, pose: npt.ArrayLike,
                    branch: npt.ArrayLike | None = None) -> SingularityMeasures:
        """Measures of the distance to type-I and type-II singularities (the definitions
        of :class:`~hexapod_pin.core.results.SingularityMeasures`, computed by
        :func:`~hexapod_pin.core.measures.singularity_measures`; the characteristic length
        is the platform radius). Does not raise at a singular pose.

        Raises:
            InputError: bad shapes or values.
            UnreachablePoseError: the pose cannot be reached.
        """
        wk = self._legs(pose, branch, refuse=(K.UNREACHABLE,))
        cosines = np.abs(wk[K.NU]) / self.chains.leg_lengths
        a_hat = np.empty((6, 6))
        K.closure_matrix_hat(self.geo, wk, a_hat)
        jac = None
        if cosines.min() >= TYPE_I_TOL:
            jac = np.empty((6, 6))
            K.jacobian(wk, jac)
        return singularity_measures(jac, cosines, a_hat, self.geometry.platform_radius)

    # -- forward kinematics and assembly modes -------------------------------------------------
    def forward_kinematics(self, actuators: npt.ArrayLike,
                           guess: npt.ArrayLike | None = None) -> npt.NDArray[np.float64]:
        """Platform pose for carriage positions ``actuators``: Newton's method from ``guess``.

        The 18 closure equations reduce exactly to three (see
        :mod:`hexapod_pin.hexapod.assembly_modes`): each platform point lies on the circle
        where its two legs' spheres meet, at angle ``theta_k``; the unknowns are
        the three angles and the equations the three sides of the platform
        triangle. Newton's method on this 3x3 system converges quadratically (its
        Jacobian is singular exactly where the full closure Jacobian is, the
        type-II singularities); it stops at side errors below 1e-14 m. The pose
        is then rebuilt from the three points and checked on the six original
        leg-length equations: every leg within 1e-12 m of ``leg_length``, else
        :class:`AssemblyError` (never a wrong pose). Both tolerances are scaled
        by ``leg_length`` when it exceeds 1 m.

        Newton converges to the assembly mode whose basin holds ``guess``; to
        follow a motion, pass the previous pose. :meth:`assembly_modes` lists all.
        Stroke limits are not checked. As built (no three-circle reduction) it is Newton's
        method on the six closure equations
        (:func:`~hexapod_pin.hexapod.assembly_modes.forward_as_built`, leg errors below
        1e-12 m, scaled as above).

        Args:
            actuators: carriage positions (6,) (m).
            guess: a pose (6,) near the wanted one; default the home pose.

        Returns:
            pose ``(x, y, z, roll, pitch, yaw)`` (6,) (m, rad), pitch in [-pi/2, pi/2].

        Raises:
            InputError: bad shapes or NaN / inf.
            AssemblyError: no assembly (two carriages of a rail more than
                ``2 leg_length`` apart), degenerate carriages (coincident, or
                exactly ``2 leg_length`` apart), a singular Jacobian (type II), no
                convergence within ``FK_MAX_ITER`` iterations, or a final leg-length error above
                1e-12 m.
        """
        q = as_array(actuators, (6,), "actuators").tolist()
        guess = self._home_list if guess is None else as_array(guess, (6,), "guess").tolist()
        if not self.geometry.is_ideal:
            return am.forward_as_built(self.chains, q, guess, max_iter=FK_MAX_ITER)
        cg = self.circles
        system = am.circle_system(cg, q)
        if system is None:
            excess = max(abs(q[1] - q[0]), abs(q[3] - q[2]), abs(q[5] - q[4])) - 2 * cg.leg_length
            raise AssemblyError("no assembly: two carriages of a rail are more than "
                                "2 leg_length apart", excess, 0)
        theta = system.angles_of_t(am.platform_points_t(cg, guess))
        scale = max(1.0, cg.leg_length)
        result = am.newton_circles(system, theta, max_iter=FK_MAX_ITER, tol=am.INNER_TOL * scale)
        pose = am.pose_from_points_t(cg, system.points_t(*result.theta))
        err = am.leg_length_error(cg, pose, q)
        if not err <= am.POSE_TOL * scale:
            raise AssemblyError("the converged pose misses the leg lengths", err,
                                result.iterations)
        return np.array(pose)

    def assembly_modes(self, actuators: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """Every real assembly of the closed chain for carriage positions ``actuators``.

        Method (details and the completeness argument in
        :func:`hexapod_pin.hexapod.assembly_modes.enumerate_assemblies`): with the
        carriages held, platform point k lies on a circle (the two leg spheres of
        rail k meet there) at an angle ``theta_k``; the three sides of the platform
        triangle give three equations bilinear in ``(cos, sin)`` of two angles.
        Eliminating two angles by Sylvester resultants leaves a trigonometric
        polynomial of degree 8 in ``theta_0`` (a polynomial of degree 16 in
        ``exp(i theta_0)``: the 16 complex assemblies of a 6-3 Stewart platform);
        its coefficients come exactly from 32 samples and a DFT, all its roots
        from a companion matrix, and every root on the unit circle is completed
        exhaustively by closed-form circle intersections, polished by Newton and
        deduplicated. Each assembly is verified on the six leg-length equations
        (1e-12 m). For the default geometry at home there are 8 (4 above the rail
        plane and their mirror images). As built, the drawing's modes at the same readings
        are followed to the as-built geometry by continuation
        (:func:`~hexapod_pin.hexapod.assembly_modes.modes_as_built`: complete for
        deviations small against the distances between modes).

        An assembly is a platform pose; the universal-joint angles follow from it
        (each up to the joint's own ``(a, b) ~ (a + pi, pi - b)`` ambiguity, which
        is not a different assembly). Stroke limits and collisions are ignored.
        The branch of each carriage in a mode is :meth:`branch_of`.

        Args:
            actuators: carriage positions (6,) (m).

        Returns:
            poses (n_modes, 6) (m, rad), sorted by height z, highest first; no rows
            when two carriages of a rail are more than ``2 leg_length`` apart.

        Raises:
            InputError: bad shape or NaN / inf.
            AssemblyError: degenerate carriage positions with a continuum of
                assemblies (two carriages of a rail coincide, stand exactly
                ``2 leg_length`` apart, or the eliminant vanishes identically).
        """
        q = as_array(actuators, (6,), "actuators")
        if not self.geometry.is_ideal:
            poses = am.modes_as_built(self.geometry, q)
            poses.sort(key=lambda p: (-p[2], tuple(p)))
            return np.array(poses).reshape(-1, 6)
        cg = self.circles
        system = am.circle_system(cg, q)
        if system is None:
            return np.empty((0, 6))
        poses = []
        for theta in am.enumerate_assemblies(system):
            pose = am.pose_from_points_t(cg, system.points_t(*theta.tolist()))
            err = am.leg_length_error(cg, pose, q.tolist())
            if err <= am.POSE_TOL * max(1.0, cg.leg_length):
                poses.append(np.array(pose))
        poses.sort(key=lambda p: (-p[2], tuple(p)))
        return np.array(poses).reshape(-1, 6)
