"""Workspace analysis at scale: reachability + Jacobian + condition number of many poses.

Prints a table of wall time per batch and poses per second (median and spread of a few
repeats, one and two threads), then checks the batch results against per-pose routes.

    python benchmarks/bench_workspace.py            # N up to 1e6
    python benchmarks/bench_workspace.py --smoke    # tiny N, agreement checks only (tests run this)
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time

import numpy as np

import hexapod_pin as hp
from hexapod_pin.hexapod import workspace as ws


def sample(robot, n: int, seed: int = 0) -> np.ndarray:
    half = np.array([0.1, 0.1, 0.1, 0.2, 0.2, 0.2])
    return ws.sample_poses(np.random.default_rng(seed), n, robot.home_pose - half,
                           robot.home_pose + half)


def time_call(fn, repeats: int) -> tuple[float, float, float]:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times)), float(np.min(times)), float(np.max(times))


def check(robot, n: int) -> float:
    """Max relative difference of batch condition numbers vs per-pose np.linalg.cond(J);
    raises when a reachability mask disagrees with per-pose inverse kinematics."""
    poses = sample(robot, n, seed=1)
    m = ws.evaluate(robot, poses, singularity=False, statics=False)
    worst = 0.0
    for i, pose in enumerate(poses):
        try:
            robot.inverse_kinematics(pose)
            ik_ok = True
        except (hp.UnreachablePoseError, hp.StrokeLimitError):
            ik_ok = False
        if ik_ok != bool(m.reachable[i] and m.within_stroke[i]):
            raise SystemExit(f"reachability mismatch at pose {i}: {pose}")
        if m.ok[i]:
            ref = np.linalg.cond(robot.jacobian(pose))
            worst = max(worst, abs(m.condition_number[i] - ref) / ref)
    return worst


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--smoke", action="store_true", help="tiny sizes, checks only")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args(argv)
    robot = hp.Hexapod.default()
    sizes = [1_000, 10_000] if args.smoke else [10_000, 100_000, 1_000_000]
    cpu = next((line.split(":", 1)[1].strip() for line in open("/proc/cpuinfo")
                if line.startswith("model name")), platform.processor()) \
        if os.path.exists("/proc/cpuinfo") else platform.processor()
    print(f"machine: {cpu}, {os.cpu_count()} cores; load {os.getloadavg()[0]:.2f}; "
          f"numpy {np.__version__}, python {platform.python_version()}")
    print(f"{'N':>9} {'threads':>7} {'median s':>9} {'min s':>8} {'max s':>8} {'poses/s':>11} "
          f"{'ok share':>8}")
    for n in sizes:
        poses = sample(robot, n)
        for threads in (1, 2):
            result = {}

            def run():
                result["m"] = ws.evaluate(robot, poses, threads=threads, singularity=False,
                                          statics=False)
            med, lo, hi = time_call(run, 1 if args.smoke else args.repeats)
            print(f"{n:>9} {threads:>7} {med:>9.3f} {lo:>8.3f} {hi:>8.3f} {n / med:>11.3g} "
                  f"{result['m'].ok.mean():>8.3f}")
    worst = check(robot, 300 if args.smoke else 2000)
    print(f"max relative difference of cond(J), batch vs per pose: {worst:.2e}")
    if worst > 1e-8:
        print("FAIL: batch and per-pose condition numbers disagree", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
