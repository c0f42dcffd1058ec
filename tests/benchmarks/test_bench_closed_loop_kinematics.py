"""benchmarks/bench_closed_loop_kinematics.py --smoke runs and its agreement checks pass
(velocity-map routes, IK targets reached, frozen dynamics = full KKT with the lock)."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_bench_closed_loop_kinematics_smoke():
    proc = subprocess.run([sys.executable, str(ROOT / "benchmarks" /
                                               "bench_closed_loop_kinematics.py"), "--smoke"],
                          cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "all checks passed" in proc.stdout
    for robot in ("five_bar_6d", "delta", "hexapod", "cassie"):
        assert robot in proc.stdout
