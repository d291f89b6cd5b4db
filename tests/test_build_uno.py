"""tools/build_uno.py links the Uno image as PlatformIO does, and platformio.ini keeps Unity out of
the Uno env.

The expected link line is the one `pio run -e uno -v` printed (PlatformIO Core 6.1.19 from PyPI,
SCons 4.8.1, a local stand-in for platform-atmelavr 5.1's builder scripts since the platform
cannot be downloaded here, Debian's avr-gcc and Arduino core; the image it made was byte for
byte build_uno.py's):

    avr-g++ -o .pio/build/uno/firmware.elf -Wl,--relax -Os -mmcu=atmega328p -Wl,--gc-sections
      -flto -fuse-linker-plugin .pio/build/uno/src/main.cpp.o -L.pio/build/uno -Wl,--start-group
      .pio/build/uno/lib71b/liblink.a .pio/build/uno/libae0/libcore.a .pio/build/uno/lib6ae/libhal.a
      .pio/build/uno/libFrameworkArduinoVariant.a .pio/build/uno/libFrameworkArduino.a -lm
      -Wl,--end-group

(PlatformIO puts each library's archive in a folder of its own, lib<hash>/; build_uno.py does not.)
None of these tests runs a compiler.
"""
from __future__ import annotations

import configparser
import importlib.util
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _load_build_uno():
    spec = importlib.util.spec_from_file_location("build_uno", ROOT / "tools" / "build_uno.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("build_uno", module)
    spec.loader.exec_module(module)
    return module


build_uno = _load_build_uno()

# platform-atmelavr's arduino.py: LINKFLAGS; PlatformIO puts the project's -Wl,... before them.
FRAMEWORK_LINKFLAGS = ["-Os", "-mmcu=atmega328p", "-Wl,--gc-sections", "-flto", "-fuse-linker-plugin"]


def _ini() -> configparser.ConfigParser:
    ini = configparser.ConfigParser(inline_comment_prefixes=(";",))
    ini.read(ROOT / "platformio.ini")
    return ini


@pytest.fixture(scope="module")
def plan(tmp_path_factory):
    if not (build_uno.ARDUINO_AVR / "cores" / "arduino" / "Arduino.h").is_file():
        pytest.skip("arduino-core-avr is not installed (scripts/test installs it)")
    build_dir = tmp_path_factory.mktemp("uno")
    return build_dir, build_uno.plan_build(build_dir)


def test_link_command_is_platformios(plan):
    build_dir, p = plan
    user_linkflags = [w for w in _ini()["env:uno"]["build_flags"].split() if w.startswith("-Wl,")]
    assert user_linkflags == ["-Wl,--relax"]
    line = [w.replace(str(build_dir), "$BUILD_DIR") for w in p.link]
    assert line == (
        ["avr-g++", "-o", "$BUILD_DIR/firmware.elf"] + user_linkflags + FRAMEWORK_LINKFLAGS +
        ["$BUILD_DIR/src/main.cpp.o", "-L$BUILD_DIR", "-Wl,--start-group",
         "$BUILD_DIR/liblink.a", "$BUILD_DIR/libcore.a", "$BUILD_DIR/libhal.a",
         "$BUILD_DIR/libFrameworkArduinoVariant.a", "$BUILD_DIR/libFrameworkArduino.a",
         "-lm", "-Wl,--end-group"])


def test_every_archive_is_made_and_linked_once(plan):
    _, p = plan
    archives = [str(a) for a, _ in p.archives]
    assert len(set(archives)) == len(archives)
    start, end = p.link.index("-Wl,--start-group"), p.link.index("-Wl,--end-group")
    assert p.link[start + 1:end] == archives + ["-lm"]
    # the Uno's variant has no sources: an empty archive, as PlatformIO makes
    variant = dict((a.name, units) for a, units in p.archives)["libFrameworkArduinoVariant.a"]
    assert variant == []
    assert [lib.name for lib in p.libraries] == ["link", "core", "hal"]


def test_a_library_comes_after_the_libraries_it_includes(plan):
    """piolib.py LibBuilderBase.build: dependencies' archives first (hal uses core and link,
    core uses link)."""
    _, p = plan
    position = {lib.name: i for i, lib in enumerate(p.libraries)}
    headers = {lib.name: lib.headers() for lib in p.libraries}
    for lib in p.libraries:
        included = {name for src in lib.sources() for name in build_uno.includes_of(src)}
        for other, its_headers in headers.items():
            if other != lib.name and included & its_headers:
                assert position[other] < position[lib.name], (lib.name, other)


def test_a_c_only_program_is_linked_by_avr_gcc():
    # SCons' smart_link: $CXX only when one of the program's own objects came from C++
    unit = build_uno.Unit(Path("a.c"), Path("a.c.o"), "c", True)
    assert build_uno.linker_for([unit]) == "avr-gcc"
    cxx = build_uno.Unit(Path("b.cpp"), Path("b.cpp.o"), "cxx", True)
    assert build_uno.linker_for([unit, cxx]) == "avr-g++"


def _library(root: Path, name: str, files: dict[str, str]) -> "build_uno.Library":
    folder = root / "lib" / name
    folder.mkdir(parents=True)
    for file, text in files.items():
        (folder / file).write_text(text)
    return build_uno.load_library(folder, True)


def _order(tmp_path: Path, main: str, libs: dict[str, dict[str, str]]) -> list[str]:
    src = tmp_path / "src"
    src.mkdir(parents=True)
    (src / "main.cpp").write_text(main)
    built = [_library(tmp_path, name, files) for name, files in sorted(libs.items())]
    return [lib.name for lib in build_uno.archive_order(built, [src / "main.cpp"], [src])]


def test_dependencies_come_first_and_otherwise_the_order_included(tmp_path):
    libs = {
        "a": {"a.h": '#include "b.h"\n', "a.cpp": '#include "a.h"\n'},
        "b": {"b.h": "", "b.cpp": '#include "b.h"\n'},
        "x": {"x.h": "", "x.cpp": '#include "x.h"\n'},
    }
    assert _order(tmp_path / "1", '#include "a.h"\n#include "x.h"\n', libs) == ["b", "a", "x"]
    assert _order(tmp_path / "2", '#include "x.h"\n#include "a.h"\n', libs) == ["x", "b", "a"]


def test_a_dependency_met_only_in_a_library_source(tmp_path):
    libs = {
        "a": {"a.h": "", "a.cpp": '#include "a.h"\n#include "c.h"\n'},
        "c": {"c.h": "", "c.cpp": ""},
    }
    assert _order(tmp_path, '#include "a.h"\n', libs) == ["c", "a"]


def test_a_cycle_is_cut_where_platformio_cuts_it(tmp_path):
    # piolib.py depend_on: b -> a would close the cycle a -> b -> a and is left out
    libs = {
        "a": {"a.h": "", "a.cpp": '#include "b.h"\n'},
        "b": {"b.h": "", "b.cpp": '#include "a.h"\n'},
    }
    assert _order(tmp_path, '#include "a.h"\n', libs) == ["b", "a"]


def test_the_uno_env_cannot_pull_unity_and_native_keeps_doctest():
    ini = _ini()
    uno, native = ini["env:uno"], ini["env:native"]
    # `pio test` with the default env ignores every suite; one let through by `--ignore` on the
    # command line stops at the missing custom runner instead of fetching Unity
    assert uno.get("test_ignore", "").split() == ["*"]
    assert uno.get("test_framework") == "custom"
    assert not (ROOT / "firmware" / "test" / "test_custom_runner.py").exists()
    assert "lib_deps" not in uno
    assert native.get("test_framework") == "doctest"
    assert native.get("build_src_filter", "").split() == ["-<*>"]


def test_every_library_source_assembles_or_compiles_to_nothing_off_the_avr(tmp_path):
    # PlatformIO's native env (`pio test -e native`) builds every file of lib/core and lib/link,
    # the AVR assembly included: off the AVR it must be empty, comments and all (the ';' comments
    # of an AVR source are statements to another assembler).
    import shutil
    import subprocess

    gcc = shutil.which("gcc")
    if gcc is None:
        pytest.skip("no gcc")
    sources = sorted((ROOT / "firmware" / "lib").glob("*/*.S"))
    assert sources
    for src in sources:
        r = subprocess.run([gcc, "-c", "-x", "assembler-with-cpp", str(src), "-o", str(tmp_path / "x.o")],
                           capture_output=True, text=True)
        assert r.returncode == 0, f"{src.name}: {r.stderr[:400]}"
