"""Kinematics of a robot loaded from a description: poses, inverse and forward kinematics,
assembly modes, Jacobians and singularity measures, all derived from the tree and its
closures (no closed form).

Conventions: :mod:`hexapod_pin.core.platform_map` (pose, twist, the maps ``A`` and ``B``).

* **Inverse kinematics** is a Gauss-Newton solve of the closures and the selected pose
  components together, ``[J_c; P] dq = -[r(q); pose(q) - target]`` (``P`` the pose rows,
  minimum-norm steps on ``pin.integrate``, halved while they do not decrease the error),
  started from the home configuration. Where the direct iteration does not converge it is
  repeated by continuation along the straight segment from the home pose (sub-steps
  halved where a solve fails, down to 1/64 of the way, and doubled after a success). The **branch** of a pose (its working mode) is therefore the one reached
  from home; ``branch`` may instead be a configuration (nq,) to start from, which
  selects the working mode nearest it. Every answer closes the loops and meets the pose
  to :attr:`RobotKinematics.tol` or raises.
* **Forward kinematics** assembles the closures with the actuators held
  (:meth:`ClosedLoopModel.assemble`), from the configuration of ``guess`` (default
  home), with the same continuation in actuator space when the direct solve fails.
* **Assembly modes**: a multi-start search (the home configuration and seeded random
  configurations, each assembled with the actuators held), verified and de-duplicated by
  pose. It finds the modes its starts reach; it is NOT proven complete.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ..errors import (AssemblyError, InconsistentMotionError, InputError, SingularityError,
                      SolverError, StrokeLimitError, UnreachablePoseError)
from .checks import MAX_MAGNITUDE, as_array, count, flag
from .compiled import all_within
from .closed_loop import ClosedLoopModel
from .measures import (TREE_TYPE_I_TOL, TREE_TYPE_II_TOL, inverse_condition,
                       tree_singularity_measures)
from .platform_map import (PlatformMap, VelocityMaps, solve_checked_columns,
                           solve_checked_square)
from .results import InverseKinematicsBatch, JacobianBatch, SingularityMeasures

#: the smallest continuation sub-step, as a fraction of the way (inverse kinematics and
#: assembly)
MIN_FRACTION = 64
#: step halvings of one Gauss-Newton line search
LINE_SEARCH = 12
#: Gauss-Newton iterations of one solve
MAX_ITER = 40
#: configurations kept by the inverse-kinematics cache
CACHE_SIZE = 4096


class RobotKinematics:
    """Kinematics of a :class:`~hexapod_pin.core.robot.ClosedLoopRobot` (module docstring).

    Args:
        clm: the closed-loop model.
        platform: its :class:`PlatformMap`.
        home: the home configuration (nq,), assembled.

    Attributes:
        tol: the closure residual and pose error every configuration meets (m, rad):
            ``1e-12 max(1, L)`` with ``L`` the characteristic length.
    """

    def __init__(self, clm: ClosedLoopModel, platform: PlatformMap, home: np.ndarray) -> None:
        self.clm = clm
        self.platform = platform
        self.model = clm.model
        self.home_q = home
        self.tol = 1e-12 * max(1.0, platform.length)
        self.home_pose = platform.pose(home)
        act = clm.actuated_v
        self._act_joints = [self.model.joints[self.model.getJointId(name)]
                            for name in clm.actuated_joints]
        self.home_actuators = self.actuator_positions(home)
        lower, upper = [], []
        for joint in self._act_joints:
            lo, hi = self.model.lowerPositionLimit[joint.idx_q], \
                self.model.upperPositionLimit[joint.idx_q]
            bounded = joint.nq == 1 and abs(lo) < 1e10 and abs(hi) < 1e10
            lower.append(lo if bounded else -math.inf)
            upper.append(hi if bounded else math.inf)
        #: actuator position limits (n_act,) from the description (-inf / inf: none)
        self.lower, self.upper = np.array(lower), np.array(upper)
        self._cache: dict[bytes, np.ndarray] = {}
        self._n_act = act.size

    # -- configurations ----------------------------------------------------------------
    def actuator_positions(self, q: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """Actuator positions (n_act,) (m or rad) read from a tree configuration (nq,) (an
        unbounded revolute joint's angle is ``atan2(sin, cos)`` of its two coordinates)."""
        q = self.clm.check_q(q)
        out = np.empty(len(self._act_joints))
        for k, joint in enumerate(self._act_joints):
            out[k] = q[joint.idx_q] if joint.nq == 1 else \
                math.atan2(q[joint.idx_q + 1], q[joint.idx_q])
        return out

    def with_actuators(self, q: np.ndarray, actuators: np.ndarray) -> np.ndarray:
        """A copy of ``q`` with the actuator coordinates set."""
        out = q.copy()
        for value, joint in zip(actuators, self._act_joints):
            if joint.nq == 1:
                out[joint.idx_q] = value
            else:
                out[joint.idx_q:joint.idx_q + 2] = (math.cos(value), math.sin(value))
        return out

    def pose_from_configuration(self, q: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """The platform pose (dim,) of a tree configuration (nq,) (m, rad)."""
        return self.platform.pose(self.clm.check_q(q))

    def seed(self, branch: object) -> np.ndarray:
        """The configuration a solve starts from: home for None, else ``branch`` itself.

        Raises:
            InputError: ``branch`` is neither None nor a configuration (nq,).
        """
        if branch is None:
            return self.home_q
        try:
            return as_array(branch, (self.model.nq,), "branch").copy()
        except InputError:
            raise InputError("branch", branch, "a ClosedLoopRobot takes None (the home "
                             "working mode) or a tree configuration (nq,) to start "
                             f"from (nq = {self.model.nq})") from None

    def configuration(self, pose: npt.ArrayLike, branch: npt.ArrayLike | None = None
                      ) -> npt.NDArray[np.float64]:
        """The tree configuration (nq,) of a pose: every closure held and the selected pose
        components met to :attr:`tol` (see the module docstring for the branch).

        Args:
            pose: (dim,) (m, rad).
            branch: None (the working mode reached from home) or a configuration (nq,) to
                start from.

        Raises:
            InputError: bad shape, NaN / inf, bad branch, a pose at pitch +-pi/2 (6-D).
            UnreachablePoseError: no configuration found (out of reach, or across a
                singularity from the start).
        """
        target = as_array(pose, (self.platform.dim,), "pose")
        start = self.seed(branch)
        key = target.tobytes() + (b"" if branch is None else start.tobytes())
        hit = self._cache.get(key)
        if hit is not None:
            return hit.copy()
        q = self._solve(start, target)
        if q is None:
            q = self._continue(start, self.platform.pose(start), target)
        if q is None:
            raise UnreachablePoseError([], [], reason=(
                f"no configuration of {self.clm.name} closes the loops at pose "
                f"{np.array2string(target, precision=6)} (Gauss-Newton from the start and "
                f"continuation in steps down to 1/{MIN_FRACTION} of the way did not "
                "converge: out of reach or across a singularity)"))
        if len(self._cache) >= CACHE_SIZE:
            self._cache.clear()
        self._cache[key] = q = q.copy()          # owned: never the caller's array
        return q.copy()

    def _continue(self, start: np.ndarray, base: np.ndarray,
                  target: np.ndarray) -> np.ndarray | None:
        """Continuation from ``start`` (at pose ``base``) to ``target`` along the straight
        pose segment: each sub-step a Gauss-Newton solve from the last configuration, the
        step halved where a solve fails (down to 1/:data:`MIN_FRACTION` of the segment)
        and doubled after a success; None when it cannot get through."""
        delta = self.platform.pose_error(target.copy(), base)
        q, done, step = start, 0.0, 0.5
        while done < 1.0:
            step = min(step, 1.0 - done)
            nxt = self._solve(q, base + delta * (done + step))
            if nxt is None:
                step *= 0.5
                if step < 1.0 / MIN_FRACTION:
                    return None
                continue
            q, done, step = nxt, done + step, 2.0 * step
        return q

    def _evaluate(self, q: np.ndarray, target: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, float]:
        """``(F, rows, max|F|)`` at ``q``: the stacked closure residual and pose error and
        their Jacobian ``[J_c; P]``, from one kinematic pass."""
        clm, plat = self.clm, self.platform
        res_c, jac_c = clm.residual_and_jacobian(q)
        pin.updateFramePlacement(self.model, clm.data, plat.frame)
        full = plat.full_pose(clm.data)
        pose_err = plat.pose_error(full[plat.sel], target)
        value = np.concatenate([res_c, pose_err])
        err = float(np.max(np.abs(value)))
        return value, np.vstack([jac_c, plat.pose_rows(clm.data, full)]), err

    def _solve(self, q: np.ndarray, target: np.ndarray) -> np.ndarray | None:
        """Gauss-Newton on the closures and the pose (steps halved while they do not
        decrease the max-abs error); None when it does not converge."""
        value, rows, err = self._evaluate(q, target)
        for _ in range(MAX_ITER):
            if err <= self.tol:
                return q
            step = np.linalg.lstsq(rows, -value, rcond=None)[0]
            alpha = 1.0
            for _ in range(LINE_SEARCH):
                trial = pin.integrate(self.model, q, alpha * step)
                if not all_within(trial, MAX_MAGNITUDE):   # beyond what the checks accept
                    alpha *= 0.5
                    continue
                t_value, t_rows, t_err = self._evaluate(trial, target)
                if math.isfinite(t_err) and t_err < err:
                    break
                alpha *= 0.5
            else:
                return None
            q, value, rows, err = trial, t_value, t_rows, t_err
        return q if err <= self.tol else None

    def clear_cache(self) -> None:
        """Forget the configurations of :meth:`configuration` (benchmarks time misses)."""
        self._cache.clear()

    # -- kinematics ----------------------------------------------------------------------
    def inverse_kinematics(self, pose: npt.ArrayLike, branch: npt.ArrayLike | None = None,
                           check_limits: bool = True) -> npt.NDArray[np.float64]:
        """Actuator positions (n_act,) (m or rad) of a pose (:meth:`configuration`).

        Raises:
            InputError: see :meth:`configuration`.
            UnreachablePoseError: see :meth:`configuration`.
            StrokeLimitError: with ``check_limits``, an actuator outside the position
                limits of its joint in the description.
        """
        act = self.actuator_positions(self.configuration(pose, branch))
        if flag(check_limits, "check_limits"):
            self.check_stroke(act)
        return act

    def stroke_violations(self, actuators: npt.ArrayLike) -> list[str]:
        """The violated actuator limits (n_act,) (m or rad), human-readable (empty when
        within).

        Raises:
            InputError: not (n_act,) real finite numbers.
        """
        actuators = as_array(actuators, (self._n_act,), "actuators")
        out = []
        for k, (value, lo, hi) in enumerate(zip(actuators, self.lower, self.upper)):
            if value < lo or value > hi:
                out.append(f"{self.clm.actuated_joints[k]} = {value:.6g} outside "
                           f"[{lo:.6g}, {hi:.6g}]")
        return out

    def check_stroke(self, actuators: npt.ArrayLike) -> None:
        """Raise :class:`StrokeLimitError` when an actuator leaves its limits.

        Raises:
            InputError: not (n_act,) real finite numbers.
        """
        bad = self.stroke_violations(actuators)
        if bad:
            raise StrokeLimitError(np.asarray(actuators, dtype=float), bad)

    def forward_kinematics(self, actuators: npt.ArrayLike,
                           guess: npt.ArrayLike | None = None) -> npt.NDArray[np.float64]:
        """The pose (dim,) of the assembly mode reached from ``guess`` (a pose; default
        home) with the actuators held at ``actuators`` (n_act,).

        Raises:
            InputError: bad shapes, NaN / inf.
            AssemblyError: the closures cannot be closed with these actuators from there.
        """
        target = as_array(actuators, (self._n_act,), "actuators")
        start = self.home_q if guess is None else self.configuration(guess)
        return self.platform.pose(self.assemble(start, target))

    def assemble(self, start: np.ndarray, actuators: np.ndarray) -> np.ndarray:
        """The configuration (nq,) with the actuators at ``actuators`` and the loops closed,
        reached from ``start``: directly, else by continuation in actuator space (the
        sub-steps of :meth:`_continue`).

        Raises:
            AssemblyError: no sub-step down to 1/:data:`MIN_FRACTION` of the way closes.
        """
        clm, act0 = self.clm, self.actuator_positions(start)

        def close(q: np.ndarray, values: np.ndarray) -> np.ndarray:
            return clm.assemble(self.with_actuators(q, values), tol=self.tol,
                                max_iter=MAX_ITER, restarts=0, method="newton").q

        try:
            return close(start, actuators)
        except AssemblyError as exc:
            failure = exc
        q, done, step = start, 0.0, 0.5
        while done < 1.0:
            step = min(step, 1.0 - done)
            try:
                q = close(q, act0 + (actuators - act0) * (done + step))
            except AssemblyError as exc:
                failure, step = exc, 0.5 * step
                if step < 1.0 / MIN_FRACTION:
                    raise failure from None
                continue
            done, step = done + step, 2.0 * step
        return q

    def assembly_modes(self, actuators: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """Assembly modes found for the actuator positions (n_act,): poses (n_modes, dim),
        nearest the home pose first (:meth:`search_assembly_modes` with 64 starts, seed 0:
        a multi-start search, not proven complete)."""
        return self.search_assembly_modes(actuators)

    def search_assembly_modes(self, actuators: npt.ArrayLike, n_starts: int = 64,
                              seed: int = 0) -> npt.NDArray[np.float64]:
        """Assembly modes found for the actuator positions (n_act,): poses (n_modes, dim),
        nearest the home pose first (:meth:`assembly_configurations`, poses only)."""
        return self.assembly_configurations(actuators, n_starts, seed)[0]

    def assembly_configurations(self, actuators: npt.ArrayLike, n_starts: int = 64,
                                seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """Assembly modes found for the actuator positions (n_act,) from the home
        configuration and ``n_starts`` random starts drawn from ``seed`` (each a random
        displacement of home: up to pi on angular coordinates, the characteristic length
        on linear ones), each assembled with the actuators held, verified (closures and
        actuators to :attr:`tol`) and de-duplicated by pose (1e-7 relative). Not proven
        complete: a mode no start reaches is missed.

        Returns:
            ``(poses, configurations)``: (n_modes, dim) and (n_modes, nq), nearest the
            home pose first.
        """
        target = as_array(actuators, (self._n_act,), "actuators")
        n_starts = count(n_starts, "n_starts", minimum=0)
        rng = np.random.default_rng(count(seed, "seed", minimum=0))
        spread = np.where(self.platform.angular_v, math.pi, self.platform.length)
        starts = [self.home_q] + [pin.integrate(self.model, self.home_q,
                                                rng.uniform(-1, 1, self.model.nv) * spread)
                                  for _ in range(n_starts)]
        found: list[tuple[np.ndarray, np.ndarray]] = []
        same = 1e-7 * max(1.0, self.platform.length)
        for start in starts:
            try:
                q = self.clm.assemble(self.with_actuators(start, target), tol=self.tol,
                                      max_iter=100, restarts=0, method="newton").q
            except AssemblyError:
                continue
            if np.max(np.abs(self.actuator_positions(q) - target)) > self.tol:
                continue
            pose = self.platform.pose(q)
            if all(np.max(np.abs(self.platform.pose_error(pose.copy(), p))) > same
                   for p, _ in found):
                found.append((pose, q))
        found.sort(key=lambda item: float(np.linalg.norm(
            self.platform.pose_error(item[0].copy(), self.home_pose))))
        poses = np.array([p for p, _ in found]).reshape(len(found), self.platform.dim)
        qs = np.array([q for _, q in found]).reshape(len(found), self.model.nq)
        return poses, qs

    # -- velocity maps ---------------------------------------------------------------------
    def maps(self, q: np.ndarray) -> VelocityMaps:
        """The velocity maps at ``q`` (see :mod:`~hexapod_pin.core.platform_map`)."""
        return self.platform.velocity_maps(q)

    def measures(self, maps: VelocityMaps) -> SingularityMeasures:
        """The singularity measures at the maps' configuration (never raises)."""
        plat = self.platform
        a_hat = plat.twist_scale[:, None] * maps.a_map
        b_hat = plat.actuator_scale[:, None] * maps.b_map
        jac = None
        if maps.a_map.shape[0] == maps.a_map.shape[1]:
            try:
                jac = solve_checked_square(maps.a_map.T, maps.b_map.T, "Jacobian").T
            except Exception:        # a singular A: the measures say so
                jac = None
        return tree_singularity_measures(a_hat, b_hat, jac, plat.length)

    def regular_maps(self, q: np.ndarray) -> VelocityMaps:
        """The maps at ``q``, refusing a singular configuration (the two measures of
        :meth:`measures`, from the singular values only).

        Raises:
            SingularityError: ``type_one`` or ``type_two`` below its threshold, or a
                closure mobility that differs from the pose dimension.
        """
        maps = self.maps(q)
        if maps.a_map.shape[1] != self.platform.dim:
            raise SingularityError(
                f"closure Jacobian of {self.clm.name} (mobility {maps.a_map.shape[1]} at "
                f"this configuration, pose dimension {self.platform.dim})",
                abs(maps.a_map.shape[1] - self.platform.dim), None, "|mobility - pose dimension|")
        plat = self.platform
        for what, mat, tol in (
                ("type-I singularity: the map from the closures' motion to the platform twist",
                 plat.twist_scale[:, None] * maps.a_map, TREE_TYPE_I_TOL),
                ("type-II singularity: the map from the closures' motion to the actuators",
                 plat.actuator_scale[:, None] * maps.b_map, TREE_TYPE_II_TOL)):
            measure, _ = inverse_condition(mat, mat.shape[1])
            if not measure >= tol:
                raise SingularityError(what, measure, tol, "inverse condition number")
        return maps

    def jacobian(self, pose: npt.ArrayLike,
                 branch: npt.ArrayLike | None = None) -> npt.NDArray[np.float64]:
        """``J`` (n_act, dim) with ``actuator velocities = J @ twist`` (``J = B A^-1``).

        Raises:
            SingularityError: a singular pose (:meth:`regular_maps`).
        """
        maps = self.regular_maps(self.configuration(pose, branch))
        return self.jacobian_of(maps)

    def jacobian_of(self, maps: VelocityMaps) -> np.ndarray:
        """``J = B A^-1`` (n_act, dim) of regular maps, verified."""
        return solve_checked_square(maps.a_map.T, maps.b_map.T, "Jacobian").T

    def velocity_map(self, maps: VelocityMaps) -> np.ndarray:
        """``T`` (nv, dim) with ``v = T twist`` (``N A^-1``), of regular maps."""
        return maps.basis @ solve_checked_square(maps.a_map, np.eye(self.platform.dim),
                                                 "velocity map")

    def twist_from_actuator_velocities(self, pose: npt.ArrayLike,
                                       actuator_velocities: npt.ArrayLike,
                                       branch: npt.ArrayLike | None = None
                                       ) -> npt.NDArray[np.float64]:
        """The twist (dim,) that gives the actuator velocities (n_act,) (``J^-1``).

        Raises:
            SingularityError: a singular pose.
            InconsistentMotionError: actuator velocities no motion of the closures has
                (redundant actuation).
        """
        qdot = as_array(actuator_velocities, (self._n_act,), "actuator_velocities")
        maps = self.regular_maps(self.configuration(pose, branch))
        if maps.b_map.shape[0] == maps.b_map.shape[1]:
            z = solve_checked_square(maps.b_map, qdot, "twist from actuator velocities")
        else:
            z = np.linalg.lstsq(maps.b_map, qdot, rcond=None)[0]
            miss = float(np.max(np.abs(maps.b_map @ z - qdot)))
            if miss > 1e-9 * max(1.0, float(np.max(np.abs(qdot)))):
                raise InconsistentMotionError("actuator velocities", miss)
        return maps.a_map @ z

    def tree_velocity(self, maps: VelocityMaps, twist: np.ndarray) -> np.ndarray:
        """The tree velocity (nv,) of a twist (dim,): ``v = N A^-1 twist``."""
        return maps.basis @ solve_checked_square(maps.a_map, twist, "tree velocity")

    def tree_acceleration(self, maps: VelocityMaps, v: np.ndarray, twist_dot: np.ndarray,
                          terms: tuple[np.ndarray, np.ndarray] | None = None
                          ) -> tuple[np.ndarray, np.ndarray]:
        """``(a, a0)``: the tree acceleration (nv,) of ``twist_dot`` (dim,) and the one at
        ``twist_dot = 0``, both keeping the closures (``J_c a = -gamma``); ``terms``: the
        state's ``(gamma, bias)`` of :meth:`PlatformMap.frame_bias` when already known."""
        a_p, free = self._drift_terms(maps, v, terms)
        both = solve_checked_columns(maps.a_map, np.stack([-free, twist_dot - free], axis=1),
                                     "tree acceleration")
        return a_p + maps.basis @ both[:, 1], a_p + maps.basis @ both[:, 0]

    def drift_acceleration(self, maps: VelocityMaps, v: np.ndarray,
                           terms: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
        """``a0``: the tree acceleration (nv,) at ``twist_dot = 0`` of :meth:`tree_acceleration`
        alone (one solve)."""
        a_p, free = self._drift_terms(maps, v, terms)
        return a_p + maps.basis @ solve_checked_square(maps.a_map, -free, "tree acceleration")

    def _drift_terms(self, maps: VelocityMaps, v: np.ndarray,
                     terms: tuple[np.ndarray, np.ndarray] | None
                     ) -> tuple[np.ndarray, np.ndarray]:
        """``(a_p, free)``: the least-norm acceleration keeping the closures' drift (nv,)
        and the platform's acceleration bias it leaves (dim,)."""
        plat = self.platform
        gamma, bias = plat.frame_bias(maps.q, v) if terms is None else terms
        a_p = plat.particular(maps, -gamma, "closure drift")
        return a_p, bias + maps.twist_rows @ a_p

    def jacobian_derivative(self, pose: npt.ArrayLike, twist: npt.ArrayLike,
                            branch: npt.ArrayLike | None = None) -> npt.NDArray[np.float64]:
        """``dJ/dt`` (n_act, dim) along the motion with ``twist``.

        ``J = E_a V`` with ``V`` (nv, dim) the velocity map, ``K V = [0; I]`` for the
        stacked closure and twist rows ``K = [J_c; T]``, so that ``dV/dt = -K^+ (dK/dt) V``
        (exact: ``K`` has full column rank at a regular pose); ``dK/dt`` from Pinocchio's
        frame Jacobian time variations (:meth:`PlatformMap.time_variation`). Verified:
        ``dJ/dt twist`` must equal the actuator accelerations at ``twist_dot = 0``.

        Raises:
            SingularityError: a singular pose.
            SolverError: the verification fails.
        """
        twist = as_array(twist, (self.platform.dim,), "twist")
        maps = self.regular_maps(self.configuration(pose, branch))
        vmap = self.velocity_map(maps)
        v = vmap @ twist
        stacked = np.vstack([maps.jac_c, maps.twist_rows])
        kdot_v = self.platform.time_variation(maps, v, vmap)
        vdot = -np.linalg.lstsq(stacked, kdot_v, rcond=None)[0]
        jdot = vdot[self.clm.actuated_v]
        a0 = self.drift_acceleration(maps, v)
        expected = a0[self.clm.actuated_v]
        miss = float(np.max(np.abs(jdot @ twist - expected), initial=0.0))
        scale = max(1e-300, float(np.max(np.abs(jdot), initial=0.0))
                    * float(np.max(np.abs(twist), initial=0.0)),
                    float(np.max(np.abs(expected), initial=0.0)))
        if miss > 1e-8 * scale:
            raise SolverError("jacobian_derivative", "unverified",
                              f"dJ/dt twist misses the actuator acceleration bias by "
                              f"{miss:.3e} (relative {miss / scale:.3e})")
        return jdot

    def singularity(self, pose: npt.ArrayLike,
                    branch: npt.ArrayLike | None = None) -> SingularityMeasures:
        """The measures of :func:`~hexapod_pin.core.measures.tree_singularity_measures` at
        a pose (never raises at a singularity)."""
        return self.measures(self.maps(self.configuration(pose, branch)))

    # -- batches -------------------------------------------------------------------------
    def _rows(self, poses: npt.ArrayLike, branch: npt.ArrayLike | None,
              each: Callable[[np.ndarray], object]) -> tuple[np.ndarray, list[object]]:
        poses = as_array(poses, (self.platform.dim,), "poses", batch=True)
        return poses, [each(pose) for pose in poses]

    def inverse_kinematics_batch(self, poses: npt.ArrayLike, branch: npt.ArrayLike | None = None
                                 ) -> InverseKinematicsBatch:
        """:meth:`inverse_kinematics` of N poses (N, dim); rows that do not reach hold the
        home actuator positions (finite, not a solution) and ``reachable`` False."""
        def one(pose: np.ndarray) -> np.ndarray | None:
            try:
                return self.inverse_kinematics(pose, branch, check_limits=False)
            except UnreachablePoseError:
                return None
        poses, out = self._rows(poses, branch, one)
        reach = np.array([x is not None for x in out], dtype=bool)
        act = np.array([self.home_actuators if x is None else x for x in out]
                       ).reshape(len(poses), self._n_act)
        within = np.array([not self.stroke_violations(a) for a in act], dtype=bool)
        return InverseKinematicsBatch(act, reach, within, reach & within)

    def jacobian_batch(self, poses: npt.ArrayLike,
                       branch: npt.ArrayLike | None = None) -> JacobianBatch:
        """:meth:`jacobian` of N poses: (N, n_act, dim), zero rows where not ``ok``."""
        ik = self.inverse_kinematics_batch(poses, branch)
        poses = as_array(poses, (self.platform.dim,), "poses", batch=True)
        jac = np.zeros((len(poses), self._n_act, self.platform.dim))
        regular = np.zeros(len(poses), dtype=bool)
        for k in np.flatnonzero(ik.reachable):
            try:
                jac[k] = self.jacobian(poses[k], branch)
                regular[k] = True
            except SingularityError:
                pass
        return JacobianBatch(jac, ik.actuator_positions, ik.reachable, regular,
                             ik.within_stroke, ik.reachable & regular)
