"""benchmarks/bench_robots.py runs (``--smoke``): every robot's forward(inverse(x)) = x."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_bench_robots_smoke():
    out = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_robots.py"),
                          "--smoke"], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stdout + out.stderr
    assert "Stewart 6-UPS" in out.stdout and "FD of ID" in out.stdout
