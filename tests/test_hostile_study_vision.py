"""Hostile input to `rovernav pose`, `rovernav study` and `rovernav locate` .

Every bad flag, file or value gives one line naming it and exit status 2, quickly, never a
traceback, never unbounded work, never a wrong or half-written output file.
"""

from __future__ import annotations

import contextlib
import inspect
import io
import json
import math
import os
import struct
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rovernav import cli as rovernav_cli
from rovernav.errors import InputError
from rovernav.files import strict_json_value
from rovernav.study import pose as pose_mod
from rovernav.study.cli import MAX_RUNS, MAX_SEED, dumps
from rovernav.study.ekf import nees_monte_carlo
from rovernav.validate import MAX_ARENA_M, MAX_SIM_STEPS
from rovernav.vision.cli import MAX_IMAGE_PIXELS, MIN_IMAGE_SIDE_PX


@pytest.fixture
def no_work(monkeypatch):
    """A refusal must come before any work: running the pose law or decoding an image fails the test."""

    def worked(*args, **kwargs):
        raise AssertionError("the command started its work before refusing the input")

    monkeypatch.setattr(pose_mod, "simulate_pose", worked)
    monkeypatch.setattr(cv2, "imread", worked)


def run(argv: list[str]) -> tuple[int, str, str]:
    """`rovernav ARGV` in-process: (exit status, stdout, stderr)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = rovernav_cli.main(argv)
        except SystemExit as exc:  # argparse
            code = exc.code if isinstance(exc.code, int) else 2
    return code, out.getvalue(), err.getvalue()


def assert_refused(result: tuple[int, str, str], *words: str) -> str:
    """Exit 2, nothing on stdout, one line on stderr naming each of `words`; returns the line."""
    code, out, err = result
    assert code == 2, (code, out, err)
    assert "Traceback" not in err and "internal error" not in err, err
    assert out == "", out
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    for w in words:
        assert w in lines[0], (w, lines[0])
    return lines[0]


def strict_json(text: str):
    """json.loads that refuses NaN and Infinity."""

    def no(constant):
        raise AssertionError(f"not strict JSON: {constant}")

    return json.loads(text, parse_constant=no)


# --- pose -------------------------------------------------------------------------------------


@pytest.mark.parametrize("dt", ["0.001", "0.01"])
def test_pose_small_dt_over_the_report_route_is_refused_before_any_work(dt, no_work):
    line = assert_refused(run(["pose", "--dt", dt]), f"--dt {dt}", f"{MAX_SIM_STEPS:,}", "steps")
    assert "a --dt of at least 0.149 s" in line


def test_pose_dt_of_1e_9_is_out_of_the_flags_limits():
    line = assert_refused(run(["pose", "--dt", "1e-9"]), "--dt", "1e-9", "0.001", "<= 1")
    assert line.startswith("rovernav pose: error: argument --dt:")


@pytest.mark.parametrize(
    "flag, values, bad",
    [
        ("--from", ["nan", "0", "0"], "nan"),
        ("--from", ["1e30", "0", "0"], "1e30"),
        ("--from", ["0", "-inf", "0"], "expected 3 arguments"),  # argparse takes -inf for an option
        ("--to", ["nan", "0", "0"], "nan"),
        ("--to", ["0", "1e30", "0"], "1e30"),
        ("--to", ["0", "0", "inf"], "inf"),
        ("--gains", ["nan", "1", "1"], "nan"),
        ("--gains", ["0.1", "1e300", "-0.2"], "1e300"),
        ("--vmax", ["nan"], "nan"),
        ("--vmax", ["inf"], "inf"),
        ("--vmax", ["0"], "'0'"),
        ("--vmax", ["-1"], "'-1'"),
        ("--vmax", ["abc"], "abc"),
    ],
)
def test_pose_non_finite_or_out_of_range_numbers_are_refused_naming_the_flag(flag, values, bad, no_work):
    assert_refused(run(["pose", flag, *values]), f"argument {flag}", bad)


def test_pose_theta_in_degrees_is_refused():
    assert_refused(run(["pose", "--to", "0", "0", "90"]), "--to", "THETA 90", "radians")


@pytest.mark.parametrize(
    "args, words",
    [
        (["--vmax", "1e-6"], ["--vmax 1e-06", "limit"]),
        (["--gains", "1e-9", "1", "-1"], ["K_rho 1e-09", "limit"]),
    ],
)
def test_pose_a_run_that_cannot_end_within_the_limits_is_refused_before_it_starts(args, words, no_work):
    assert_refused(run(["pose", *args]), *words)


def test_pose_unstable_gains_name_the_flag_and_the_condition():
    assert_refused(run(["pose", "--gains", "0.1", "0.05", "-0.19"]), "--gains 0.1 0.05 -0.19", "K_alpha - K_rho > 0")


@pytest.mark.parametrize("make", [lambda d: str(d) + "/", lambda d: str(d), lambda d: str(d / "sub") + os.sep])
def test_pose_plot_into_a_folder_is_refused_and_writes_nothing(tmp_path, make):
    (tmp_path / "sub").mkdir()
    line = assert_refused(run(["pose", "--plot", make(tmp_path)]), "--plot", "not a folder")
    assert str(tmp_path) in line
    assert not (tmp_path / ".png").exists() and not (tmp_path / "sub" / ".png").exists()


@pytest.mark.parametrize(
    "name, words", [("picture.jpg", [".png"]), ("missing/p.png", ["no folder"]), ("9" * 400 + ".png", ["too long"])]
)
def test_pose_plot_needs_a_png_name_in_an_existing_folder(tmp_path, name, words):
    assert_refused(run(["pose", "--plot", str(tmp_path / name)]), "--plot", *words)


def test_pose_a_legal_small_dt_finishes_quickly_with_strict_json_and_a_whole_plot(tmp_path):
    png = tmp_path / "p.png"
    code, out, err = run(
        [
            "pose",
            "--from",
            "0",
            "0",
            "0",
            "--to",
            "3",
            "0",
            "0",
            "--gains",
            "0.5",
            "1.5",
            "-0.3",
            "--vmax",
            "1",
            "--dt",
            "0.001",
            "--json",
            "--plot",
            str(png),
        ]
    )
    assert code == 0, err
    data = strict_json(out)
    assert data["converged"] and abs(data["final_error"][0]) < 0.1
    assert png.stat().st_size > 10_000
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p.png"]  # no temporary left behind


def test_simulate_pose_caps_its_steps_and_refuses_non_finite_poses():
    run_ = pose_mod.simulate_pose((0.0, 0.0, 0.0), (1000.0, 0.0, 0.0), vmax=0.01, dt=0.001, max_steps=5_000)
    assert len(run_.t) == 5_001 and not run_.converged
    assert inspect.signature(pose_mod.simulate_pose).parameters["max_steps"].default == MAX_SIM_STEPS
    for bad in [(math.nan, 0.0, 0.0), (0.0, math.inf, 0.0)]:
        with pytest.raises(ValueError, match="finite"):
            pose_mod.simulate_pose(bad, (1.0, 0.0, 0.0))


def test_min_time_is_a_lower_bound_of_the_simulated_time():
    gains = pose_mod.PoseGains(0.3, 0.8, -0.15)
    for start, goal, vmax, dt in [
        ((0, 0, 0), (3, 0, 0), 1.0, 0.05),
        ((0, 0, 0), (3, 0, 0), 1.0, 1.0),
        ((0, 0, 0), (3, 0, 0), 10.0, 0.001),
        ((0, 0, 0), (20, 10, 1.0), 0.5, 0.05),
        ((0, 0, 0), (1000, 0, 0), 0.5, 1.0),
        (pose_mod.REPORT_P0, pose_mod.REPORT_P1, 0.04, 1.0),
    ]:
        r = pose_mod.simulate_pose(start, goal, gains, vmax=vmax, dt=dt)
        bound = pose_mod.min_time_s(start, goal, gains.k_rho, vmax, dt)
        assert r.converged and bound <= r.time_s, (start, goal, vmax, dt, bound, r.time_s)
        assert bound > 0.5 * r.time_s, (start, goal, vmax, dt, bound, r.time_s)  # and not a useless bound
    # A goal already within the arrival tolerance (0.1 m): no step is taken, and the bound says so.
    r = pose_mod.simulate_pose((0, 0, 0), (0.05, 0, 0), gains, vmax=1.0, dt=0.05)
    assert r.converged and len(r.t) == 1
    assert r.time_s == 0.0 and pose_mod.min_time_s((0, 0, 0), (0.05, 0, 0), gains.k_rho, 1.0, 0.05) == 0.0


def test_json_output_has_no_nan_or_infinity():
    value = {"a": math.nan, "b": [math.inf, -math.inf, 1.5, np.float64("nan")], "c": np.array([1.0, np.nan])}
    assert strict_json_value(value) == {"a": None, "b": [None, None, 1.5, None], "c": [1.0, None]}
    assert strict_json(dumps(value))["a"] is None


# --- study ------------------------------------------------------------------------------------


@pytest.mark.parametrize("value", ["0", "-3", str(10**12), str(MAX_RUNS + 1), "nan", "1.5", "", "1e3"])
def test_study_runs_must_be_a_whole_number_within_its_limits(value, tmp_path):
    assert_refused(run(["study", "--out", str(tmp_path / "o"), "--runs", value]), "--runs", repr(value))
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("value", ["-1", str(MAX_SEED + 1), "inf", "x"])
def test_study_seed_must_be_a_whole_number_within_its_limits(value, tmp_path):
    assert_refused(run(["study", "--out", str(tmp_path / "o"), "--seed", value]), "--seed", repr(value))


def test_study_out_naming_an_existing_file_is_refused(tmp_path):
    f = tmp_path / "summary.txt"
    f.write_text("keep me")
    assert_refused(run(["study", "--out", str(f)]), "--out", str(f), "not a folder")
    assert f.read_text() == "keep me"


def test_study_library_refuses_bad_runs_and_seeds(tmp_path):
    from rovernav.study.cli import study

    for kwargs in ({"runs": 0}, {"runs": -3}, {"runs": 10**9}, {"seed": -1}, {"runs": 2.5}):
        with pytest.raises(InputError):
            study(tmp_path / "o", **kwargs)
    with pytest.raises(ValueError, match="n_runs"):
        nees_monte_carlo(0)
    with pytest.raises(ValueError, match="n_runs"):
        nees_monte_carlo(-3)


def test_study_writes_nothing_when_a_task_fails(tmp_path, monkeypatch):
    from rovernav.planning import NoPathError
    from rovernav.study import crater

    def no_path(*args, **kwargs):
        raise NoPathError("walled off")

    monkeypatch.setattr(crater, "crater_map", lambda *a, **k: None)  # the map is not needed here
    monkeypatch.setattr(crater, "plan_on_map", no_path)
    out = tmp_path / "o"
    assert_refused(run(["study", "--out", str(out), "--runs", "1"]), "no path", "--seed 0")
    assert not out.exists()


# --- locate -----------------------------------------------------------------------------------


@pytest.fixture
def frame_png(tmp_path) -> Path:
    path = tmp_path / "frame.png"
    cv2.imwrite(str(path), np.zeros((48, 64, 3), np.uint8))
    return path


@pytest.mark.parametrize("shape", [(1, 1, 3), (MIN_IMAGE_SIDE_PX - 1, 200, 3), (200, 5, 3)])
def test_locate_refuses_an_image_too_small_to_search(tmp_path, shape):
    path = tmp_path / "tiny.png"
    cv2.imwrite(str(path), np.zeros(shape, np.uint8))
    assert_refused(run(["locate", str(path)]), str(path), f"{shape[1]} x {shape[0]} pixels", "too small")


def test_locate_refuses_an_image_whose_header_claims_too_many_pixels_without_decoding_it(tmp_path, no_work):
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    for w, h in [(100_000, 100_000), (6000, 5000)]:
        path = tmp_path / f"bomb{w}.png"
        path.write_bytes(
            b"\x89PNG\r\n\x1a\n"
            + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(b"\0" * 100))
            + chunk(b"IEND", b"")
        )
        assert_refused(run(["locate", str(path)]), str(path), f"{MAX_IMAGE_PIXELS / 1e6:g} megapixels")


@pytest.mark.parametrize(
    "make, words",
    [
        (lambda p: p.mkdir(), ["is a folder"]),
        (lambda p: p.write_text("hello, not a picture"), ["not an image OpenCV can decode"]),
        (lambda p: p.write_bytes(np.random.default_rng(0).bytes(20_000)), ["not an image OpenCV can decode"]),
        (lambda p: p.write_bytes(b""), ["not an image OpenCV can decode"]),
        (lambda p: None, ["no such file"]),
    ],
)
def test_locate_refuses_what_is_not_an_image(tmp_path, make, words):
    path = tmp_path / "frame.png"
    make(path)
    assert_refused(run(["locate", str(path)]), str(path), *words)


def test_locate_refuses_a_device_as_an_image():
    if not Path("/dev/zero").exists():
        pytest.skip("no /dev/zero")
    assert_refused(run(["locate", "/dev/zero"]), "/dev/zero", "not a regular file")


@pytest.mark.parametrize("size", [["nan", "2"], ["0", "2"], ["-1", "2"], ["1e9", "2"], ["2", "inf"], ["2", ""]])
def test_locate_arena_size_must_be_finite_positive_and_at_most_the_largest_arena(frame_png, size):
    bad = size[0] if size[1] == "2" else size[1]
    assert_refused(run(["locate", str(frame_png), "--arena-size", *size]), "--arena-size", repr(bad))


@pytest.mark.parametrize(
    "make, words",
    [
        (lambda p: p.mkdir(), ["folder"]),
        (lambda p: p.write_bytes(b"[arena]\nwidth_m = 2.0\n# \xff\xfe\n"), ["UTF-8"]),
        (lambda p: p.write_text("[arena]\nwidth_m = inf\n"), ["width_m"]),
        (lambda p: p.write_text("[arena]\nwidth_m = 1e9\n"), ["width_m"]),
        (lambda p: p.write_text("[arena]\nwidth_m = nan\n"), ["width_m"]),
        (lambda p: p.write_text("not = [toml"), ["TOML"]),
    ],
)
def test_locate_refuses_a_config_it_cannot_use_naming_it(frame_png, tmp_path, make, words):
    config = tmp_path / "rovernav.toml"
    make(config)
    assert_refused(run(["locate", str(frame_png), "--config", str(config)]), str(config), *words)


def test_locate_json_is_strict(frame_png):
    code, out, err = run(["locate", str(frame_png), "--json"])
    assert code == 1, err
    data = strict_json(out)
    assert data["rover"] is None and data["reason"]


def test_the_real_command_exits_2_with_one_line_and_no_traceback(rovernav_command, repo_root, tmp_path):
    """Two runs through `python -m rovernav.cli`, as a user types them."""
    tiny = tmp_path / "tiny.png"
    cv2.imwrite(str(tiny), np.zeros((1, 1, 3), np.uint8))
    for argv, words in [(["pose", "--dt", "0.001"], ["--dt 0.001"]), (["locate", str(tiny)], [str(tiny), "too small"])]:
        proc = rovernav_command(*argv, cwd=repo_root)
        assert_refused((proc.returncode, proc.stdout, proc.stderr), *words)


# --- help: units and limits of every numeric flag ---------------------------------------------


@pytest.mark.parametrize(
    "command, expected",
    [
        (
            "pose",
            [
                "--from",
                "metres within +-100,000",
                "radians within +-10",
                "--gains",
                "1/s, each within +-10",
                "--vmax",
                "m/s, > 0 and <= 10",
                "--dt",
                "seconds, 0.001 to 1",
                "2,000,000",
                "exit status",
            ],
        ),
        ("study", ["--seed", "integer 0 to 4294967295", "--runs", "integer 1 to 200", "exit status"]),
        (
            "locate",
            ["--arena-size", "metres, each > 0 and <= 100", "at least 32 x 32 pixels", "25 megapixels", "exit status"],
        ),
    ],
)
def test_help_states_the_units_and_limits_of_each_numeric_flag(command, expected):
    code, out, _ = run([command, "--help"])
    assert code == 0
    flat = " ".join(out.split())
    for text in expected:
        assert text in flat, text


# --- every numeric flag against hostile strings ------------------------------------------------

# (command, flag, number of values, index of the value under test, lo, hi, lo_open, integer)
NUMERIC_FLAGS = [
    ("pose", "--from", 3, 0, -1e5, 1e5, False, False),
    ("pose", "--from", 3, 1, -1e5, 1e5, False, False),
    ("pose", "--from", 3, 2, -10.0, 10.0, False, False),
    ("pose", "--to", 3, 0, -1e5, 1e5, False, False),
    ("pose", "--to", 3, 1, -1e5, 1e5, False, False),
    ("pose", "--to", 3, 2, -10.0, 10.0, False, False),
    ("pose", "--gains", 3, 0, -10.0, 10.0, False, False),
    ("pose", "--gains", 3, 1, -10.0, 10.0, False, False),
    ("pose", "--gains", 3, 2, -10.0, 10.0, False, False),
    ("pose", "--vmax", 1, 0, 0.0, 10.0, True, False),
    ("pose", "--dt", 1, 0, 1e-3, 1.0, False, False),
    ("study", "--seed", 1, 0, 0, MAX_SEED, False, True),
    ("study", "--runs", 1, 0, 1, MAX_RUNS, False, True),
    ("locate", "--arena-size", 2, 0, 0.0, MAX_ARENA_M, True, False),
    ("locate", "--arena-size", 2, 1, 0.0, MAX_ARENA_M, True, False),
]
HOSTILE = [
    "nan",
    "NaN",
    "inf",
    "-inf",
    "Infinity",
    "0",
    "-0",
    "-1",
    "1e308",
    "-1e308",
    "1e309",
    "",
    " ",
    "abc",
    "1e-300",
    "0x10",
    "1_000",
    "9" * 400,
    "--help",
    "-h",
    "1,5",
    "\x00",
    "١",
]
hostile = st.one_of(st.sampled_from(HOSTILE), st.floats().map(repr), st.integers().map(str), st.text(max_size=8))
PARSER = rovernav_cli.build_parser()


@pytest.mark.parametrize("spec", NUMERIC_FLAGS, ids=lambda s: f"{s[0]}{s[1]}[{s[3]}]")
@settings(max_examples=80, deadline=None)
@given(text=hostile)
def test_a_numeric_flag_parses_to_a_finite_value_within_its_limits_or_exits_2(spec, text):
    command, flag, n, i, lo, hi, lo_open, integer = spec
    values = ["1"] * n
    values[i] = text
    argv = [command, *(["frame.png"] if command == "locate" else []), flag, *values]
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            args = PARSER.parse_args(argv)
        except SystemExit as exc:
            assert exc.code == 2, (argv, exc.code)
            assert len(err.getvalue().strip().splitlines()) == 1 and "Traceback" not in err.getvalue()
            return
    dest = {"--from": "start", "--to": "goal", "--arena-size": "arena_size"}.get(flag, flag.lstrip("-"))
    got = getattr(args, dest)
    value = got[i] if n > 1 else got
    assert isinstance(value, int if integer else float) and not isinstance(value, bool)
    assert math.isfinite(value), (argv, value)
    assert (value > lo if lo_open else value >= lo) and value <= hi, (argv, value)
