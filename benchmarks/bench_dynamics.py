"""Timings of the closed-loop dynamics of the hexapod (µs per call from Python).

Usage::

    python benchmarks/bench_dynamics.py            # full table
    python benchmarks/bench_dynamics.py --smoke    # tiny counts; checks that routes agree

Each row: median and interquartile range of the per-call time over ``--repeat`` blocks
of ``--number`` calls. Pose-level calls cycle through distinct random poses so that no
per-pose cache hides the cost of building the tree configuration. The simulation rows
time whole steps of 1 ms (RK4: four constrained forward dynamics, projection when the
closure residual exceeds 1e-10 m) and give the real-time factor at 1 kHz. BLAS threads
are limited to one (``OPENBLAS_NUM_THREADS=1`` unless set): the matrices are tiny.
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
from hexapod_pin.dynamics import dynamics_of, forward_dynamics_tree, inverse_dynamics_tree
from hexapod_pin.simulate import (
    CircleTrajectory,
    ClosedLoopIntegrator,
    ComputedTorqueController,
    simulate,
)


def _poses(robot, rng, n):
    out = []
    while len(out) < n:
        pose = robot.home_pose + np.concatenate([rng.uniform(-0.02, 0.02, 3),
                                                 rng.uniform(-0.08, 0.08, 3)])
        try:
            robot.inverse_kinematics(pose)
        except hp.HexapodPinError:
            continue
        out.append(pose)
    return np.array(out)


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


def _row(name, times, note=""):
    med = statistics.median(times)
    q = np.percentile(times, [25, 75])
    print(f"| {name:<46} | {med:9.1f} | {q[0]:7.1f} - {q[1]:<7.1f} | {note} |")
    return med


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
    rng = np.random.default_rng(0)
    n_states = 8 if args.smoke else 64
    poses = _poses(robot, rng, n_states)
    twists = np.concatenate([0.05 * rng.normal(size=(n_states, 3)),
                             0.3 * rng.normal(size=(n_states, 3))], axis=1)
    twist_dots = np.concatenate([0.5 * rng.normal(size=(n_states, 3)),
                                 2.0 * rng.normal(size=(n_states, 3))], axis=1)
    wrenches = np.concatenate([2.0 * rng.normal(size=(n_states, 3)),
                               0.2 * rng.normal(size=(n_states, 3))], axis=1)
    # keep states well inside the actuator bounds (far from singular poses)
    keep = [k for k in range(len(poses))
            if np.abs(robot.inverse_dynamics_batch(poses[k:k + 1], twists[k:k + 1],
                                                   twist_dots[k:k + 1], wrenches[k:k + 1],
                                                   bounded=False).actuator_forces).max() < 50.0]
    poses, twists, twist_dots, wrenches = (x[keep] for x in (poses, twists, twist_dots, wrenches))
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
    for k in range(min(n_states, 4)):
        q, v, a, tau = tree[k]
        fds = {m: forward_dynamics_tree(clm, q, v, tau, m) for m in ("pinocchio", "qp", "kkt")}
        worst["FD routes, a"] = max(worst.get("FD routes, a", 0.0),
                                    max(np.abs(fds[m].a - fds["kkt"].a).max() for m in fds))
        worst["FD(ID(x)) - x, a"] = max(worst.get("FD(ID(x)) - x, a", 0.0),
                                        np.abs(fds["pinocchio"].a - a).max())
        ids = {m: inverse_dynamics_tree(clm, q, v, a, method=m) for m in ("qp", "kkt")}
        worst["ID routes, tau"] = max(worst.get("ID routes, tau", 0.0),
                                      np.abs(ids["qp"].actuator_forces
                                             - ids["kkt"].actuator_forces).max())
    batch = robot.inverse_dynamics_batch(poses, twists, twist_dots, wrenches, bounded=False)
    single = np.array([robot.inverse_dynamics(poses[k], twists[k], twist_dots[k], wrenches[k],
                                              method="kkt", bounded=False,
                                              joint_wrenches=False).actuator_forces
                       for k in range(n_states)])
    worst["batch - single, tau"] = np.abs(batch.actuator_forces - single).max()
    ok = all(value < 1e-9 for value in worst.values())

    print(f"# hexapod_pin dynamics benchmark ({'smoke' if args.smoke else 'full'})")
    print(f"python {platform.python_version()}, pinocchio {pin.__version__}, proxsuite "
          f"{proxsuite.__version__}, numpy {np.__version__}, {platform.machine()} "
          f"{platform.processor() or platform.platform()}")
    print()
    print("| agreement check | max abs difference |")
    print("|---|---|")
    for name, value in worst.items():
        print(f"| {name} | {value:.2e} |")
    print()
    print("| call | median µs | IQR µs | note |")
    print("|---|---|---|---|")

    def cyc(k):
        return k % n_states

    small = np.ones(24)
    _row("calibration: numpy a + a, a of size 24", _time(lambda k: small + small, number, repeat),
         "machine speed reference")
    prox = pin.ProximalSettings(1e-13, 0.0, 1)
    data = clm.model.createData()
    cms = dyn._cms
    cds = dyn._cds
    pin.initConstraintDynamics(clm.model, data, cms, cds)
    _row("pin.rnea (floor)", _time(lambda k: pin.rnea(clm.model, data, *tree[cyc(k)][:3]),
                                   number, repeat))
    _row("pin.constraintDynamics (floor)",
         _time(lambda k: pin.constraintDynamics(clm.model, data, tree[cyc(k)][0],
                                                tree[cyc(k)][1], tree[cyc(k)][3], cms, cds,
                                                prox), number, repeat))
    for method in ("pinocchio", "qp", "kkt"):
        _row(f"forward_dynamics_tree {method}",
             _time(lambda k, m=method: forward_dynamics_tree(clm, tree[cyc(k)][0],
                                                             tree[cyc(k)][1], tree[cyc(k)][3], m),
                   number, repeat),
             "q, v given")
    for method in ("qp", "kkt"):
        _row(f"inverse_dynamics_tree {method}",
             _time(lambda k, m=method: inverse_dynamics_tree(clm, *tree[cyc(k)][:3], method=m,
                                                             bounds=100.0), number, repeat),
             "q, v, a given; bounds 100 N")
    _row("Hexapod.configuration(pose) (kinematics)",
         _time(lambda k: robot.configuration(poses[cyc(k)]), number, repeat),
         "part of every pose-level call")
    for method in ("qp", "kkt"):
        _row(f"inverse_dynamics {method}, no joint wrenches",
             _time(lambda k, m=method: robot.inverse_dynamics(
                 poses[cyc(k)], twists[cyc(k)], twist_dots[cyc(k)], wrenches[cyc(k)], method=m,
                 joint_wrenches=False),
                   number, repeat), "new pose each call")
    _row("inverse_dynamics qp, with joint wrenches",
         _time(lambda k: robot.inverse_dynamics(poses[cyc(k)], twists[cyc(k)], twist_dots[cyc(k)],
                                                wrenches[cyc(k)]), number, repeat),
         "new pose each call")
    _row("inverse_dynamics kkt, same pose",
         _time(lambda k: robot.inverse_dynamics(poses[0], twists[cyc(k)], twist_dots[cyc(k)],
                                                method="kkt", joint_wrenches=False),
               number, repeat), "configuration cached")
    for method in ("pinocchio", "qp", "kkt"):
        _row(f"forward_dynamics {method}",
             _time(lambda k, m=method: robot.forward_dynamics(
                 poses[cyc(k)], twists[cyc(k)], tree[cyc(k)][3][clm.actuated_v],
                 wrenches[cyc(k)], method=m),
                   number, repeat), "new pose each call")
    _row("static_forces", _time(lambda k: robot.static_forces(poses[cyc(k)]), number, repeat),
         "new pose each call")
    _row("reduced_dynamics",
         _time(lambda k: robot.reduced_dynamics(poses[cyc(k)], twists[cyc(k)]), number, repeat),
         "new pose each call")
    n_batch = 16 if args.smoke else 256
    big = np.arange(n_batch) % n_states
    per_state = [t / n_batch for t in _time(
        lambda k: robot.inverse_dynamics_batch(poses[big], twists[big], twist_dots[big],
                                               wrenches[big], bounded=False),
        1, max(3, repeat // 3))]
    _row(f"inverse_dynamics_batch, per state (N={n_batch})", per_state, "kkt, stacked solve")
    integ = ClosedLoopIntegrator(clm)
    q0, v0 = robot.home_configuration.copy(), np.zeros(clm.nv)
    state = {"q": q0, "v": v0}

    def one_step(_):
        state["q"], state["v"], _res = integ.step(state["q"], state["v"], np.zeros(clm.nv), 1e-3)

    step = _row("simulation step, RK4 + projection (1 ms)", _time(one_step, number, repeat),
                "unactuated fall")
    duration = 0.05 if args.smoke else 1.0
    traj = simulate(robot, duration, 1e-3, check_limits=False)
    _row("simulate(), per 1 ms step (unactuated)", [traj.wall_time / (len(traj.times) - 1) * 1e6],
         f"real-time factor {traj.real_time_factor:.2f} at 1 kHz")
    ref = CircleTrajectory(robot.home_pose, 0.02, 1.0)
    traj = simulate(robot, duration, 1e-3, controller=ComputedTorqueController(robot, ref))
    _row("simulate(), computed torque, per step", [traj.wall_time / (len(traj.times) - 1) * 1e6],
         f"real-time factor {traj.real_time_factor:.2f} at 1 kHz")
    print()
    print(f"RK4 step: {step:.0f} µs, i.e. {1e3 / step:.1f}x real time at 1 kHz "
          f"(target in issue 5: 1000x).")
    if not ok:
        print("ROUTES DISAGREE", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
