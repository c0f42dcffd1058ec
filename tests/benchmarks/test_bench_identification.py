"""benchmarks/bench_identification.py --smoke runs: the estimates are within 5 standard
errors of the truth and the residuals drop (it exits 1 otherwise), for both robots."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_bench_identification_smoke():
    proc = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_identification.py"),
                           "--smoke"], cwd=ROOT, capture_output=True, text=True, timeout=600,
                          check=False)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "all checks passed" in proc.stdout
    for robot in ("### hexapod", "### planar"):
        assert robot in proc.stdout
