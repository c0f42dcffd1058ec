"""benchmarks/bench_generic.py runs (``--smoke``) and every route agrees with its null-space
reference (the script exits 1 otherwise); timings are printed, never asserted."""

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.skipif(importlib.util.find_spec("mujoco") is None, reason="mujoco not installed")
def test_bench_generic_smoke():
    out = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_generic.py"),
                          "--smoke"], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stdout[-2000:] + out.stderr[-2000:]
    assert "| five_bar_6d | 5 | 6/3 | FD pinocchio |" in out.stdout
    assert "mj_step" in out.stdout
    # a robot with drive effects: every route against the reference with the effects
    # written in the benchmark, and MuJoCo's export carrying them (mass matrix, passive)
    assert "| five_bar_6d+drives | 5 | 6/3 | FD pinocchio |" in out.stdout
    assert "| five_bar_6d+drives | armature, damping, springs |" in out.stdout
