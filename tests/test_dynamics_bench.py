"""The dynamics benchmark runs in smoke mode (tiny counts) and its routes agree."""

import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[1] / "benchmarks" / "bench_dynamics.py"


def test_bench_dynamics_smoke():
    out = subprocess.run([sys.executable, str(SCRIPT), "--smoke"], capture_output=True,
                         text=True, timeout=300, check=False)
    assert out.returncode == 0, out.stdout + out.stderr
    assert "| FD routes, a |" in out.stdout and "simulation step" in out.stdout
