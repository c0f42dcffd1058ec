"""Timings of the compiled fast path (:mod:`hexapod_pin.hexapod.fast`, numba).

Usage::

    python benchmarks/bench_fast.py            # full table
    python benchmarks/bench_fast.py --smoke    # tiny counts; checks that routes agree

Rows "µs per call": median and inter-quartile range over ``--repeat`` blocks of
``--number`` calls from Python, cycling through distinct random states; the reference
routes are the library's single-state methods (Pinocchio tree + closed-form tree state),
the fast ones :class:`hexapod_pin.hexapod.fast.FastDynamics` (input validation included).

Simulation rows, for each integrator of :func:`~hexapod_pin.hexapod.fast.simulate_fast` at
dt = 1 ms: µs per step and real-time factor (simulated time / wall time of the compiled
code, every step recorded), fastest of three runs. "constant static forces" starts at rest
at home under the static forces of home (an unstable equilibrium: it drifts off and
stops at the carriage gap after about 6.5 s); "PID holding home" starts from an offset
(one reference sample: one IK before the loop); "PID on a circle" tracks a reference
sampled per step (an IK per sample, before the loop, included in the wall time; the
Python sampling of the circle is reported separately).

Accuracy rows: max abs error of the final pose / twist after 0.1 s of constant forces
and a wrench from a moving start, against RK4 at dt = 0.1 ms. Energy rows: the total
energy (Pinocchio's) minus its start, over the largest kinetic energy, for the
unactuated fall from home (to a stroke limit, ~0.34 s) and for a 2 s swing under a
spring (P-law kp = 2000 N/m, no ki / kd, plus the static forces; potential of both
included).

First call: a fresh process with an empty numba cache (compile) and then a second one
with that cache (load), each timing ``import`` + first ID + FD + statics + a 10-step
simulation per integrator. Agreement rows: max-abs difference between the fast and
reference routes.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse
import platform
import statistics
import subprocess
import sys
import tempfile
import time

import numba
import numpy as np

import hexapod_pin as hp
from hexapod_pin.hexapod import fast
from hexapod_pin.hexapod.simulation import CircleTrajectory, PIDController, simulate

FIRST_CALL = """
import time
t0 = time.perf_counter()
import numpy as np, hexapod_pin as hp
from hexapod_pin.hexapod import fast
r = hp.Hexapod.default()
t1 = time.perf_counter()
fd = fast.fast_dynamics(r)
p, z = r.home_pose, np.zeros(6)
fd.inverse_dynamics(p, z, z); fd.forward_dynamics(p, z, z); fd.static_forces(p)
for name in fast.INTEGRATORS:
    fast.simulate_fast(r, 0.01, 1e-3, integrator=name)
t2 = time.perf_counter()
print(f"{t1 - t0:.3f} {t2 - t1:.3f}")
"""


def states(robot, rng, n):
    """n random regular states (pose, twist, twist_dot, wrench) near home."""
    out = []
    while len(out) < n:
        pose = robot.home_pose + rng.uniform(-1, 1, 6) * np.r_[0.03, 0.03, 0.02, 0.1, 0.1, 0.2]
        try:
            robot.static_forces(pose, bounded=False)
        except hp.HexapodPinError:
            continue
        out.append((pose, rng.normal(size=6) * 0.3, rng.normal(size=6), rng.normal(size=6)))
    return out


def timing(fn, args, number, repeat):
    """Median and IQR of µs per call of ``fn(*args[k % len(args)])``."""
    fn(*args[0])
    blocks = []
    for _ in range(repeat):
        start = time.perf_counter()
        for k in range(number):
            fn(*args[k % len(args)])
        blocks.append((time.perf_counter() - start) / number * 1e6)
    q = statistics.quantiles(blocks, n=4) if len(blocks) > 1 else blocks * 3
    return statistics.median(blocks), q[2] - q[0]


def swing(robot, integrator):
    """2 s swing about home under a spring (P-law kp = 2000 N/m) plus the static forces."""
    home = robot.home_pose
    return fast.simulate_fast(robot, 2.0, 1e-3, integrator=integrator, reference=(
        home[None], np.zeros((1, 6))), kp=2000.0, ki=0.0, kd=0.0, feedforward=True,
        pose0=home + np.r_[0.003, 0, 0.002, 0, 0.01, 0], record_every=5)


def energy_error(robot, tr, kp=None):
    """max |E - E(0)| / max kinetic energy along ``tr`` (Pinocchio's energies); with
    ``kp``, E includes the spring and the static forces' potential of :func:`swing`."""
    parts = [robot.energies(p, t) for p, t in zip(tr.poses, tr.twists)]
    total = np.array([e.total for e in parts])
    if kp is not None:
        home = robot.home_pose
        q_ref = robot.configuration(home)[robot.indices.carriage_q]
        total += 0.5 * kp * ((q_ref - tr.q) ** 2).sum(axis=1) - tr.q @ robot.static_forces(home)
    return float(np.abs(total - total[0]).max() / max(e.kinetic for e in parts))


def first_call_rows():
    """(compile, cache load) seconds from two fresh processes sharing a new cache dir."""
    rows = []
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        for label in ("empty cache (compile)", "warm cache (load)"):
            out = subprocess.run([sys.executable, "-c", FIRST_CALL], capture_output=True,
                                 text=True, env=env, check=True)
            imp, first = out.stdout.split()
            rows.append((label, float(imp), float(first)))
    return rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--smoke", action="store_true", help="tiny counts, agreement only")
    parser.add_argument("--number", type=int, default=2000)
    parser.add_argument("--repeat", type=int, default=7)
    parser.add_argument("--seconds", type=float, default=10.0, help="simulated time (s)")
    args = parser.parse_args(argv)
    if args.smoke:
        args.number, args.repeat, args.seconds = 20, 3, 0.02
    robot = hp.Hexapod.default()
    fd = fast.fast_dynamics(robot)
    rng = np.random.default_rng(7)
    sample = states(robot, rng, 5 if args.smoke else 50)

    # -- agreement ---------------------------------------------------------------------
    err_id = err_fd = err_st = 0.0
    for pose, tw, td, wr in sample:
        ref = robot.inverse_dynamics(pose, tw, td, wr, method="kkt", bounded=False,
                                     joint_wrenches=False).actuator_forces
        err_id = max(err_id, np.abs(fd.inverse_dynamics(pose, tw, td, wr, bounded=False)
                                    - ref).max() / max(1.0, np.abs(ref).max()))
        acc = robot.forward_dynamics(pose, tw, ref, wr).twist_dot
        err_fd = max(err_fd, np.abs(fd.forward_dynamics(pose, tw, ref, wr) - acc).max()
                     / max(1.0, np.abs(acc).max()))
        st = robot.static_forces(pose, wr, bounded=False)
        err_st = max(err_st, np.abs(fd.static_forces(pose, wr, bounded=False) - st).max()
                     / max(1.0, np.abs(st).max()))
    reference = CircleTrajectory(robot.home_pose, 0.01, 1.0)
    gains = {"kp": 2000.0, "ki": 500.0, "kd": 50.0}
    span = 0.02 if args.smoke else 0.2
    start0 = reference(0.0)
    tree = simulate(robot, span, 1e-3, controller=PIDController(robot, reference, **gains),
                    pose0=start0.pose, twist0=start0.twist)
    quick = fast.simulate_fast(robot, span, 1e-3, reference=reference, **gains)
    err_sim = float(np.abs(tree.poses - quick.poses).max())

    print(f"# hexapod_pin.hexapod.fast benchmark ({'smoke' if args.smoke else 'full'})")
    print(f"python {platform.python_version()}, numpy {np.__version__}, numba "
          f"{numba.__version__}, "
          f"{platform.machine()}, {os.cpu_count()} CPUs, load average "
          f"{os.getloadavg()[0]:.2f}")
    print()
    print("| agreement (max abs; ID / FD / statics relative to max(1, max abs)) | value |")
    print("| --- | --- |")
    print(f"| fast - reference ID, tau | {err_id:.2e} |")
    print(f"| fast - reference FD, twist_dot | {err_fd:.2e} |")
    print(f"| fast - reference statics, tau | {err_st:.2e} |")
    print(f"| fast - tree simulate, pose over {span:g} s (PID) | {err_sim:.2e} |")
    print()

    # -- per-call timings ----------------------------------------------------------------
    id_args = [s for s in sample]
    fd_args = [(p, t, np.zeros(6), w) for p, t, _, w in sample]
    st_args = [(p, w) for p, _, _, w in sample]
    rows = [
        ("inverse_dynamics, reference (kkt)", lambda p, t, d, w: robot.inverse_dynamics(
            p, t, d, w, method="kkt", bounded=False, joint_wrenches=False), id_args),
        ("inverse_dynamics, fast", lambda p, t, d, w: fd.inverse_dynamics(p, t, d, w,
                                                                          bounded=False),
         id_args),
        ("forward_dynamics, reference (pinocchio)", robot.forward_dynamics, fd_args),
        ("forward_dynamics, fast", fd.forward_dynamics, fd_args),
        ("static_forces, reference", lambda p, w: robot.static_forces(p, w, bounded=False),
         st_args),
        ("static_forces, fast", lambda p, w: fd.static_forces(p, w, bounded=False), st_args),
    ]
    print("| call | µs per call (median) | IQR |")
    print("| --- | --- | --- |")
    for name, fn, fargs in rows:
        med, iqr = timing(fn, fargs, args.number, args.repeat)
        print(f"| {name} | {med:.2f} | {iqr:.2f} |")
    print()

    # -- simulation ------------------------------------------------------------------------
    hold = robot.static_forces(robot.home_pose)
    seconds = args.seconds
    print("| simulation, dt = 1 ms | integrator | simulated s | wall s | µs per step | "
          "real-time factor |")
    print("| --- | --- | --- | --- | --- | --- |")
    ref_span = min(seconds, 0.02 if args.smoke else 0.5)
    tr = simulate(robot, ref_span, 1e-3, actuator_forces=hold)
    print(f"| tree simulate(), constant forces | rk4 | {ref_span:g} | {tr.wall_time:.4f} | "
          f"{tr.wall_time / (len(tr.times) - 1) * 1e6:.1f} | {tr.real_time_factor:.1f} |")
    n_steps = round(seconds / 1e-3)
    start = time.perf_counter()
    sampled = [reference(k * 1e-3) for k in range(n_steps + 1)]
    circle = (np.array([c.pose for c in sampled]), np.array([c.twist for c in sampled]))
    sampling = time.perf_counter() - start
    runs = (("constant static forces from home", {"actuator_forces": hold}),
            ("PID holding home from an offset", dict(
                reference=(robot.home_pose[None], np.zeros((1, 6))),
                pose0=robot.home_pose + np.r_[0.005, 0, 0, 0, 0.02, 0], **gains)),
            ("PID on a circle", dict(reference=circle, **gains)))
    for label, kwargs in runs:
        for name in fast.INTEGRATORS:
            best = None
            for _ in range(1 if args.smoke else 3):       # the fastest of three runs
                tr = fast.simulate_fast(robot, seconds, 1e-3, integrator=name, **kwargs)
                best = tr if best is None or tr.wall_time < best.wall_time else best
            steps = max(1, len(best.times) - 1)
            print(f"| fast, {label} ({best.status}) | {name} | {best.times[-1]:g} | "
                  f"{best.wall_time:.4f} | {best.wall_time / steps * 1e6:.3f} | "
                  f"{best.real_time_factor:.0f} |")
    print(f"| (Python sampling of the circle reference) | | {seconds:g} | {sampling:.4f} | "
          f"{sampling / n_steps * 1e6:.2f} | {seconds / sampling:.0f} |")
    print()

    # -- accuracy and energy of the integrators --------------------------------------------
    moving = {"actuator_forces": hold * 1.3, "wrench": np.r_[0.5, -0.3, 0.0, 0.01, 0.0, 0.02],
              "twist0": np.r_[0.01, -0.02, 0.01, 0.1, -0.2, 0.3]}
    exact = fast.simulate_fast(robot, 0.1, 1e-4, **moving)
    print("| integrator (dt = 1 ms) | pose error after 0.1 s (m, rad) | twist error "
          "| energy error, unactuated fall | energy error, 2 s swing (P-law) |")
    print("| --- | --- | --- | --- | --- |")
    pose_error = {}
    for name in fast.INTEGRATORS:
        tr = fast.simulate_fast(robot, 0.1, 1e-3, integrator=name, **moving)
        pose_error[name] = float(np.abs(tr.poses[-1] - exact.poses[-1]).max())
        row = [f"{pose_error[name]:.1e}",
               f"{np.abs(tr.twists[-1] - exact.twists[-1]).max():.1e}"]
        if args.smoke:
            row += ["(full run only)"] * 2
        else:
            fall = fast.simulate_fast(robot, 2.0, 1e-3, integrator=name, record_every=2)
            row += [f"{energy_error(robot, fall):.1e} (of {fall.times[-1]:.2f} s)",
                    f"{energy_error(robot, swing(robot, name), 2000.0):.1e}"]
        print(f"| {name} | " + " | ".join(row) + " |")
    print()

    if not args.smoke:
        print("| first call in a fresh process | import + robot (s) | first ID + FD + "
              "statics + 10-step simulation (s) |")
        print("| --- | --- | --- |")
        for label, imp, first in first_call_rows():
            print(f"| {label} | {imp:.2f} | {first:.2f} |")
    # FD of near-singular states amplifies round-off (cond(J) ~ 500 among these states)
    # the integrators at 1 ms: rk4 to round-off, the others at their order (sanity bounds)
    ok = (max(err_id, err_st) < 1e-10 and err_fd < 1e-9 and err_sim < 1e-8
          and pose_error["rk4"] < 1e-11 and pose_error["rk2"] < 1e-6
          and pose_error["semi_implicit_euler"] < 1e-3)
    if not ok:
        print("ROUTES DISAGREE", file=sys.stderr)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
