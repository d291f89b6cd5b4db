"""platformio.ini, as the Uno build reads it: the project's folders, [env:uno]'s build_flags and
build_unflags combined with the flags PlatformIO adds itself (PIO_*), and the image's budget
(board_upload.maximum_size and .maximum_ram_size) with the check of the sizes against it.

Part of tools/build_uno.py (its docstring tells the whole build).
"""

from __future__ import annotations

import configparser
import os
import re
import shlex
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PLATFORMIO_INI = ROOT / "platformio.ini"
ENV_NAME = "uno"

BOARD_FLASH_BYTES = 32_256  # the Uno: 32 KiB less the 512-byte optiboot bootloader (uno.json)
BOARD_RAM_BYTES = 2_048
# The budget: [env:uno] board_upload.maximum_size and .maximum_ram_size (budget_of()).
BUDGET_OPTIONS = ("board_upload.maximum_size", "board_upload.maximum_ram_size")

MCU = "atmega328p"
# --- Added by PlatformIO itself (platform-atmelavr builder/frameworks/arduino.py and the
# board manifest uno.json), not by platformio.ini. Keep in step with PlatformIO.
PIO_CCFLAGS = ["-Os", "-Wall", "-ffunction-sections", "-fdata-sections", "-flto", f"-mmcu={MCU}"]
PIO_CFLAGS = ["-std=gnu11", "-fno-fat-lto-objects"]
PIO_CXXFLAGS = ["-fno-exceptions", "-fno-threadsafe-statics", "-fpermissive", "-std=gnu++11"]
PIO_ASFLAGS = ["-x", "assembler-with-cpp"]
PIO_DEFINES = ["-DF_CPU=16000000L", "-DARDUINO_ARCH_AVR", "-DARDUINO=10808", "-DARDUINO_AVR_UNO"]
# arduino.py's LINKFLAGS and LIBS=["m"]; platform-atmelavr's builder/main.py names the tools
# (CC avr-gcc, CXX avr-g++, AR avr-gcc-ar) and adds no flags of its own.
PIO_LINKFLAGS = ["-Os", f"-mmcu={MCU}", "-Wl,--gc-sections", "-flto", "-fuse-linker-plugin"]
PIO_LIBS = ["-lm"]
# The framework's archives, as arduino.py names them (BuildLibrary of variants/<variant> and of
# cores/<core>). The Uno's variant (standard) has no sources: PlatformIO still archives and links
# an empty libFrameworkArduinoVariant.a, and so does this build.
VARIANT_ARCHIVE = "FrameworkArduinoVariant"
CORE_ARCHIVE = "FrameworkArduino"
# --- Added here, not by PlatformIO: dependency files for incremental builds.
DEPFLAGS = ["-MMD"]


class SetupError(Exception):
    """The toolchain, the Arduino core or platformio.ini is not usable."""


# ----------------------------------------------------------------------------- platformio.ini


class PioConfig:
    """The subset of PlatformIO's configuration rules this build needs.

    Options of [env:NAME] fall back to `extends` sections and then to [env]; `${section.option}`
    is replaced by that option's value. Multi-line values are split on whitespace.
    """

    _REF = re.compile(r"\$\{([^.}]+)\.([^}]+)\}")

    def __init__(self, path: Path) -> None:
        if not path.is_file():
            raise SetupError(f"{path} not found")
        self._parser = configparser.ConfigParser(interpolation=None, strict=False)
        self._parser.optionxform = str  # keep option names as written
        try:
            self._parser.read(path, encoding="utf-8")
        except configparser.Error as exc:
            raise SetupError(f"{path}: {exc}") from exc
        self._path = path

    def _sections_for(self, env: str) -> list[str]:
        chain, todo = [], [f"env:{env}"]
        while todo:
            section = todo.pop(0)
            if section in chain or not self._parser.has_section(section):
                continue
            chain.append(section)
            extends = self._parser.get(section, "extends", fallback="")
            todo.extend(s.strip() for s in extends.replace(",", " ").split())
        if "env" not in chain and self._parser.has_section("env"):
            chain.append("env")
        return chain

    def has_env(self, env: str) -> bool:
        return self._parser.has_section(f"env:{env}")

    def raw(self, section: str, option: str, depth: int = 0) -> str | None:
        if section.startswith("env:"):
            sections = self._sections_for(section[4:])
        else:
            sections = [section]
        for sec in sections:
            if self._parser.has_option(sec, option):
                return self._expand(self._parser.get(sec, option), depth)
        return None

    def _expand(self, value: str, depth: int) -> str:
        if depth > 10:
            raise SetupError(f"{self._path}: ${{...}} references nest too deep")

        def replace(match: re.Match[str]) -> str:
            section, option = match.group(1), match.group(2)
            if section == "sysenv":
                return os.environ.get(option, "")
            found = self.raw(section, option, depth + 1)
            if found is None:
                raise SetupError(f"{self._path}: ${{{section}.{option}}} is not defined")
            return found

        return self._REF.sub(replace, value)

    def words(self, env: str, option: str) -> list[str]:
        value = self.raw(f"env:{env}", option) or ""
        return shlex.split(value, comments=False)

    def items(self, env: str, option: str) -> list[str]:
        """A comma- or newline-separated list (lib_ignore, lib_deps)."""
        value = self.raw(f"env:{env}", option) or ""
        return [item.strip() for item in re.split(r"[,\n]", value) if item.strip()]

    def directory(self, option: str, default: str) -> Path:
        value = self._parser.get("platformio", option, fallback=default).strip()
        return (ROOT / value).resolve()


@dataclass
class Flags:
    """Compiler flags by the kind of source they apply to, as PlatformIO sorts build_flags."""

    common: list[str] = field(default_factory=list)  # CCFLAGS: C, C++ and assembler
    c: list[str] = field(default_factory=list)  # CFLAGS
    cxx: list[str] = field(default_factory=list)  # CXXFLAGS
    asm: list[str] = field(default_factory=list)  # ASFLAGS
    defines: list[str] = field(default_factory=list)  # -D / -U / -I
    link: list[str] = field(default_factory=list)  # LINKFLAGS

    def add_build_flags(self, words: list[str]) -> None:
        """Sorts build_flags the way PlatformIO's ParseFlags does."""
        it = iter(words)
        for word in it:
            if word in ("-D", "-U", "-I", "-include"):
                self.defines += [word, next(it, "")]
            elif word.startswith(("-D", "-U", "-I")):
                self.defines.append(word)
            elif word.startswith("-std="):
                (self.cxx if "++" in word else self.c).append(word)
            elif word.startswith("-Wl,"):
                self.link.append(word)
            else:
                self.common.append(word)

    def remove(self, unflags: list[str]) -> None:
        for name in ("common", "c", "cxx", "asm", "defines", "link"):
            setattr(self, name, [f for f in getattr(self, name) if f not in unflags])

    def for_kind(self, kind: str) -> list[str]:
        if kind == "c":
            return self.common + self.c + self.defines
        if kind == "cxx":
            return self.common + self.cxx + self.defines
        return self.asm + self.common + self.defines


def uno_flags(config: PioConfig) -> Flags:
    user = Flags()
    user.add_build_flags(config.words(ENV_NAME, "build_flags"))
    flags = Flags(
        common=PIO_CCFLAGS + user.common,
        c=PIO_CFLAGS + user.c,
        cxx=PIO_CXXFLAGS + user.cxx,
        asm=PIO_ASFLAGS + user.asm,
        defines=PIO_DEFINES + user.defines,
        # LINKFLAGS: platformio-core's piobuild.py ProcessProgramDeps applies build_flags
        # (ProcessFlags) before BuildFrameworks runs arduino.py, which appends its own;
        # so the project's -Wl,... come first on PlatformIO's link line.
        link=user.link + PIO_LINKFLAGS,
    )
    flags.remove(config.words(ENV_NAME, "build_unflags"))
    return flags


# ----------------------------------------------------------------------------- the budget


@dataclass(frozen=True)
class Budget:
    """The image's budget, from platformio.ini ([env:uno] board_upload.*)."""

    flash_bytes: int
    ram_bytes: int


def budget_of(config: PioConfig) -> Budget:
    values = []
    for option in BUDGET_OPTIONS:
        raw = (config.raw(f"env:{ENV_NAME}", option) or "").strip()
        if not raw.isdigit():
            raise SetupError(
                f"{config._path}: [env:{ENV_NAME}] {option} must be a number of bytes "
                f"(the image's budget), not {raw or 'missing'!r}"
            )
        values.append(int(raw))
    flash, ram = values
    if not 0 < flash <= BOARD_FLASH_BYTES or not 0 < ram <= BOARD_RAM_BYTES:
        raise SetupError(
            f"{config._path}: the budget ({flash} B flash, {ram} B RAM) must fit the board "
            f"({BOARD_FLASH_BYTES} B, {BOARD_RAM_BYTES} B)"
        )
    return Budget(flash, ram)


@dataclass
class Sizes:
    flash_bytes: int
    ram_bytes: int
    budget: Budget
    sections: dict[str, int] = field(default_factory=dict)

    def report(self) -> str:
        b = self.budget
        return (
            f"flash {self.flash_bytes:,} of {b.flash_bytes:,} budgeted bytes "
            f"({b.flash_bytes - self.flash_bytes:,} free; the board has {BOARD_FLASH_BYTES:,})   "
            f"static RAM {self.ram_bytes:,} of {b.ram_bytes:,} "
            f"({b.ram_bytes - self.ram_bytes:,} free; the stack has the rest of {BOARD_RAM_BYTES:,}: "
            f"{BOARD_RAM_BYTES - self.ram_bytes:,})"
        )

    def problems(self) -> list[str]:
        found = []
        b = self.budget
        if self.flash_bytes > b.flash_bytes:
            found.append(
                f"flash {self.flash_bytes:,} bytes exceeds the budget of {b.flash_bytes:,} "
                f"(platformio.ini board_upload.maximum_size)"
            )
        if self.ram_bytes > b.ram_bytes:
            found.append(
                f"static RAM {self.ram_bytes:,} bytes exceeds the budget of {b.ram_bytes:,} "
                f"(platformio.ini board_upload.maximum_ram_size; the stack needs the rest of "
                f"{BOARD_RAM_BYTES:,})"
            )
        return found
