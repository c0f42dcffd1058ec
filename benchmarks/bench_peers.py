"""The hexapod against its peers: hexapod_pin ("ours"), raw Pinocchio, MuJoCo, plain numpy.

Prints (Markdown tables):

1. a model check: the generated MJCF against our Pinocchio model (site positions, joint
   values, mass matrix) and the effect of the tiny inertias MuJoCo needs;
2. accuracy: max abs difference between every pair of routes over random states for
   IK, Jacobian, FK, inverse dynamics, forward dynamics, statics and one simulation step;
3. speed: microseconds per state (median [inter-quartile range] over repeats) for N = 1,
   100, 10^4, 10^6 states, and the ratio ours / MuJoCo.

Usage (from the repository root)::

    python benchmarks/bench_peers.py              # full run (a few minutes)
    python benchmarks/bench_peers.py --smoke      # seconds; exit 1 when routes disagree

``--smoke`` checks agreement only (never timings): every pair of routes that computes
the same rigid physics must agree to 1e-8 (:data:`RIGID_TOL`); MuJoCo's own soft-constraint
answers get a sanity bound (:data:`SOFT_FD_TOL`) and one step of different integration
schemes a data-driven bound (:meth:`HexapodPeers.scheme_tol`); see benchmarks/README.md.
"""

from __future__ import annotations

import os

# tiny dense matrices: BLAS threads only add contention (set before numpy loads)
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from dataclasses import dataclass, field  # noqa: E402
from functools import partial  # noqa: E402
from typing import Callable  # noqa: E402

import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402

import hexapod_pin as hp  # noqa: E402
import hexapod_pin.core.dynamics as hpd  # noqa: E402
import numpy_hexapod as nh  # noqa: E402
import pinocchio_raw as pr  # noqa: E402
from bench_common import (CLOCK, MIN_SAMPLE, NO_ROUTE, NOT_IMPLEMENTED, States, Timing, fmt_us,  # noqa: E402
                          measure, measure_interleaved, peak_memory, print_machine_info,
                          random_states, table)

try:
    import mujoco

    import mjcf
except ImportError:  # MuJoCo is a benchmark extra
    mujoco = None

#: distinct random states; larger batches tile them
UNIQUE_STATES = 20000
#: time step of the simulation-step rows (s)
DT = 1e-3
#: agreement required between routes that compute the same rigid physics
RIGID_TOL = 1e-8
#: MuJoCo's soft closures (solimp at mjMAXIMP) give accelerations off by up to ~0.8 m/s^2,
#: rad/s^2 over 1000 states (typically 1e-2): a sanity bound only, the rigid check of the
#: MuJoCo model is its refined forward dynamics and its inverse dynamics (1e-8)
SOFT_FD_TOL = 2.0


@dataclass
class Route:
    """One way to compute an operation.

    ``single(i)`` computes state i; ``batch(n)`` the first n states at once (vectorised).
    Either may be None; a route with neither shows ``missing``.
    """

    name: str
    single: Callable[[int], np.ndarray] | None = None
    batch: Callable[[int], np.ndarray] | None = None
    missing: str = NOT_IMPLEMENTED
    soft: bool = False          # MuJoCo's soft-constraint physics (looser tolerance)
    scheme: str = ""            # integration scheme; different schemes differ at O(dt^2)
    timed: bool = True          # False: a reference column of the accuracy table only

    @property
    def available(self) -> bool:
        return self.single is not None or self.batch is not None

    def run(self, n: int) -> np.ndarray:
        if self.batch is not None:
            return np.asarray(self.batch(n)).reshape(n, -1)
        return np.stack([np.ravel(self.single(i)) for i in range(n)])


@dataclass
class Operation:
    name: str
    routes: list[Route] = field(default_factory=list)
    reference: str | None = None   # name of the route the others are compared to
    #: n -> tolerance between different integration schemes over the first n states
    scheme_tol: Callable[[int], float] | None = None


def _ours(robot, name):
    """A method of the robot if the library has it (the API grows while we benchmark)."""
    return getattr(robot, name, None)


def _fast(robot):
    """``(FastDynamics, simulate_fast, label)`` of hexapod_pin.hexapod.fast, or None without it."""
    try:
        import hexapod_pin.hexapod.fast as fast
    except ImportError:
        return None
    label = "numba"
    return fast.fast_dynamics(robot), getattr(fast, "simulate_fast", None), label


class HexapodPeers:
    """Inputs and routes of every peer for N random hexapod states.

    Args:
        geometry: a ``HexapodGeometry``.
        n_states: number of random states (vectorised routes use up to this many).
        n_tree: how many of them get tree states prepared for the per-state routes.
    """

    def __init__(self, geometry, n_states: int, n_tree: int, seed: int = 0):
        self.robot = hp.Hexapod(geometry)
        self.p = nh.params_from_geometry(geometry)
        self.raw = pr.RawHexapod(self.robot)
        self.mj = mjcf.MujocoHexapod(geometry, timestep=DT) if mujoco is not None else None
        s = random_states(geometry, min(n_states, UNIQUE_STATES), seed)
        if n_states > len(s):      # large batches repeat the unique states (timing only)
            reps = -(-n_states // len(s))
            s = States(*(np.tile(a, (reps, 1))[:n_states] for a in
                         (s.poses, s.twists, s.twist_dots, s.wrenches)))
        self.s = s
        self.poses, self.twists, self.twist_dots, self.wrenches = \
            s.poses, s.twists, s.twist_dots, s.wrenches
        # actuator forces of the sampled motions: input of forward dynamics and of the steps
        self.forces = nh.inverse_dynamics(self.p, s.poses, s.twists, s.twist_dots, s.wrenches)
        self.q_act = nh.inverse_kinematics(self.p, s.poses)
        self.qddot = nh._leg_terms(self.p, s.poses, s.twists, s.twist_dots)[4]
        self.n_tree = 0
        self.pin_state: list[tuple] = []
        self.mj_state: list[tuple] = []
        self.tau_ext: list[np.ndarray] = []
        self.prepare_tree(n_tree)

    def prepare_tree(self, n: int) -> None:
        """Tree states (Pinocchio and MuJoCo) of the first n states (not timed)."""
        for i in range(self.n_tree, min(n, len(self.poses))):
            q, v, a = self.raw.tree_state(self.poses[i], self.twists[i], self.twist_dots[i])
            self.pin_state.append((q, v, a))
            pin.forwardKinematics(self.raw.model, self.raw.data, q)
            self.tau_ext.append(self.raw.wrench_generalised(self.wrenches[i]))
            if self.mj is not None:
                self.mj_state.append(self.mj.set_task_state(self.poses[i], self.twists[i],
                                                            self.twist_dots[i]))
        self.n_tree = max(self.n_tree, min(n, len(self.poses)))

    # -- operations -----------------------------------------------------------------------
    def operations(self) -> list[Operation]:
        return [self.op_ik(), self.op_jacobian(), self.op_fk(), self.op_inverse(),
                self.op_forward(), self.op_static(), self.op_step()]

    def op_ik(self) -> Operation:
        r, p = self.robot, self.p
        batch = _ours(r, "inverse_kinematics_batch")
        return Operation("inverse kinematics", [
            Route("ours inverse_kinematics", lambda i: r.inverse_kinematics(
                self.poses[i], check_limits=False)),
            Route("ours inverse_kinematics_batch", batch=None if batch is None else (
                lambda n: batch(self.poses[:n]).actuator_positions)),
            Route("numpy", batch=lambda n: nh.inverse_kinematics(p, self.poses[:n])),
            Route("raw Pinocchio", missing=NO_ROUTE), Route("MuJoCo", missing=NO_ROUTE),
        ], reference="numpy")

    def op_jacobian(self) -> Operation:
        r, p = self.robot, self.p
        batch = _ours(r, "jacobian_batch")
        return Operation("Jacobian", [
            Route("ours jacobian", lambda i: r.jacobian(self.poses[i])),
            Route("ours jacobian_batch", batch=None if batch is None else (
                lambda n: batch(self.poses[:n]).jacobian)),
            Route("numpy", batch=lambda n: nh.jacobian(p, self.poses[:n])),
            Route("raw Pinocchio", missing=NO_ROUTE), Route("MuJoCo", missing=NO_ROUTE),
        ], reference="numpy")

    def op_fk(self) -> Operation:
        r, p = self.robot, self.p
        home = np.array(r.geometry.home_pose)
        fk = _ours(r, "forward_kinematics")
        routes = [Route("ours forward_kinematics", None if fk is None else (
            lambda i: _pose_of(fk(self.q_act[i]))))]
        batch = _ours(r, "forward_kinematics_batch")
        if batch is not None:
            routes.append(Route("ours forward_kinematics_batch",
                                batch=lambda n: _pose_of(batch(self.q_act[:n]))))
        routes += [
            Route("numpy Newton", batch=lambda n: nh.forward_kinematics(
                p, self.q_act[:n], home)[0]),
            Route("raw Pinocchio", missing=NO_ROUTE), Route("MuJoCo", missing=NO_ROUTE)]
        return Operation("forward kinematics", routes, reference="numpy Newton")

    def op_inverse(self) -> Operation:
        r, p, raw, mj = self.robot, self.p, self.raw, self.mj
        s = self
        routes = []
        inv = _ours(r, "inverse_dynamics")
        if inv is not None:
            routes.append(Route("ours inverse_dynamics qp", lambda i: inv(
                s.poses[i], s.twists[i], s.twist_dots[i], s.wrenches[i]).actuator_forces))
            routes.append(Route("ours inverse_dynamics kkt, no joint wrenches", lambda i: inv(
                s.poses[i], s.twists[i], s.twist_dots[i], s.wrenches[i], method="kkt",
                joint_wrenches=False).actuator_forces))
        else:
            routes.append(Route("ours inverse_dynamics"))
        fast = _fast(r)
        if fast is not None:
            routes.append(Route(f"ours fast.inverse_dynamics ({fast[2]})", lambda i: fast[0]
                                .inverse_dynamics(s.poses[i], s.twists[i], s.twist_dots[i],
                                                  s.wrenches[i])))
        batch = _ours(r, "inverse_dynamics_batch")
        routes.append(Route("ours inverse_dynamics_batch", batch=None if batch is None else (
            lambda n: batch(s.poses[:n], s.twists[:n], s.twist_dots[:n],
                            s.wrenches[:n]).actuator_forces)))
        tree_id = getattr(hpd, "inverse_dynamics_tree", None)
        routes.append(Route("ours inverse_dynamics_tree kkt (tree state given)",
                            None if tree_id is None else (lambda i: tree_id(
                                r.model, *s.pin_state[i], tau_ext=s.tau_ext[i],
                                method="kkt").actuator_forces)))
        routes.append(Route("raw Pinocchio rnea + solve (tree state given)",
                            lambda i: raw.inverse(*s.pin_state[i], s.wrenches[i])))
        routes.append(Route("raw Pinocchio incl. state completion",
                            lambda i: raw.inverse_task(s.poses[i], s.twists[i],
                                                       s.twist_dots[i], s.wrenches[i])))
        if mj is not None:
            routes.append(Route("MuJoCo mj_inverse + reduction (tree state given)",
                                lambda i: mj.inverse_tree_state(*s.mj_state[i], s.wrenches[i])))
            routes.append(Route("MuJoCo incl. state completion",
                                lambda i: mj.inverse_task(s.poses[i], s.twists[i],
                                                          s.twist_dots[i], s.wrenches[i])))
        else:
            routes.append(Route("MuJoCo", missing="mujoco not installed"))
        routes.append(Route("numpy Newton-Euler", batch=lambda n: nh.inverse_dynamics(
            p, s.poses[:n], s.twists[:n], s.twist_dots[:n], s.wrenches[:n])))
        return Operation("inverse dynamics", routes, reference="numpy Newton-Euler")

    def op_forward(self) -> Operation:
        r, p, raw, mj, s = self.robot, self.p, self.raw, self.mj, self
        routes = []
        fwd = _ours(r, "forward_dynamics")
        for method in ("nullspace", "pinocchio", "kkt", "qp"):
            if fwd is None:
                routes.append(Route(f"ours forward_dynamics {method}"))
                continue
            routes.append(Route(
                f"ours forward_dynamics {method}",
                lambda i, m=method: _fd_out(fwd(s.poses[i], s.twists[i], s.forces[i],
                                                s.wrenches[i], method=m))))
        fast = _fast(r)
        if fast is not None:
            routes.append(Route(f"ours fast.forward_dynamics_full ({fast[2]})",
                                lambda i: np.concatenate(fast[0].forward_dynamics_full(
                                    s.poses[i], s.twists[i], s.forces[i], s.wrenches[i]))))
        batch = _ours(r, "forward_dynamics_batch")
        routes.append(Route("ours forward_dynamics_batch", batch=None if batch is None else (
            lambda n: _fd_out(batch(s.poses[:n], s.twists[:n], s.forces[:n], s.wrenches[:n])))))

        tree_fd = getattr(hpd, "forward_dynamics_tree", None)

        def ours_tree_fd(i):
            q, v, _ = s.pin_state[i]
            acc = tree_fd(r.model, q, v, s.forces[i], s.tau_ext[i], method="pinocchio").a
            return np.concatenate([raw.twist_dot_from_a(q, v, acc), acc[raw.idx.carriage_v]])

        routes.append(Route("ours forward_dynamics_tree pinocchio (tree state given)",
                            None if tree_fd is None else ours_tree_fd))

        def raw_fd(i, kkt=False):
            q, v, _ = s.pin_state[i]
            acc = (raw.forward_kkt if kkt else raw.forward)(q, v, s.forces[i], s.wrenches[i])
            return np.concatenate([raw.twist_dot_from_a(q, v, acc), acc[raw.idx.carriage_v]])

        routes.append(Route("raw Pinocchio constraintDynamics (tree state given)", raw_fd))
        routes.append(Route("raw Pinocchio crba + KKT (tree state given)",
                            lambda i: raw_fd(i, kkt=True)))
        if mj is not None:
            def mj_fd(i, refined=False):
                qpos, qvel, _ = s.mj_state[i]
                fn = mj.forward_refined if refined else mj.forward
                tdd, qdd, _ = fn(qpos, qvel, s.forces[i], s.wrenches[i])
                return np.concatenate([tdd, qdd])
            routes.append(Route("MuJoCo mj_forward (soft closures, tree state given)", mj_fd,
                                soft=True))
            routes.append(Route("MuJoCo + proximal refinement (rigid, tree state given)",
                                lambda i: mj_fd(i, refined=True)))
        else:
            routes.append(Route("MuJoCo", missing="mujoco not installed"))
        routes.append(Route("numpy Newton-Euler", batch=lambda n: np.concatenate(
            nh.forward_dynamics(p, s.poses[:n], s.twists[:n], s.forces[:n], s.wrenches[:n]),
            axis=-1)))
        routes.append(Route("sampled input (FD of ID = identity)", batch=lambda n: np.concatenate(
            [s.twist_dots[:n], s.qddot[:n]], axis=-1), timed=False))
        return Operation("forward dynamics", routes,
                         reference="sampled input (FD of ID = identity)")

    def op_static(self) -> Operation:
        r, p, raw, mj, s = self.robot, self.p, self.raw, self.mj, self
        st = _ours(r, "static_forces")
        routes = [Route("ours static_forces", None if st is None else (
            lambda i: st(s.poses[i], s.wrenches[i])))]
        fast = _fast(r)
        if fast is not None:
            routes.append(Route(f"ours fast.static_forces ({fast[2]})",
                                lambda i: fast[0].static_forces(s.poses[i], s.wrenches[i])))
        batch = _ours(r, "static_forces_batch")
        if batch is not None:
            routes.append(Route("ours static_forces_batch",
                                batch=lambda n: _forces_of(batch(s.poses[:n], s.wrenches[:n]))))
        routes.append(Route("raw Pinocchio gravity + solve (tree state given)",
                            lambda i: raw.static(s.pin_state[i][0], s.wrenches[i])))
        routes.append(Route("raw Pinocchio incl. closed-form q",
                            lambda i: raw.static(raw.configuration(s.poses[i]), s.wrenches[i])))
        if mj is not None:
            zero = np.zeros(mj.model.nv)
            routes.append(Route("MuJoCo mj_inverse at rest + reduction (tree state given)",
                                lambda i: mj.inverse_tree_state(s.mj_state[i][0], zero, zero,
                                                                s.wrenches[i])))
            routes.append(Route("MuJoCo incl. closed-form qpos",
                                lambda i: mj.inverse_tree_state(mj.qpos_from_pose(s.poses[i]),
                                                                zero, zero, s.wrenches[i])))
        else:
            routes.append(Route("MuJoCo", missing="mujoco not installed"))
        routes.append(Route("numpy Newton-Euler", batch=lambda n: nh.static_forces(
            p, s.poses[:n], s.wrenches[:n])))
        return Operation("statics", routes, reference="numpy Newton-Euler")

    def op_step(self) -> Operation:
        raw, mj, p, s = self.raw, self.mj, self.p, self
        routes = self._ours_step()

        def raw_step(i):
            q, v, _ = s.pin_state[i]
            q1, v1 = raw.step(q, v, s.forces[i], DT, s.wrenches[i])
            return _pin_platform_state(raw, q1, v1)

        routes.append(Route("raw Pinocchio constraintDynamics + integrate", raw_step,
                            scheme="semi-implicit Euler on the tree"))
        if mj is not None:
            routes.append(Route("MuJoCo mj_step (Euler, soft closures, tree state given)",
                                lambda i: _mj_step(mj, s.mj_state[i], s.forces[i],
                                                   s.wrenches[i]), soft=True,
                                batch=_mj_rollout(mj, s),
                                scheme="semi-implicit Euler on the platform"))
        else:
            routes.append(Route("MuJoCo", missing="mujoco not installed"))
        routes.append(Route("numpy semi-implicit Euler", batch=lambda n: np.concatenate(
            nh.step(p, s.poses[:n], s.twists[:n], s.forces[:n], DT, s.wrenches[:n]), -1),
            scheme="semi-implicit Euler on the platform"))
        return Operation(f"simulation step (dt = {DT:g} s)", routes,
                         reference="numpy semi-implicit Euler", scheme_tol=self.scheme_tol)

    def scheme_tol(self, n: int) -> float:
        """Bound on one-step differences between integration schemes over n states.

        Semi-implicit Euler moves the twist by ``dt a(t)``, RK4 by about
        ``dt (a(t) + a(t + dt)) / 2``: they differ by up to ``dt |a(t + dt) - a(t)| / 2``
        in the twist and ``O(dt^2 |a|)`` in the pose; projections onto the closures are of
        the same order. Returns ``dt max |a(t + dt) - a(t)| + 10 dt^2 max |a|`` from the
        numpy peer (near-singular states have large ``|a(t + dt) - a(t)|``).
        """
        p, s = self.p, self
        poses1, twists1 = nh.step(p, s.poses[:n], s.twists[:n], s.forces[:n], DT,
                                  s.wrenches[:n])
        acc1, _ = nh.forward_dynamics(p, poses1, twists1, s.forces[:n], s.wrenches[:n])
        acc0 = s.twist_dots[:n]
        return float(DT * np.max(np.abs(acc1 - acc0)) + 10 * DT ** 2 * np.max(np.abs(acc0)))

    def _ours_step(self) -> list[Route]:
        try:
            import hexapod_pin.hexapod.simulation as sim
        except ImportError:
            return [Route("ours simulate step")]
        integ_cls = getattr(sim, "ClosedLoopIntegrator", None)
        simulate = getattr(sim, "simulate", None)
        raw, s, r = self.raw, self, self.robot
        routes = []
        if integ_cls is not None:
            for kind in ("semi_implicit_euler", "rk4"):
                integ = integ_cls(r.model, "pinocchio", kind)

                def ours(i, integ=integ):
                    q, v, _ = s.pin_state[i]
                    tau = s.tau_ext[i].copy()
                    tau[raw.actuated_v] += s.forces[i]
                    q1, v1, _ = integ.step(q, v, tau, DT)
                    return _pin_platform_state(raw, q1, v1)
                routes.append(Route(f"ours ClosedLoopIntegrator.step {kind} (tree state given)",
                                    ours, scheme=f"ours {kind} + projection"))
        if simulate is not None:
            def ours_sim(i):
                traj = simulate(r, DT, DT, pose0=s.poses[i], twist0=s.twists[i],
                                actuator_forces=s.forces[i], wrench=s.wrenches[i],
                                check_limits=False, saturation="ignore")
                return np.concatenate([traj.poses[-1], traj.twists[-1]])
            routes.append(Route("ours simulate(duration=dt), rk4", ours_sim,
                                scheme="ours rk4 + projection"))
        fast = _fast(r)
        if fast is not None and fast[1] is not None:
            def ours_fast(i, kind="rk4"):
                traj = fast[1](r, DT, DT, pose0=s.poses[i], twist0=s.twists[i],
                               actuator_forces=s.forces[i], wrench=s.wrenches[i],
                               check_limits=False, saturation="ignore", integrator=kind)
                return np.concatenate([traj.poses[-1], traj.twists[-1]])
            routes.append(Route(f"ours simulate_fast(duration=dt), rk4 on the platform "
                                f"({fast[2]})", ours_fast, scheme="ours fast rk4 platform"))
            routes.append(Route(f"ours simulate_fast(duration=dt), semi-implicit Euler on the "
                                f"platform ({fast[2]})",
                                lambda i: ours_fast(i, "semi_implicit_euler"),
                                scheme="semi-implicit Euler on the platform"))
            stepper_cls = getattr(sys.modules.get("hexapod_pin.hexapod.fast"), "FastStepper", None)
            if stepper_cls is not None:
                stepper = stepper_cls(r, DT, check_limits=False)

                def ours_step(i):
                    stepper.reset(s.poses[i], s.twists[i])
                    stepper.step(s.forces[i], s.wrenches[i])
                    return np.concatenate([stepper.pose, stepper.twist])
                routes.append(Route(f"ours FastStepper reset + step, semi-implicit Euler on the "
                                    f"platform ({fast[2]})", ours_step,
                                    scheme="semi-implicit Euler on the platform"))
        return routes or [Route("ours simulate step")]


# -- small conversions --------------------------------------------------------------------
def _pose_of(result):
    return getattr(result, "pose", result)


def _forces_of(result):
    return getattr(result, "actuator_forces", result)


def _fd_out(result) -> np.ndarray:
    return np.concatenate([np.asarray(result.twist_dot), np.asarray(result.actuator_accelerations)], axis=-1)


def _pin_platform_state(raw, q, v) -> np.ndarray:
    """(pose, world twist) (12,) of the platform from a Pinocchio tree state."""
    ff = q[raw.idx.platform_q]
    rot = pin.Quaternion(ff[6], ff[3], ff[4], ff[5]).toRotationMatrix()
    vb = v[raw.idx.platform_v]
    rpy = nh.rpy_from_rotation(rot[None])[0]
    return np.concatenate([ff[:3], rpy, rot @ vb[:3], rot @ vb[3:]])


def _mj_platform_state(mj, qpos, qvel) -> np.ndarray:
    fq = qpos[mj.free_q:mj.free_q + 7]
    rot = np.empty(9)
    mujoco.mju_quat2Mat(rot, fq[3:] / np.linalg.norm(fq[3:]))
    rot = rot.reshape(3, 3)
    fv = qvel[mj.free_v:mj.free_v + 6]
    return np.concatenate([fq[:3], nh.rpy_from_rotation(rot[None])[0], fv[:3], rot @ fv[3:]])


def _mj_step(mj, state, forces, wrench) -> np.ndarray:
    m, d = mj.model, mj.data
    d.qpos[:], d.qvel[:] = state[0], state[1]
    d.ctrl[:] = forces
    d.xfrc_applied[mj.platform_body] = wrench
    d.qacc_warmstart[:] = 0.0
    mujoco.mj_step(m, d)
    return _mj_platform_state(mj, d.qpos, d.qvel)


def _mj_rollout(mj, peers):
    """Batched MuJoCo steps with ``mujoco.rollout`` (one thread), or None."""
    try:
        from mujoco import rollout
    except ImportError:
        return None
    m, d = mj.model, mj.data
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    ctrl_spec = mujoco.mjtState.mjSTATE_CTRL | mujoco.mjtState.mjSTATE_XFRC_APPLIED
    cache: dict[int, tuple] = {}

    def inputs(n):
        if n not in cache:
            nstate = mujoco.mj_stateSize(m, spec)
            ncontrol = mujoco.mj_stateSize(m, ctrl_spec)
            init = np.empty((n, nstate))
            control = np.empty((n, 1, ncontrol))
            for i in range(n):
                d.qpos[:], d.qvel[:] = peers.mj_state[i][0], peers.mj_state[i][1]
                d.qacc_warmstart[:] = 0.0
                d.ctrl[:] = peers.forces[i]
                d.xfrc_applied[:] = 0.0
                d.xfrc_applied[mj.platform_body] = peers.wrenches[i]
                mujoco.mj_getState(m, d, init[i], spec)
                mujoco.mj_getState(m, d, control[i, 0], ctrl_spec)
            cache.clear()
            cache[n] = (init, control, np.empty((n, 1, nstate)))
        return cache[n]

    def batch(n):
        init, control, out = inputs(n)
        rollout.rollout(m, d, init, control, control_spec=ctrl_spec, nstep=1, state=out)
        qpos = out[:, 0, 1:1 + m.nq]
        qvel = out[:, 0, 1 + m.nq:1 + m.nq + m.nv]
        return np.stack([_mj_platform_state(mj, qpos[i], qvel[i]) for i in range(n)])
    batch.needs_tree = True
    return batch


# -- model check --------------------------------------------------------------------------
def model_check(peers: HexapodPeers, n: int = 20) -> tuple[list[list[str]], dict[str, float]]:
    """MJCF vs Pinocchio: joint values, sites, mass matrix; tiny-inertia effect on ID."""
    mj, robot = peers.mj, peers.robot
    m, d = mj.model, mj.data
    model = robot.model.model
    data = model.createData()
    perm = np.empty(model.nv, dtype=int)
    for j in range(1, model.njoints):
        joint = model.joints[j]
        perm[joint.idx_v:joint.idx_v + joint.nv] = m.joint(model.names[j]).dofadr[0] + \
            np.arange(joint.nv)
    worst = dict(joints=0.0, sites=0.0, closure=0.0, mass=0.0)
    fv = robot.indices.platform_v.start
    for i in range(n):
        pose = peers.poses[i]
        q = robot.configuration(pose)
        qpos = mj.qpos_from_pose(pose)
        for j in range(1, model.njoints):
            joint = model.joints[j]
            if joint.nq == 1:
                worst["joints"] = max(worst["joints"], abs(
                    q[joint.idx_q] - qpos[m.joint(model.names[j]).qposadr[0]]))
        d.qpos[:] = qpos
        mujoco.mj_forward(m, d)
        pin.framesForwardKinematics(model, data, q)
        for k in range(6):
            tip = data.oMf[model.getFrameId(f"leg_{k}_tip")].translation
            anchor = data.oMf[model.getFrameId(f"platform_anchor_{k}")].translation
            worst["sites"] = max(worst["sites"],
                                 np.abs(d.site_xpos[mj.tip_sites[k]] - tip).max(),
                                 np.abs(d.site_xpos[mj.anchor_sites[k]] - anchor).max())
            worst["closure"] = max(worst["closure"], np.abs(
                d.site_xpos[mj.tip_sites[k]] - d.site_xpos[mj.anchor_sites[k]]).max())
        full = np.zeros((m.nv, m.nv))
        mujoco.mj_fullM(m, d, full)
        full = full[np.ix_(perm, perm)]
        vmap = np.eye(model.nv)          # v_mujoco = vmap v_pinocchio (free joint: R on v)
        vmap[fv:fv + 3, fv:fv + 3] = d.xmat[mj.platform_body].reshape(3, 3)
        mass = pin.crba(model, data, q)
        mass = np.triu(mass) + np.triu(mass, 1).T
        worst["mass"] = max(worst["mass"], np.abs(vmap.T @ full @ vmap - mass).max())
    # tiny inertias: ID with TINY_INERTIA vs 1000x it (the effect is linear in it)
    big = mjcf.MujocoHexapod(robot.geometry, timestep=DT, tiny_inertia=1e3 * mjcf.TINY_INERTIA)
    diff = 0.0
    for i in range(min(n, peers.n_tree)):
        a = mj.inverse_tree_state(*peers.mj_state[i], peers.wrenches[i])
        b = big.inverse_tree_state(*peers.mj_state[i], peers.wrenches[i])
        diff = max(diff, np.abs(a - b).max())
    worst["tiny inertia"] = diff / 1e3
    rows = [
        ["joint values: closed form (MuJoCo qpos) vs Pinocchio q", f"{worst['joints']:.1e}",
         "rad, m"],
        ["site positions vs Pinocchio frames leg_i_tip / platform_anchor_k",
         f"{worst['sites']:.1e}", "m"],
        ["closure residual of the connect sites in MuJoCo", f"{worst['closure']:.1e}", "m"],
        ["mass matrix: MuJoCo (velocity map applied) vs Pinocchio crba", f"{worst['mass']:.1e}",
         "kg, kg m, kg m^2"],
        [f"actuator forces due to tiny inertia {mjcf.TINY_INERTIA:g} kg m^2 (carriages, leg "
         "axis)", f"{worst['tiny inertia']:.1e}", "N"],
    ]
    return rows, worst


# -- wrapper cost -------------------------------------------------------------------------
def wrapper_cost(peers: HexapodPeers, repeats: int) -> str:
    """One inverse dynamics from a platform state: ours against the raw calls it needs."""
    r, raw, s = peers.robot, peers.raw, peers
    pool = min(64, peers.n_tree)
    peers.prepare_tree(pool)
    dyn = r.dynamics.tree_dynamics
    items = [
        ("raw Pinocchio calls only (Jacobian frames, drift frames, rnea)",
         lambda i: pr.pinocchio_calls_of_inverse(raw, *s.pin_state[i])),
        ("raw route incl. closed-form q and numpy completion/solves",
         lambda i: raw.inverse_task(s.poses[i], s.twists[i], s.twist_dots[i], s.wrenches[i])),
    ]
    inv = _ours(r, "inverse_dynamics")
    if inv is not None:
        items += [
            ("ours inverse_dynamics kkt, joint_wrenches=False, bounded=False",
             lambda i: inv(s.poses[i], s.twists[i], s.twist_dots[i], s.wrenches[i],
                           method="kkt", joint_wrenches=False, bounded=False)),
            ("ours inverse_dynamics (defaults: kkt, bounded, joint wrenches)",
             lambda i: inv(s.poses[i], s.twists[i], s.twist_dots[i], s.wrenches[i])),
        ]
    items.append(("  part: ours Pinocchio call (one rnea on the tree state)",
                  lambda i: pin.rnea(raw.model, raw.data, *s.pin_state[i])))
    items.append(("  part: ours Hexapod.configuration (closed-form tree q)",
                  lambda i: r.configuration(s.poses[i])))
    if dyn is not None:
        items += [
            ("  part: ours constraint_jacobian", lambda i: dyn.constraint_jacobian(
                s.pin_state[i][0])),
            ("  part: ours constraint_drift", lambda i: dyn.constraint_drift(
                s.pin_state[i][0], s.pin_state[i][1])),
        ]
    rows, base = [], None
    for name, fn in items:
        counter = iter(range(10 ** 12))
        t = measure(lambda: fn(next(counter) % pool), repeats=repeats)
        base = t if base is None else base
        rows.append([name, fmt_us(t), f"{t.median / base.median:.2f}"])
    return table(["one inverse dynamics, platform state in", "us per call",
                  "/ raw Pinocchio calls"], rows,
                 title="## Wrapper cost: one inverse dynamics against the Pinocchio calls it "
                       "needs")



# -- single-call overhead ---------------------------------------------------------------------
def single_call(peers: HexapodPeers, repeats: int) -> str:
    """One inverse / forward dynamics call of the facade on the default route against
    MuJoCo's bare ``mj_inverse`` / ``mj_forward`` on the same mechanism (issue 32 item 3).

    MuJoCo's data are prepared per state beforehand (one ``MjData`` each, the tree state
    set): its rows time the bare call only, no state transfer, no reduction to actuator
    forces, soft closures. Ours start from the platform state (closed-form tree state,
    input checks, lock, result object, finiteness check included)."""
    r, s = peers.robot, peers
    pool = min(64, peers.n_tree)
    peers.prepare_tree(pool)
    items = [
        ("ours Hexapod.inverse_dynamics (defaults: kkt, bounded)", "inverse",
         lambda i: r.inverse_dynamics(s.poses[i], s.twists[i], s.twist_dots[i])),
        ("ours Hexapod.inverse_dynamics with a wrench", "inverse",
         lambda i: r.inverse_dynamics(s.poses[i], s.twists[i], s.twist_dots[i], s.wrenches[i])),
        ("ours Hexapod.forward_dynamics (defaults: nullspace)", "forward",
         lambda i: r.forward_dynamics(s.poses[i], s.twists[i], s.forces[i])),
        ("ours Hexapod.forward_dynamics with a wrench", "forward",
         lambda i: r.forward_dynamics(s.poses[i], s.twists[i], s.forces[i], s.wrenches[i])),
    ]
    base: dict[str, float] = {}
    if peers.mj is not None:
        m = peers.mj.model
        datas = []
        for i in range(pool):
            d = mujoco.MjData(m)
            d.qpos[:], d.qvel[:], d.qacc[:] = s.mj_state[i]
            datas.append(d)
        items = [("MuJoCo mj_inverse (bare, tree state set)", "inverse",
                  lambda i: mujoco.mj_inverse(m, datas[i])),
                 ("MuJoCo mj_forward (bare, tree state set)", "forward",
                  lambda i: mujoco.mj_forward(m, datas[i]))] + items
    rows = []
    # samples interleaved: a change of load hits ours and MuJoCo's alike (the ratios hold)
    timings = measure_interleaved([_cycled(fn, list(range(pool))) for _, _, fn in items],
                                  repeats=repeats)
    for (name, kind, _), t in zip(items, timings):
        base.setdefault(kind, t.median)
        rows.append([name, fmt_us(t), f"{t.median / base[kind]:.2f}"])
    return table(["one call, random states", "us per call", "/ MuJoCo bare call"], rows,
                 title="## Single-call overhead: the facade against MuJoCo's bare calls")

def _cycled(call: Callable[[object], object], items: list) -> Callable[[], object]:
    """A zero-argument function calling ``call`` on the next item of ``items``, cycling."""
    counter = iter(range(10 ** 12))
    return lambda: call(items[next(counter) % len(items)])


def _ratio(ours: Timing, peer: Timing | None) -> str:
    return "" if peer is None else f"{ours.median / peer.median:.2f}"


def single_call_robots(repeats: int, n_states: int = 64) -> str:
    """The same single-call comparison for the planar 3-PRR (its compiled closed form) and
    robots loaded from descriptions (``hp.ClosedLoopRobot``: the tree routes): each
    against MuJoCo's bare ``mj_inverse`` / ``mj_forward`` on its exported twin
    (:func:`hexapod_pin.core.mujoco_export.to_mujoco`, tree state set beforehand, as in
    :func:`single_call`). States: :func:`bench_robots.states` (regular, near home), cycled;
    a loaded robot solves its configuration in every call (the last one is no help)."""
    import bench_robots

    from hexapod_pin.core.mujoco_export import mujoco_state, to_mujoco

    hexapod = hp.Hexapod.default()
    data = bench_robots.DATA
    robots = {
        "planar 3-PRR (closed form)": hp.Planar3PRR.default(),
        "hexapod loaded (ClosedLoopRobot on its tree)": hp.ClosedLoopRobot(
            hexapod.model, "platform", home=hexapod.home_configuration),
        "Stewart 6-UPS (hp.load_robot)": hp.load_robot(data / "stewart" / "stewart.urdf"),
    }
    rows = []
    for name, robot in robots.items():
        states = bench_robots.states(robot, n_states)
        inv = [robot.inverse_dynamics(p, t, a, bounded=False) for p, t, a in states]
        taus = [r.actuator_forces for r in inv]
        mj_inv = mj_fwd = None
        mj_calls: list = []
        if mujoco is not None:
            try:
                model = to_mujoco(robot.model)
            except hp.InputError:
                model = None
            if model is not None:
                datas = []
                for r, u in zip(inv, taus):
                    d = mujoco.MjData(model)
                    st = mujoco_state(robot.model, r.configuration, r.velocity, r.acceleration)
                    d.qpos[:], d.qvel[:], d.qacc[:], d.ctrl[:] = st.qpos, st.qvel, st.qacc, u
                    datas.append(d)
                mj_calls = [_cycled(partial(mujoco.mj_inverse, model), datas),
                            _cycled(partial(mujoco.mj_forward, model), datas)]
        calls = [_cycled(lambda s, r=robot: r.inverse_dynamics(*s, bounded=False), states),
                 _cycled(lambda s, r=robot: r.forward_dynamics(*s),
                         [(p, t, u) for (p, t, _), u in zip(states, taus)])]
        if mj_calls:
            ours_inv, ours_fwd, mj_inv, mj_fwd = measure_interleaved(calls + mj_calls,
                                                                     repeats=repeats)
        else:
            ours_inv, ours_fwd = measure_interleaved(calls, repeats=repeats)
        rows.append([name, fmt_us(ours_inv), fmt_us(mj_inv), _ratio(ours_inv, mj_inv),
                     fmt_us(ours_fwd), fmt_us(mj_fwd), _ratio(ours_fwd, mj_fwd)])
    return table(["robot", "ours inverse_dynamics", "MuJoCo mj_inverse (bare)", "ratio",
                  "ours forward_dynamics", "MuJoCo mj_forward (bare)", "ratio"], rows,
                 title="## Single-call overhead of the other robots: the facade (defaults, "
                       "bounded=False) against MuJoCo's bare calls on the exported twin")


# -- simulation throughput ------------------------------------------------------------------
def simulation_throughput(peers: HexapodPeers, repeats: int, steps: int = 200) -> str:
    """Microseconds per step of a run of ``steps`` steps at dt = 1 ms from one state."""
    r, raw, mj, p = peers.robot, peers.raw, peers.mj, peers.p
    pose = peers.poses[0]
    wrench = peers.wrenches[0]
    forces = nh.static_forces(p, pose[None], wrench[None])[0] + 1.0   # a slow drift
    zero = np.zeros(6)
    items = []
    try:
        import hexapod_pin.hexapod.simulation as sim
    except ImportError:
        sim = None
    if sim is not None and hasattr(sim, "simulate"):
        for kind in ("rk4", "semi_implicit_euler"):
            items.append((f"ours simulate, {kind}", lambda kind=kind: sim.simulate(
                r, steps * DT, DT, pose0=pose, twist0=zero, actuator_forces=forces,
                wrench=wrench, integrator=kind, check_limits=False, saturation="ignore")))
    fast = _fast(r)
    if fast is not None and fast[1] is not None:
        for kind in ("rk4", "semi_implicit_euler"):
            items.append((f"ours simulate_fast, {kind} on the platform ({fast[2]})",
                          lambda kind=kind: fast[1](
                              r, steps * DT, DT, pose0=pose, twist0=zero, actuator_forces=forces,
                              wrench=wrench, check_limits=False, saturation="ignore",
                              integrator=kind)))
        stepper_cls = getattr(sys.modules.get("hexapod_pin.hexapod.fast"), "FastStepper", None)
        if stepper_cls is not None:
            stepper = stepper_cls(r, DT, check_limits=False)

            def step_run():
                stepper.reset(pose, zero)
                for _ in range(steps):
                    stepper.step(forces, wrench)
            items.append((f"ours FastStepper.step, semi_implicit_euler, a Python loop ({fast[2]})",
                          step_run))
    q0, v0, _ = raw.tree_state(pose, zero, zero)

    def raw_run():
        q, v = q0, v0
        for _ in range(steps):
            q, v = raw.step(q, v, forces, DT, wrench)
    items.append(("raw Pinocchio constraintDynamics + integrate (loop)", raw_run))
    if mj is not None:
        qpos, qvel, _ = mj.set_task_state(pose, zero)

        def mj_run():
            m, d = mj.model, mj.data
            d.qpos[:], d.qvel[:], d.ctrl[:] = qpos, qvel, forces
            d.xfrc_applied[mj.platform_body] = wrench
            d.qacc_warmstart[:] = 0.0
            for _ in range(steps):
                mujoco.mj_step(m, d)
        items.append(("MuJoCo mj_step, Euler (loop)", mj_run))

    def numpy_run():
        ps, tw = pose[None], zero[None]
        for _ in range(steps):
            ps, tw = nh.step(p, ps, tw, forces[None], DT, wrench[None])
    items.append(("numpy semi-implicit Euler (loop)", numpy_run))
    rows = []
    for name, fn in items:
        t = measure(fn, repeats=max(3, repeats // 2)).per_state(steps)
        rows.append([name, fmt_us(t), f"{DT / t.median:.1f}"])
    return table(["route", "us per step", "real-time factor at 1 kHz"], rows,
                 title=f"## Simulation throughput: {steps} steps of dt = {DT:g} s from one state")


# -- accuracy -----------------------------------------------------------------------------
def tolerance(a: Route, b: Route, op: Operation, scheme_tol: float) -> float:
    """Agreement required between two routes (see the module constants)."""
    tol = RIGID_TOL if a.scheme == b.scheme else scheme_tol
    if a.soft or b.soft:
        tol += SOFT_FD_TOL * (DT if op.scheme_tol is not None else 1.0)
    return tol


def accuracy(op: Operation, n: int) -> tuple[list[str], list[list[str]], list[str]]:
    """Pairwise max-abs differences over n states; returns headers, rows, failures."""
    routes = [r for r in op.routes if r.available]
    outs = {}
    for r in routes:
        outs[r.name] = r.run(n)
    labels = [f"({k + 1})" for k in range(len(routes))]
    scheme_tol = op.scheme_tol(n) if op.scheme_tol is not None else RIGID_TOL
    rows, failures = [], []
    for i, a in enumerate(routes):
        row = [f"{labels[i]} {a.name}"]
        for j, b in enumerate(routes):
            if j <= i:
                row.append("")
                continue
            diff = float(np.max(np.abs(outs[a.name] - outs[b.name])))
            tol = tolerance(a, b, op, scheme_tol)
            flag = "" if diff <= tol else " FAIL"
            if flag:
                failures.append(f"{op.name}: {a.name} vs {b.name}: {diff:.2e} > {tol:g}")
            row.append(f"{diff:.1e}{flag}")
        rows.append(row)
    return ["route"] + labels, rows, failures


# -- timing -------------------------------------------------------------------------------
def time_route(route: Route, peers: HexapodPeers, n: int, repeats: int, budget: float,
               mem_limit: float, history: dict) -> Timing | str:
    """Seconds per state for ``n`` states (one call on n states, or a loop of n calls)."""
    if not route.available:
        return route.missing
    key = route.name
    if route.batch is not None and n > 1:
        needs_tree = getattr(route.batch, "needs_tree", False)
        est = history.get((key, "batch"))
        if est is not None and est * n * (repeats + 2) > budget:
            return f"skipped (~{est * n * (repeats + 2):.0f} s)"
        if n >= 10 ** 6 and (key, "mem") in history:
            mem = history[(key, "mem")] * n
            if mem > mem_limit:
                return f"skipped (~{mem / 2 ** 30:.0f} GiB)"
        if needs_tree and n > peers.n_tree:
            peers.prepare_tree(n)
        if n == 10 ** 4:
            history[(key, "mem")] = peak_memory(lambda: route.batch(n)) / n
        t = measure(lambda: route.batch(n), repeats=repeats).per_state(n)
        history[(key, "batch")] = t.median
        return t
    if route.single is None:          # batch only, n == 1
        t = measure(lambda: route.batch(1), repeats=repeats)
        history[(key, "batch")] = t.median
        return t
    est = history.get((key, "single"))
    if n > 1 and est is not None and est * n * (repeats + 2) > budget:
        return f"skipped (~{est * n * (repeats + 2):.0f} s)"
    pool = min(max(n, 64), len(peers.poses))
    if n == 1:
        peers.prepare_tree(pool)
        counter = iter(range(10 ** 12))
        t = measure(lambda: route.single(next(counter) % pool), repeats=repeats)
        history[(key, "single")] = t.median
        return t
    peers.prepare_tree(n)
    single = route.single

    def loop():
        for i in range(n):
            single(i)
    t = measure(loop, repeats=repeats).per_state(n)
    history[(key, "single")] = t.median
    return t


def ratio(ours: Timing | str, theirs: Timing | str) -> str:
    if isinstance(ours, Timing) and isinstance(theirs, Timing):
        return f"{ours.median / theirs.median:.2f}"
    return NO_ROUTE


def timing_tables(peers: HexapodPeers, ops: list[Operation], sizes: list[int], repeats: int,
                  budget: float, mem_limit: float) -> str:
    history: dict = {}
    out = []
    for op in ops:
        rows = []
        results: dict[str, list] = {}
        for route in op.routes:
            if not route.timed:
                continue
            cells = []
            for n in sizes:
                t = time_route(route, peers, n, repeats if n < 10 ** 5 else max(3, repeats // 2),
                               budget, mem_limit, history)
                cells.append(t)
            results[route.name] = cells
            label = route.name + (" (loop)" if route.batch is None and route.single else "")
            rows.append([label] + [fmt_us(c) for c in cells])
        ours = [n for n in results if n.startswith("ours")]
        mj = [r.name for r in op.routes if r.name.startswith("MuJoCo") and r.available
              and r.timed]
        best = []
        for k in range(len(sizes)):
            times = [results[n][k] for n in ours if isinstance(results[n][k], Timing)]
            best.append(min(times, key=lambda t: t.median) if times else NO_ROUTE)
        for name in mj:
            rows.append([f"ratio fastest ours / {name}"] +
                        [ratio(best[k], results[name][k]) for k in range(len(sizes))])
        out.append(table(["route"] + [f"N = {_n(n)} (us/state)" for n in sizes], rows,
                         title=f"### {op.name}"))
    return "\n".join(out)


def _n(n: int) -> str:
    return f"10^{int(np.log10(n))}" if n >= 1000 else str(n)


# -- main ---------------------------------------------------------------------------------
def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--smoke", action="store_true", help="tiny run; check agreement only")
    parser.add_argument("--states", type=int, default=1000, help="states for accuracy")
    parser.add_argument("--sizes", default="1,100,10000,1000000",
                        help="batch sizes N for the timing tables")
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--budget", type=float, default=30.0,
                        help="skip a timing cell estimated to take longer (s)")
    parser.add_argument("--mem-limit", type=float, default=4.0, help="GiB per timing cell")
    parser.add_argument("--no-timing", action="store_true")
    parser.add_argument("--single-call", action="store_true",
                        help="only the single-call table (the facade against MuJoCo's bare "
                             "mj_inverse / mj_forward)")
    parser.add_argument("--cpu-time", action="store_true",
                        help="time with the thread's CPU time (time.thread_time) instead of "
                             "wall time: on a shared machine, waits for a core not counted")
    parser.add_argument("--perturb-numpy-mass", type=float, default=0.0,
                        help="relative error put on the numpy peer's platform mass (to "
                             "check that a disagreement is caught)")
    args = parser.parse_args(argv)
    if args.smoke:
        args.states, args.sizes, args.repeats, args.budget = 12, "1,10", 2, 2.0
        MIN_SAMPLE["seconds"] = 1e-3
    sizes = [int(float(x)) for x in args.sizes.split(",")]
    if args.cpu_time:
        CLOCK["now"] = time.thread_time
    print_machine_info()
    if mujoco is None:
        print("mujoco is not installed: MuJoCo rows are skipped (pip install mujoco)")
    geometry = hp.HexapodGeometry()
    n_vec = max([args.states] + sizes)
    peers = HexapodPeers(geometry, n_vec, n_tree=args.states)
    if args.perturb_numpy_mass:
        peers.p = dataclasses.replace(
            peers.p, platform_mass=peers.p.platform_mass * (1 + args.perturb_numpy_mass))
    if args.single_call:
        print(single_call(peers, args.repeats))
        print(single_call_robots(args.repeats))
        return 0
    failures = []
    if peers.mj is not None:
        rows, worst = model_check(peers, n=min(20, args.states))
        print(table(["MJCF check (max over states)", "max abs", "unit"], rows,
                    title="## MJCF vs our Pinocchio model"))
        for key, value in worst.items():
            if value > RIGID_TOL:
                failures.append(f"MJCF check {key}: {value:.2e}")
    ops = peers.operations()
    print(f"\n## Accuracy: max abs difference over {args.states} random states "
          "(N, m/s^2, rad/s^2, m, rad)")
    for op in ops:
        if peers.mj is not None:
            peers.mj.refinements.clear()
        headers, rows, fails = accuracy(op, args.states)
        note = ""
        if op.scheme_tol is not None:
            note = (f" (different integration schemes: tolerance "
                    f"{op.scheme_tol(args.states):.1e}, see scheme_tol)")
        print(table(headers, rows, title=f"### {op.name}{note}"))
        if peers.mj is not None and peers.mj.refinements:
            counts = np.array(peers.mj.refinements)
            print(f"\nMuJoCo proximal refinement passes: median {np.median(counts):.0f}, "
                  f"max {counts.max()} (stop at 1e-12 relative change)")
        failures += fails
    if not args.no_timing:
        print(single_call(peers, args.repeats))
        print(wrapper_cost(peers, args.repeats))
        print(simulation_throughput(peers, args.repeats, steps=20 if args.smoke else 200))
        print("\n## Speed: microseconds per state, median [inter-quartile range] over "
              f"{args.repeats} repeats ((loop): a Python loop of single calls)")
        print(timing_tables(peers, ops, sizes, args.repeats, args.budget,
                            args.mem_limit * 2 ** 30))
    if failures:
        print("\nDISAGREEMENT:\n" + "\n".join(failures))
        return 1
    print("\nall routes agree within their tolerances")
    return 0


if __name__ == "__main__":
    sys.exit(main())
