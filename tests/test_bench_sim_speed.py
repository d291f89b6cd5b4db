"""benchmarks/bench_sim_speed.py: its missions in one process as trials run them, and its check
that every configuration ran the same missions."""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _module():
    spec = importlib.util.spec_from_file_location("bench_sim_speed", ROOT / "benchmarks" / "bench_sim_speed.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


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


def test_the_options_are_checked():
    mod = _module()
    with pytest.raises(SystemExit):
        mod.main(["--runs", "0"])
    with pytest.raises(SystemExit):
        mod.main(["--arenas", "201"])
