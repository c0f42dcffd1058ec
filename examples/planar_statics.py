"""Statics of the planar 3-PRR robot, and actuator forces along a planar trajectory.

Prints the actuator forces that hold the platform at a few poses (gravity -g along y,
an optional load), then follows a smooth trajectory (a circle of the platform origin with
a rocking rotation), computes the inverse dynamics and statics along it (the batch
methods: one compiled kernel over every sample) and plots the three actuator forces,
dynamic and static, against time.

Usage::

    python examples/planar_statics.py [OUTPUT.png]
    python examples/planar_statics.py --help

The plot goes to OUTPUT.png, or to a file in a fresh temporary folder; its path is
printed last. Needs matplotlib (the ``plot`` extra).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

from hexapod_pin.planar.robot import Planar3PRR


def trajectory(t: np.ndarray, radius: float = 0.02, period: float = 1.0,
               tilt: float = 0.15):
    """Pose, twist and twist_dot (each (N, 3)) of a circle with a rocking rotation."""
    w = 2 * np.pi / period
    pose = np.stack([radius * np.cos(w * t) - radius, radius * np.sin(w * t),
                     tilt * np.sin(w * t)], axis=1)
    twist = np.stack([-radius * w * np.sin(w * t), radius * w * np.cos(w * t),
                      tilt * w * np.cos(w * t)], axis=1)
    twist_dot = np.stack([-radius * w ** 2 * np.cos(w * t), -radius * w ** 2 * np.sin(w * t),
                          -tilt * w ** 2 * np.sin(w * t)], axis=1)
    return pose, twist, twist_dot


def parse_arguments(argv: list[str]) -> argparse.Namespace:
    """The command line: an optional output image (``--help`` prints the usage)."""
    parser = argparse.ArgumentParser(
        prog="planar_statics.py",
        description="Statics of the planar 3-PRR at a few poses, and its actuator forces "
                    "along a trajectory plotted to an image (needs matplotlib).")
    parser.add_argument("output", nargs="?", type=Path, default=None,
                        help="image to write (.png, .svg, .pdf); default: a file in a "
                             "fresh temporary folder")
    return parser.parse_args(argv)


def main(argv: list[str]) -> int:
    args = parse_arguments(argv)
    robot = Planar3PRR.default()
    g = robot.geometry
    print(f"planar 3-PRR: rail_radius {g.rail_radius} m, platform_radius {g.platform_radius} m, "
          f"link_length {g.link_length} m, gravity {g.gravity} m/s^2 along -y")
    print(f"home sliders s = {np.array2string(robot.home_actuators, precision=4)} m")
    print()
    print(f"{'pose (x, y, theta)':>28} | {'wrench (fx, fy, mz)':>22} | static forces tau (N)")
    cases = [(robot.home_pose, None),
             (np.array([0.02, -0.01, 0.1]), None),
             (np.array([0.0, 0.0, 0.0]), np.array([0.0, -10.0, 0.0])),
             (np.array([-0.02, 0.02, -0.1]), np.array([2.0, 0.0, 0.2]))]
    for pose, wrench in cases:
        tau = robot.static_forces(pose, wrench)
        shown = np.zeros(3) if wrench is None else wrench
        print(f"{np.array2string(pose, precision=3):>28} | "
              f"{np.array2string(shown, precision=2):>22} | "
              f"{np.array2string(tau, precision=4)}")

    times = np.linspace(0.0, 2.0, 121)
    poses, twists, twist_dots = trajectory(times)
    dynamic = robot.inverse_dynamics_batch(poses, twists, twist_dots).actuator_forces
    static = robot.static_forces_batch(poses)
    print()
    print(f"trajectory: {times.size} samples over {times[-1]:g} s; "
          f"peak |tau| dynamic {np.abs(dynamic).max():.4f} N, static {np.abs(static).max():.4f} N")

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = args.output or Path(tempfile.mkdtemp(prefix="planar_")) / "forces.png"
    fig, ax = plt.subplots(figsize=(7, 4))
    for k, colour in enumerate(("C0", "C1", "C2")):
        ax.plot(times, dynamic[:, k], color=colour, label=f"slider {k}")
        ax.plot(times, static[:, k], color=colour, linestyle="--", linewidth=0.8)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("actuator force along +u_k (N)")
    ax.set_title("planar 3-PRR: inverse dynamics (solid) and statics (dashed)")
    ax.legend(loc="best")
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=100)
    plt.close(fig)
    print(f"plot written to {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
