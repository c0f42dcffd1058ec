"""Kinematics of the planar 3-PRR robot: inverse kinematics, Jacobian and its derivative,
singularity measures, the closed-form tree state, and their batches.

Every route runs the compiled closed form of :mod:`hexapod_pin.planar.kernels` (one
kernel call per single state; the batches run the same kernels over N states) and raises
the library's exception with the values the kernel reports. Conventions: see
:mod:`hexapod_pin.planar.geometry`; ``actuator velocities = J @ twist``, ``J`` (3, 3),
rows in actuator order, columns ``(vx, vy, omega)`` (world axes).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from ..core import effects_projection as drv
from ..core.checks import as_array, flag, vector
from ..core.closed_loop import ClosedLoopModel
from ..core.measures import TYPE_I_TOL, TYPE_II_TOL, singularity_measures
from ..core.results import InverseKinematicsBatch, JacobianBatch, SingularityMeasures
from ..errors import (AssemblyError, BatchSingularityError, BatchUnreachablePoseError,
                      DescriptionError, InputError, SingularityError, StrokeLimitError,
                      UnreachablePoseError)
from . import kernels
from .geometry import HOME_BRANCH, N_ACTUATORS, PlanarGeometry, PlanarIndices, check_branch

#: closure residual accepted for a closed-form configuration (m), for robots up to 1 m;
#: scaled by the robot's size above (round-off grows with the coordinates)
CLOSED_FORM_TOL = 1e-12
_TYPE_I_WHAT = "inverse kinematic Jacobian (a link perpendicular to its rail)"
_TYPE_I_MEASURE = "|cos| of a link and its rail"
_TYPE_II_WHAT = ("leg matrix A_hat = [e_k, (r_k x e_k) / platform_radius] (type-II "
                 "singularity; sigma_min(A_hat))")


def vec3(value: npt.ArrayLike, name: str) -> np.ndarray:
    """:func:`~hexapod_pin.core.checks.vector` of size 3 (a planar pose, twist or wrench)."""
    return vector(value, 3, name)


class PlanarWorkspace:
    """The cache of one robot: the kernels' geometry vector (with the sliders' drives of
    the model's joint effects, :mod:`hexapod_pin.core.effects_projection`) and tree
    indices, scratch buffers (single states; not thread-safe), and where the closures' rows
    sit.

    Args:
        geometry: the robot's geometry.
        model: its :class:`ClosedLoopModel` (closures ``link_<k>_tip`` on
            ``platform_anchor_<k>``, in that order); its effects give the drives of
            :attr:`geo`, an armature written into ``model.model.armature`` by hand noticed
            at the next access of :attr:`geo`.

    Raises:
        DescriptionError: the loops file does not hold those closures.
    """

    def __init__(self, geometry: PlanarGeometry, model: ClosedLoopModel) -> None:
        expected = [("point", f"link_{k}_tip", f"platform_anchor_{k}")
                    for k in range(N_ACTUATORS)]
        if [(c.type, c.frame1, c.frame2) for c in model.closures] != expected:
            raise DescriptionError("planar_3prr.loops.yaml", "expected the point closures "
                                   f"{expected}, in that order")
        self.indices = PlanarIndices(
            np.array([model.joint_v_index(f"slider_{k}") for k in range(N_ACTUATORS)]),
            np.array([model.joint_v_index(f"link_{k}_joint") for k in range(N_ACTUATORS)]),
            np.array([model.joint_v_index(j) for j in ("platform_x", "platform_y",
                                                       "platform_theta")]))
        #: first multiplier row of each closure (its in-plane rows: that one and the next)
        self.rows = np.array([r.start for r in model.row_slices])
        self.idx = np.concatenate([self.indices.platform, self.indices.slider,
                                   self.indices.link, self.rows]).astype(np.int64)
        self._packed = drv.PackedDrives(
            model, lambda drives, passive: kernels.pack_geometry(geometry, drives, passive))
        #: the kernels' vector as built: its geometry part is all that the kinematic kernels
        #: read; the dynamics kernels take :attr:`dynamics_geo`
        self.geo = self._packed.vector
        #: the characteristic length of the singularity measures (m)
        self.platform_radius = float(geometry.platform_radius)
        #: rail midpoints ``m_k``, directions ``u_k``, platform points ``p_k`` (3, 2), read-only
        self.mids = _frozen(geometry.rail_midpoints)
        self.dirs = _frozen(geometry.rail_directions)
        self.pts = _frozen(geometry.platform_points)
        self.half_stroke = geometry.rail_half_length
        self.nq, self.nv, self.n_rows = model.nq, model.nv, model.n_rows
        self.home_signs = HOME_BRANCH.copy()
        self.zero3 = np.zeros(3)
        self.buf = np.zeros((N_ACTUATORS, kernels.LEG_COLS))
        self.info = np.zeros(kernels.INFO_SIZE)

    @property
    def dynamics_geo(self) -> np.ndarray:
        """The kernels' geometry vector with the current drives (a new array when the
        armature was written by hand since the last access): what the dynamics kernels
        read."""
        return self._packed.vector

    def signs(self, branch: npt.ArrayLike | None) -> np.ndarray:
        """A validated branch (3,) (``None``: the home branch)."""
        return self.home_signs if branch is None else np.array(check_branch(branch))

    def raise_for(self, status: int, inputs: Sequence[tuple[Any, str]],
                  info: np.ndarray | None = None, index: int | None = None) -> None:
        """Raise the library's exception for a kernel status.

        Args:
            status: the kernel's status (not OK).
            inputs: ``(value, name)`` pairs as given, for an :class:`InputError`.
            info: the kernel's info vector (default: the single-state one).
            index: the state of a batch (Batch* errors), or None.

        A residual refusal (a closed form that failed its own residual check, which happens
        near a singularity) reports the measure nearer its threshold (``|cos|`` against
        TYPE_I_TOL or ``sigma_min(A_hat)`` against TYPE_II_TOL) of the legs in the leg
        buffer, which must hold the refused state's legs.

        Raises:
            InputError: bad shape, non-finite or non-real values.
            UnreachablePoseError: a leg cannot reach the pose.
            SingularityError: at a singular configuration (Batch* with ``index``).
        """
        info = self.info if info is None else info
        if status == kernels.NONFINITE:
            for value, name in inputs:
                if value is not None:
                    as_array(value, (3,), name)          # raises, naming the value
            raise InputError(inputs[0][1], inputs[0][0], "contains NaN or inf")
        if status == kernels.UNREACHABLE:
            bad = [k for k in range(N_ACTUATORS) if info[3 + k] > 0.0]
            # an overflowing discriminant leaves NaN: out of range, an infinite shortfall
            short = [info[k] if info[k] >= 0.0 else math.inf for k in bad]
            if index is not None:
                raise BatchUnreachablePoseError(index, bad, short)
            raise UnreachablePoseError(bad, short)
        measure = "smallest singular value"
        if status == kernels.TYPE_I:
            what, value, tol = _TYPE_I_WHAT, info[kernels.X_WORST], kernels.TYPE_I_TOL
            measure = _TYPE_I_MEASURE
        elif status == kernels.TYPE_II:
            what, value, tol = _TYPE_II_WHAT, info[kernels.X_TYPE_TWO], kernels.TYPE_II_TOL
        else:
            # the closed form failed its own residual check (round-off near a singularity):
            # the measure of the legs in the buffer nearer its threshold, with that threshold
            cosines, a_hat = np.empty(N_ACTUATORS), np.empty((N_ACTUATORS, 3))
            kernels.singularity_parts(self.geo, self.buf, cosines, a_hat)
            measures = singularity_measures(None, cosines, a_hat, self.platform_radius)
            label = "closed-form closure system (ill-conditioned: max-abs residual " \
                f"{info[kernels.X_RES]:.3e}, beyond {kernels.RESIDUAL_RTOL:.0e} of the " \
                "terms' magnitude) near a "
            if measures.type_one / TYPE_I_TOL <= measures.type_two / TYPE_II_TOL:
                what = label + "type-I singularity"
                value, tol, measure = measures.type_one, TYPE_I_TOL, _TYPE_I_MEASURE
            else:
                what = label + "type-II singularity (A_hat)"
                value, tol = measures.type_two, TYPE_II_TOL
        if index is not None:
            raise BatchSingularityError(index, what, value, tol, measure)
        raise SingularityError(what, value, tol, measure)

    def legs(self, level: int, singular: bool, branch: npt.ArrayLike | None,
             inputs: Sequence[tuple[Any, str]], pose: npt.ArrayLike,
             twist: npt.ArrayLike | None = None) -> None:
        """Fill the leg buffer of a platform state by :func:`kernels.leg_state` (``level``
        0: legs and Jacobian rows; 1: also the rates of ``twist``). Raises as
        :meth:`raise_for`."""
        status = kernels.leg_state(self.geo, pose, self.zero3 if twist is None else twist,
                                   self.zero3, self.signs(branch), level, singular, self.buf,
                                   self.info)
        if status != kernels.OK:
            self.raise_for(status, inputs)

    def state(self, level: int, singular: bool, branch: npt.ArrayLike | None,
              inputs: Sequence[tuple[Any, str]], pose: npt.ArrayLike,
              twist: npt.ArrayLike | None = None,
              twist_dot: npt.ArrayLike | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Tree ``q``, ``v``, ``a`` (fresh (nv,) arrays, model order) of a platform state,
        by :func:`kernels.tree_state` (``v`` filled from ``level`` 1, ``a`` from 2); the
        leg buffer then holds the legs. Raises as :meth:`raise_for`."""
        nv = self.nv
        q, v, a = np.empty(nv), np.empty(nv), np.empty(nv)
        status = kernels.tree_state(self.geo, self.idx, pose,
                                    self.zero3 if twist is None else twist,
                                    self.zero3 if twist_dot is None else twist_dot,
                                    self.signs(branch), level, singular, q, v, a, self.buf,
                                    self.info)
        if status != kernels.OK:
            self.raise_for(status, inputs)
        return q, v, a


class PlanarKinematics:
    """The kinematics of one planar 3-PRR (see the module docstring).

    Args:
        geometry: the robot's geometry.
        model: its :class:`ClosedLoopModel`.
        workspace: its :class:`PlanarWorkspace`.
    """

    def __init__(self, geometry: PlanarGeometry, model: ClosedLoopModel,
                 workspace: PlanarWorkspace) -> None:
        self.geometry, self.model, self.ws = geometry, model, workspace
        self.mids, self.dirs, self.pts = workspace.mids, workspace.dirs, workspace.pts

    # -- points ----------------------------------------------------------------------------
    def platform_points_world(self, pose: npt.ArrayLike) -> np.ndarray:
        """World positions ``P_k`` of the three platform joints (m), shape (3, 2)."""
        pose = as_array(pose, (3,), "pose")
        c, s = np.cos(pose[2]), np.sin(pose[2])
        return pose[:2] + self.pts @ np.array([[c, s], [-s, c]])

    def slider_points(self, actuators: npt.ArrayLike) -> np.ndarray:
        """World positions ``c_k = m_k + s_k u_k`` of the slider joints (m), shape (3, 2)."""
        s = as_array(actuators, (N_ACTUATORS,), "actuators")
        return self.mids + s[:, None] * self.dirs

    def link_vectors(self, pose: npt.ArrayLike, actuators: npt.ArrayLike) -> np.ndarray:
        """Link vectors ``n_k = P_k - c_k`` (m), shape (3, 2); ``|n_k| = L`` when closed."""
        return self.platform_points_world(pose) - self.slider_points(actuators)

    def size(self) -> float:
        """The robot's size (m): the largest of link length, rail and platform radii."""
        g = self.geometry
        return float(max(g.link_length, g.rail_radius, g.platform_radius))

    def branch_of(self, pose: npt.ArrayLike, actuators: npt.ArrayLike) -> np.ndarray:
        """The IK branch (3 signs) that maps ``pose`` to ``actuators``: ``-sign(n_k . u_k)``.

        Raises:
            InputError: bad shapes, or ``actuators`` that do not assemble at ``pose`` (a
                link length off by more than 1e-9 m, times the size above 1 m).
            SingularityError: a link perpendicular to its rail (both branches meet).
        """
        links = self.link_vectors(pose, actuators)
        dots = np.einsum("ki,ki->k", links, self.dirs)
        worst = float(np.min(np.abs(dots))) / self.geometry.link_length
        if worst < kernels.TYPE_I_TOL:
            raise SingularityError(_TYPE_I_WHAT, worst, kernels.TYPE_I_TOL, _TYPE_I_MEASURE)
        with np.errstate(over="ignore"):
            err = np.abs(np.linalg.norm(links, axis=1) - self.geometry.link_length)
        if not np.max(err) <= 1e-9 * max(1.0, self.size()):
            raise InputError("actuators", actuators,
                             f"do not assemble at the pose (link length errors {err})")
        return -np.sign(dots)

    # -- inverse kinematics ----------------------------------------------------------------
    def inverse_kinematics(self, pose: npt.ArrayLike, branch: npt.ArrayLike | None = None,
                           check_limits: bool = True) -> npt.NDArray[np.float64]:
        """Slider positions (3,) (m along ``u_k`` from the rail midpoint) of a pose.

        ``s_k = u_k . d_k + branch_k sqrt(L^2 - |d_k|^2 + (u_k . d_k)^2)``,
        ``d_k = P_k - m_k`` (closed form, :func:`kernels.legs`).

        Args:
            pose: ``(x, y, theta)`` (m, m, rad), shape (3,).
            branch: three signs ``+1`` / ``-1`` choosing the root of each slider's
                quadratic (``+1``: the larger ``s_k``, the home branch); default all
                ``+1``. The 8 branches are :data:`~hexapod_pin.planar.geometry.ALL_BRANCHES`.
            check_limits: check ``abs(s_k) <= rail_half_length``.

        Raises:
            InputError: wrong shape, NaN / inf, or a malformed branch.
            UnreachablePoseError: a link cannot reach its rail (``carriages``: the
                actuator indices, ``shortfall``: how much too short, m).
            StrokeLimitError: with ``check_limits``, a slider outside its stroke.
        """
        check_limits = flag(check_limits, "check_limits")
        ws = self.ws
        ws.legs(0, False, branch, ((pose, "pose"),), vec3(pose, "pose"))
        s = ws.buf[:, kernels.S].copy()
        if check_limits and ws.info[kernels.X_SMAX] > ws.half_stroke:
            self.check_stroke(s)
        return s

    def stroke_violations(self, actuators: npt.ArrayLike) -> list[str]:
        """Human-readable stroke violations of slider positions (3,)."""
        s = as_array(actuators, (N_ACTUATORS,), "actuators")
        h = self.ws.half_stroke
        return [f"slider {k}: |s|={abs(s[k]):.6g} > rail_half_length={h:g}"
                for k in range(N_ACTUATORS) if abs(s[k]) > h]

    def check_stroke(self, actuators: npt.ArrayLike) -> None:
        """Raise :class:`StrokeLimitError` when the slider positions leave the stroke."""
        violations = self.stroke_violations(actuators)
        if violations:
            raise StrokeLimitError(actuators, violations)

    # -- Jacobian ---------------------------------------------------------------------------
    def jacobian(self, pose: npt.ArrayLike,
                 branch: npt.ArrayLike | None = None) -> npt.NDArray[np.float64]:
        """Workspace Jacobian ``J`` (3, 3), ``actuator velocities = J @ twist``.

        From ``d/dt |n_k|^2 = 0`` with ``dP_k/dt = v + omega z x r_k``, ``r_k = R p_k``:
        ``J[k] = [n_k, r_k x n_k] / (n_k . u_k)``.

        Raises:
            InputError: bad shape, non-finite or non-real values (see :meth:`inverse_kinematics`).
            UnreachablePoseError: a leg cannot reach the pose (see :meth:`inverse_kinematics`).
            SingularityError: a link perpendicular to its rail (type I singularity).
        """
        self.ws.legs(0, True, branch, ((pose, "pose"),), vec3(pose, "pose"))
        return self.ws.buf[:, kernels.J0:kernels.J2 + 1].copy()

    def twist_from_actuator_velocities(self, pose: npt.ArrayLike,
                                       actuator_velocities: npt.ArrayLike,
                                       branch: npt.ArrayLike | None = None
                                       ) -> npt.NDArray[np.float64]:
        """Platform twist (3,) from slider velocities (m/s): solves ``J @ twist = sdot``.

        Raises:
            SingularityError: a type-I singularity, or a type-II one (``sigma_min(A_hat)``
                below :data:`~hexapod_pin.core.measures.TYPE_II_TOL`, the test of every
                route).
        """
        jac = self.jacobian(pose, branch=branch)
        sdot = as_array(actuator_velocities, (N_ACTUATORS,), "actuator_velocities")
        sigma = kernels.type_two_sigma(self.ws.geo, self.ws.buf)
        if not sigma >= kernels.TYPE_II_TOL:
            raise SingularityError(_TYPE_II_WHAT, sigma, kernels.TYPE_II_TOL)
        return np.linalg.solve(jac, sdot)

    def jacobian_derivative(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
                            branch: npt.ArrayLike | None = None) -> npt.NDArray[np.float64]:
        """``dJ/dt`` (3, 3) along the motion ``twist`` (closed form,
        :func:`kernels.jacobian_derivative`); ``actuator accelerations = J twist_dot +
        dJ/dt twist``.

        Raises:
            InputError: bad shape, non-finite or non-real values (see :meth:`jacobian`).
            UnreachablePoseError: a leg cannot reach the pose (see :meth:`jacobian`).
            SingularityError: at a singular configuration (see :meth:`jacobian`).
        """
        twist_a = vec3(twist, "twist")
        self.ws.legs(1, True, branch, ((pose, "pose"), (twist, "twist")), vec3(pose, "pose"),
                     twist_a)
        out = np.empty((3, 3))
        kernels.jacobian_derivative(self.ws.geo, self.ws.buf, twist_a, out)
        return out

    def singularity(self, pose: npt.ArrayLike,
                    branch: npt.ArrayLike | None = None) -> SingularityMeasures:
        """Distances to type-I and type-II singularities (never raises at one).

        Definitions: :class:`~hexapod_pin.core.results.SingularityMeasures`, computed by
        :func:`hexapod_pin.core.measures.singularity_measures`; the characteristic length
        is the platform radius.

        Raises:
            InputError: bad shape, non-finite or non-real values.
            UnreachablePoseError: a leg cannot reach the pose.
        """
        ws = self.ws
        ws.legs(0, False, branch, ((pose, "pose"),), vec3(pose, "pose"))
        cosines, a_hat = np.empty(N_ACTUATORS), np.empty((N_ACTUATORS, 3))
        kernels.singularity_parts(ws.geo, ws.buf, cosines, a_hat)
        jac = None
        if ws.info[kernels.X_WORST] >= kernels.TYPE_I_TOL:
            jac = ws.buf[:, kernels.J0:kernels.J2 + 1].copy()
        return singularity_measures(jac, cosines, a_hat, self.geometry.platform_radius)

    # -- tree state -------------------------------------------------------------------------
    def configuration(self, pose: npt.ArrayLike,
                      branch: npt.ArrayLike | None = None) -> npt.NDArray[np.float64]:
        """Pinocchio configuration ``q`` (nq = 9,) of the tree for a pose (closed form).

        Sliders from the inverse kinematics (stroke not checked), link angles
        ``atan2(n_k) - (a_k + 90 deg)`` in (-pi, pi], the platform chain the pose itself;
        the closures are then evaluated on the Pinocchio model.

        Raises:
            InputError: bad shape, non-finite or non-real values (see :meth:`inverse_kinematics`).
            UnreachablePoseError: a leg cannot reach the pose (see :meth:`inverse_kinematics`).
            AssemblyError: the closed form misses the closures by more than 1e-12 m
                (times the robot's size in m above 1 m: :meth:`size`).
        """
        q, _, _ = self.ws.state(0, False, branch, ((pose, "pose"),), vec3(pose, "pose"))
        err = float(np.max(np.abs(self.model.residual(q))))
        if not err <= CLOSED_FORM_TOL * max(1.0, self.size()):
            raise AssemblyError("closed-form configuration misses the closures", err, 0, q)
        return q

    def velocity(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
                 branch: npt.ArrayLike | None = None) -> np.ndarray:
        """Tree velocity ``v`` (nv = 9,) of a platform motion, every closure kept: sliders
        ``J @ twist``, link rates ``n_k x (dP_k/dt - s'_k u_k) / L^2``, the platform
        chain the twist itself.

        Raises:
            InputError: bad shape, non-finite or non-real values (see :meth:`jacobian`).
            UnreachablePoseError: a leg cannot reach the pose (see :meth:`jacobian`).
            SingularityError: at a singular configuration (see :meth:`jacobian`).
        """
        inputs = ((pose, "pose"), (twist, "twist"))
        return self.ws.state(1, True, branch, inputs, vec3(pose, "pose"),
                             vec3(twist, "twist"))[1]

    def acceleration(self, pose: npt.ArrayLike, twist: npt.ArrayLike, twist_dot: npt.ArrayLike,
                     branch: npt.ArrayLike | None = None) -> np.ndarray:
        """Tree acceleration ``a`` (nv = 9,) of a platform motion, every closure kept
        (closed form: :func:`kernels.accelerations`); the platform chain's is
        ``twist_dot``.

        Raises:
            InputError: bad shape, non-finite or non-real values (see :meth:`jacobian`).
            UnreachablePoseError: a leg cannot reach the pose (see :meth:`jacobian`).
            SingularityError: at a singular configuration (see :meth:`jacobian`).
        """
        inputs = ((pose, "pose"), (twist, "twist"), (twist_dot, "twist_dot"))
        return self.ws.state(2, True, branch, inputs, vec3(pose, "pose"),
                             vec3(twist, "twist"), vec3(twist_dot, "twist_dot"))[2]

    def pose_from_configuration(self, q: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """Platform pose (3,) read from a Pinocchio configuration (nq,)."""
        return self.model.check_q(q)[self.ws.indices.platform].copy()

    def actuator_positions(self, q: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """Slider positions (3,) read from a Pinocchio configuration (nq,)."""
        return self.model.check_q(q)[self.ws.indices.slider].copy()

    # -- batches ----------------------------------------------------------------------------
    def inverse_kinematics_batch(self, poses: npt.ArrayLike,
                                 branch: npt.ArrayLike | None = None) -> InverseKinematicsBatch:
        """:meth:`inverse_kinematics` of N poses (N, 3) at once (never raises for a state).

        Raises:
            InputError: bad shape, NaN / inf, malformed branch.
        """
        poses = as_array(poses, (3,), "poses", batch=True)
        n = poses.shape[0]
        positions = np.empty((n, N_ACTUATORS))
        reachable, regular = np.empty(n, bool), np.empty(n, bool)
        infos = np.empty((n, kernels.INFO_SIZE))
        kernels.inverse_kinematics_batch(self.ws.geo, self.ws.signs(branch), poses,
                                         positions, reachable, regular, infos)
        within = np.all(np.abs(positions) <= self.ws.half_stroke, axis=1)
        return InverseKinematicsBatch(positions, reachable, within, reachable & within)

    def jacobian_batch(self, poses: npt.ArrayLike,
                       branch: npt.ArrayLike | None = None) -> JacobianBatch:
        """:meth:`jacobian` of N poses (N, 3) at once: ``J`` (N, 3, 3), zero where a state
        is unreachable or type-I singular (never raises for a state).

        Raises:
            InputError: bad shape, NaN / inf, malformed branch.
        """
        poses = as_array(poses, (3,), "poses", batch=True)
        n = poses.shape[0]
        jac, positions = np.empty((n, N_ACTUATORS, 3)), np.empty((n, N_ACTUATORS))
        reachable, regular = np.empty(n, bool), np.empty(n, bool)
        infos = np.empty((n, kernels.INFO_SIZE))
        kernels.jacobian_batch(self.ws.geo, self.ws.signs(branch), poses, jac, positions,
                               reachable, regular, infos)
        within = np.all(np.abs(positions) <= self.ws.half_stroke, axis=1)
        return JacobianBatch(jac, positions, reachable, regular, within, reachable & regular)


def _frozen(array: np.ndarray) -> np.ndarray:
    array = np.array(array, dtype=float)
    array.setflags(write=False)
    return array
