"""Every bad input gets a clear one-line answer, and no run leaves wrong or half-written files.

- Every flag of every subcommand, fed hostile strings (NaN, infinities, 0, negatives, huge, empty,
  not a number): the parser refuses with status 2 and one line naming the flag, or gives a finite
  value (hypothesis, in-process: fast).
- Every key of a scenario and of a configuration file, given hostile values: a ScenarioError or
  ConfigError naming the file and the key, never another exception (hypothesis).
- Bad input to each command, end to end through `python -m rovernav.cli` under a 3 GB memory
  limit: status 2, one line, no traceback.
- Strict JSON in report.json when a value is undefined; a run cut short leaves a report saying
  so and none of the previous run's files.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rovernav.cli import build_parser
from rovernav.config import ConfigError, config_from_dict
from rovernav.scenario import ScenarioError, parse_scenario

HOSTILE = [
    "nan",
    "NaN",
    "inf",
    "-inf",
    "infinity",
    "0",
    "-0",
    "-1",
    "-1e308",
    "1e308",
    "1e999",
    "",
    " ",
    "abc",
    "1e-300",
    "0x10",
    "1_000",
    "--",
    "9" * 400,
    "\x00",
    "1:2:3",
    "nan:nan",
    "-5:10",
    "5:-1",
    "1:inf",
]


def _subparsers() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


def _typed_options(p: argparse.ArgumentParser):
    """(subcommand parser, the option's flag, its action) for every option that takes a value."""
    for a in p._actions:
        if a.option_strings and a.nargs != 0 and not isinstance(a, (argparse._HelpAction, argparse._VersionAction)):
            yield a.option_strings[-1], a


def _finite(value) -> bool:
    if isinstance(value, (list, tuple)):
        return all(_finite(v) for v in value)
    if isinstance(value, float):
        return math.isfinite(value)
    return True


ALL_OPTIONS = [(cmd, flag, action) for cmd, p in sorted(_subparsers().items()) for flag, action in _typed_options(p)]


def test_no_numeric_flag_takes_a_bare_float_or_int():
    # float("nan") and int("10**400" digits) parse: every numeric flag goes through rovernav.validate
    bare = [f"{cmd} {flag}" for cmd, flag, a in ALL_OPTIONS if a.type in (float, int)]
    assert not bare, f"flags without limits: {bare}"


def _parse(cmd: str, flag: str, action, value: str, capsys):
    """Parse `rovernav CMD FLAG VALUE` (plus what the command needs); (exit code or None, namespace, stderr)."""
    argv = [cmd]
    if cmd == "trials":
        argv.append("somewhere")
    if cmd == "locate":
        argv.append("image.png")
    if cmd == "plan":
        argv.append("seed-small-obstacles")
    if cmd == "replay":
        argv.append(__file__)  # a file that exists (the log's checks come after parsing)
    if cmd in ("link-check", "provision") and flag != "--port":
        argv += ["--port", "loop://"]
    if cmd == "provision" and flag not in ("--key-file", "--erase"):
        argv.append("--erase")
    nargs = action.nargs if isinstance(action.nargs, int) else 1
    argv += [flag] + [value] * nargs
    try:
        ns = build_parser().parse_args(argv)
    except SystemExit as exc:
        return exc.code, None, capsys.readouterr().err
    return None, ns, capsys.readouterr().err


@pytest.mark.parametrize("cmd, flag, action", ALL_OPTIONS, ids=[f"{c} {f}" for c, f, _ in ALL_OPTIONS])
@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    value=st.one_of(
        st.sampled_from(HOSTILE), st.floats().map(repr), st.integers(-(10**30), 10**30).map(str), st.text(max_size=12)
    )
)
def test_every_flag_refuses_hostile_values_in_one_line_or_gives_a_finite_value(cmd, flag, action, value, capsys):
    code, ns, err = _parse(cmd, flag, action, value, capsys)
    if code is not None:
        assert code == 2
        lines = [line for line in err.splitlines() if line.strip()]
        assert len(lines) == 1 and flag in lines[0] and "Traceback" not in err, err
        return
    got = getattr(ns, action.dest)
    assert _finite(got), f"{cmd} {flag} {value!r} gave {got!r}"
    if isinstance(got, (int, float)) and not isinstance(got, bool) and action.type not in (None, str):
        assert abs(got) < 1e12, f"{cmd} {flag} {value!r} gave {got!r}: unbounded"


# ---------------------------------------------------------------- files: scenario and configuration keys

GOOD_SCENARIO = {
    "name": "t",
    "version": 1,
    "arena": {"width_m": 2.0, "height_m": 1.5},
    "start": {"x_m": 0.3, "y_m": 0.3, "heading_deg": 0.0},
    "target": {"x_m": 1.7, "y_m": 1.2},
    "mission": {"kind": "reach", "trips": 1},
    "obstacles": [{"x_m": 1.0, "y_m": 0.7, "w_m": 0.2, "h_m": 0.1, "known": True}],
    "walls": [{"x0_m": 0.2, "y0_m": 1.0, "x1_m": 0.8, "y1_m": 1.0, "thickness_m": 0.05}],
    "posts": [{"x_m": 1.5, "y_m": 0.4, "radius_m": 0.05}],
}
SCENARIO_KEYS = [
    (t, i, k)
    for t, v in GOOD_SCENARIO.items()
    if isinstance(v, (dict, list))
    for i, table in enumerate(v if isinstance(v, list) else [v])
    for k in table
] + [(None, None, "name"), (None, None, "version")]
HOSTILE_VALUES = st.one_of(
    st.sampled_from([math.nan, math.inf, -math.inf, 0, -1, 1e308, -1e308, 10**30, "", "x", True, [], {}, [1, 2]]),
    st.floats(),
    st.integers(-(10**20), 10**20),
    st.text(max_size=8),
)


def _toml(doc: dict) -> str:
    def value(v):
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, float):
            return "nan" if math.isnan(v) else ("inf" if v == math.inf else "-inf" if v == -math.inf else repr(v))
        if isinstance(v, str):
            return json.dumps(v)
        if isinstance(v, list):
            return "[" + ", ".join(value(x) for x in v) + "]"
        if isinstance(v, dict):
            return "{" + ", ".join(f"{k} = {value(x)}" for k, x in v.items()) + "}"
        return str(v)

    lines = [
        f"{k} = {value(v)}"
        for k, v in doc.items()
        if not isinstance(v, (dict, list)) or (isinstance(v, list) and not all(isinstance(x, dict) for x in v))
    ]
    for k, v in doc.items():
        if isinstance(v, dict):
            lines += [f"[{k}]"] + [f"{kk} = {value(vv)}" for kk, vv in v.items()]
        elif isinstance(v, list) and v and all(isinstance(x, dict) for x in v):
            for x in v:
                lines += [f"[[{k}]]"] + [f"{kk} = {value(vv)}" for kk, vv in x.items()]
    return "\n".join(lines) + "\n"


def test_the_good_scenario_loads():
    """The document every hostile one is made from loads with each of its values, so a refusal
    below is the hostile value's doing."""
    s = parse_scenario(_toml(GOOD_SCENARIO), "good.toml")
    for key, value in GOOD_SCENARIO.items():
        if isinstance(value, dict):
            assert dataclasses.asdict(getattr(s, key)) == value, key
        elif isinstance(value, list):
            loaded = getattr(s, key)
            assert len(loaded) == len(value), key
            for i, table in enumerate(value):
                assert {k: getattr(loaded[i], k) for k in table} == table, f"{key}[{i}]"
            assert all(item.known for item in loaded), key  # the default where a table leaves it out
        else:
            assert getattr(s, key) == value, key


@pytest.mark.parametrize("table, index, key", SCENARIO_KEYS, ids=[f"{t}.{k}" for t, _, k in SCENARIO_KEYS])
@settings(max_examples=10, deadline=None)
@given(value=HOSTILE_VALUES)
def test_every_scenario_key_refuses_hostile_values_naming_the_key(table, index, key, value):
    doc = json.loads(json.dumps(GOOD_SCENARIO))
    target = doc if table is None else (doc[table][index] if isinstance(doc[table], list) else doc[table])
    target[key] = value
    try:
        s = parse_scenario(_toml(doc), "hostile.toml")
    except ScenarioError as exc:
        assert str(exc).startswith("hostile.toml: ")
        return
    for v in (
        s.arena.width_m,
        s.arena.height_m,
        s.start.x_m,
        s.start.y_m,
        s.start.heading_deg,
        s.target.x_m,
        s.target.y_m,
    ):
        assert math.isfinite(v)
    assert 1 <= s.mission.trips <= 1000 and s.arena.width_m <= 100 and s.arena.height_m <= 100


CONFIG_KEYS = [
    ("arena", "width_m"),
    ("arena", "height_m"),
    ("link", "port"),
    ("link", "baud"),
    ("camera", "source"),
    ("camera", "fps"),
    ("mission", "trips"),
    ("mission", "heartbeat_hz"),
    ("mission", "fix_sd_mm"),
    ("mission", "map"),
    ("rover", "arrival_radius_mm"),
    ("rover", "pose_k_rho_x1000"),
    ("rover", "pose_k_beta_x1000"),
    ("rover", "drive_mode"),
    ("planner", "resolution_m"),
    ("planner", "robot_radius_m"),
]


@pytest.mark.parametrize("section, key", CONFIG_KEYS, ids=[f"{s}.{k}" for s, k in CONFIG_KEYS])
@settings(max_examples=10, deadline=None)
@given(value=HOSTILE_VALUES)
def test_every_config_key_refuses_hostile_values_naming_the_key(section, key, value):
    try:
        cfg = config_from_dict({section: {key: value}}, where="hostile.toml: ")
    except ConfigError as exc:
        assert str(exc).startswith("hostile.toml: ") and f"[{section}]" in str(exc)
        return
    got = getattr(getattr(cfg, section), key, None) if section not in ("rover",) else list(cfg.rover.values())[0]
    assert _finite(got)


def test_unstable_pose_gains_in_a_configuration_are_refused_as_rovernav_pose_refuses_them():
    with pytest.raises(ConfigError, match="unstable gains: K_alpha - K_rho > 0 required"):
        config_from_dict({"rover": {"pose_k_rho_x1000": 5000, "pose_k_alpha_x1000": 1}}, where="c.toml: ")
    with pytest.raises(ConfigError, match=r"arrival_radius_mm = 1000 is outside \[5, 300\]"):
        config_from_dict({"rover": {"arrival_radius_mm": 1000}})


# ---------------------------------------------------------------- end to end: bad input to each command

SC = "seed-fig4-8-unknown-obstacle"
#: The address space each command run end to end may take.
MEMORY_LIMIT_BYTES = 3 << 30


@pytest.fixture(scope="module")
def rovernav(rovernav_command):
    """`python -m rovernav.cli ARGS` under MEMORY_LIMIT_BYTES: (exit status, stdout, stderr)."""

    def run(*args, cwd=None):
        r = rovernav_command(*args, cwd=cwd, memory_limit_bytes=MEMORY_LIMIT_BYTES)
        return r.returncode, r.stdout, r.stderr

    return run


@pytest.fixture(scope="module")
def files(tmp_path_factory, scenario_toml):
    base = scenario_toml(SC)
    d = tmp_path_factory.mktemp("hostile")
    (d / "afile").write_text("x")
    (d / "adir").mkdir()
    (d / "latin.toml").write_bytes(b"\xff\xfe[mission]\n")
    (d / "outside.toml").write_text(base + "\n[[obstacles]]\nx_m = 9.0\ny_m = 9.0\nw_m = 0.2\nh_m = 0.2\n")
    (d / "start_in.toml").write_text(base + "\n[[obstacles]]\nx_m = 0.42\ny_m = 0.30\nw_m = 0.2\nh_m = 0.2\n")
    (d / "trips.toml").write_text(base.replace('kind = "reach"', 'kind = "out-and-back"\ntrips = 1000000000'))
    (d / "km.toml").write_text(base.replace("width_m = 2.36", "width_m = 1000.0"))
    (d / "inf.toml").write_text("[mission]\nheartbeat_hz = inf\n")
    (d / "arrival.toml").write_text("[rover]\narrival_radius_mm = 1000\n")
    (d / "gains.toml").write_text("[rover]\npose_k_rho_x1000 = 5000\npose_k_alpha_x1000 = 1\n")
    return d


CASES = [
    ("sim --camera-fps 0", lambda d: ["sim", SC, "--camera-fps", "0"], "--camera-fps"),
    ("sim --out a file", lambda d: ["sim", SC, "--out", d / "afile"], "--out"),
    ("sim --config a folder", lambda d: ["sim", SC, "--config", d / "adir"], "--config"),
    ("sim --config not UTF-8", lambda d: ["sim", SC, "--config", d / "latin.toml"], "latin.toml"),
    ("sim --max-time -5", lambda d: ["sim", SC, "--max-time", "-5"], "--max-time"),
    ("sim --link-outage nan:nan", lambda d: ["sim", SC, "--link-outage", "nan:nan"], "--link-outage"),
    ("sim an obstacle off the arena", lambda d: ["sim", d / "outside.toml"], "obstacles[1]"),
    ("sim a start on a box", lambda d: ["sim", d / "start_in.toml", "--out", d / "o"], "start"),
    ("sim a billion trips", lambda d: ["sim", d / "trips.toml"], "mission.trips"),
    ("sim heartbeat_hz = inf", lambda d: ["sim", SC, "--config", d / "inf.toml"], "heartbeat_hz"),
    ("sim a 1 m arrival radius", lambda d: ["sim", SC, "--config", d / "arrival.toml"], "arrival_radius_mm"),
    ("sim unstable pose gains", lambda d: ["sim", SC, "--config", d / "gains.toml"], "pose_k_alpha_x1000"),
    ("calibrate camera a missing image", lambda d: ["calibrate", "camera", d / "missing.png"], "missing.png"),
    ("calibrate camera a text file", lambda d: ["calibrate", "camera", d / "afile"], "afile"),
    (
        "calibrate camera --config not UTF-8",
        lambda d: ["calibrate", "camera", d / "afile", "--config", d / "latin.toml"],
        "latin.toml",
    ),
    (
        "calibrate camera --write a folder",
        lambda d: ["calibrate", "camera", d / "afile", "--write", d / "adir"],
        "--write",
    ),
    ("calibrate camera --frames 0", lambda d: ["calibrate", "camera", "--camera", "0", "--frames", "0"], "--frames"),
    ("calibrate tags into a file", lambda d: ["calibrate", "tags", d / "afile"], "afile"),
    ("plan a 1 km arena", lambda d: ["plan", d / "km.toml"], "arena.width_m"),
    ("plan --resolution 1e-6", lambda d: ["plan", SC, "--resolution", "1e-6"], "--resolution"),
    ("plan --plot a folder", lambda d: ["plan", SC, "--plot", f"{d / 'adir'}/"], "--plot"),
    ("arenas --count 0", lambda d: ["arenas", "--count", "0", "--out", d / "ar"], "--count"),
    ("trials --max-time nan", lambda d: ["trials", d / "adir", "--max-time", "nan"], "--max-time"),
    ("link-check --port ''", lambda d: ["link-check", "--port", ""], "--port"),
    ("link-check --timeout nan", lambda d: ["link-check", "--port", "loop://", "--timeout", "nan"], "--timeout"),
    ("demo --seconds nan", lambda d: ["demo", "--seconds", "nan"], "--seconds"),
]


@pytest.mark.parametrize("what, argv, names", CASES, ids=[c[0] for c in CASES])
def test_bad_input_end_to_end_gives_one_line_and_status_2(rovernav, files, what, argv, names):
    code, out, err = rovernav(*argv(files), cwd=files)
    assert code == 2, (what, code, out, err)
    assert "Traceback" not in err + out
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and names in lines[0], err


def test_every_help_states_the_exit_statuses_once():
    for cmd, p in _subparsers().items():
        text = " ".join(p.format_help().split()).lower()
        assert text.count("exit status") == 1, cmd  # `locate --help` once said them twice
        statuses = text[text.index("exit status") :]
        for code in ("0 ", "1 ", "2 ", "3 ", "130 interrupted"):
            assert code in statuses, (cmd, code)


# ---------------------------------------------------------------- what a run leaves on disk


def _strict(text: str):
    def refuse(name):
        raise ValueError(f"not JSON: {name}")

    return json.loads(text, parse_constant=refuse)


@pytest.mark.mission
def test_an_unreachable_target_gives_a_strict_json_report_with_nulls(rovernav, scenario_toml, tmp_path):
    walled = scenario_toml(SC).replace("known = false", "known = true") + "".join(
        f"\n[[walls]]\nx0_m = {a}\ny0_m = {b}\nx1_m = {c}\ny1_m = {e}\nthickness_m = 0.05\n"
        for a, b, c, e in ((1.7, 1.1, 2.3, 1.1), (1.7, 1.1, 1.7, 1.7), (2.3, 1.1, 2.3, 1.7))
    )
    sc = tmp_path / "walled.toml"
    sc.write_text(walled.replace("height_m = 1.75", "height_m = 1.70"))
    code, out, err = rovernav("sim", sc, "--no-video", "--quiet", "--out", tmp_path / "run", "--max-time", "60")
    assert code == 1 and "Traceback" not in err, err
    report = _strict((tmp_path / "run" / "report.json").read_text())
    assert report["reached"] is False and report["optimal_length_m"] is None and report["spl"] in (None, 0, 0.0)


def test_a_run_cut_short_leaves_a_report_saying_so_and_none_of_the_last_runs_files(tmp_path, monkeypatch, capsys):
    from rovernav.sim import cli as sim_cli
    from rovernav.sim.runner import Simulation

    out = tmp_path / "run"
    out.mkdir()
    for name in ("report.json", "summary.png", "video.mp4"):
        (out / name).write_text("from the previous run")

    def interrupted(self):
        self.t = 1.0
        raise KeyboardInterrupt

    monkeypatch.setattr(Simulation, "run", interrupted)
    args = build_parser().parse_args(["sim", SC, "--out", str(out), "--quiet"])
    with pytest.raises(KeyboardInterrupt):
        sim_cli.cmd_sim(args)
    report = _strict((out / "report.json").read_text())
    assert report["interrupted"] is True and report["outcome"] == "interrupted" and report["reached"] is False
    assert not (out / "summary.png").exists() and not (out / "video.mp4").exists()
    assert not list(out.glob(".*partial*"))  # no half video under any name


@pytest.mark.mission
def test_the_report_names_the_drive_mode_the_configuration_sent(rovernav, tmp_path):
    cfg = tmp_path / "pose.toml"
    cfg.write_text("[rover]\ndrive_mode = 1\n")
    code, out, err = rovernav(
        "sim", SC, "--config", cfg, "--no-video", "--quiet", "--out", tmp_path / "run", "--max-time", "5"
    )
    assert "Traceback" not in err
    assert _strict((tmp_path / "run" / "report.json").read_text())["drive_mode"] == "pose_law"
