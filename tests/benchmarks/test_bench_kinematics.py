"""The kinematics benchmark runs in smoke mode (tiny counts) and its routes agree."""

import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "bench_kinematics.py"


def test_bench_kinematics_smoke():
    out = subprocess.run([sys.executable, str(SCRIPT), "--smoke"], capture_output=True,
                         check=False, text=True, timeout=300)
    assert out.returncode == 0, out.stdout + out.stderr
    assert "| jacobian_batch (IK + J) |" in out.stdout
    assert "routes agree" in out.stdout and "DISAGREEMENT" not in out.stdout
