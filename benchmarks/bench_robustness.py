"""Solver robustness on example-parallel-robots folders (issue 31 item 6).

For each folder given (``robot.urdf`` + ``robot.yaml``; default: the delta and the 6-D
five-bar of tests/data/parallel) and ``--states`` seeded closure-consistent states (a
configuration assembled with every coordinate free from the first assembled one displaced
by up to 0.05 rad, a random velocity in ``ker J_c``, actuator forces ``N(0, 1)`` times
``--load``, plus gravity):

* forward dynamics, routes "pinocchio" (the default), "qp", "kkt": failures (SolverError),
  the largest iteration count, us per call (on the first state); the raw
  ``pin.constraintDynamics`` call with the route's constraint models (mu = 1e-8, one
  iteration) for scale;
* assembly (``ClosedLoopModel.assemble``, actuated coordinates held) from the neutral
  configuration displaced by up to 0.05 and 0.1 rad (seeded): successes, the largest
  iteration count, ms per assembly.

Run ``python benchmarks/bench_robustness.py [FOLDER ...] [--load 1e6]`` (``--smoke``: two
states; a test runs it). Prints Markdown tables; exits 1 when an assembly or a forward
route failed on a state (the states are well posed).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import pinocchio as pin

from hexapod_pin.core.dynamics import forward_dynamics_tree
from hexapod_pin.errors import AssemblyError, SolverError
from hexapod_pin.loaders.parallel_robots import load_parallel_robot

ROOT = Path(__file__).resolve().parents[1]
DEFAULT = [ROOT / "tests" / "data" / "parallel" / "delta",
           ROOT / "tests" / "data" / "parallel" / "five_bar_6d"]


def states(clm, n: int, load: float, seed: int = 0):
    """``n`` seeded closure-consistent states ``(q, v, u)``."""
    rng = np.random.default_rng(seed)
    home = clm.assemble(clm.neutral(), fixed=[]).q
    out = []
    while len(out) < n:
        try:
            q = clm.assemble(pin.integrate(clm.model, home, 0.05 * rng.uniform(-1, 1, clm.nv)),
                             fixed=[]).q
        except AssemblyError:
            continue
        _, sv, vt = np.linalg.svd(clm.constraint_jacobian(q))
        basis = vt[int(np.sum(sv > 1e-10 * sv[0])):].T
        out.append((q, basis @ rng.normal(size=basis.shape[1]),
                    load * rng.normal(size=clm.n_actuated)))
    return out


def per_call_us(fn, seconds: float = 0.2) -> float:
    fn()
    n, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        fn()
        n += 1
    return (time.perf_counter() - t0) / n * 1e6


def forward_rows(name, clm, sts, seconds):
    rows, failed = [], False
    q0, v0, u0 = sts[0]
    for method in ("pinocchio", "qp", "kkt"):
        fails, iters, statuses = 0, 0, set()
        for q, v, u in sts:
            try:
                res = forward_dynamics_tree(clm, q, v, u, method=method)
            except SolverError:
                fails += 1
                continue
            iters = max(iters, res.iterations)
            statuses.add(res.status.split(";")[0][:70])
        failed |= fails > 0
        us = per_call_us(lambda m=method: forward_dynamics_tree(clm, q0, v0, u0, method=m),
                         seconds) if not fails else float("nan")
        rows.append(f"| {name} | FD {method} | {fails}/{len(sts)} | {iters} | {us:.1f} | "
                    f"{' / '.join(sorted(statuses))} |")
    cms, cds = clm.pinocchio_constraints()
    data = clm.model.createData()
    pin.initConstraintDynamics(clm.model, data, cms, cds)
    prox = pin.ProximalSettings(1e-12, 1e-8, 1)
    tau = np.zeros(clm.nv)
    tau[clm.actuated_v] = u0
    us = per_call_us(lambda: pin.constraintDynamics(clm.model, data, q0, v0, tau, cms, cds,
                                                    prox), seconds)
    rows.append(f"| {name} | raw pin.constraintDynamics | - | 1 | {us:.1f} | |")
    return rows, failed


def assembly_rows(name, clm, n):
    rows, failed = [], False
    rng = np.random.default_rng(7)
    for spread in (0.05, 0.1):
        ok, iters, seconds = 0, 0, 0.0
        for _ in range(n):
            start = pin.integrate(clm.model, clm.neutral(), spread * rng.uniform(-1, 1, clm.nv))
            t0 = time.perf_counter()
            try:
                res = clm.assemble(start)
            except AssemblyError:
                continue
            finally:
                seconds += time.perf_counter() - t0
            ok += 1
            iters = max(iters, res.iterations)
        failed |= ok < n
        off = float(np.max(np.abs(clm.residual(clm.neutral()))))
        rows.append(f"| {name} | {spread} | {off:.2f} | {ok}/{n} | {iters} | "
                    f"{seconds / n * 1e3:.1f} |")
    return rows, failed


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folders", nargs="*", type=Path)
    parser.add_argument("--states", type=int, default=10)
    parser.add_argument("--load", type=float, default=1.0)
    parser.add_argument("--smoke", action="store_true")
    args = parser.parse_args(argv)
    folders = args.folders or DEFAULT
    n = 2 if args.smoke else args.states
    seconds = 0.02 if args.smoke else 0.3
    fd = ["| robot | route | failures | max iterations | us per call | statuses |",
          "| --- | --- | --- | --- | --- | --- |"]
    asm = [("| robot | start spread (rad) | neutral residual (m) | assembled | max iterations "
            "| ms per assembly |"), "| --- | --- | --- | --- | --- | --- |"]
    failed = False
    for folder in folders:
        clm = load_parallel_robot(folder)
        name = folder.name
        rows, bad = forward_rows(name, clm, states(clm, n, args.load), seconds)
        fd += rows
        failed |= bad
        rows, bad = assembly_rows(name, clm, n)
        asm += rows
        failed |= bad
    print(f"## Forward dynamics (load {args.load:g})\n")
    print("\n".join(fd))
    print("\n## Assembly (actuated coordinates held)\n")
    print("\n".join(asm))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
