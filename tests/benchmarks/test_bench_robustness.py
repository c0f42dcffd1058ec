"""benchmarks/bench_robustness.py runs (``--smoke``, the test-data delta and five-bar): every
forward route answers and every assembly succeeds (the script exits 1 otherwise); timings
are printed, never asserted."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_bench_robustness_smoke():
    out = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_robustness.py"),
                          "--smoke"], cwd=ROOT, capture_output=True, text=True, timeout=600,
                         check=False)
    assert out.returncode == 0, out.stdout[-2000:] + out.stderr[-2000:]
    assert "| delta | FD qp | 0/2 |" in out.stdout
    assert "| five_bar_6d | 0.1 |" in out.stdout
