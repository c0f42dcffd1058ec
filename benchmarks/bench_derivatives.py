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

A second table, per robot at its home pose (twist 0.05, held static forces): the
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
    print(bc.table(["robot", "ID derivs (robot)", "ID derivs (core)", "rk4 step",
                    "rk4 step Jacobians", "Euler step", "Euler step Jacobians"],
                   robot_rows(args.smoke, repeats),
                   title="Inverse-dynamics derivatives and step Jacobians, per call (µs)"))
    return 0 if worst <= 1e-5 else 1


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
