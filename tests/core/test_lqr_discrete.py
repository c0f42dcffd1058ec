"""Discrete-time LQR on the step Jacobians (examples/hexapod_dlqr.py).

Independent routes: the closed loop's eigenvalues from ``numpy.linalg.eigvals`` of
``Ad - Bd K`` (inside the unit circle), the simulated nonlinear closed loop of
``hp.simulate`` (its pose error decays), and the same simulation against the linear
recursion ``x_{k+1} = (Ad - Bd K) x_k`` written here, step by step from the same start: the
two agree to second order in the start's size (the step Jacobians are the simulation's).
"""

from __future__ import annotations

import re
import runpy
from pathlib import Path

import numpy as np
import pytest

import hexapod_pin as hp
from hexapod_pin.core.controllers import platform_error

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "hexapod_dlqr.py"
NUMBER = r"([-+0-9.e]+)"
INTEGRATORS = ("semi_implicit_euler", "rk4")


@pytest.fixture(scope="module")
def example() -> dict:
    """The example's functions and constants (run as a module, not as a script)."""
    return runpy.run_path(str(EXAMPLE))


def test_the_example_stabilises_the_hexapod(capsys):
    """Per integrator: the open loop at the held forces is unstable (spectral radius > 1),
    the discrete gain's sampled closed loop is stable, the continuous gain's (same
    weights, 10 ms sampling) is not, and the simulated pose error falls by two orders."""
    runpy.run_path(str(EXAMPLE), run_name="__main__")
    out = capsys.readouterr().out
    for name in INTEGRATORS:
        def read(label, name=name):
            return float(re.search(f"{name} {label} spectral radius {NUMBER}", out).group(1))

        assert read("open-loop") > 1.0
        assert read("discrete-gain") < 1.0
        assert read("continuous-gain") > 1.0
        assert f"{name} status completed" in out
        start, half, end = (float(x) for x in re.search(
            f"{name} pose error start {NUMBER} half {NUMBER} end {NUMBER}", out).groups())
        assert end < 1e-2 * start and half < start


@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_simulation_follows_the_discrete_closed_loop(example, integrator):
    """The sampled states ``x_k = (-platform_error(pose_ref, pose_k), twist_k)`` of the
    nonlinear simulation under the discrete gain follow ``x_lin_k = (Ad - Bd K)^k x_0``:
    the largest gap, relative to the largest ``|x_lin|`` entry, is a few per cent from a
    1 mm / 3 mrad start and shrinks like the start (the gap like ``|x_0|^2``: the linear
    part is exact), and the pose error falls below a tenth in 30 steps."""
    robot = hp.Hexapod.default()
    pose = robot.home_pose + np.array([0.0, 0.0, 0.01, 0.0, 0.0, 0.0])
    held, gain, model = example["design"](robot, pose, integrator)
    closed = model.ad - model.bd @ gain
    assert np.max(np.abs(np.linalg.eigvals(closed))) < 1.0

    def gap(scale: float) -> float:
        start = pose + scale * example["START_OFFSET"]
        traj = hp.simulate(robot, 0.3, dt=example["DT"], integrator=integrator,
                           controller=example["LQRController"](pose, held, gain),
                           initial=(robot.configuration(start), np.zeros(robot.model.nv)))
        assert traj.status == "completed"
        xs = np.array([np.concatenate([-platform_error(pose, p), w])
                       for p, w in zip(traj.poses, traj.twists)])
        linear = [xs[0]]
        for _ in range(len(xs) - 1):
            linear.append(closed @ linear[-1])
        assert len(xs) == 31
        assert np.linalg.norm(xs[-1, :6]) < 0.1 * np.linalg.norm(xs[0, :6])
        return float(np.max(np.abs(xs - np.array(linear))) / np.max(np.abs(linear)))

    coarse, fine = gap(0.25), gap(0.0625)
    assert coarse < 0.1
    assert fine < 0.3 * coarse
