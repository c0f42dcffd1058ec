"""Timings of the hexapod kinematics (µs per call from Python, one core).

Usage::

    python benchmarks/bench_kinematics.py            # full table (about a minute)
    python benchmarks/bench_kinematics.py --smoke    # tiny counts; checks that routes agree

Each row: median and interquartile range of the wall time per call over ``--repeat``
blocks, each block long enough (>= 20 ms, or one call) to make the clock resolution
irrelevant, and the median CPU time of the process per call (robust on a shared machine).
Single-pose calls cycle through distinct random poses near home. "FK, good guess" starts
Newton from the pose perturbed by 1 mm / 1 mrad per coordinate (a previous sample of a
smooth motion); "FK, home guess" from the home pose. Batch rows give poses per second
for ``jacobian_batch`` (IK + J in one pass) and ``inverse_kinematics_batch``.
BLAS threads are limited to one (the batch kernels are element-wise numpy anyway).

The smoke mode runs every route once on a few poses and checks that they agree
(batch vs single pose, FK(IK(p)) = p, p among the assembly modes of IK(p), the closed
form J against the ProxSuite generic route); exit status 1 on any disagreement.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse
import platform
import sys
import time

import numpy as np
import pinocchio as pin
import proxsuite

import hexapod_pin as hp


def cpu_model() -> str:
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def poses_near_home(robot, rng, n, scale=1.0):
    """Random poses near home that pass IK with stroke checks (rejection sampling)."""
    out = []
    while len(out) < n:
        pose = robot.home_pose + scale * np.concatenate([rng.uniform(-0.02, 0.02, 3),
                                                         rng.uniform(-0.08, 0.08, 3)])
        try:
            robot.inverse_kinematics(pose)
        except hp.HexapodPinError:
            continue
        out.append(pose)
    return np.array(out)


def time_calls(fn, repeat, min_block=0.02):
    """Seconds per call of ``fn(k)`` (k = call index) over ``repeat`` blocks.

    Returns (median wall time, IQR of the wall time, median CPU time of this
    process). On a shared machine the CPU time (``time.process_time``) is the
    better figure: it leaves out the time the process waited for a core.
    """
    fn(0)
    t0 = time.perf_counter()
    fn(1)
    one = max(time.perf_counter() - t0, 1e-9)
    number = max(1, int(min_block / one))
    walls, cpus = [], []
    k = 0
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        for _ in range(number):
            fn(k)
            k += 1
        walls.append((time.perf_counter() - t0) / number)
        cpus.append((time.process_time() - c0) / number)
    walls = np.array(walls)
    return (float(np.median(walls)), float(np.percentile(walls, 75) - np.percentile(walls, 25)),
            float(np.median(cpus)))


def smoke_checks(robot, rng) -> list[str]:
    """Agreement of the routes on a few poses; returns the failures."""
    failures = []
    poses = poses_near_home(robot, rng, 8)
    batch = robot.jacobian_batch(poses)
    ik = robot.inverse_kinematics_batch(poses)
    for n, pose in enumerate(poses):
        q = robot.inverse_kinematics(pose)
        if not (batch.ok[n] and ik.ok[n]):
            failures.append(f"batch masks reject the reachable pose {n}")
        if (np.max(np.abs(batch.actuator_positions[n] - q)) > 1e-14
                or np.max(np.abs(ik.actuator_positions[n] - q)) > 1e-14):
            failures.append(f"batch IK differs from IK at pose {n}")
        jac = robot.jacobian(pose)
        if np.max(np.abs(batch.jacobian[n] - jac)) > 1e-11 * np.max(np.abs(jac)):
            failures.append(f"batch J differs from J at pose {n}")
        if np.max(np.abs(robot.forward_kinematics(q, pose + 1e-3) - pose)) > 1e-11:
            failures.append(f"FK(IK(p)) != p at pose {n}")
    q = robot.inverse_kinematics(poses[0])
    if min(np.max(np.abs(m - poses[0])) for m in robot.assembly_modes(q)) > 1e-11:
        failures.append("the pose is not among the assembly modes of its IK")
    tree_q = robot.configuration(poses[0])
    generic = robot.model.frame_jacobian_from_actuated(tree_q, "platform")
    if np.max(np.abs(robot.jacobian(poses[0]) @ generic - np.eye(6))) > 1e-10:
        failures.append("closed-form J disagrees with the ProxSuite generic route")
    return failures


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--smoke", action="store_true", help="tiny counts, check agreement")
    parser.add_argument("--repeat", type=int, default=15, help="timing blocks per row")
    args = parser.parse_args(argv)
    smoke = args.smoke
    repeat = 2 if smoke else args.repeat
    min_block = 0.0 if smoke else 0.02
    rng = np.random.default_rng(0)
    robot = hp.Hexapod.default()

    failures = smoke_checks(robot, rng)

    poses = poses_near_home(robot, rng, 4 if smoke else 200)
    qs = np.array([robot.inverse_kinematics(p) for p in poses])
    guesses = poses + 1e-3 * rng.choice([-1.0, 1.0], size=poses.shape)
    twists = rng.normal(scale=0.2, size=poses.shape)
    twist_dots = rng.normal(size=poses.shape)
    trees = [robot.configuration(p) for p in poses[:4]]
    n = len(poses)

    rows = []

    def single(name, fn):
        median, iqr, cpu = time_calls(fn, repeat, min_block)
        rows.append((name, "1", median * 1e6, iqr * 1e6, cpu * 1e6, 1.0 / cpu))

    single("inverse_kinematics", lambda k: robot.inverse_kinematics(poses[k % n]))
    single("jacobian", lambda k: robot.jacobian(poses[k % n]))
    single("IK + jacobian", lambda k: (robot.inverse_kinematics(poses[k % n]),
                                       robot.jacobian(poses[k % n])))
    single("forward_kinematics, good guess",
           lambda k: robot.forward_kinematics(qs[k % n], guesses[k % n]))
    single("forward_kinematics, home guess", lambda k: robot.forward_kinematics(qs[k % n]))
    single("assembly_modes", lambda k: robot.assembly_modes(qs[k % n]))
    single("twist_from_qdot", lambda k: robot.twist_from_qdot(poses[k % n], twists[k % n]))
    single("jacobian_derivative", lambda k: robot.jacobian_derivative(poses[k % n],
                                                                      twists[k % n]))
    single("qddot", lambda k: robot.qddot(poses[k % n], twists[k % n], twist_dots[k % n]))
    single("leg_motion (with accelerations)",
           lambda k: robot.leg_motion(poses[k % n], twists[k % n], twist_dots[k % n]))
    single("singularity", lambda k: robot.singularity(poses[k % n]))
    single("generic route: frame_jacobian_from_actuated (ProxSuite)",
           lambda k: robot.model.frame_jacobian_from_actuated(trees[k % len(trees)],
                                                              "platform"))

    sizes = (10, 100) if smoke else (100, 10_000, 1_000_000)
    for size in sizes:
        batch = poses_near_home(robot, rng, min(size, 1000), scale=1.5)
        batch = batch[rng.integers(0, len(batch), size)] + rng.normal(scale=1e-4, size=(size, 6))
        for name, fn in (("jacobian_batch (IK + J)", robot.jacobian_batch),
                         ("inverse_kinematics_batch", robot.inverse_kinematics_batch)):
            median, iqr, cpu = time_calls(lambda k, b=batch, f=fn: f(b),
                                          repeat if size < 1_000_000 else max(3, repeat // 3),
                                          min_block)
            rows.append((name, f"{size:,}", median * 1e6, iqr * 1e6, cpu * 1e6, size / cpu))

    print(f"# hexapod_pin kinematics benchmark{' (smoke)' if smoke else ''}")
    print(f"CPU: {cpu_model()} ({os.cpu_count()} logical cores visible, one used); "
          f"Python {platform.python_version()}, numpy {np.__version__}, "
          f"pinocchio {pin.__version__}, proxsuite {proxsuite.__version__}")
    print()
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"load average at the end: {load:.2f} (wall times inflate when it exceeds the "
          "number of cores; the CPU column does not)")
    print()
    print("| operation | N | median wall µs / call | IQR µs | median CPU µs / call "
          "| poses per CPU second |")
    print("|---|---:|---:|---:|---:|---:|")
    for name, size, median, iqr, cpu, rate in rows:
        print(f"| {name} | {size} | {median:,.1f} | {iqr:,.1f} | {cpu:,.1f} | {rate:,.0f} |")
    print()
    if failures:
        print("DISAGREEMENT:")
        for failure in failures:
            print(f"  - {failure}")
        return 1
    print("routes agree: batch = single pose, FK(IK(p)) = p, p in assembly_modes(IK(p)), "
          "closed-form J = inverse of the ProxSuite workspace Jacobian")
    return 0


if __name__ == "__main__":
    sys.exit(main())
