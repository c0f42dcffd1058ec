"""benchmarks/bench_effects.py runs (``--smoke``): forward(inverse(a)) = a with every effect."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_bench_effects_smoke():
    out = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_effects.py"),
                          "--smoke"], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stdout + out.stderr
    assert "stick/slip QP" in out.stdout and "FD of ID" in out.stdout
