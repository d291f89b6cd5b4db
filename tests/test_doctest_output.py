"""The native doctest suites stay short under success reporting, as `pio test -e native` runs them
(it turns success reporting on and reads the output in quadratic time: one test case that printed
700,000 passing assertions, 88 MB, kept `pio test` from finishing). A loop over many inputs counts
its failures and asserts once."""

from __future__ import annotations

import collections
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BUILD = ROOT / "build" / "native"
MAX_LINES_PER_CASE = 2000
MAX_LINES_PER_SUITE = 20000


@pytest.fixture(scope="module")
def suites() -> list[Path]:
    if shutil.which("cmake") is None:
        pytest.skip("cmake is not installed (scripts/test installs it)")
    if not (BUILD / "CMakeCache.txt").exists():
        subprocess.run(
            ["cmake", "-S", str(ROOT / "firmware"), "-B", str(BUILD), "-DCMAKE_BUILD_TYPE=Release"],
            check=True,
            capture_output=True,
        )
    subprocess.run(
        ["cmake", "--build", str(BUILD), "--target", "test_core", "test_link", "-j2"], check=True, capture_output=True
    )
    return [BUILD / "test_core", BUILD / "test_link"]


def test_every_case_prints_a_few_lines_under_success_reporting(suites):
    for suite in suites:
        proc = subprocess.run([str(suite), "--success", "--no-colors"], capture_output=True, text=True, timeout=600)
        assert proc.returncode == 0, proc.stdout[-2000:]
        lines = proc.stdout.splitlines()
        per_case: collections.Counter[str] = collections.Counter()
        case = "(before any case)"
        for line in lines:
            if line.startswith("TEST CASE:"):
                case = line
            per_case[case] += 1
        worst_case, worst = per_case.most_common(1)[0]
        assert worst <= MAX_LINES_PER_CASE, f"{suite.name}: {worst_case.strip()} prints {worst} lines"
        assert len(lines) <= MAX_LINES_PER_SUITE, f"{suite.name}: {len(lines)} lines in all"


def test_platformio_runs_the_suites_only_natively():
    # `pio test` with the default env (uno) ignores every suite; the native env builds no shell.
    import configparser
    import fnmatch

    ini = configparser.ConfigParser(inline_comment_prefixes=(";",))
    ini.read(ROOT / "platformio.ini")
    suites = sorted(p.name for p in (ROOT / "firmware" / "test").iterdir() if p.is_dir() and p.name.startswith("test_"))
    assert suites
    ignored = ini["env:uno"].get("test_ignore", "").split()
    assert all(any(fnmatch.fnmatch(s, pat) for pat in ignored) for s in suites), (suites, ignored)
    assert not any(fnmatch.fnmatch(s, pat) for s in suites for pat in ini["env:native"].get("test_ignore", "").split())
    assert ini["env:native"].get("build_src_filter", "").split() == ["-<*>"]
