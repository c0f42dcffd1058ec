"""benchmarks/bench_derivatives.py runs (``--smoke``): the analytic forward-dynamics
derivatives agree with the script's central differences (it exits 1 otherwise), and the
inverse-dynamics and step-Jacobian table is printed."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_bench_derivatives_smoke():
    out = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_derivatives.py"),
                          "--smoke"], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stdout + out.stderr
    assert "FD miss" in out.stdout and "rk4 step Jacobians" in out.stdout
