"""Discrete-time LQR of the hexapod about a pose, from the Jacobians of one simulation step.

``robot.linearize(pose, 0, u_s, dt=dt, integrator=...)`` at the static forces ``u_s``
holds, besides the continuous ``A``, ``B``, the discrete ``dx_{k+1} = Ad dx_k + Bd du_k``
of one ``hp.simulate`` step of that integrator (zero-order hold, the projection onto the
closures included; ``x = (dp, dtheta, twist)``, world axes,
:mod:`hexapod_pin.core.step_jacobians`). ``scipy.linalg.solve_discrete_are`` gives the
gain ``K = (R + Bd^T P Bd)^-1 Bd^T P Ad`` of ``du_k = -K x_k``, applied once per step by the
controller that ``hp.simulate`` calls with the simulated platform pose and twist. The
step is long (10 ms), so the sampling matters: the same weights through the continuous
Riccati equation give a gain whose sampled closed loop is unstable.

Prints, per integrator (semi-implicit Euler and RK4): the spectral radius of the sampled
closed loop ``Ad - Bd K`` of the discrete gain and of the continuous one, the simulation's
status, and the pose error at the start, halfway and at the end.

Usage::

    python examples/hexapod_dlqr.py
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

import hexapod_pin as hp
from hexapod_pin.core.controllers import SimState, platform_error
from hexapod_pin.core.platform_derivatives import StateSpaceModel

#: the control period and simulation step (s)
DT = 0.01
#: state weights (dp m, dtheta rad, twist m/s and rad/s) and the actuator-force weight (N)
Q_COST = np.diag([1e4] * 3 + [1e3] * 3 + [1e1] * 6)
R_COST = np.eye(6) * 1e-3
#: the initial displacement from the reference pose (m, rad) and the simulated time (s)
START_OFFSET = np.array([0.004, -0.003, 0.002, 0.01, -0.008, 0.012])
DURATION = 0.6


class LQRController:
    """``u = u_s - K x`` with ``x = (-platform_error(pose_ref, pose), twist)``: the world
    displacement ``(dp, dtheta)`` of the platform from the reference, then its twist."""

    def __init__(self, pose_ref: np.ndarray, held: np.ndarray, gain: np.ndarray) -> None:
        self.pose_ref, self.held, self.gain = pose_ref, held, gain

    def __call__(self, state: SimState, robot: hp.Hexapod) -> np.ndarray:
        if state.pose is None or state.twist is None:
            raise ValueError("the controller needs the platform pose and twist")
        x = np.concatenate([-platform_error(self.pose_ref, state.pose), state.twist])
        return self.held - self.gain @ x


def spectral_radius(matrix: np.ndarray) -> float:
    """The largest eigenvalue modulus (below 1: the sampled loop is stable)."""
    return float(np.max(np.abs(np.linalg.eigvals(matrix))))


def design(robot: hp.Hexapod, pose: np.ndarray, integrator: str
           ) -> tuple[np.ndarray, np.ndarray, StateSpaceModel]:
    """``(held, gain, model)``: the static forces at ``pose``, the discrete LQR gain on the
    step model of ``integrator`` and that model (``model.ad``, ``model.bd``)."""
    held = robot.static_forces(pose, bounded=False)
    model = robot.linearize(pose, np.zeros(6), held, dt=DT, integrator=integrator)
    ad, bd = model.ad, model.bd
    riccati = scipy.linalg.solve_discrete_are(ad, bd, Q_COST, R_COST)
    gain = np.linalg.solve(R_COST + bd.T @ riccati @ bd, bd.T @ riccati @ ad)
    return held, gain, model


def run(integrator: str) -> hp.Trajectory:
    """Design the discrete gain (and the continuous one, for comparison) on the step model
    of ``integrator``; simulate the discrete one from a displaced pose at rest."""
    robot = hp.Hexapod.default()
    pose = robot.home_pose + np.array([0.0, 0.0, 0.01, 0.0, 0.0, 0.0])
    held, gain, model = design(robot, pose, integrator)
    ad, bd = model.ad, model.bd
    continuous = scipy.linalg.solve_continuous_are(model.a, model.b, Q_COST, R_COST)
    gain_c = np.linalg.solve(R_COST, model.b.T @ continuous)
    print(f"{integrator} open-loop spectral radius {spectral_radius(ad):.6f}")
    print(f"{integrator} discrete-gain spectral radius {spectral_radius(ad - bd @ gain):.6f}")
    print(f"{integrator} continuous-gain spectral radius "
          f"{spectral_radius(ad - bd @ gain_c):.6f}")

    start = pose + START_OFFSET
    traj = hp.simulate(robot, DURATION, dt=DT, controller=LQRController(pose, held, gain),
                       integrator=integrator,
                       initial=(robot.configuration(start), np.zeros(robot.model.nv)))
    errors = np.array([np.linalg.norm(platform_error(pose, p)) for p in traj.poses])
    half = len(errors) // 2
    print(f"{integrator} status {traj.status}")
    print(f"{integrator} pose error start {errors[0]:.3e} half {errors[half]:.3e} "
          f"end {errors[-1]:.3e}")
    return traj


def main() -> None:
    for integrator in ("semi_implicit_euler", "rk4"):
        run(integrator)


if __name__ == "__main__":
    main()
