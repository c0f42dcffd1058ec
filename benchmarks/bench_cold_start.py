"""Cold-cache time of the first calls: how long a new user waits for numba.

Each case runs in a fresh Python process whose ``NUMBA_CACHE_DIR`` is an empty temporary
folder (nothing compiled yet, as right after an install), and times the import, the first
call (compilation included) and a second call (the compiled code). Then the same case again
on that now-filled cache: the first call of a later session (kernels loaded from disk).

    python benchmarks/bench_cold_start.py            # every case cold (minutes each)
    python benchmarks/bench_cold_start.py --smoke    # the cases on the current cache

Prints a Markdown table; ``--smoke`` exits 1 when a case fails.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: case -> Python code run twice after the import (``robot`` is the default hexapod)
CASES = {
    "inverse_dynamics": "robot.inverse_dynamics(robot.home_pose, np.zeros(6), np.zeros(6))",
    "simulate_fast": "simulate_fast(robot, 0.01, 1e-3)",
    'simulate(backend="compiled")': 'hp.simulate(robot, 0.01, 1e-3, backend="compiled")',
    "time_optimal": ("time_optimal(robot, robot.home_pose + np.array([[0.0] * 6, "
                     "[0.01, 0, 0.005, 0, 0, 0.02]]), limits=Limits(actuator_force=60.0), "
                     "grid_points=20)"),
    "hp.warmup()": "hp.warmup()",
}

_RUNNER = """
import json, time
t0 = time.perf_counter()
import numpy as np
import hexapod_pin as hp
from hexapod_pin.hexapod.fast import simulate_fast
from hexapod_pin.planning import Limits, time_optimal
robot = hp.Hexapod.default()
t1 = time.perf_counter()
{code}
t2 = time.perf_counter()
{code}
t3 = time.perf_counter()
print(json.dumps({{"import": t1 - t0, "first": t2 - t1, "second": t3 - t2}}))
"""


def run_case(code: str, cache_dir: str | None) -> dict:
    """Times of one case in a fresh process (``cache_dir``: its NUMBA_CACHE_DIR; None:
    the environment's)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    if cache_dir is not None:
        env["NUMBA_CACHE_DIR"] = cache_dir
    start = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", _RUNNER.format(code=code)], env=env,
                          capture_output=True, text=True, cwd=ROOT)
    if proc.returncode != 0:
        raise RuntimeError(proc.stderr[-2000:])
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    out["process"] = time.perf_counter() - start
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--smoke", action="store_true", help="the current cache, no cold runs")
    parser.add_argument("--cases", default=",".join(CASES),
                        help="comma-separated cases (default: all)")
    args = parser.parse_args()
    names = [n for n in CASES if n in args.cases.split(",")] if not args.smoke else list(CASES)
    print("| first call | import (s) | first call, cold cache (s) | second call (s) | "
          "first call, next session (s) |")
    print("|---|---|---|---|---|")
    for name in names:
        if args.smoke:
            warm = run_case(CASES[name], None)
            print(f"| {name} | {warm['import']:.2f} | (smoke: not cold) | "
                  f"{warm['second']:.4f} | {warm['first']:.2f} |", flush=True)
            continue
        with tempfile.TemporaryDirectory(prefix="numba_cold_") as cache:
            cold = run_case(CASES[name], cache)
            warm = run_case(CASES[name], cache)
        print(f"| {name} | {cold['import']:.2f} | {cold['first']:.1f} | "
              f"{cold['second']:.4f} | {warm['first']:.2f} |", flush=True)
    print("all cases ran")
    return 0


if __name__ == "__main__":
    sys.exit(main())
