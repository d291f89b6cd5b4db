"""`rovernav plan`: JSON and exit 0 when a path is found, exit 1 with the reason when none is,
exit 2 on a bad scenario or flag, waypoints printed and a picture drawn.
(Split from test_planning.py.)"""

from __future__ import annotations

import json
import math

import cv2

from rovernav.planning.cli import add_plan_parser
from rovernav.validate import ArgParser

# --- the command ------------------------------------------------------------------------------------


def run_cli(argv, capsys):
    parser = ArgParser(prog="rovernav")
    add_plan_parser(parser.add_subparsers(dest="command", parser_class=ArgParser))
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # a flag refused: one line on stderr, status 2
        out, err = capsys.readouterr()
        return exc.code, out, err
    code = args.func(args)
    out, err = capsys.readouterr()
    return code, out, err


def test_plan_prints_json_and_exits_0_when_a_path_is_found(capsys):
    code, out, err = run_cli(["plan", "seed-small-obstacles", "--json"], capsys)
    assert code == 0 and err == ""
    doc = json.loads(out)
    assert set(doc) == {"found", "waypoints", "length_m", "time_ms", "planner", "reason"}
    assert doc["found"] is True and doc["planner"] == "astar" and doc["reason"] is None
    assert doc["waypoints"][0] == [0.3, 0.3] and doc["waypoints"][-1] == [2.0, 1.4]
    assert doc["length_m"] > math.dist((0.3, 0.3), (2.0, 1.4))
    assert isinstance(doc["time_ms"], float) and math.isfinite(doc["time_ms"])


def test_plan_exits_1_with_the_reason_when_there_is_no_path(capsys):
    code, out, err = run_cli(["plan", "seed-large-obstacles", "--planner", "potential", "--json"], capsys)
    doc = json.loads(out)
    assert code == 1 and doc["found"] is False and doc["waypoints"] == [] and doc["length_m"] is None
    assert doc["reason"].startswith("trapped in a local minimum at")
    assert doc["reason"] in err


def test_plan_exits_2_on_a_bad_scenario_file(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text("version = 1\n[arena]\nwidth_m = -1\n")
    code, out, err = run_cli(["plan", str(bad)], capsys)
    assert code == 2 and out == ""
    assert f"{bad}: arena.width_m must be a number > 0" in err
    code, _, err = run_cli(["plan", "no-such-scenario"], capsys)
    assert code == 2 and "no scenario named 'no-such-scenario'" in err
    code, _, err = run_cli(["plan", "seed-small-obstacles", "--resolution", "0"], capsys)
    assert code == 2 and "argument --resolution: '0': must be a number >= 0.001 and <= 1" in err


def test_plan_prints_waypoints_and_draws_a_picture(tmp_path, capsys):
    picture = tmp_path / "plan.png"
    code, out, _ = run_cli(
        ["plan", "out-and-back", "--all-obstacles", "--resolution", "0.05", "--plot", str(picture)], capsys
    )
    assert code == 0
    assert "A* found a path of" in out and "48 × 35 cells of 0.05 m" in out and "all obstacles" in out
    assert "x  0.300 m  y  0.300 m" in out and "x  2.000 m  y  1.400 m" in out
    image = cv2.imread(str(picture))
    assert image is not None and image.shape[1] >= 700 and image.shape[0] > image.shape[1] / 2
