"""The training-throughput benchmark runs (a tiny batch): it is not a timed test, but a
benchmark that no longer runs would leave docs/training.md's figures without their command."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_the_training_benchmark_runs_every_row():
    out = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_training.py"),
                          "--repeats", "1", "--scenarios", "1", "--samples", "2"],
                         capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    for row in ("simulator + greedy", "ITA decoder, prior alone", "ITA decoder with the network",
                "ITA training step", "pi_C / pi_TR training step"):
        assert row in out.stdout, row
