"""Cold-cache time of the first calls: how long a new user waits for numba.

Each case runs in a fresh Python process whose ``NUMBA_CACHE_DIR`` is an empty temporary
folder (nothing compiled yet, as right after an install), once with
``HEXAPOD_PIN_COMPILE=eager`` (every kernel compiled on its first call: the behaviour
before tiered execution) and once with ``tiered`` (the default:
:mod:`hexapod_pin.core.tiers`), and times the first call (after the import and the robot's
construction) with the number of kernels it compiled, and a second call. Then the first
call of a later session, on the cache the eager run filled. The command-line case times
the whole process (``python -m hexapod_pin id motion.csv``).

``--per-call``: the steady cost of one call interpreted (an empty cache and an infinite
budget: nothing ever compiles) against compiled (a filled cache), median of repeated calls.

    python benchmarks/bench_cold_start.py              # every case cold (minutes)
    python benchmarks/bench_cold_start.py --per-call   # interpreted against compiled
    python benchmarks/bench_cold_start.py --smoke      # the cases on the current cache

Prints Markdown tables; ``--smoke`` exits 1 when a case fails.
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

#: robots a case may use (``robot``: built before the timed call)
ROBOTS = {
    "hexapod": "hp.Hexapod.default()",
    "planar": "hp.Planar3PRR.default()",
    "loaded": f"hp.load_robot({str(ROOT / 'tests/data/stewart/stewart.urdf')!r})",
}
Z = "np.zeros(robot.pose_dim)"
PLAN = ("time_optimal(robot, robot.home_pose + np.array([[0.0] * 6, [0.01, 0, 0.005, 0, 0, "
        "0.02]]), limits=Limits(actuator_force=60.0), grid_points=20)")
BATCH = ("robot.inverse_dynamics_batch(np.repeat(robot.home_pose[None], 100, 0), "
         "np.zeros((100, 6)), np.zeros((100, 6)))")
ID = f"robot.inverse_dynamics(robot.home_pose, {Z}, {Z})"
#: case -> (robot, the call timed twice)
CASES = {
    "Hexapod.inverse_dynamics": ("hexapod", ID),
    "Hexapod.forward_dynamics": (
        "hexapod", f"robot.forward_dynamics(robot.home_pose, {Z}, np.full(6, 10.0))"),
    "Hexapod.static_forces": ("hexapod", "robot.static_forces(robot.home_pose)"),
    "Hexapod.inverse_kinematics": ("hexapod", "robot.inverse_kinematics(robot.home_pose)"),
    "simulate_fast (0.01 s, dt 1 ms)": ("hexapod", "simulate_fast(robot, 0.01, 1e-3)"),
    'hp.simulate (0.01 s, backend="compiled")': (
        "hexapod", 'hp.simulate(robot, 0.01, 1e-3, backend="compiled")'),
    "time_optimal (2 waypoints, 20 grid points)": ("hexapod", PLAN),
    "Hexapod.inverse_dynamics_batch (100 states)": ("hexapod", BATCH),
    "Planar3PRR.inverse_dynamics": ("planar", ID),
    "Planar3PRR.forward_dynamics": (
        "planar", f"robot.forward_dynamics(robot.home_pose, {Z}, np.full(3, 5.0))"),
    "loaded Stewart platform: inverse_dynamics": ("loaded", ID),
    "loaded Stewart platform: forward_dynamics": (
        "loaded", f"robot.forward_dynamics(robot.home_pose, {Z}, np.full(6, 10.0))"),
    "hp.warmup() (every kernel)": ("hexapod", "hp.warmup()"),
}
#: per-call cases: (robot, call, calls per timing)
PER_CALL = {
    "Hexapod.inverse_dynamics": ("hexapod", ID, 50),
    "Hexapod.forward_dynamics": CASES["Hexapod.forward_dynamics"] + (50,),
    "Hexapod.static_forces": CASES["Hexapod.static_forces"] + (50,),
    "Hexapod.inverse_kinematics": CASES["Hexapod.inverse_kinematics"] + (50,),
    "simulate_fast, per step (RK4)": ("hexapod", "simulate_fast(robot, 0.01, 1e-3)", 10),
    "inverse_dynamics_batch, per state": ("hexapod", BATCH, 100),
    "Planar3PRR.inverse_dynamics": ("planar", ID, 50),
    "loaded Stewart platform: inverse_dynamics": ("loaded", ID, 20),
}

_RUNNER = """
import json, time
import numpy as np
from numba.core import event
import hexapod_pin as hp
from hexapod_pin.hexapod.fast import simulate_fast
from hexapod_pin.planning import Limits, time_optimal
robot = {robot}
t1 = time.perf_counter()
with event.install_recorder("numba:compile") as rec:
    {code}
t2 = time.perf_counter()
{code}
t3 = time.perf_counter()
compiled = sum(1 for _, ev in rec.buffer if ev.is_start)
print(json.dumps({{"first": t2 - t1, "second": t3 - t2, "compiled": compiled}}))
"""

_PER_CALL = """
import json, time
import numpy as np
import hexapod_pin as hp
from hexapod_pin.hexapod.fast import simulate_fast
robot = {robot}
{code}
times = []
for _ in range(7):
    t = time.perf_counter()
    for _ in range({repeat}):
        {code}
    times.append((time.perf_counter() - t) / {repeat})
print(json.dumps({{"per_call": sorted(times)[3]}}))
"""

MOTION = "t,x,y,z,roll,pitch,yaw\n" + "\n".join(
    f"{0.01 * k:.2f},0,0,{0.3565 + 0.0005 * k:.4f},0,0,{0.001 * k:.3f}" for k in range(11))
#: the name of the command-line case in ``--cases``
CLI = "hexapod-pin id"


def _env(cache_dir: str | None, mode: str | None, budget: str | None = None) -> dict:
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    for key, value in (("NUMBA_CACHE_DIR", cache_dir), ("HEXAPOD_PIN_COMPILE", mode),
                       ("HEXAPOD_PIN_COMPILE_BUDGET", budget)):
        if value is not None:
            env[key] = value
    return env


def _python(code: str, env: dict) -> dict:
    proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                          text=True, cwd=ROOT, check=False)
    if proc.returncode != 0:
        raise RuntimeError(proc.stderr[-2000:])
    return json.loads(proc.stdout.strip().splitlines()[-1])


def run_case(name: str, cache_dir: str | None, mode: str | None) -> dict:
    """Times of one case in a fresh process (``cache_dir``: its NUMBA_CACHE_DIR; None:
    the environment's; ``mode``: its HEXAPOD_PIN_COMPILE)."""
    robot, code = CASES[name]
    return _python(_RUNNER.format(robot=ROBOTS[robot], code=code), _env(cache_dir, mode))


def run_cli(cache_dir: str | None, mode: str | None, folder: str) -> float:
    """Wall time (s) of ``python -m hexapod_pin id motion.csv --quiet``."""
    motion = Path(folder) / "motion.csv"
    motion.write_text(MOTION, encoding="utf-8")
    start = time.perf_counter()
    proc = subprocess.run([sys.executable, "-m", "hexapod_pin", "id", str(motion), "--quiet"],
                          env=_env(cache_dir, mode), capture_output=True, text=True, cwd=ROOT,
                          check=False)
    if proc.returncode != 0:
        raise RuntimeError(proc.stdout[-1000:] + proc.stderr[-2000:])
    return time.perf_counter() - start


def cold_table(names: list[str], cli: bool) -> None:
    print("| first call | before: eager, cold (s) | kernels compiled | after: tiered, "
          "cold (s) | kernels compiled | after: second call (s) | next session, warm "
          "cache (s) |")
    print("|---|---|---|---|---|---|---|")
    for name in names:
        with tempfile.TemporaryDirectory(prefix="numba_cold_") as eager_cache, \
                tempfile.TemporaryDirectory(prefix="numba_cold_") as tiered_cache:
            before = run_case(name, eager_cache, "eager")
            after = run_case(name, tiered_cache, "tiered")
            warm = run_case(name, eager_cache, "tiered")
        print(f"| {name} | {before['first']:.2f} | {before['compiled']} | "
              f"{after['first']:.3f} | {after['compiled']} | {after['second']:.4f} | "
              f"{warm['first']:.3f} |", flush=True)
    if cli:
        with tempfile.TemporaryDirectory(prefix="numba_cold_") as eager_cache, \
                tempfile.TemporaryDirectory(prefix="numba_cold_") as tiered_cache:
            before = run_cli(eager_cache, "eager", eager_cache)
            after = run_cli(tiered_cache, "tiered", tiered_cache)
            warm = run_cli(eager_cache, "tiered", eager_cache)
        print(f"| `hexapod-pin id motion.csv` (11 samples), whole process | {before:.2f} | | "
              f"{after:.2f} | | | {warm:.2f} |", flush=True)


def per_call_table() -> None:
    print("| call | interpreted (ms) | compiled (ms) | ratio |")
    print("|---|---|---|---|")
    with tempfile.TemporaryDirectory(prefix="numba_cold_") as empty, \
            tempfile.TemporaryDirectory(prefix="numba_cold_") as filled:
        for name, (robot, code, repeat) in PER_CALL.items():
            script = _PER_CALL.format(robot=ROBOTS[robot], code=code, repeat=repeat)
            interp = _python(script, _env(empty, "tiered", "inf"))["per_call"]
            compiled = _python(script, _env(filled, "eager"))["per_call"]
            unit = 100 if "per state" in name else (10 if "per step" in name else 1)
            print(f"| {name} | {1e3 * interp / unit:.3f} | {1e3 * compiled / unit:.4f} | "
                  f"{interp / compiled:.0f} |", flush=True)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--smoke", action="store_true", help="the current cache, no cold runs")
    parser.add_argument("--per-call", action="store_true",
                        help="interpreted against compiled cost of one call")
    parser.add_argument("--cases", default=";".join([*CASES, CLI]),
                        help="cases separated by ';' (default: all, and the command line)")
    args = parser.parse_args()
    if args.per_call:
        per_call_table()
    elif args.smoke:
        print("| first call | first call (s) | kernels compiled | second call (s) |")
        print("|---|---|---|---|")
        for name in CASES:
            got = run_case(name, None, None)
            print(f"| {name} | {got['first']:.3f} | {got['compiled']} | "
                  f"{got['second']:.4f} |", flush=True)
    else:
        names = [n for n in CASES if n in args.cases.split(";")]
        cold_table(names, cli=CLI in args.cases.split(";"))
    print("all cases ran")
    return 0


if __name__ == "__main__":
    sys.exit(main())
