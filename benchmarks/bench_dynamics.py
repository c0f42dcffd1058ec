"""Timings of the closed-loop dynamics of the hexapod (µs per call from Python).

Usage::

    python benchmarks/bench_dynamics.py            # full table
    python benchmarks/bench_dynamics.py --smoke    # tiny counts; checks that routes agree

Each row: median and inter-quartile range of the per-call time over ``--repeat`` blocks
of ``--number`` calls (batches: per state, over N states). Pose-level calls cycle through
distinct random states so that no cache hides the cost of building the tree state.

Columns "before":

* "legacy, same run": the previous pose-level route rebuilt here from the public generic
  pieces and timed in the same run: tree state by solving the closure Jacobian system
  (``J_c v = 0``, ``J_c a = -gamma`` with Pinocchio's ``J_c`` and drift), then the tree
  solvers (:func:`inverse_dynamics_tree` / :func:`forward_dynamics_tree`); the legacy
  batch is a Python loop of it. It uses today's (fast) ``configuration``, so it
  understates the old cost.
* "recorded": the pose-level calls of the library before this work (commit c6e271a),
  measured on this 2-core VM at the start of the work (load average 2-3; fastest block).

The simulation rows time whole RK4 steps of 1 ms (four constrained forward dynamics,
closure check, projection when the closure residual exceeds 1e-10 m) and give the
real-time factor at 1 kHz. BLAS threads are limited to one (the matrices are tiny).
"""

from __future__ import annotations

import os

# small dense matrices: BLAS threads only add contention (set before numpy loads)
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse
import platform
import statistics
import sys
import time

import numpy as np
import pinocchio as pin
import proxsuite

import hexapod_pin as hp
from hexapod_pin.core.dynamics import dynamics_of
from hexapod_pin.core.dynamics import forward_dynamics_tree, inverse_dynamics_tree
from hexapod_pin.core.pose import rotation_from_rpy
from hexapod_pin.hexapod.simulation import (
    CircleTrajectory,
    ClosedLoopIntegrator,
    ComputedTorqueController,
    simulate,
)

from bench_kinematics import poses_near_home  # benchmarks/ is the script's folder

#: µs per call of the pose-level API before this work (commit c6e271a, this VM, fastest
#: block of 5 x 300 calls, load average 2-3)
RECORDED_BEFORE = {
    "configuration": 578.0,
    "inverse_dynamics qp": 1991.0,
    "inverse_dynamics kkt": 876.0,
    "forward_dynamics pinocchio": 925.0,
    "static_forces": 1304.0,
    "reduced_dynamics": 1380.0,
    "rk4 step": 457.0,
}



def _time(fn, number, repeat):
    """Per-call times (µs) of ``fn(k)`` (k the call index) over ``repeat`` blocks."""
    fn(0)
    times = []
    k = 0
    for _ in range(repeat):
        start = time.perf_counter()
        for _ in range(number):
            fn(k)
            k += 1
        times.append((time.perf_counter() - start) / number * 1e6)
    return times


def _fmt(value):
    return "-" if value is None else f"{value:.1f}"


def _row(name, times, legacy=None, recorded=None, note=""):
    med = statistics.median(times)
    q = np.percentile(times, [25, 75])
    print(f"| {name:<44} | {med:9.2f} | {q[0]:8.2f} - {q[1]:<8.2f} | {_fmt(legacy):>9} | "
          f"{_fmt(recorded):>9} | {note} |")
    return med


# -- the legacy route (tree state through the closure Jacobian) ----------------------------
class Legacy:
    """The previous pose-level route, rebuilt from public generic pieces."""

    def __init__(self, robot):
        self.robot = robot
        self.clm = robot.model
        self.dyn = dynamics_of(robot.model)
        idx = robot.indices
        self.ff = np.arange(idx.platform_v.start, idx.platform_v.stop)
        self.free = np.setdiff1d(np.arange(self.clm.nv), self.ff)

    def state(self, pose, twist, twist_dot=None):
        q = self.robot.configuration(pose)
        rot = rotation_from_rpy(pose[3:])
        jac = self.dyn.constraint_jacobian(q)
        inv = np.linalg.inv(jac[:, self.free])
        v = np.empty(self.clm.nv)
        v_ff = np.concatenate([rot.T @ twist[:3], rot.T @ twist[3:]])
        v[self.ff] = v_ff
        v[self.free] = inv @ (-jac[:, self.ff] @ v_ff)
        a = None
        if twist_dot is not None:
            gamma = self.dyn.constraint_drift(q, v)
            a_ff = np.concatenate([rot.T @ (twist_dot[:3] - np.cross(twist[3:], twist[:3])),
                                   rot.T @ twist_dot[3:]])
            a = np.empty(self.clm.nv)
            a[self.ff] = a_ff
            a[self.free] = inv @ (-gamma - jac[:, self.ff] @ a_ff)
        return q, v, a, rot

    def tau_ext(self, rot, wrench):
        tau = np.zeros(self.clm.nv)
        tau[self.ff] = np.concatenate([rot.T @ wrench[:3], rot.T @ wrench[3:]])
        return tau

    def inverse(self, pose, twist, twist_dot, wrench, method="kkt"):
        q, v, a, rot = self.state(pose, twist, twist_dot)
        return inverse_dynamics_tree(self.clm, q, v, a, self.tau_ext(rot, wrench),
                                     bounds=100.0, method=method).actuator_forces

    def forward(self, pose, twist, forces, wrench):
        q, v, _, rot = self.state(pose, twist)
        a = forward_dynamics_tree(self.clm, q, v, forces, self.tau_ext(rot, wrench),
                                  method="pinocchio").a
        a_ff = a[self.ff]
        return np.concatenate([rot @ a_ff[:3] + np.cross(twist[3:], twist[:3]), rot @ a_ff[3:]])

    def static(self, pose, wrench):
        q, v, a, rot = self.state(pose, np.zeros(6), np.zeros(6))
        return inverse_dynamics_tree(self.clm, q, v, a, self.tau_ext(rot, wrench),
                                     method="kkt").actuator_forces


def _batch_rows(robot, legacy, n, states, number, repeat):
    """Per-state times of the batch APIs for N = n states (and of a loop of the legacy
    single-state route for small n)."""
    idx = np.arange(n) % len(states[0])
    P, T, D, W, F = (x[idx] for x in states)
    reps = max(3, repeat // 3)
    calls = max(1, min(number, 2000 // n))

    def per(fn):
        return [t / n for t in _time(fn, calls, reps)]

    loop_legacy = None
    if n <= 100:
        loop_legacy = statistics.median(per(lambda k: [legacy.inverse(P[j], T[j], D[j], W[j])
                                                       for j in range(n)]))
    _row(f"inverse_dynamics_batch, per state (N={n})",
         per(lambda k: robot.inverse_dynamics_batch(P, T, D, W, bounded=False)),
         legacy=loop_legacy, note="closed form, vectorised (legacy: Python loop)")
    _row(f"forward_dynamics_batch, per state (N={n})",
         per(lambda k: robot.forward_dynamics_batch(P, T, F, W)), note="closed form, vectorised")
    _row(f"static_forces_batch, per state (N={n})",
         per(lambda k: robot.static_forces_batch(P, W)), note="closed form, vectorised")


def _mujoco_rows(robot, poses, twists, twist_dots, number, repeat):
    """Raw ``mj_inverse`` / ``mj_forward`` in a Python loop (the peer's floor), if present."""
    try:
        import mujoco
        sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
        from mjcf import MujocoHexapod
        mj = MujocoHexapod(robot.geometry)
        mj.set_task_state(poses[0], twists[0], twist_dots[0])
    except Exception as exc:   # optional peer: any failure only drops its rows
        print(f"| MuJoCo rows skipped | - | - | - | - | {type(exc).__name__}: {exc} |")
        return
    m, d = mj.model, mj.data
    _row("MuJoCo mj_inverse, Python loop (state set)",
         _time(lambda k: mujoco.mj_inverse(m, d), number, repeat),
         note=f"mujoco {mujoco.__version__}: tree forces only (no reduction)")
    _row("MuJoCo mj_forward, Python loop (state set)",
         _time(lambda k: mujoco.mj_forward(m, d), number, repeat),
         note="soft closures")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--smoke", action="store_true", help="tiny counts, check agreement")
    parser.add_argument("--number", type=int, default=200)
    parser.add_argument("--repeat", type=int, default=15)
    args = parser.parse_args(argv)
    number, repeat = (3, 3) if args.smoke else (args.number, args.repeat)

    robot = hp.Hexapod.default()
    clm = robot.model
    dyn = dynamics_of(clm)
    legacy = Legacy(robot)
    rng = np.random.default_rng(0)
    n_states = 8 if args.smoke else 64
    poses = poses_near_home(robot, rng, n_states)
    twists = np.concatenate([0.05 * rng.normal(size=(n_states, 3)),
                             0.3 * rng.normal(size=(n_states, 3))], axis=1)
    twist_dots = np.concatenate([0.5 * rng.normal(size=(n_states, 3)),
                                 2.0 * rng.normal(size=(n_states, 3))], axis=1)
    wrenches = np.concatenate([2.0 * rng.normal(size=(n_states, 3)),
                               0.2 * rng.normal(size=(n_states, 3))], axis=1)
    # keep states well inside the actuator bounds (far from singular poses)
    forces = robot.inverse_dynamics_batch(poses, twists, twist_dots, wrenches,
                                          bounded=False).actuator_forces
    keep = np.flatnonzero(np.abs(forces).max(axis=1) < 50.0)
    poses, twists, twist_dots, wrenches, forces = (x[keep] for x in (poses, twists, twist_dots,
                                                                     wrenches, forces))
    n_states = len(keep)
    # tree states for the generic functions (no wrench: tau is the actuation alone)
    tree = []
    for k in range(n_states):
        res = robot.inverse_dynamics(poses[k], twists[k], twist_dots[k], method="kkt",
                                     bounded=False)
        tau = np.zeros(clm.nv)
        tau[clm.actuated_v] = res.actuator_forces
        tree.append((res.configuration, res.velocity, res.acceleration, tau))

    # -- agreement of the routes (the smoke test's purpose) -----------------------------------
    worst = {}

    def note(name, value):
        worst[name] = max(worst.get(name, 0.0), float(value))

    for k in range(min(n_states, 4)):
        q, v, a, tau = tree[k]
        fds = {m: forward_dynamics_tree(clm, q, v, tau[clm.actuated_v], method=m)
               for m in ("pinocchio", "qp", "kkt")}
        note("FD routes, a", max(np.abs(fds[m].a - fds["kkt"].a).max() for m in fds))
        note("FD(ID(x)) - x, a", np.abs(fds["pinocchio"].a - a).max())
        ids = {m: inverse_dynamics_tree(clm, q, v, a, method=m) for m in ("qp", "kkt")}
        note("ID routes, tau", np.abs(ids["qp"].actuator_forces
                                      - ids["kkt"].actuator_forces).max())
    single = np.array([robot.inverse_dynamics(poses[k], twists[k], twist_dots[k], wrenches[k],
                                              method="kkt", bounded=False).actuator_forces
                       for k in range(n_states)])
    single_qp = np.array([robot.inverse_dynamics(poses[k], twists[k], twist_dots[k],
                                                 wrenches[k]).actuator_forces
                          for k in range(n_states)])
    note("pose-level ID qp - kkt, tau", np.abs(single_qp - single).max())
    note("pose-level ID - legacy route, tau", max(
        np.abs(single[k] - legacy.inverse(poses[k], twists[k], twist_dots[k], wrenches[k])).max()
        for k in range(n_states)))
    batch = robot.inverse_dynamics_batch(poses, twists, twist_dots, wrenches, bounded=False)
    note("batch (closed form) - single (tree) ID, tau", np.abs(batch.actuator_forces - single).max())
    fwd_batch = robot.forward_dynamics_batch(poses, twists, single, wrenches)
    note("batch FD - sampled twist_dot", np.abs(fwd_batch.twist_dot - twist_dots).max())
    fwd_single = np.array([robot.forward_dynamics(poses[k], twists[k], single[k],
                                                  wrenches[k]).twist_dot
                           for k in range(n_states)])
    note("single FD (constraintDynamics) - sampled twist_dot",
         np.abs(fwd_single - twist_dots).max())
    note("single FD - legacy route, twist_dot", max(
        np.abs(fwd_single[k] - legacy.forward(poses[k], twists[k], single[k], wrenches[k])).max()
        for k in range(n_states)))
    static_batch = robot.static_forces_batch(poses, wrenches)
    note("batch - single statics, tau", max(
        np.abs(static_batch[k] - robot.static_forces(poses[k], wrenches[k])).max()
        for k in range(n_states)))
    note("statics - legacy route, tau", max(
        np.abs(static_batch[k] - legacy.static(poses[k], wrenches[k])).max()
        for k in range(n_states)))
    ok = all(value < 1e-9 for value in worst.values())

    load = os.getloadavg() if hasattr(os, "getloadavg") else (float("nan"),) * 3
    print(f"# hexapod_pin dynamics benchmark ({'smoke' if args.smoke else 'full'})")
    print(f"python {platform.python_version()}, pinocchio {pin.__version__}, proxsuite "
          f"{proxsuite.__version__}, numpy {np.__version__}, {platform.machine()} "
          f"{platform.processor() or platform.platform()}, {os.cpu_count()} CPUs, "
          f"load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")
    print()
    print("| agreement check | max abs difference |")
    print("|---|---|")
    for name, value in worst.items():
        print(f"| {name} | {value:.2e} |")
    print()
    print("| call | median µs | IQR µs | legacy, same run µs | recorded before µs | note |")
    print("|---|---|---|---|---|---|")

    def cyc(k):
        return k % n_states

    rec = RECORDED_BEFORE
    small = np.ones(24)
    _row("calibration: numpy a + a, a of size 24", _time(lambda k: small + small, number, repeat),
         note="machine speed reference")
    prox = pin.ProximalSettings(1e-13, 0.0, 1)
    data = clm.model.createData()
    cms, cds = dyn.pin_models, dyn.pin_datas
    pin.initConstraintDynamics(clm.model, data, cms, cds)
    t_rnea = _row("pin.rnea (floor)", _time(lambda k: pin.rnea(clm.model, data, *tree[cyc(k)][:3]),
                                            number, repeat))
    mat6, vec6 = np.eye(6) + 0.1, np.ones(6)
    t_solve = _row("np.linalg.solve 6x6 (floor)",
                   _time(lambda k: np.linalg.solve(mat6, vec6), number, repeat))
    _row("pin.constraintDynamics (floor)",
         _time(lambda k: pin.constraintDynamics(clm.model, data, tree[cyc(k)][0],
                                                tree[cyc(k)][1], tree[cyc(k)][3], cms, cds,
                                                prox), number, repeat))
    t_generic = None
    try:
        sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
        import pinocchio_raw as pr
        raw = pr.RawHexapod(robot)
        t_generic = _row("Pinocchio calls of a generic closed-loop ID (floor)",
                         _time(lambda k: pr.pinocchio_calls_of_inverse(raw, *tree[cyc(k)][:3]),
                               number, repeat),
                         note="J_c, drift, rnea: benchmarks/pinocchio_raw.py")
    except Exception as exc:   # helper of the peers benchmark: optional here
        print(f"| generic Pinocchio floor skipped | - | - | - | - | {type(exc).__name__}: {exc} |")
    _mujoco_rows(robot, poses, twists, twist_dots, number, repeat)
    _row("Hexapod.configuration(pose)",
         _time(lambda k: robot.configuration(poses[cyc(k)]), number, repeat),
         recorded=rec["configuration"], note="IK + closed-form angles + exact closure check")
    kkt = _row("inverse_dynamics kkt",
               _time(lambda k: robot.inverse_dynamics(poses[cyc(k)], twists[cyc(k)],
                                                      twist_dots[cyc(k)], wrenches[cyc(k)],
                                                      method="kkt"), number, repeat),
               legacy=statistics.median(_time(lambda k: legacy.inverse(
                   poses[cyc(k)], twists[cyc(k)], twist_dots[cyc(k)], wrenches[cyc(k)]),
                   number, repeat)),
               recorded=rec["inverse_dynamics kkt"],
               note="new pose each call; closure forces / joint wrenches on access")
    _row("inverse_dynamics qp (default)",
         _time(lambda k: robot.inverse_dynamics(poses[cyc(k)], twists[cyc(k)], twist_dots[cyc(k)],
                                                wrenches[cyc(k)]), number, repeat),
         legacy=statistics.median(_time(lambda k: legacy.inverse(
             poses[cyc(k)], twists[cyc(k)], twist_dots[cyc(k)], wrenches[cyc(k)], "qp"),
             number, repeat)),
         recorded=rec["inverse_dynamics qp"],
         note="ProxSuite box QP, 6 variables, warm-started at the LU solution")
    _row("inverse_dynamics kkt + closure_forces",
         _time(lambda k: robot.inverse_dynamics(poses[cyc(k)], twists[cyc(k)], twist_dots[cyc(k)],
                                                wrenches[cyc(k)], method="kkt").closure_forces,
               number, repeat), note="closure forces accessed")
    for method in ("nullspace", "pinocchio", "kkt", "qp"):
        _row(f"forward_dynamics {method}" + (" (default)" if method == "nullspace" else ""),
             _time(lambda k, m=method: robot.forward_dynamics(
                 poses[cyc(k)], twists[cyc(k)], forces[cyc(k)], wrenches[cyc(k)], method=m),
                   number, repeat),
             legacy=statistics.median(_time(lambda k: legacy.forward(
                 poses[cyc(k)], twists[cyc(k)], forces[cyc(k)], wrenches[cyc(k)]),
                 number, repeat)) if method == "pinocchio" else None,
             recorded=rec["forward_dynamics pinocchio"] if method == "pinocchio" else None,
             note="new pose each call")
    _row("static_forces", _time(lambda k: robot.static_forces(poses[cyc(k)]), number, repeat),
         legacy=statistics.median(_time(lambda k: legacy.static(poses[cyc(k)], np.zeros(6)),
                                        number, repeat)),
         recorded=rec["static_forces"], note="new pose each call")
    _row("reduced_dynamics",
         _time(lambda k: robot.reduced_dynamics(poses[cyc(k)], twists[cyc(k)]), number, repeat),
         recorded=rec["reduced_dynamics"], note="M_x, h_x, J, T")
    _row("inverse_dynamics_derivatives",
         _time(lambda k: robot.inverse_dynamics_derivatives(
             poses[cyc(k)], twists[cyc(k)], twist_dots[cyc(k)], wrenches[cyc(k)]),
             number, repeat),
         note="analytic: pose, twist, twist_dot, wrench (pin.computeConstraintDynamicsDerivatives)")

    sizes = (1, 10) if args.smoke else (1, 100, 10000)
    for n in sizes:
        _batch_rows(robot, legacy, n, (poses, twists, twist_dots, wrenches, forces), number,
                    repeat)

    integ = ClosedLoopIntegrator(clm, residual=robot.closed_form.closure_residual)
    generic = ClosedLoopIntegrator(clm)
    q0, v0 = robot.home_configuration.copy(), np.zeros(clm.nv)
    state = {"q": q0, "v": v0}

    def one_step(_, integ=integ):
        state["q"], state["v"], _res = integ.step(state["q"], state["v"], np.zeros(clm.nv), 1e-3)

    step = _row("simulation step, RK4 (1 ms), closed-form closure check", _time(one_step, number, repeat),
                recorded=rec["rk4 step"], note="unactuated fall")
    state.update(q=q0, v=v0)
    _row("simulation step, RK4 (1 ms), generic closure check",
         _time(lambda k: one_step(k, generic), number, repeat), note="Pinocchio frames")
    duration = 0.05 if args.smoke else 1.0
    traj = simulate(robot, duration, 1e-3, check_limits=False)
    _row("simulate(), per 1 ms step (unactuated)", [traj.wall_time / (len(traj.times) - 1) * 1e6],
         note=f"real-time factor {traj.real_time_factor:.2f} at 1 kHz")
    ref = CircleTrajectory(robot.home_pose, 0.02, 1.0)
    traj = simulate(robot, duration, 1e-3, controller=ComputedTorqueController(robot, ref))
    _row("simulate(), computed torque, per step", [traj.wall_time / (len(traj.times) - 1) * 1e6],
         note=f"real-time factor {traj.real_time_factor:.2f} at 1 kHz")
    print()
    print(f"inverse_dynamics kkt: {kkt:.0f} µs = {kkt / (t_rnea + t_solve):.1f}x the raw "
          f"Pinocchio calls it needs (rnea + a 6x6 solve, {t_rnea + t_solve:.0f} µs).")
    if t_generic is not None:
        print(f"inverse_dynamics kkt: {kkt / t_generic:.1f}x the Pinocchio calls of a generic "
              f"closed-loop ID from a platform state ({t_generic:.0f} µs).")
    print(f"RK4 step: {step:.0f} µs, i.e. {1e3 / step:.1f}x real time at 1 kHz "
          f"(target in issue 5: 1000x).")
    if not ok:
        print("ROUTES DISAGREE", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
