"""Dynamic identification (hexapod_pin.identification): time of one identification
against the number of samples, and its accuracy.

The truth is the nominal robot with every massive body's mass and inertia off by
10-30 %, its centre of mass moved by up to 1 cm, and drive friction and offsets on
(viscous 1-5, Coulomb 0.5-2, offsets +-1); its forces at random closure-consistent states
(:func:`hexapod_pin.identification.random_states`: accelerations of 2-10 m/s^2 at poses
up to the singularity thresholds, so peak forces reach kN) plus Gaussian noise of 1 % of
each actuator's force standard deviation. Timed: ``identify_from_states`` with the base parameters given
(found once, timed apart), without and with the physically consistent fit; and the
regressor alone (``ClosedLoopRegressor.batch``), the part that grows with the samples.

    python benchmarks/bench_identification.py               # 1e3 and 1e4 samples
    python benchmarks/bench_identification.py --large       # also 1e5
    python benchmarks/bench_identification.py --smoke       # small sizes, a quick check
    python benchmarks/bench_identification.py --routes      # the regressor's two routes

``--routes`` times the regressor alone by each route (``route="tree"``: Pinocchio's
joint-torque regressor projected through the closures; ``route="closed_form"``: the
robot's closed form, where it supplies one), per state: one state at a time
(``ClosedLoopRegressor.rows``) and in a batch (``ClosedLoopRegressor.batch``), medians of
alternated repeats, and checks that the routes agree (1e-10 of each column's scale).
"""

from __future__ import annotations

import argparse
import os
import platform
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")     # before numpy: see benchmarks/README.md
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np
import pinocchio as pin
import scipy

import hexapod_pin as hp
from hexapod_pin.identification import (
    ClosedLoopRegressor,
    base_parameters,
    identify_from_states,
    nominal_parameters,
    random_states,
)

DRIVE = ("viscous", "coulomb", "offset")
ROBOTS = {"hexapod": hp.Hexapod.default, "planar": hp.Planar3PRR.default}


def perturbed(robot, rng) -> np.ndarray:
    """The truth of the module docstring."""
    reg = ClosedLoopRegressor(robot, DRIVE)
    out = nominal_parameters(robot, DRIVE)
    for b in range(len(reg.layout.bodies)):
        nominal = pin.Inertia.FromDynamicParameters(out[10 * b:10 * b + 10]) \
            if out[10 * b] > 0 else None
        if nominal is None:
            continue
        sign = rng.choice([-1.0, 1.0], 2)
        out[10 * b:10 * b + 10] = pin.Inertia(
            nominal.mass * (1 + sign[0] * rng.uniform(0.1, 0.3)),
            nominal.lever + rng.uniform(-0.01, 0.01, 3),
            nominal.inertia * (1 + sign[1] * rng.uniform(0.1, 0.3))).toDynamicParameters()
    n = len(reg.layout.actuators)
    for kind, (lo, hi) in {"viscous": (1, 5), "coulomb": (0.5, 2), "offset": (-1, 1)}.items():
        out[reg.layout.drive_slice(kind)] = rng.uniform(lo, hi, n)
    return out


def run(name: str, sizes: list[int]) -> bool:
    robot = ROBOTS[name]()
    rng = np.random.default_rng(0)
    truth = perturbed(robot, rng)
    t0 = time.perf_counter()
    base = base_parameters(robot, DRIVE)
    t_base = time.perf_counter() - t0
    reg = ClosedLoopRegressor(robot, DRIVE)
    print(f"\n### {name}: {base.layout.size} parameters, {base.count} base parameters "
          f"(found in {t_base:.2f} s)\n")
    print("| samples | force rows | regressor (s) | identification, WLS (s) | with the "
          "consistent fit (s) | rms before / after (N) | max abs error (std errors) "
          "| consistent gap (std errors) |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|")
    ok = True
    for n in sizes:
        states = random_states(robot, n, seed=n)
        t0 = time.perf_counter()
        full = reg.batch(*states)
        t_reg = time.perf_counter() - t0
        clean = (full @ truth).reshape(n, -1)
        noise = 0.01 * np.std(clean, axis=0)
        measured = clean + rng.normal(size=clean.shape) * noise
        t0 = time.perf_counter()
        plain = identify_from_states(robot, *states, measured, base=base, consistent=False)
        t_wls = time.perf_counter() - t0
        t0 = time.perf_counter()
        res = identify_from_states(robot, *states, measured, base=base)
        t_all = time.perf_counter() - t0
        z = float(np.max(np.abs(plain.values - base.values(truth)) / plain.std_errors))
        print(f"| {n} | {n * robot.n_actuators} | {t_reg:.2f} | {t_wls:.2f} | {t_all:.2f} | "
              f"{res.before.rms:.3g} / {res.after.rms:.3g} | {z:.2f} | "
              f"{res.consistent_gap:.2f} |")
        ok = ok and z < 5.0 and res.after.rms < res.before.rms
    return ok


def routes(name: str, n_single: int = 200, n_batch: int = 2000, repeats: int = 5) -> bool:
    """The time per state of each regressor route (module docstring); True when the
    routes agree."""
    robot = ROBOTS[name]()
    regs = {route: ClosedLoopRegressor(robot, DRIVE, route=route)
            for route in ("tree", "closed_form") if route == "tree"
            or ClosedLoopRegressor(robot, DRIVE, route="auto").route == route}
    states = random_states(robot, n_batch, seed=1)
    single = [s[:n_single] for s in states]
    times: dict[tuple[str, str], list[float]] = {}
    for reg in regs.values():                       # compile and load before timing
        reg.batch(*(s[:2] for s in states))
    for _ in range(repeats):                        # the routes alternated
        for route, reg in regs.items():
            t0 = time.perf_counter()
            for k in range(n_single):
                reg.rows(single[0][k], single[1][k], single[2][k])
            times.setdefault((route, "single"), []).append(
                (time.perf_counter() - t0) / n_single)
            t0 = time.perf_counter()
            reg.batch(*states)
            times.setdefault((route, "batch"), []).append(
                (time.perf_counter() - t0) / n_batch)
    print(f"\n### {name}: regressor routes, us per state (median of {repeats})\n")
    print(f"| route | single (rows, {n_single} states) | batch ({n_batch} states) |")
    print("|---|---:|---:|")
    for route in regs:
        print(f"| {route} | {1e6 * np.median(times[route, 'single']):.1f} | "
              f"{1e6 * np.median(times[route, 'batch']):.1f} |")
    if len(regs) < 2:
        return True
    tree, closed = (regs[r].batch(*single) for r in ("tree", "closed_form"))
    scale = np.max(np.abs(tree), axis=0)
    agree = bool(np.all(np.abs(closed - tree) <= 1e-10 * scale))
    print(f"\nroutes agree to 1e-10 of each column's scale: {agree}")
    return agree


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--smoke", action="store_true", help="small sizes, a quick check")
    parser.add_argument("--large", action="store_true", help="also 1e5 samples")
    parser.add_argument("--robots", default="hexapod,planar")
    parser.add_argument("--routes", action="store_true",
                        help="only the regressor's routes, time per state")
    args = parser.parse_args()
    sizes = [100] if args.smoke else [1000, 10000] + ([100000] if args.large else [])
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, "
          f"Python {platform.python_version()}, numpy {np.__version__}, scipy "
          f"{scipy.__version__}, pinocchio {pin.__version__}, hexapod_pin {hp.__version__}")
    if args.routes:
        passed = [routes(name) for name in args.robots.split(",")]
    else:
        passed = [run(name, sizes) for name in args.robots.split(",")]   # every robot runs
    ok = all(passed)
    print("\nall checks passed" if ok else "\nCHECK FAILED")
    raise SystemExit(0 if ok else 1)


if __name__ == "__main__":
    main()
