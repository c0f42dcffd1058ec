"""Benchmark of the time-optimal planner (hexapod_pin.planning): speed, optimality,
robustness, and the choice of solver (own compiled TOPP-RA against toppra's).

Tables (Markdown) on stdout:

1. time per path (median of repeats, ms) at 100 / 1,000 / 10,000 grid points, for the
   hexapod and the planar 3-PRR, split into stages (path sampling, ID coefficients, solver);
2. the duration against a constant-path-speed profile and against the best uniform
   time-scaling of a rest-to-rest quintic timing law of the same path (both exact: the
   slow-down factor of :func:`hexapod_pin.planning.feasibility.check_feasibility`);
3. random feasible paths around home: success rate and the worst limit overshoot when
   the planned motion is resampled 10x denser and re-evaluated with the robot's batch
   inverse dynamics (and, on the first paths, the single-state Pinocchio route); on the
   first paths, the open-loop re-simulation (forward dynamics driven by the planned
   forces) and its largest position error;
4. solver choice: the same constraint rows through toppra 0.6.10 (seidel solver wrapper,
   interpolation discretisation, a ``LinearConstraint`` carrying the precomputed rows),
   and the cost of the per-grid-point Python callbacks that toppra's
   ``SecondOrderConstraint`` would make (3 single-state ID calls per grid point).

``--smoke``: a few seconds, small sizes; exits 1 when a planned motion violates a limit
by more than 0.5 % or a path fails. Timings are printed, never asserted.
"""

from __future__ import annotations

import argparse
import itertools
import os
import sys
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np

import hexapod_pin as hp
from hexapod_pin.errors import HexapodPinError
from hexapod_pin.planning import (
    Limits,
    Payload,
    solver,
    time_optimal,
)
from hexapod_pin.planning import limits as planning_limits
from hexapod_pin.planning.feasibility import check_feasibility
from hexapod_pin.planning.path import GeometricPath

PLANAR_LIMITS = Limits(actuator_force=30.0)


def median_ms(func, repeats: int) -> float:
    func()
    samples = []
    for _ in range(repeats):
        start = time.perf_counter()
        func()
        samples.append(time.perf_counter() - start)
    return 1e3 * float(np.median(samples))


def hexapod_path(robot):
    h = robot.home_pose
    return np.array([h, h + [0.02, 0.0, 0.01, 0.03, 0.0, 0.05],
                     h + [0.0, 0.02, -0.01, 0.0, 0.04, -0.05]])


def planar_path():
    return np.array([[0.0, 0.0, 0.0], [0.03, 0.02, 0.2], [-0.02, 0.04, -0.1]])


def random_path(robot, rng, dim):
    count = rng.integers(2, 5)
    if dim == 6:
        span = np.array([0.01, 0.01, 0.008, 0.04, 0.04, 0.06])
    else:
        span = np.array([0.02, 0.02, 0.1])
    return robot.home_pose + rng.uniform(-1, 1, (count, dim)) * span


def table(title, header, rows):
    print(f"\n### {title}\n")
    print("| " + " | ".join(header) + " |")
    print("|" + "---|" * len(header))
    for row in rows:
        print("| " + " | ".join(str(v) for v in row) + " |")


def stage_times(robot, waypoints, limits, grid, repeats):
    path = GeometricPath(waypoints, robot.singularity(robot.home_pose).characteristic_length)
    samples = path.sample(np.linspace(0, path.length, grid))
    payload = Payload()
    coeffs = planning_limits.path_coefficients(robot, samples, limits, payload)
    rows = planning_limits.constraint_rows(coeffs, robot, limits)
    steps = np.diff(samples.s)
    lo, hi, x, u = np.empty(grid), np.empty(grid), np.empty(grid), np.empty(grid - 1)

    def solve():
        solver.backward_pass(rows, steps, coeffs.speed_bound, 0.0, lo, hi)
        solver.forward_pass(rows, steps, lo, hi, 0.0, x, u)

    return {
        "total": median_ms(lambda: time_optimal(robot, waypoints, limits=limits,
                                                grid_points=grid), repeats),
        "path": median_ms(lambda: path.sample(np.linspace(0, path.length, grid)), repeats),
        "coefficients": median_ms(lambda: planning_limits.path_coefficients(
            robot, samples, limits, payload), repeats),
        "solver": median_ms(solve, repeats),
    }, (rows, steps, coeffs, samples)


def bench_speed(robots, sizes, repeats):
    out, kept = [], {}
    for name, robot, waypoints, limits in robots:
        for grid in sizes:
            times, data = stage_times(robot, waypoints, limits, grid, repeats)
            kept[(name, grid)] = data
            out.append([name, grid] + [f"{times[k]:.2f}" for k in
                                       ("total", "path", "coefficients", "solver")])
    table("Time per path (ms, median)",
          ["robot", "grid points", "total", "path sampling", "ID coefficients",
           "TOPP-RA (both passes)"], out)
    return kept


def uniform_durations(robot, traj, limits, count=2000):
    """Durations of the constant-path-speed profile and of the best uniform scaling of the
    quintic timing law (exact slow-down factors of check_feasibility)."""
    length = traj.path.length
    s = np.linspace(0, length, count)
    samples = traj.path.sample(s)
    const = {"t": s, "poses": samples.poses, "twists": samples.tangents,
             "twist_dots": samples.curvatures}
    k_const = check_feasibility(robot, const, limits=limits).slow_down
    tau = np.linspace(0, 1, count)
    sigma = 10 * tau ** 3 - 15 * tau ** 4 + 6 * tau ** 5
    d1 = 30 * tau ** 2 - 60 * tau ** 3 + 30 * tau ** 4
    d2 = 60 * tau - 180 * tau ** 2 + 120 * tau ** 3
    samples = traj.path.sample(length * sigma)
    quintic = {"t": tau, "poses": samples.poses,
               "twists": samples.tangents * (length * d1)[:, None],
               "twist_dots": samples.tangents * (length * d2)[:, None]
               + samples.curvatures * ((length * d1) ** 2)[:, None]}
    k_quintic = check_feasibility(robot, quintic, limits=limits).slow_down
    return length * k_const, k_quintic


def bench_optimality(robots, grid):
    rows = []
    for name, robot, waypoints, limits in robots:
        traj = time_optimal(robot, waypoints, limits=limits, grid_points=grid)
        const, quintic = uniform_durations(robot, traj, limits)
        rows.append([name, f"{traj.duration * 1e3:.2f}", f"{const * 1e3:.2f}",
                     f"{quintic * 1e3:.2f}", f"{traj.duration / quintic:.3f}"])
    table(f"Duration (ms) at {grid} grid points",
          ["robot", "time-optimal", "constant path speed (not at rest at the ends)",
           "best uniform scaling of a quintic", "ratio"], rows)


def open_loop_error(robot, traj) -> float:
    """Max position error (m) of the platform origin when the forward dynamics is driven
    open loop by the planned forces (RK4, one step per grid segment, Euler-angle pose)."""
    from hexapod_pin.core.pose import euler_rates_matrix

    dim = robot.pose_dim
    lin = 3 if dim == 6 else 2
    grid = traj.phase_times()
    eps = 1e-12 * traj.duration
    stages = np.concatenate([[a + eps, (a + b) / 2, b - eps] for a, b in itertools.pairwise(grid)])
    forces = traj.sample(stages).actuator_forces.reshape(len(grid) - 1, 3, -1)

    def rates(state, force):
        pose, twist = state[:dim], state[dim:]
        twist_dot = robot.forward_dynamics(pose, twist, force).twist_dot
        ang = np.linalg.solve(euler_rates_matrix(pose[3:]), twist[3:]) if dim == 6 \
            else twist[2:]
        return np.concatenate([twist[:lin], ang, twist_dot])

    state = np.concatenate([traj.poses[0], traj.twists[0]])
    worst = 0.0
    for k in range(len(grid) - 1):
        dt = grid[k + 1] - grid[k]
        f0, fh, f1 = forces[k]
        k1 = rates(state, f0)
        k2 = rates(state + dt / 2 * k1, fh)
        k3 = rates(state + dt / 2 * k2, fh)
        k4 = rates(state + dt * k3, f1)
        state = state + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        worst = max(worst, float(np.linalg.norm(state[:lin] - traj.poses[k + 1, :lin])))
    return worst


def bench_random(robots, count, grid, single_checks):
    rows, bad = [], False
    for name, robot, _, limits in robots:
        rng = np.random.default_rng(1)
        bounds = limits.per_actuator(robot)
        ok, fails, worst, worst_single, start = 0, [], -np.inf, -np.inf, time.perf_counter()
        drift = 0.0
        for n in range(count):
            waypoints = random_path(robot, rng, robot.pose_dim)
            try:
                traj = time_optimal(robot, waypoints, limits=limits, grid_points=grid)
            except HexapodPinError as exc:
                fails.append(f"{n}: {type(exc).__name__}")
                continue
            ok += 1
            dense = traj.sample(np.linspace(0, traj.duration, 10 * grid))
            ratio = np.max(np.abs(dense.actuator_forces) / bounds["force"])
            worst = max(worst, ratio - 1)
            if n < single_checks:
                drift = max(drift, open_loop_error(robot, traj))
                for k in range(0, len(dense.t), 7):
                    tau = robot.inverse_dynamics(dense.poses[k], dense.twists[k],
                                                 dense.twist_dots[k],
                                                 bounded=False).actuator_forces
                    worst_single = max(worst_single,
                                       np.max(np.abs(tau) / bounds["force"]) - 1)
        elapsed = time.perf_counter() - start
        bad |= bool(fails) or worst > 0.005 or worst_single > 0.005 or drift > 1e-6
        rows.append([name, count, f"{100 * ok / count:.1f} %",
                     f"{100 * worst:+.4f} %",
                     f"{100 * worst_single:+.4f} % (first {single_checks})",
                     f"{drift:.1e} (first {single_checks})",
                     f"{elapsed:.1f}", "; ".join(fails[:3]) or "-"])
    table(f"Random paths around home ({grid} grid points; overshoot = max |tau| / bound - 1 "
          "over 10x denser samples)",
          ["robot", "paths", "success", "worst overshoot (batch ID)",
           "worst overshoot (single-state Pinocchio ID)",
           "open-loop re-simulation: max position error (m)", "wall time (s)", "failures"],
          rows)
    return bad


class _Rows:
    """A toppra LinearConstraint carrying precomputed rows ``alpha u + beta x + gamma <= 0``
    (interpolation discretisation) and the velocity bound."""

    def __new__(cls, rows, speed_bound):
        import toppra.constraint as tc

        class RowsConstraint(tc.LinearConstraint):
            def __init__(self):
                super().__init__()
                self.discretization_type = tc.DiscretizationType.Interpolation
                self.identical = True
                self._params = (rows, speed_bound)

            def compute_constraint_params(self, path, gridpoints, *args, **kwargs):
                r, xmax = self._params
                m = r.shape[1]
                xbound = np.stack([np.zeros(len(xmax)), np.minimum(xmax, 1e8)], axis=1)
                a, b, c = r[:, :, 0], r[:, :, 1], r[:, :, 2]
                a, b, c, f, g, _, _ = tc.canlinear_colloc_to_interpolate(
                    a, b, c, np.eye(m), np.zeros(m), None, None, gridpoints, identical=True)
                return a, b, c, f, g, None, xbound

        return RowsConstraint()


def toppra_row(toppra, name, grid, data, repeats):
    """One row of the solver table: own solver and toppra on the same rows."""
    rows, steps, coeffs, samples = data
    path = toppra.SplineInterpolator(samples.s, samples.poses)
    constraint = _Rows(rows, coeffs.speed_bound)

    def run_toppra():
        algo = toppra.algorithm.TOPPRA([constraint], path, gridpoints=samples.s,
                                       solver_wrapper="seidel")
        return algo.compute_parameterization(0, 0)

    t_toppra = median_ms(run_toppra, repeats)
    _, sd, _ = run_toppra()
    lo, hi, x, u = np.empty(grid), np.empty(grid), np.empty(grid), np.empty(grid - 1)

    def run_own():
        solver.backward_pass(rows, steps, coeffs.speed_bound, 0.0, lo, hi)
        solver.forward_pass(rows, steps, lo, hi, 0.0, x, u)

    t_own = median_ms(run_own, repeats)

    def duration(speed):
        return float(np.sum(2 * steps / np.maximum(speed[:-1] + speed[1:], 1e-300)))

    single = robot_single(name)
    t_callbacks = median_ms(lambda: [single(samples, k) for k in range(grid) for _ in range(3)],
                            1)
    return [name, grid, f"{t_own:.2f}", f"{t_toppra:.2f}", f"{duration(np.sqrt(x)) * 1e3:.3f}",
            "failed" if sd is None else f"{duration(sd) * 1e3:.3f}", f"{t_callbacks:.1f}"]


def bench_toppra(kept, sizes, repeats):
    try:
        import toppra
    except ImportError:
        print("\n(toppra not installed: solver comparison skipped)")
        return
    import logging
    logging.getLogger("toppra").setLevel(logging.ERROR)
    rows_out = [toppra_row(toppra, name, grid, data, repeats)
                for (name, grid), data in kept.items() if grid in sizes]
    table("Solver: own compiled TOPP-RA against toppra 0.6.10 on the same rows",
          ["robot", "grid points", "own (ms)", "toppra seidel (ms)", "own duration (ms)",
           "toppra duration (ms)", "toppra SecondOrderConstraint callbacks alone (ms)"],
          rows_out)


_SINGLE = {}


def robot_single(name):
    robot = _SINGLE[name]

    def call(samples, k):
        return robot.inverse_dynamics(samples.poses[k], samples.tangents[k],
                                      samples.curvatures[k], bounded=False)

    return call


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--smoke", action="store_true", help="seconds, tiny sizes")
    parser.add_argument("--paths", type=int, default=1000, help="random paths per robot")
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args(argv)
    hexapod, planar = hp.Hexapod.default(), hp.Planar3PRR.default()
    _SINGLE.update(hexapod=hexapod, planar=planar)
    robots = [("hexapod", hexapod, hexapod_path(hexapod), Limits()),
              ("planar", planar, planar_path(), PLANAR_LIMITS)]
    sizes = (100, 300) if args.smoke else (100, 1000, 10000)
    repeats = 2 if args.smoke else args.repeats
    print(f"# planning benchmark ({'smoke' if args.smoke else 'full'}), "
          f"{os.cpu_count()} CPUs, numpy {np.__version__}")
    kept = bench_speed(robots, sizes, repeats)
    bench_optimality(robots, 300 if args.smoke else 1000)
    bad = bench_random(robots, 4 if args.smoke else args.paths, 200 if args.smoke else 1000,
                       2 if args.smoke else 20)
    bench_toppra(kept, sizes[:1] if args.smoke else (100, 1000), repeats)
    print("\nOK" if not bad else "\nFAILED: a path failed or overshot its limits by > 0.5 %")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
