"""The cost of the analytic forward-dynamics derivatives
(``hexapod_pin.core.dynamics_derivatives``) against a central-difference Jacobian and
Pinocchio's ``computeConstraintDynamicsDerivatives``.

Per call, at the home configuration of each robot with a random closure-keeping velocity
and random actuator forces: one verified forward-dynamics call (``forward_dynamics_tree``,
"pinocchio" route: the unit of the comparison); the analytic derivatives
(``forward_dynamics_derivatives_tree``: ``d a / d q`` along the closures' null space, ``d a
/ d v``, ``d a / d u``, ``d a / d tau_ext`` and the multipliers'); a central-difference
Jacobian of the same derivatives in ``q`` (along the m tangent directions, the velocity
re-projected) and ``v`` (nv directions), ``2 (m + nv) + 1`` verified calls, step 1e-5;
Pinocchio's ``constraintDynamics`` + ``computeConstraintDynamicsDerivatives`` (its ``d ddq /
dq`` is wrong for point loops between two moving bodies, marked "wrong dq"); and the robot
level (``robot.forward_dynamics_derivatives`` at the home pose: inverse kinematics, maps,
the platform rows). "FD miss" is the max relative difference between the analytic and the
central-difference derivatives (the smoke run exits 1 above 1e-5).

A robot-level table, per robot near its home pose (seeded: pose within 1 cm / 0.01 rad,
twist 0.05 N(0, 1), forces the static ones plus N(0, 1), no wrench): one verified
``robot.forward_dynamics`` call (the unit), ``robot.forward_dynamics_derivatives`` and
their ratio (the issue's target: below 3x), the route that answered ("closed form": the
robot's compiled inverse-dynamics partials and the implicit-function theorem; "tree": the
KKT derivatives), a central-difference Jacobian of the same call in the pose coordinates,
the twist and the forces (``2 (2 dim + n_act) + 1`` calls, step 1e-5) and
``robot.inverse_dynamics_derivatives`` at the forward answer; "FD miss" the analytic
against those differences.

A last table, per robot at its home pose (twist 0.05, held static forces): the
inverse-dynamics derivatives as the robot answers them (the hexapod's and planar robot's
closed forms, a loaded robot's core route) and by the core route
(``platform_derivatives.inverse_dynamics_derivatives``, the implicit-function theorem on
the forward-dynamics derivatives, the forces given); one simulation step of a fresh
integrator ("rk4", "semi_implicit_euler", dt = 1 ms) and its analytic step Jacobians
(``robot.step_jacobians``).

    python benchmarks/bench_derivatives.py            # the table (~1 min)
    python benchmarks/bench_derivatives.py --smoke    # what the tests run (seconds)
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import pinocchio as pin

import bench_common as bc
import hexapod_pin as hp
from hexapod_pin.core.dynamics import forward_dynamics_tree
from hexapod_pin.core.dynamics_derivatives import forward_dynamics_derivatives_tree
from hexapod_pin.core.platform_derivatives import (PlatformLinearization,
                                                   inverse_dynamics_derivatives)
from hexapod_pin.core.simulation import ClosedLoopIntegrator
from hexapod_pin.loaders.robots import cassie

DATA = Path(__file__).resolve().parents[1] / "tests" / "data"
STEP = 1e-5


def robots(smoke: bool):
    """(name, robot or None, ClosedLoopModel, configuration, Pinocchio right?) of the
    table."""
    out = [("four-bar", hp.load_robot(DATA / "four_bar" / "four_bar.urdf"), False),
           ("hexapod", hp.Hexapod.default(), True)]
    if not smoke:
        out += [("planar 3-PRR", hp.Planar3PRR.default(), True),
                ("five-bar", hp.load_robot(DATA / "parallel" / "five_bar_3d", platform="end_1",
                                           pose_axes=("x", "z")), False),
                ("delta", hp.load_robot(DATA / "parallel" / "delta",
                                        platform="platform_center",
                                        pose_axes=("x", "y", "z")), True),
                ("Stewart 6-UPS", hp.load_robot(DATA / "stewart" / "stewart.urdf"), False)]
    rows = [(name, r, r.model, r.home_configuration, right) for name, r, right in out]
    if not smoke:
        model = cassie()
        rng = np.random.default_rng(7)
        dq = np.zeros(model.nv)
        dq[model.actuated_v] = 0.1 * rng.normal(size=model.n_actuated)
        q = model.assemble(pin.integrate(model.model, pin.neutral(model.model), dq)).q
        rows.append(("Cassie (tree)", None, model, q, False))
    return rows


def projector(clm, q):
    """The orthogonal projector on ``null(J_c(q))``."""
    _, sv, vt = np.linalg.svd(clm.constraint_jacobian(q))
    null = vt[int(np.sum(sv > 1e-10 * sv[0])):]
    return null.T @ null


def fd_jacobian(clm, q, v, u, basis):
    """Central differences of ``a`` along ``basis`` (velocity re-projected) and along each
    velocity coordinate (projected): ``2 (m + nv) + 1`` verified forward-dynamics calls."""
    base = forward_dynamics_tree(clm, q, v, u).a
    cols_q = []
    for k in range(basis.shape[1]):
        pair = []
        for s in (STEP, -STEP):
            qq = pin.integrate(clm.model, q, s * basis[:, k])
            pair.append(forward_dynamics_tree(clm, qq, projector(clm, qq) @ v, u).a)
        cols_q.append((pair[0] - pair[1]) / (2 * STEP))
    proj = projector(clm, q)
    cols_v = [(forward_dynamics_tree(clm, q, v + STEP * proj[:, k], u).a
               - forward_dynamics_tree(clm, q, v - STEP * proj[:, k], u).a) / (2 * STEP)
              for k in range(clm.nv)]
    return base, np.array(cols_q).T, np.array(cols_v).T


def pinocchio_derivatives(clm, q, v, u):
    """``constraintDynamics`` then ``computeConstraintDynamicsDerivatives`` (a callable)."""
    cms, cds = clm.pinocchio_constraints()
    data = clm.model.createData()
    pin.initConstraintDynamics(clm.model, data, cms, cds)
    tau = np.zeros(clm.nv)
    tau[clm.actuated_v] = u
    rank = np.linalg.matrix_rank(clm.constraint_jacobian(q))
    prox = pin.ProximalSettings(1e-12, 1e-10 if rank < clm.n_rows else 0.0, 50)

    def call():
        pin.constraintDynamics(clm.model, data, q, v, tau, cms, cds, prox)
        pin.computeConstraintDynamicsDerivatives(clm.model, data, cms, cds, prox)
    return call


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--smoke", action="store_true", help="two robots, few repeats")
    args = parser.parse_args()
    repeats = 1 if args.smoke else 7
    bc.print_machine_info()
    rows, worst = [], 0.0
    for name, robot, clm, q, right in robots(args.smoke):
        rng = np.random.default_rng(0)
        v = projector(clm, q) @ rng.normal(size=clm.nv)
        u = rng.normal(size=clm.n_actuated)
        der = forward_dynamics_derivatives_tree(clm, q, v, u)
        basis = der.tangent_basis
        _, num_q, num_v = fd_jacobian(clm, q, v, u, basis)
        scale = max(1.0, float(np.max(np.abs(num_q))), float(np.max(np.abs(num_v))))
        miss = max(float(np.max(np.abs(num_q - der.d_q))),
                   float(np.max(np.abs(num_v - der.d_v)))) / scale
        worst = max(worst, miss)
        one = bc.measure(lambda: forward_dynamics_tree(clm, q, v, u), repeats=repeats)
        analytic = bc.measure(lambda: forward_dynamics_derivatives_tree(clm, q, v, u),
                              repeats=repeats)
        central = bc.measure(lambda: fd_jacobian(clm, q, v, u, basis), repeats=repeats)
        raw = bc.measure(pinocchio_derivatives(clm, q, v, u), repeats=repeats)
        level = "-"
        if robot is not None:
            dim = robot.pose_layout.dim
            held = robot.static_forces(robot.home_pose, bounded=False)
            level = bc.fmt_us(bc.measure(lambda: robot.forward_dynamics_derivatives(
                robot.home_pose, np.zeros(dim), held), repeats=repeats))
        rows.append([name, f"{clm.nv} / {basis.shape[1]}", bc.fmt_us(one), bc.fmt_us(analytic),
                     f"{analytic.median / one.median:.0f}x", bc.fmt_us(central),
                     bc.fmt_us(raw) + ("" if right else " (wrong dq)"), level,
                     f"{miss:.1e}"])
    print(bc.table(["robot", "nv / m", "one FD call", "analytic", "analytic / FD call",
                    "central differences", "pin constraint derivs", "robot level",
                    "FD miss"], rows,
                   title="Forward-dynamics derivatives, per call (µs)"))
    level_rows, level_worst = robot_level_rows(args.smoke, repeats)
    worst = max(worst, level_worst)
    print(bc.table(["robot", "dim / n_act", "one FD call", "FD derivatives",
                    "derivatives / FD call", "route", "central differences",
                    "ID derivatives", "FD miss"], level_rows,
                   title="Robot level: forward-dynamics derivatives, per call (µs)"))
    print(bc.table(["robot", "ID derivs (robot)", "ID derivs (core)", "rk4 step",
                    "rk4 step Jacobians", "Euler step", "Euler step Jacobians"],
                   robot_rows(args.smoke, repeats),
                   title="Inverse-dynamics derivatives and step Jacobians, per call (µs)"))
    return 0 if worst <= 1e-5 else 1


def paired(first, second, repeats: int) -> tuple[bc.Timing, bc.Timing]:
    """``bc.measure`` of two calls with their samples interleaved (first, second, first,
    ...), so that a load spike of the shared machine hits both: their ratio is the
    figure compared."""
    counts = []
    for fn in (first, second):
        fn()
        t0 = time.perf_counter()
        fn()
        counts.append(max(1, int(bc.MIN_SAMPLE["seconds"] / max(time.perf_counter() - t0,
                                                                1e-9))))
    samples: list[list[float]] = [[], []]
    for _ in range(repeats):
        for j, fn in enumerate((first, second)):
            t0 = time.perf_counter()
            for _ in range(counts[j]):
                fn()
            samples[j].append((time.perf_counter() - t0) / counts[j])
    out = []
    for j in range(2):
        arr = np.array(samples[j])
        out.append(bc.Timing(float(np.median(arr)), float(np.percentile(arr, 25)),
                             float(np.percentile(arr, 75)), repeats, counts[j]))
    return out[0], out[1]


def robot_central(robot, pose, twist, u):
    """Central differences of ``robot.forward_dynamics(...).twist_dot`` in the pose
    coordinates, the twist and the forces (step 1e-5): ``(d_pose, d_twist, d_u)``."""
    def acc(p, t, f):
        return robot.forward_dynamics(p, t, f).twist_dot

    acc(pose, twist, u)
    out = []
    for arg in range(3):
        base = [pose, twist, u]
        cols = []
        for k in range(len(base[arg])):
            step = np.zeros(len(base[arg]))
            step[k] = STEP
            plus, minus = list(base), list(base)
            plus[arg], minus[arg] = base[arg] + step, base[arg] - step
            cols.append((acc(*plus) - acc(*minus)) / (2 * STEP))
        out.append(np.array(cols).T)
    return out


def robot_level_rows(smoke: bool, repeats: int) -> tuple[list[list[str]], float]:
    """The robot-level table (module docstring) and its worst FD miss."""
    rows, worst = [], 0.0
    for name, robot, _, _, _ in robots(smoke):
        if robot is None:
            continue
        dim, n_act = robot.pose_layout.dim, robot.model.n_actuated
        rng = np.random.default_rng(1)
        pose = robot.home_pose + 0.01 * rng.uniform(-1, 1, dim)
        twist = 0.05 * rng.normal(size=dim)
        u = robot.static_forces(pose, bounded=False) + rng.normal(size=n_act)
        der = robot.forward_dynamics_derivatives(pose, twist, u)
        num = robot_central(robot, pose, twist, u)
        scale = max(1.0, *(float(np.max(np.abs(x))) for x in num))
        miss = max(float(np.max(np.abs(a - b))) for a, b in zip(
            num, (der.d_pose, der.d_twist, der.d_actuator_forces))) / scale
        worst = max(worst, miss)
        partials = getattr(getattr(robot, "dynamics", None), "inverse_dynamics_partials",
                           None)
        closed = partials is not None and partials(pose, twist, der.twist_dot) is not None
        one, analytic = paired(lambda: robot.forward_dynamics(pose, twist, u),
                               lambda: robot.forward_dynamics_derivatives(pose, twist, u),
                               repeats)
        central = bc.measure(lambda: robot_central(robot, pose, twist, u), repeats=repeats)
        inverse = bc.measure(lambda: robot.inverse_dynamics_derivatives(
            pose, twist, der.twist_dot), repeats=repeats)
        rows.append([name, f"{dim} / {n_act}", bc.fmt_us(one), bc.fmt_us(analytic),
                     f"{analytic.median / one.median:.1f}x",
                     "closed form" if closed else "tree", bc.fmt_us(central),
                     bc.fmt_us(inverse), f"{miss:.1e}"])
    return rows, worst


def robot_rows(smoke: bool, repeats: int) -> list[list[str]]:
    """The second table (module docstring)."""
    rows = []
    for name, robot, clm, _, _ in robots(smoke):
        if robot is None:
            continue
        dim = robot.pose_layout.dim
        pose, twist = robot.home_pose, np.full(dim, 0.05)
        held = robot.static_forces(pose, bounded=False)
        accel = np.full(dim, 0.1)
        forces = robot.inverse_dynamics(pose, twist, accel, bounded=False).actuator_forces
        own = bc.measure(lambda: robot.inverse_dynamics_derivatives(pose, twist, accel),
                         repeats=repeats)
        core = bc.measure(lambda: inverse_dynamics_derivatives(robot, pose, twist, accel,
                                                               forces), repeats=repeats)
        start = PlatformLinearization(robot, pose, twist, held, None, None)
        q, vel = start.tree.q, start.tree.v
        tau = np.zeros(clm.nv)
        tau[clm.actuated_v] = held
        cells = [name, bc.fmt_us(own), bc.fmt_us(core)]
        for integrator in ("rk4", "semi_implicit_euler"):
            def one_step(integrator=integrator):
                ClosedLoopIntegrator(clm, integrator=integrator).step(q, vel, tau, 1e-3)
            step = bc.measure(one_step, repeats=repeats)
            jac = bc.measure(lambda integrator=integrator: robot.step_jacobians(
                pose, twist, held, 1e-3, integrator=integrator), repeats=repeats)
            cells += [bc.fmt_us(step), bc.fmt_us(jac)]
        rows.append(cells)
    return rows


if __name__ == "__main__":
    sys.exit(main())
