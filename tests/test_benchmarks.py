"""Every benchmark runs, in a smoke mode of seconds: a renamed parameter or variable breaks this test, not a
user (the figures they print are measured by hand on a named machine: docs/native.md, docs/batch.md).

A benchmark added to benchmarks/ without a smoke mode here fails ``test_every_benchmark_has_a_smoke_mode``.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

# benchmark -> its arguments for a run of seconds ({ssp}: the test's built MAST.ssp)
SMOKE = {
    "variable_step.py": ["--steps", "40", "--repeats", "1"],
    "dk_step.py": ["--steps", "20", "--repeat", "1"],
    "batch_throughput.py": ["--ssp", "{ssp}", "--cases", "2", "--stop-time", "0.02", "--repeats", "1"],
    "native_speed.py": [
        "--ssp",
        "{ssp}",
        "--stop-time",
        "0.02",
        "--repeats",
        "1",
        "--mechanisms",
        "--mechanism-steps",
        "5",
    ],
    "animate_page.py": ["--ssp", "{ssp}", "--stop-time", "0.2", "--repeat", "1"],
    "backlash_regimes.py": ["--ssp", "{ssp}", "--runs", "1", "--duration", "0.3", "--settle", "0.1"],
}


def test_every_benchmark_has_a_smoke_mode():
    scripts = sorted(p.name for p in (ROOT / "benchmarks").glob("*.py"))
    assert sorted(SMOKE) == scripts, (
        f"tests/test_benchmarks.py SMOKE must name every benchmarks/*.py with short arguments: has {sorted(SMOKE)}"
    )


@pytest.mark.parametrize("script", sorted(SMOKE))
def test_benchmark_runs_in_smoke_mode(script, built_native):
    args = [a.format(ssp=built_native / "ssp" / "MAST.ssp") for a in SMOKE[script]]
    env = {**os.environ, "MAST_BUILD": str(built_native), "PYTHONPATH": str(ROOT)}
    proc = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / script), *args],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert proc.returncode == 0, f"benchmarks/{script} {' '.join(args)}:\n{proc.stdout[-2000:]}\n{proc.stderr[-3000:]}"
    assert proc.stdout.strip(), f"benchmarks/{script} printed no figure"


def test_make_bench_batch_runs_the_benchmark_that_is_smoke_tested():
    """`make bench-batch` (README, docs/batch.md) is benchmarks/batch_throughput.py: the test above runs it."""
    makefile = (ROOT / "Makefile").read_text()
    assert "bench-batch:" in makefile and "benchmarks/batch_throughput.py" in makefile.split("bench-batch:")[1]
