"""The vehicle's facts (protocol/vehicle.toml) are written once: generated into C++ and Python,
and nowhere else by hand (issue 27)."""

from __future__ import annotations

import importlib.util
import io
import re
import shutil
import subprocess
import sys
import tokenize
from pathlib import Path

import pytest

from rovernav import vehicle_gen as vehicle

ROOT = Path(__file__).resolve().parent.parent

# What the generator reads and writes, as tests/test_protocol.py copies it.
GENERATOR_TREE = ("protocol", "firmware/lib/link", "firmware/test/test_link", "host/rovernav/link")


def _copy_generator_tree(dest: Path) -> None:
    for rel in GENERATOR_TREE:
        shutil.copytree(ROOT / rel, dest / rel)
    shutil.copy(ROOT / "host/rovernav/vehicle_gen.py", dest / "host/rovernav/vehicle_gen.py")


def _set_fact(toml: Path, name: str, value: int) -> None:
    text = toml.read_text()
    new, n = re.subn(rf'(name = "{name}"\nvalue = )\d+', rf"\g<1>{value}", text)
    assert n == 1, f"fact {name} not found once in {toml}"
    toml.write_text(new)


def _generate(tree: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, str(tree / "protocol" / "generate.py"), *args], capture_output=True, text=True
    )


def _load_module(path: Path):
    spec = importlib.util.spec_from_file_location(f"vehicle_gen_copy_{abs(hash(path))}", path)
    module = importlib.util.module_from_spec(spec)
    assert spec.loader is not None
    spec.loader.exec_module(module)
    return module


def _schema_hash(tree: Path) -> str:
    m = re.search(r"kSchemaHash = (0x[0-9A-F]{8})UL", (tree / "firmware/lib/link/messages_gen.h").read_text())
    assert m
    return m.group(1)


# ---------------------------------------------------------------- one edit, both sides follow


def test_the_committed_vehicle_outputs_are_the_definition_s():
    result = _generate(ROOT, "--check")
    assert result.returncode == 0, result.stderr
    for f in (ROOT / "protocol/vehicle.toml").read_text().split("[[fact]]")[1:]:
        name = re.search(r'name = "(\w+)"', f).group(1)
        value = int(re.search(r"value = (\d+)", f).group(1))
        assert vehicle.FACTS[name] == value


def test_changing_the_sonar_s_range_in_a_copy_moves_both_sides_and_the_parameter_limit(tmp_path):
    _copy_generator_tree(tmp_path)
    before = _schema_hash(tmp_path)
    _set_fact(tmp_path / "protocol/vehicle.toml", "sonar_max_range_mm", 1200)
    assert _generate(tmp_path, "--check").returncode == 1  # the committed outputs are now stale
    result = _generate(tmp_path)
    assert result.returncode == 0, result.stderr

    header = (tmp_path / "firmware/lib/link/vehicle_gen.h").read_text()
    assert "constexpr uint16_t kSonarMaxRangeMm = 1200;" in header
    assert _load_module(tmp_path / "host/rovernav/vehicle_gen.py").SONAR_MAX_RANGE_MM == 1200
    # sonar_report_mm's limit names the fact: both sides' parameter tables follow, and the wire's
    # meaning changed with it, so the schema hash does.
    assert "11 sonar_report_mm: 600, 50..1200" in (tmp_path / "firmware/lib/link/messages_gen.h").read_text()
    assert (
        "ParamSpec(11, 'sonar_report_mm', 'mm', 600, 50, 1200,"
        in (tmp_path / "host/rovernav/link/messages_gen.py").read_text()
    )
    assert _schema_hash(tmp_path) != before
    assert _generate(tmp_path, "--check").returncode == 0


def test_changing_the_body_in_a_copy_moves_both_sides_but_not_the_schema_hash(tmp_path):
    _copy_generator_tree(tmp_path)
    before = _schema_hash(tmp_path)
    _set_fact(tmp_path / "protocol/vehicle.toml", "body_width_mm", 180)
    _set_fact(tmp_path / "protocol/vehicle.toml", "sonar_offset_mm", 120)
    assert _generate(tmp_path).returncode == 0

    header = (tmp_path / "firmware/lib/link/vehicle_gen.h").read_text()
    assert "constexpr uint16_t kBodyWidthMm = 180;" in header
    module = _load_module(tmp_path / "host/rovernav/vehicle_gen.py")
    assert (module.BODY_WIDTH_MM, module.SONAR_OFFSET_MM) == (180, 120)
    # A parameter's default may name a fact: the rover's default and the host's follow.
    assert (
        "ParamSpec(32, 'sonar_offset_mm', 'mm', 120, 0, 300,"
        in (tmp_path / "host/rovernav/link/messages_gen.py").read_text()
    )
    assert "32 sonar_offset_mm: 120, 0..300" in (tmp_path / "firmware/lib/link/messages_gen.h").read_text()
    assert _schema_hash(tmp_path) == before  # not on the wire


@pytest.mark.skipif(shutil.which("c++") is None, reason="no C++ compiler")
def test_the_core_s_derived_body_sizes_follow_a_changed_body(tmp_path):
    # body.h computes the half-width and half-diagonal from the generated facts: compile it
    # against a copy generated with another body and check them at compile time.
    _copy_generator_tree(tmp_path)
    _set_fact(tmp_path / "protocol/vehicle.toml", "body_length_mm", 300)
    _set_fact(tmp_path / "protocol/vehicle.toml", "body_width_mm", 160)
    assert _generate(tmp_path).returncode == 0
    probe = tmp_path / "probe.cpp"
    probe.write_text(
        '#include "body.h"\n'
        'static_assert(rovernav::kBodyLengthMm == 300, "length");\n'
        'static_assert(rovernav::core::kBodyHalfWidthMm == 80, "half-width");\n'
        'static_assert(rovernav::core::kBodyHalfDiagonalMm == 170, "half-diagonal");  // sqrt(300^2+160^2)=340\n'
        "int main() { return 0; }\n"
    )
    # The copy's link directory comes first, so body.h (the repository's) reads the copy's facts.
    result = subprocess.run(
        [
            "c++",
            "-std=c++14",
            "-fsyntax-only",
            f"-I{tmp_path / 'firmware/lib/link'}",
            f"-I{ROOT / 'firmware/lib/core'}",
            str(probe),
        ],
        capture_output=True,
        text=True,
    )
    assert result.returncode == 0, result.stderr


# ---------------------------------------------------------------- written once

# The copies no generated file can reach (an .ini, C): each is
# pinned here to the fact, so a changed fact fails this test until the copy is changed too.
PINNED = [
    ("platformio.ini", r"^monitor_speed = (\d+)$", "link_baud", 1),
    ("tools/avrsim/rovernav_avrsim.c", r"^#define DEFAULT_BAUD (\d+)u$", "link_baud", 1),
]


@pytest.mark.parametrize("path, pattern, fact, scale", PINNED, ids=[p[0] for p in PINNED])
def test_a_copy_outside_the_generator_s_reach_agrees_with_the_fact(path, pattern, fact, scale):
    found = re.findall(pattern, (ROOT / path).read_text(), re.M)
    assert len(found) == 1, f"{path}: {pattern!r} found {len(found)} times"
    assert int(found[0].replace("_", "")) == vehicle.FACTS[fact] * scale, (
        f"{path} writes {fact} as {found[0]}; protocol/vehicle.toml says {vehicle.FACTS[fact]}"
    )


# Hand-written copies of the facts, as code (comments, docstrings and strings are prose and
# are not read): a number, or a fact-named constant given a bare number.
COPIES = {
    "link_baud": re.compile(r"\b57_?600[uUlL]*\b"),
    "default arena": re.compile(r"\b(2\.36|1\.75|2_?360|1_?750)\b"),
    "step_period_ms": re.compile(
        r"(?i)\b\w*step_?(s|ms|us|period\w*)\s*(:\s*\w+\s*)?=\s*(0?\.010?|10|10_?000)\b(?!\.)"
    ),
    "the body": re.compile(
        r"(?i)\b\w*(body|rover|half)_?(width|length|diagonal|radius)\w*\s*(:\s*\w+\s*)?=\s*[\d.]+\b"
        r"|\bk(CornerReach|HalfWidth)Mm\s*=\s*\d"
    ),
    "wheel_track_mm": re.compile(r"(?i)\btrack_?(m|mm)\s*(:\s*\w+\s*)?=\s*[\d.]+"),
    "sonar_max_range_mm": re.compile(
        r"(?i)\b\w*(sonar|sensor)_?(max_?(range|m\b|mm\b)|range_?max)\w*\s*(:\s*\w+\s*)?=\s*[\d.]+"
    ),
    "sonar_cone_cdeg": re.compile(r"(?i)\bcone_?(deg|cdeg|rad)\s*(:\s*\w+\s*)?=\s*[\d.]+"),
    # A parameter's scale is its name's (param_scale): not a number next to its read.
    "a parameter's scale": re.compile(
        r"\bParam\s*\.\s*\w+_(X100|X1000|PERMILLE)\s*\)?\s*[*/]\s*100"
        r"|\b(hundredths|thousandths)\(Param::\w*(X100|X1000|Permille)\)"
    ),
}
# Lines that hold the number for another reason, each with it.
NOT_COPIES = {
    (
        "firmware/lib/hal/link_serial.cpp",
        "baud == 57600",
    ): "the Arduino core's UART rule for that rate, whatever the link's",
    (
        "host/rovernav/config.py",
        "frozenset((9600, 19200, 38400, 57600, 115200))",
    ): "the standard rates a user may choose",
}
SCANNED = ("host/rovernav", "firmware/lib", "firmware/src", "firmware/abi", "tools")
GENERATED = re.compile(r"_gen\.(h|py)$")


_NOT_CODE = {
    tokenize.COMMENT,
    tokenize.STRING,
    tokenize.NL,
    tokenize.NEWLINE,
    tokenize.INDENT,
    tokenize.DEDENT,
    tokenize.ENDMARKER,
} | {getattr(tokenize, "FSTRING_MIDDLE", tokenize.STRING)}  # f-string text (3.12+)


def python_code_lines(text: str) -> dict[int, str]:
    """Each line's code, without its comments and strings (docstrings included)."""
    lines: dict[int, list[str]] = {}
    for tok in tokenize.generate_tokens(io.StringIO(text).readline):
        if tok.type in _NOT_CODE:
            continue
        lines.setdefault(tok.start[0], []).append(tok.string)
    return {n: " ".join(parts) for n, parts in lines.items()}


_C_PROSE = re.compile(r'//[^\n]*|/\*.*?\*/|"(?:\\.|[^"\\\n])*"', re.S)


def c_code_lines(text: str) -> dict[int, str]:
    """Each line's code, without comments and string literals (line numbers kept)."""
    code = _C_PROSE.sub(lambda m: "\n" * m.group(0).count("\n"), text)
    return dict(enumerate(code.splitlines(), start=1))


def find_copies(path: str, text: str) -> list[str]:
    if path.endswith(".py"):
        code = python_code_lines(text)
    elif path.endswith((".h", ".hpp", ".cpp", ".c")):
        code = c_code_lines(text)
    else:
        return []
    raw = text.splitlines()
    hits = []
    for n, line in code.items():
        for fact, pattern in COPIES.items():
            if pattern.search(line) and not any(p == path and s in raw[n - 1] for p, s in NOT_COPIES):
                if not any(p == path and re.search(pat, raw[n - 1]) for p, pat, _, _ in PINNED):
                    hits.append(f"{path}:{n}: {fact}: {raw[n - 1].strip()}")
    return hits


def _tracked_sources() -> list[str]:
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("not a git checkout")
    out = subprocess.run(
        ["git", "-C", str(ROOT), "ls-files", "--", *SCANNED], capture_output=True, text=True, check=True
    )
    return [p for p in out.stdout.splitlines() if not GENERATED.search(p) and (ROOT / p).is_file()]


def test_no_tracked_source_writes_a_vehicle_fact_by_hand():
    hits = []
    for path in _tracked_sources():
        hits += find_copies(path, (ROOT / path).read_text(errors="replace"))
    assert not hits, "hand-written copies of protocol/vehicle.toml's facts:\n" + "\n".join(hits)


@pytest.mark.parametrize(
    "path, line",
    [
        ("host/rovernav/config.py", "    baud: int = 57600"),
        ("host/rovernav/sim/camera.py", "    arena_w_m: float = 2.36"),
        ("host/rovernav/sim/runner.py", "STEP_S = 0.010"),
        ("firmware/src/main.cpp", "constexpr uint8_t kStepMs = 10;  // the core runs at 100 Hz"),
        ("firmware/lib/core/local_planner.h", "  enum : int16_t { kFaceRunMm = 250, kHalfWidthMm = 75 };"),
        ("firmware/lib/core/rover.h", "    kCornerReachMm = 140,"),
        ("host/rovernav/sim/plant.py", "    track_m: float = 0.13             # distance between the wheels"),
        ("host/rovernav/sim/world.py", "ROVER_WIDTH_M = 0.15"),
        ("host/rovernav/mapping/sonar_map.py", "    body_radius_m: float = 0.075      # (half its width)"),
        ("host/rovernav/mapping/sonar_map.py", "SENSOR_MAX_RANGE_M = 4.0"),
        ("host/rovernav/sim/plant.py", "    sonar_max_m: float = 4.0"),
        ("firmware/lib/hal/board.h", "constexpr uint16_t kSonarMaxRangeMm = 1000;"),
        ("host/rovernav/calibrate/rover.py", "def fit(runs, cone_deg: float = 15.0):"),
        (
            "host/rovernav/evaluation/report.py",
            "    return max(pwm, 0) * get(mg.Param.SPEED_MM_S_PER_PWM_X1000) / 1000 / 1000",
        ),
        ("firmware/lib/core/params.h", "  float kp() const { return hundredths(Param::PidKpX100); }"),
    ],
)
def test_the_scan_finds_a_copy_added_by_hand(path, line):
    # The copies this change removed, put back: each is found. Prose about them is not.
    assert find_copies(path, line + "\n")
    prose = f'"""{line}"""\n' if path.endswith(".py") else f"// {line}\n"
    assert not find_copies(path, prose)


# ---------------------------------------------------------------- parameter scales


def _camel(name: str) -> str:
    return "".join(part.capitalize() for part in name.split("_"))


def test_a_parameter_s_scale_is_the_one_its_name_gives_on_both_sides():
    from rovernav.link import messages_gen as mg

    header = (ROOT / "firmware/lib/link/messages_gen.h").read_text()
    scaled = 0
    for spec in mg.PARAMS.values():
        m = re.search(r"_x(\d+)$", spec.name)
        want = int(m.group(1)) if m else 1000 if spec.name.endswith("_permille") else 1
        assert spec.scale == want, spec.name
        assert (f"p == Param::{_camel(spec.name)} ? {want} :" in header) == (want != 1), spec.name
        assert spec.to_raw(spec.to_value(spec.default)) == spec.default
        scaled += want != 1
    assert scaled == 10
    assert mg.PARAMS[mg.Param.PID_KP_X100].to_value(3000) == 30.0
    assert mg.PARAMS[mg.Param.RIGHT_BIAS_PERMILLE].to_raw(0.8) == 800
