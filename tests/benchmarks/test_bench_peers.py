"""The peer benchmarks (benchmarks/bench_peers.py, bench_scaling.py) run and agree.

The scripts run in a subprocess with ``--smoke``: tiny N, every pair of routes that
computes the same rigid physics must agree to 1e-8 (the script exits 1 otherwise);
timings are printed, never asserted. The plain-numpy peer is also checked directly
against the independent reference states.
"""

import importlib.util
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import geometry_from_reference, import_benchmarks, load_reference

ROOT = Path(__file__).resolve().parents[2]
BENCH = ROOT / "benchmarks"
HAVE_MUJOCO = importlib.util.find_spec("mujoco") is not None


def run_smoke(script: str, *extra: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(BENCH / script), "--smoke", *extra], cwd=ROOT,
                          capture_output=True, text=True, timeout=300)


@pytest.fixture(scope="module")
def peers_output():
    proc = run_smoke("bench_peers.py")
    assert proc.returncode == 0, f"bench_peers.py --smoke failed:\n{proc.stdout}\n{proc.stderr}"
    return proc.stdout


@pytest.fixture(scope="module")
def numpy_peer():
    return import_benchmarks("numpy_hexapod")[0]


@pytest.mark.parametrize("entry", load_reference()["hexapod"], ids=lambda e: e["name"])
def test_numpy_peer_matches_reference_states(numpy_peer, entry):
    nh = numpy_peer
    p = nh.params_from_geometry(geometry_from_reference(entry))
    pose, twist, twist_dot, wrench = (np.array(entry[k])[None] for k in
                                      ("pose", "twist", "twist_dot", "wrench"))
    scale = lambda ref: 1e-9 * max(1.0, np.max(np.abs(ref)))  # noqa: E731
    checks = {
        "q": nh.inverse_kinematics(p, pose)[0],
        "jacobian": nh.jacobian(p, pose)[0],
        "actuator_forces": nh.inverse_dynamics(p, pose, twist, twist_dot, wrench)[0],
        "static_forces": nh.static_forces(p, pose, wrench)[0],
    }
    for key, value in checks.items():
        ref = np.array(entry[key])
        assert np.max(np.abs(value - ref)) <= scale(ref), key
    tau = np.array(entry["actuator_forces"])[None]
    twist_dot_fd, qddot_fd = nh.forward_dynamics(p, pose, twist, tau, wrench)
    assert np.max(np.abs(twist_dot_fd - twist_dot)) <= scale(twist_dot)
    assert np.max(np.abs(qddot_fd[0] - entry["qddot"])) <= scale(np.array(entry["qddot"]))


def test_bench_peers_smoke(peers_output):
    assert "all routes agree" in peers_output
    for section in ("inverse kinematics", "Jacobian", "forward kinematics", "inverse dynamics",
                    "forward dynamics", "statics", "simulation step"):
        assert f"### {section}" in peers_output


def test_bench_peers_smoke_detects_a_wrong_model():
    """The agreement check can fail: a numpy peer with a 1e-6 heavier platform is caught."""
    proc = run_smoke("bench_peers.py", "--no-timing", "--perturb-numpy-mass", "1e-6")
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert "DISAGREEMENT" in proc.stdout and "numpy Newton-Euler" in proc.stdout


def test_bench_scaling_smoke():
    proc = run_smoke("bench_scaling.py")
    assert proc.returncode == 0, f"bench_scaling.py --smoke failed:\n{proc.stdout}\n{proc.stderr}"
    assert "all routes agree" in proc.stdout
    assert "ladder n=3" in proc.stdout


@pytest.mark.skipif(not HAVE_MUJOCO, reason="mujoco not installed (pip install mujoco): "
                                            "the smoke runs skip the MuJoCo peer")
def test_mujoco_peer_is_compared(peers_output):
    out = peers_output
    assert "MJCF vs our Pinocchio model" in out
    assert "MuJoCo mj_inverse + reduction" in out
    assert "MuJoCo + proximal refinement (rigid, tree state given)" in out
