"""Benchmark of one MSWPF filter step (1000 particles, 3 sensors): the issue's 5 ms target on
CPU time (process_time is robust to other processes sharing the cores; wall time is not)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tools"))


@pytest.mark.slow
def test_filter_step_under_5_ms_cpu() -> None:
    from mswpf_bench import time_step

    r = time_step(repeat=100)
    assert r["step_cpu_median_ms"] < 5.0, r
