"""Closed-loop kinematics on the generic model: velocity maps, frame IK, projections, freezing.

For each robot (the five-bar with a 6-D closure and the delta of ``tests/data/parallel``,
the hexapod, Cassie with a fixed pelvis) it prints one Markdown table, microseconds per
call (median [inter-quartile range]), of

* ``constraint_jacobian``;
* ``velocity_from_actuated`` and ``frame_jacobian_from_actuated`` on the direct route
  ("lstsq": compiled QR / SVD least squares) and the ProxSuite route ("qp");
* ``acceleration_from_actuated``; ``project_velocity`` (Euclidean and mass metrics);
* ``frame_inverse_kinematics`` of the end effector to a target taken from an assembled
  configuration, from a perturbed start whose loops are closed first (time per solve and
  per iteration, iterations, residuals), both routes;
* ``freeze_joints`` (building the reduced model) and a forward dynamics on it.

Agreement checks (also in ``--smoke``, exit status 1 on failure): the two routes of the
velocity map agree to 1e-10, every IK target is reached to 1e-10 with closures to 1e-12,
and the frozen model's forward dynamics equals the full model's KKT with the locked
joints' accelerations held at zero (1e-9 relative).

Usage (from the repository root)::

    python benchmarks/bench_closed_loop_kinematics.py           # full run (about a minute)
    python benchmarks/bench_closed_loop_kinematics.py --smoke   # seconds: checks, few samples
"""

from __future__ import annotations

import os

# tiny dense matrices: BLAS threads only add contention (set before numpy loads)
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import sys  # noqa: E402
from dataclasses import dataclass  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402

import hexapod_pin as hp  # noqa: E402
from bench_common import MIN_SAMPLE, fmt_us, measure, print_machine_info, table  # noqa: E402
from hexapod_pin.core.closed_loop import ClosedLoopModel  # noqa: E402
from hexapod_pin.core.dynamics import forward_dynamics_tree  # noqa: E402
from hexapod_pin.core.freeze import freeze_joints  # noqa: E402
from hexapod_pin.loaders import robots  # noqa: E402
from hexapod_pin.loaders.parallel_robots import load_parallel_robot  # noqa: E402

DATA = Path(__file__).resolve().parent.parent / "tests" / "data" / "parallel"


@dataclass
class Case:
    """A robot, an assembled configuration, its end effector and a joint to lock."""

    name: str
    clm: ClosedLoopModel
    q: np.ndarray
    effector: str
    position_only: bool
    lock: str
    fixed: tuple[str, ...] = ()


def _assembled(clm, values, fixed_extra=()):
    q0 = clm.neutral()
    for joint, value in values.items():
        q0[clm.joint_q_index(joint)] = value
    fixed = np.r_[clm.actuated_v, [clm.joint_v_index(j) for j in fixed_extra]].astype(int)
    return clm.assemble(q0, fixed=fixed).q


def cases() -> list[Case]:
    five = load_parallel_robot(DATA / "five_bar_6d")
    delta = load_parallel_robot(DATA / "delta")
    hexapod = hp.Hexapod.default()
    cassie = robots.cassie(root="fixed")
    springs = tuple(f"{s}-{j}" for s in ("left", "right")
                    for j in ("knee-shin-joint", "tarsus-spring-joint"))
    delta_values = {f"{j}_{k}": v for k in range(3)
                    for j, v in (("motor", 0.5), ("elbow", 0.0), ("wrist", 0.0))
                    if j == "motor"}
    delta_values.update({f"elbow_{k}_Y": 1.9 for k in range(3)})
    delta_values.update({f"wrist_{k}_Y": -2.4 for k in range(3)})
    cassie_values = {f"{s}-{j}": v for s in ("left", "right")
                     for j, v in (("pitch-op", 0.3), ("foot-op", -0.4))}
    return [
        Case("five_bar_6d", five, _assembled(five, {"mot1": 1.2, "mot2": 1.9, "free1": -1.0,
                                                    "free2": 1.0}),
             "closure_A", True, "mot1"),
        Case("delta", delta, _assembled(delta, delta_values), "platform_center", True,
             "motor_0"),
        Case("hexapod", hexapod.model, hexapod.home_configuration, "platform", False,
             hexapod.model.actuated_joints[0]),
        Case("cassie (fixed pelvis)", cassie, _assembled(cassie, cassie_values, springs),
             "left-foot", True, "left-knee-shin-joint", springs),
    ]


def kkt_with_locked(clm, q, v, tau, locked_v):
    """Full-model forward dynamics with ``a[locked_v] = 0`` added (numpy least squares; the
    description's joint damping, Pinocchio's ``model.damping``, acts as ``-D v``)."""
    data = clm.model.createData()
    mass = pin.crba(clm.model, data, q)
    mass = np.triu(mass) + np.triu(mass, 1).T
    sel = np.zeros((len(locked_v), clm.nv))
    sel[np.arange(len(locked_v)), locked_v] = 1.0
    jac = np.vstack([clm.constraint_jacobian(q), sel])
    rhs = np.concatenate([-clm.constraint_drift(q, v), np.zeros(len(locked_v))])
    n = jac.shape[0]
    kkt = np.block([[mass, -jac.T], [jac, np.zeros((n, n))]])
    sol = np.linalg.lstsq(kkt, np.concatenate([tau - np.asarray(clm.model.damping) * v
                                              - pin.nle(clm.model, data, q, v), rhs]),
                          rcond=None)[0]
    return sol[:clm.nv]


def run_case(case: Case, rng, repeats: int, trials: int) -> tuple[list[list[str]], list[str]]:
    clm, q = case.clm, case.q
    rows, failures = [], []
    qdot = rng.normal(size=clm.n_actuated)
    v = clm.velocity_from_actuated(q, qdot)

    def row(label, fn, note=""):
        rows.append([label, fmt_us(measure(fn, repeats)), note])

    row("constraint_jacobian", lambda: clm.constraint_jacobian(q),
        f"{clm.n_rows} rows, rank {clm.rank(q).rank}, nv {clm.nv}")
    gaps = {}
    for method in ("lstsq", "qp"):
        row(f"velocity_from_actuated ({method})",
            lambda m=method: clm.velocity_from_actuated(q, qdot, m))
        row(f"frame_jacobian_from_actuated ({method})",
            lambda m=method: clm.frame_jacobian_from_actuated(q, case.effector, method=m))
        gaps[method] = clm.actuated_velocity_map(q, method)
    gap = float(np.max(np.abs(gaps["lstsq"] - gaps["qp"])))
    rows[-1][2] = f"routes differ by {gap:.1e}"
    if not gap <= 1e-10 * max(1.0, np.abs(gaps["lstsq"]).max()):
        failures.append(f"{case.name}: velocity-map routes differ by {gap:.1e}")
    row("acceleration_from_actuated (lstsq)",
        lambda: clm.acceleration_from_actuated(q, v, np.zeros(clm.n_actuated)))
    raw = rng.normal(size=clm.nv)
    row("project_velocity (euclidean)", lambda: clm.project_velocity(q, raw, "euclidean"))
    try:
        clm.project_velocity(q, raw, "mass")
        row("project_velocity (mass)", lambda: clm.project_velocity(q, raw, "mass"))
    except hp.HexapodPinError as exc:
        rows.append(["project_velocity (mass)", "-", type(exc).__name__])

    # frame IK: targets from assembled configurations, perturbed starts
    data = clm.model.createData()
    fid = clm.frame_id(case.effector)
    fixed_v = np.r_[clm.actuated_v, [clm.joint_v_index(j) for j in case.fixed]].astype(int)
    problems = []
    for _ in range(trials):
        goal = q.copy()
        moved = [clm.joint_q_index(j) for j in clm.actuated_joints if "knee" not in j]
        goal[moved] += rng.uniform(-0.05, 0.05, len(moved))
        try:
            goal = clm.assemble(goal, fixed=fixed_v).q
        except hp.AssemblyError:
            continue
        pin.framesForwardKinematics(clm.model, data, goal)
        target = pin.SE3(data.oMf[fid])
        target = target.translation.copy() if case.position_only else target
        kick = 0.01 * rng.uniform(-1, 1, clm.nv)
        kick[[clm.joint_v_index(j) for j in case.fixed]] = 0.0   # held joints stay put
        try:   # starts that keep the closures: the solve times exclude a first assembly
            start = clm.assemble(pin.integrate(clm.model, q, kick), fixed=np.array(
                [clm.joint_v_index(j) for j in case.fixed], dtype=int)).q
        except hp.AssemblyError:
            continue
        problems.append((target, start))
    for method in ("qp", "lstsq"):
        iters, worst, worst_closure = [], 0.0, 0.0

        def solve_all(m=method):
            for target, start in problems:
                res = clm.frame_inverse_kinematics(
                    case.effector, target, start, position_only=case.position_only,
                    fixed=case.fixed or None, method=m, limits=False)
                iters.append(res.iterations)
                yield res

        results = list(solve_all())
        for res in results:
            worst = max(worst, res.target_residual if res.reachable else np.inf)
            worst_closure = max(worst_closure, res.closure_residual)
        if not (worst <= 1e-10 and worst_closure <= 1e-12):
            failures.append(f"{case.name}: IK ({method}) target {worst:.1e}, "
                            f"closures {worst_closure:.1e}")
        n_iter = sum(res.iterations for res in results)
        timing = measure(lambda m=method: list(solve_all(m)), max(3, repeats // 2))
        rows.append([f"frame_inverse_kinematics ({method}), per solve",
                     fmt_us(timing.per_state(max(1, len(problems)))),
                     f"{len(results)} targets, iterations {min(iters)}-{max(iters)}, "
                     f"target {worst:.0e}, closures {worst_closure:.0e}"])
        rows.append([f"frame_inverse_kinematics ({method}), per iteration",
                     fmt_us(timing.per_state(max(1, n_iter))),
                     "solve time / iterations (set-up and the answer's check included)"])

    # freezing
    row("freeze_joints (build the reduced model)",
        lambda: freeze_joints(clm, [case.lock], q))
    frozen = freeze_joints(clm, [case.lock], q)
    red = frozen.model
    q_red = frozen.reduced_configuration(q)
    v_red = red.project_velocity(q_red, rng.normal(size=red.nv), "euclidean")
    u = rng.normal(size=red.n_actuated)
    acc = forward_dynamics_tree(red, q_red, v_red, u, method="kkt").a
    tau = np.zeros(clm.nv)
    for joint, value in zip(red.actuated_joints, u):
        tau[clm.joint_v_index(joint)] = value
    locked_v = np.setdiff1d(np.arange(clm.nv), frozen.v_index)
    ref = kkt_with_locked(clm, q, frozen.full_velocity(v_red), tau, locked_v)
    miss = float(np.max(np.abs(frozen.full_velocity(acc) - ref)))
    row("forward_dynamics_tree on the frozen model (kkt)",
        lambda: forward_dynamics_tree(red, q_red, v_red, u, method="kkt"),
        f"{case.lock} locked; = full KKT to {miss:.1e}")
    if not miss <= 1e-9 * max(1.0, np.abs(ref).max()):
        failures.append(f"{case.name}: frozen dynamics differ by {miss:.1e}")
    return rows, failures


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--smoke", action="store_true", help="few samples, checks only")
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--trials", type=int, default=10, help="IK targets per robot")
    args = parser.parse_args(argv)
    repeats, trials = args.repeats, args.trials
    if args.smoke:
        MIN_SAMPLE["seconds"] = 0.001
        repeats, trials = 3, 2
    else:
        print_machine_info()
    rng = np.random.default_rng(0)
    failures = []
    for case in cases():
        rows, bad = run_case(case, rng, repeats, trials)
        failures += bad
        print(table(["operation", "µs per call", "notes"], rows,
                    title=f"{case.name}: nq={case.clm.nq}, nv={case.clm.nv}, "
                          f"{case.clm.n_actuated} actuated"))
    if failures:
        print("FAILED:\n" + "\n".join(failures))
        return 1
    print("all checks passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
