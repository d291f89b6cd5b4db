"""benchmarks/bench_sim_speed.py: its missions in one process as trials run them, and its check
that every configuration ran the same missions."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_the_worker_runs_missions_one_after_another_with_and_without_the_camera_process():
    missions = [str(ROOT / "scenarios" / "seed-small-obstacles.toml")]
    got = {}
    for camera in ("on", "off"):
        out = subprocess.run(
            [sys.executable, str(ROOT / "benchmarks" / "bench_sim_speed.py"), "--_worker", camera, *missions],
            capture_output=True,
            text=True,
            check=True,
            cwd=ROOT,
        ).stdout
        rows = [json.loads(line) for line in out.splitlines()]
        assert [r["mission"] for r in rows] == missions  # the warm-up mission is not reported
        got[camera] = rows[0]
        assert got[camera]["outcome"] == "reached" and got[camera]["wall_s"] > 0
    assert got["on"]["mission_s"] == got["off"]["mission_s"]


def test_the_options_are_checked(benchmark_module):
    mod = benchmark_module("bench_sim_speed")
    with pytest.raises(SystemExit):
        mod.main(["--runs", "0"])
    with pytest.raises(SystemExit):
        mod.main(["--arenas", "201"])
