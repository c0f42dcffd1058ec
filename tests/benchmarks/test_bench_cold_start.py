"""benchmarks/bench_cold_start.py --smoke runs every first-call case (on the current cache,
not cold) and prints its table."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_bench_cold_start_smoke():
    proc = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_cold_start.py"),
                           "--smoke"], cwd=ROOT, capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "all cases ran" in proc.stdout
    for case in ("inverse_dynamics", "simulate_fast", "time_optimal", "hp.warmup()"):
        assert case in proc.stdout
