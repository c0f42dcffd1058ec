"""LQR stabilisation of the hexapod about a pose, from its linearised closed-loop dynamics.

``robot.linearize(pose, 0, u_s)`` at the static forces ``u_s`` gives ``dx/dt = A x + B du``
in ``x = (dp, dtheta, twist)`` (world axes, :mod:`hexapod_pin.core.platform_derivatives`);
``scipy.linalg.solve_continuous_are`` gives the gain ``K`` of ``du = -K x``. The controller
reads the simulated platform pose and twist, and ``hp.simulate`` integrates the nonlinear
closed-loop dynamics on the Pinocchio tree from a displaced pose at rest. Prints the
closed loop's slowest eigenvalue and the pose error at the start, halfway and at the end.

Usage::

    python examples/hexapod_lqr.py
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

import hexapod_pin as hp
from hexapod_pin.core.controllers import SimState, platform_error


class LQRController:
    """``u = u_s - K x`` with ``x = (-platform_error(pose_ref, pose), twist)``: the world
    displacement ``(dp, dtheta)`` of the platform from the reference, then its twist."""

    def __init__(self, pose_ref: np.ndarray, held: np.ndarray, gain: np.ndarray) -> None:
        self.pose_ref, self.held, self.gain = pose_ref, held, gain

    def __call__(self, state: SimState, robot: hp.Hexapod) -> np.ndarray:
        assert state.pose is not None and state.twist is not None
        x = np.concatenate([-platform_error(self.pose_ref, state.pose), state.twist])
        return self.held - self.gain @ x


def main() -> None:
    robot = hp.Hexapod.default()
    pose = robot.home_pose + np.array([0.0, 0.0, 0.01, 0.0, 0.0, 0.0])
    held = robot.static_forces(pose, bounded=False)
    model = robot.linearize(pose, np.zeros(6), held)
    q_cost = np.diag([1e4] * 3 + [1e3] * 3 + [1e1] * 6)
    r_cost = np.eye(6) * 1e-3
    riccati = scipy.linalg.solve_continuous_are(model.a, model.b, q_cost, r_cost)
    gain = np.linalg.solve(r_cost, model.b.T @ riccati)
    closed = np.linalg.eigvals(model.a - model.b @ gain)
    print("open-loop max real part", float(np.max(np.linalg.eigvals(model.a).real)))
    print("closed-loop max real part", float(np.max(closed.real)))

    start = pose + np.array([0.004, -0.003, 0.002, 0.01, -0.008, 0.012])
    q0 = robot.configuration(start)
    traj = hp.simulate(robot, 0.6, dt=1e-3, controller=LQRController(pose, held, gain),
                       initial=(q0, np.zeros(robot.model.nv)), record_every=10)
    errors = np.array([np.linalg.norm(platform_error(pose, p)) for p in traj.poses])
    half = len(errors) // 2
    print("status", traj.status)
    print("pose error start", errors[0], "half", errors[half], "end", errors[-1])


if __name__ == "__main__":
    main()
