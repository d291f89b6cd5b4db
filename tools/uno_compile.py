"""Compiling and linking the Uno image: every command of a build worked out first (plan_build), then
run (build): compile what is stale, archive, link as PlatformIO links, objcopy, avr-size.

Part of tools/build_uno.py.
"""

from __future__ import annotations

import concurrent.futures
import shlex
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

from uno_libraries import SOURCE_SUFFIXES, Library, archive_order, find_libraries
from uno_platformio import (
    CORE_ARCHIVE,
    DEPFLAGS,
    ENV_NAME,
    PIO_LIBS,
    PLATFORMIO_INI,
    ROOT,
    VARIANT_ARCHIVE,
    Budget,
    Flags,
    PioConfig,
    SetupError,
    Sizes,
    budget_of,
    uno_flags,
)
from uno_toolchain import ARDUINO_AVR, Toolchain, require_tools


class BuildError(Exception):
    """A compile, archive or link step failed; the message says which."""


# ----------------------------------------------------------------------------- compiling


@dataclass
class Unit:
    source: Path
    obj: Path
    kind: str  # c, cxx, asm
    project: bool  # our code: show its warnings


def compiler_for(kind: str) -> str:
    return "avr-g++" if kind == "cxx" else "avr-gcc"


def command_for(unit: Unit, flags: Flags, include_flags: list[str], extra: list[str]) -> list[str]:
    return (
        [compiler_for(unit.kind)]
        + flags.for_kind(unit.kind)
        + (extra if unit.project else [])
        + DEPFLAGS
        + include_flags
        + ["-c", str(unit.source), "-o", str(unit.obj)]
    )


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


def compile_unit(
    unit: Unit, command: list[str], verbose: bool, env: dict | None = None, compiler_id: str = ""
) -> tuple[Unit, int, str]:
    unit.obj.parent.mkdir(parents=True, exist_ok=True)
    if verbose:
        print(" ".join(shlex.quote(c) for c in command), flush=True)
    proc = subprocess.run(command, capture_output=True, text=True, cwd=ROOT, env=env)
    if proc.returncode == 0:
        unit.obj.with_suffix(unit.obj.suffix + ".cmd").write_text(stamp_text(command, compiler_id), encoding="utf-8")
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


def link_command(
    linker: str, elf: Path, link_flags: list[str], objects: list[Path], build_dir: Path, archives: list[Path]
) -> list[str]:
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
    return (
        [linker, "-o", str(elf)]
        + link_flags
        + [str(o) for o in objects]
        + [f"-L{build_dir}", "-Wl,--start-group"]
        + [str(a) for a in archives]
        + PIO_LIBS
        + ["-Wl,--end-group"]
    )


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

    units: list[Unit]  # everything to compile
    compile: dict[Path, list[str]]  # source -> its compile command
    archives: list[tuple[Path, list[Unit]]]  # in link order
    link: list[str]
    elf: Path
    hex_file: Path
    libraries: list[Library]  # in link order
    budget: Budget
    src_units: list[Unit] = field(default_factory=list)  # firmware/src: linked as objects


def plan_build(build_dir: Path, strict: bool = False) -> Plan:
    config = PioConfig(PLATFORMIO_INI)
    if not config.has_env(ENV_NAME):
        raise SetupError(f"{PLATFORMIO_INI} has no [env:{ENV_NAME}]")
    if config.items(ENV_NAME, "lib_deps"):
        raise SetupError(f"[env:{ENV_NAME}] has lib_deps; this build only knows the project's libraries and the core's")
    flags = uno_flags(config)
    src_dir = config.directory("src_dir", "src")
    include_dir = config.directory("include_dir", "include")
    lib_dir = config.directory("lib_dir", "lib")
    test_dir = config.directory("test_dir", "test")
    core_dir = ARDUINO_AVR / "cores" / "arduino"
    variant_dir = ARDUINO_AVR / "variants" / "standard"
    if not core_dir.is_dir():
        raise SetupError(f"the Arduino core is missing: {core_dir} (apt-get install arduino-core-avr)")

    libs = find_libraries(src_dir, include_dir, lib_dir, set(config.items(ENV_NAME, "lib_ignore")))
    include_flags = [f"-I{p}" for p in [include_dir, src_dir] if p.is_dir()]
    include_flags += [f"-I{lib.include_dir}" for lib in libs]
    include_flags += [f"-I{core_dir}", f"-I{variant_dir}"]
    extra = ["-Werror"] if strict else []

    def units_in(files: list[Path], base: Path, out: Path, project: bool) -> list[Unit]:
        return [
            Unit(f, out / (f.relative_to(base).as_posix() + ".o"), SOURCE_SUFFIXES[f.suffix], project)
            for f in files
            if test_dir not in f.parents
        ]

    def sources_in(folder: Path) -> list[Path]:
        return [p for p in sorted(folder.iterdir()) if p.suffix in SOURCE_SUFFIXES]

    src_files = [p for p in sorted(src_dir.rglob("*")) if p.suffix in SOURCE_SUFFIXES]
    src_units = units_in(src_files, src_dir, build_dir / "src", True)
    if not src_units:
        raise SetupError(f"no sources in {relative(src_dir)}")
    variant_units = units_in(sources_in(variant_dir), variant_dir, build_dir / VARIANT_ARCHIVE, False)
    core_units = units_in(sources_in(core_dir), core_dir, build_dir / CORE_ARCHIVE, False)
    ordered = archive_order(libs, src_files, [p for p in (include_dir, src_dir) if p.is_dir()])
    lib_units = {
        lib.name: units_in(lib.sources(), lib.include_dir, build_dir / "lib" / lib.name, lib.project) for lib in ordered
    }

    # Archives like PlatformIO's: an ISR in an unused core file (Tone.cpp's Timer2 interrupt,
    # say) stays out of the image. A library without sources has no archive (piolib.py
    # LibBuilderBase.build); the framework's variant archive is made even when empty.
    archives = [(build_dir / f"lib{lib.name}.a", lib_units[lib.name]) for lib in ordered if lib_units[lib.name]]
    archives += [
        (build_dir / f"lib{VARIANT_ARCHIVE}.a", variant_units),
        (build_dir / f"lib{CORE_ARCHIVE}.a", core_units),
    ]
    all_units = src_units + [u for _, units in archives for u in units]
    elf = build_dir / "firmware.elf"
    return Plan(
        units=all_units,
        compile={u.source: command_for(u, flags, include_flags, extra) for u in all_units},
        archives=archives,
        link=link_command(
            linker_for(src_units), elf, flags.link, [u.obj for u in src_units], build_dir, [a for a, _ in archives]
        ),
        elf=elf,
        hex_file=build_dir / "firmware.hex",
        libraries=ordered,
        budget=budget_of(config),
        src_units=src_units,
    )


def build(
    build_dir: Path, jobs: int, strict: bool, verbose: bool, chain: Toolchain | None = None
) -> tuple[Sizes, Plan]:
    chain = chain or Toolchain("path", None)
    require_tools(chain)
    env = chain.env()
    compiler_id = f"{chain.which('avr-gcc')} {chain.version()}"
    plan = plan_build(build_dir, strict)
    stale = [u for u in plan.units if not up_to_date(u, plan.compile[u.source], compiler_id)]
    failures, hidden_warnings = [], 0
    with concurrent.futures.ThreadPoolExecutor(max_workers=jobs) as pool:
        futures = [pool.submit(compile_unit, u, plan.compile[u.source], verbose, env, compiler_id) for u in stale]
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
    print(
        f"compiled {len(stale)} of {len(plan.units)} files with {chain.describe()} "
        f"(libraries: {', '.join(lib.name for lib in plan.libraries) or 'none'})"
    )
    if hidden_warnings:
        print(f"({hidden_warnings} warnings in the Arduino core and its libraries not shown)")

    # Rebuilt every time (it takes milliseconds), so an object whose source was deleted never
    # lingers in an archive.
    for archive, units in plan.archives:
        archive.parent.mkdir(parents=True, exist_ok=True)
        archive.unlink(missing_ok=True)
        run(
            ["avr-gcc-ar", "rcs", str(archive)] + [str(u.obj) for u in units], f"archiving {archive.name}", verbose, env
        )

    run(plan.link, "linking firmware.elf", verbose, env)
    run(["avr-objcopy", "-O", "ihex", "-R", ".eeprom", str(plan.elf), str(plan.hex_file)], "avr-objcopy", verbose, env)
    print(f"wrote {relative(plan.hex_file)}")
    return section_sizes(plan.elf, verbose, plan.budget, env), plan
