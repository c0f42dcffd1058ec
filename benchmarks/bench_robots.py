"""Robots loaded from descriptions (``hp.ClosedLoopRobot``) against the closed forms.

Per call, from a platform state: inverse kinematics, Jacobian, forward kinematics,
inverse dynamics, forward dynamics ("nullspace" and "pinocchio"), statics; on the
hexapod and the planar 3-PRR (their compiled closed forms, and the same mechanisms loaded
as ``ClosedLoopRobot`` from their own trees), the Stewart platform, the five-bar and the
delta of ``tests/data``. The states cycle and a loaded robot's inverse-kinematics cache is
cleared before every call (every call solves its configuration); the "FD of ID" column is the max relative error of ``forward(inverse(x)) = x``
over the states (the smoke run exits 1 above 1e-9).

    python benchmarks/bench_robots.py            # the table (~2 min)
    python benchmarks/bench_robots.py --smoke    # what the tests run (seconds)
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

import bench_common as bc
import hexapod_pin as hp

DATA = Path(__file__).resolve().parents[1] / "tests" / "data"
#: distinct states per robot
N_STATES = 64


def robots() -> dict[str, object]:
    """The robots of the table."""
    hexapod, planar = hp.Hexapod.default(), hp.Planar3PRR.default()
    return {
        "hexapod (closed form)": hexapod,
        "hexapod (loaded)": hp.ClosedLoopRobot(hexapod.model, "platform",
                                               home=hexapod.home_configuration),
        "planar 3-PRR (closed form)": planar,
        "planar 3-PRR (loaded)": hp.ClosedLoopRobot(planar.model, "platform",
                                                    ("x", "y", "yaw"),
                                                    home=planar.home_configuration),
        "Stewart 6-UPS": hp.load_robot(DATA / "stewart" / "stewart.urdf"),
        "five-bar": hp.load_robot(DATA / "parallel" / "five_bar_3d", platform="end_1",
                                  pose_axes=("x", "z")),
        "delta 3-RUU": hp.load_robot(DATA / "parallel" / "delta",
                                     platform="platform_center", pose_axes=("x", "y", "z")),
    }


def states(robot, n: int, seed: int = 0):
    """n random regular states near home (pose, twist, twist_dot)."""
    rng = np.random.default_rng(seed)
    dim = robot.pose_dim
    axes = robot.pose_axes if hasattr(robot, "pose_axes") else (
        ("x", "y", "z", "roll", "pitch", "yaw") if dim == 6 else ("x", "y", "yaw"))
    ang = np.array([a in ("roll", "pitch", "yaw") for a in axes])
    size = getattr(robot.geometry, "characteristic_length", 0.3)
    out = []
    while len(out) < n:
        pose = robot.home_pose + rng.uniform(-1, 1, dim) * np.where(ang, 0.05, 0.02 * size)
        try:
            if not robot.singularity(pose).regular:
                continue
            robot.inverse_kinematics(pose, check_limits=False)
        except hp.HexapodPinError:
            continue
        out.append((pose, rng.uniform(-1, 1, dim) * np.where(ang, 0.3, 0.05),
                    rng.uniform(-1, 1, dim) * np.where(ang, 2.0, 0.5)))
    return out


def row(name: str, robot, n: int, repeats: int) -> tuple[list[str], float]:
    """One table row and the FD-of-ID error."""
    sts = states(robot, n)
    taus = [robot.inverse_dynamics(p, t, a, bounded=False).actuator_forces for p, t, a in sts]
    acts = [robot.inverse_kinematics(p, check_limits=False) for p, _, _ in sts]
    err = max(np.abs(robot.forward_dynamics(p, t, u).twist_dot - a).max()
              / max(1.0, np.abs(a).max()) for (p, t, a), u in zip(sts, taus))
    k = [0]

    clear = getattr(getattr(robot, "kinematics", None), "clear_cache", None)

    def cycle(call):
        def run():
            i = k[0] = (k[0] + 1) % n
            if isinstance(robot, hp.ClosedLoopRobot):
                clear()
            call(i)
        return run

    ops = [
        lambda i: robot.inverse_kinematics(sts[i][0], check_limits=False),
        lambda i: robot.jacobian(sts[i][0]),
        lambda i: robot.forward_kinematics(acts[i], guess=sts[i][0]),
        lambda i: robot.inverse_dynamics(sts[i][0], sts[i][1], sts[i][2], bounded=False),
        lambda i: robot.forward_dynamics(sts[i][0], sts[i][1], taus[i]),
        lambda i: robot.forward_dynamics(sts[i][0], sts[i][1], taus[i], method="pinocchio"),
        lambda i: robot.static_forces(sts[i][0], bounded=False),
    ]
    cells = [bc.fmt_us(bc.measure(cycle(op), repeats=repeats)) for op in ops]
    return [name] + cells + [f"{err:.1e}"], err


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--smoke", action="store_true", help="tiny run (the tests)")
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args(argv)
    n, repeats = (8, 1) if args.smoke else (N_STATES, args.repeats)
    if args.smoke:
        bc.MIN_SAMPLE["seconds"] = 0.001
    bc.print_machine_info()
    rows, worst = [], 0.0
    for name, robot in robots().items():
        cells, err = row(name, robot, n, repeats)
        rows.append(cells)
        worst = max(worst, err)
    print(bc.table(["robot", "IK", "Jacobian", "FK", "ID", "FD nullspace", "FD pinocchio",
                    "statics", "FD of ID"], rows,
                   title="us per call from a platform state, median [IQR]"))
    if worst > 1e-9:
        print(f"FD of ID error {worst:.2e} above 1e-9", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
