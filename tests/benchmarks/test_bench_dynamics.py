"""The dynamics benchmark runs in smoke mode (tiny counts) and its routes agree."""

import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "bench_dynamics.py"


def test_bench_dynamics_smoke():
    out = subprocess.run([sys.executable, str(SCRIPT), "--smoke"], capture_output=True,
                         text=True, timeout=300, check=False)
    assert out.returncode == 0, out.stdout + out.stderr
    for row in ("| FD routes, a |", "| batch (closed form) - single (tree) ID, tau |",
                "| pose-level ID - legacy route, tau |", "simulation step",
                "inverse_dynamics_batch, per state (N=10)"):
        assert row in out.stdout, row
