"""Where the Uno image's flash and RAM go: by library, and the largest symbols.

Used by `python tools/build_uno.py --size-report`. The image is linked with LTO, which inlines
across libraries: a function counts where the linker kept it (most of lib/core is inside
Rover::step), so the split is of the code as it ships, not as it was written.

A symbol of the final ELF is given to a library by, in order:
  1. the symbol tables of the project's archives and objects (external symbols; the LTO objects
     list no file-local ones) and of the toolchain's libraries, in the link's order (avr-libc's
     libm before libgcc, as the driver puts them);
  2. its namespace: rovernav::core, rovernav::hal, other rovernav:: (the link library);
  3. the one library whose sources name its identifier (a file-local variable such as an
     anonymous namespace's ring buffer);
and otherwise to "other". Bytes of a section that no symbol covers (the vector table, start-up
code, alignment) are "start-up and vectors".
"""

from __future__ import annotations

import re
import subprocess
from dataclasses import dataclass, field
from pathlib import Path

# LTO and IPA clones keep their origin's name with a suffix: foo.constprop.3, foo.lto_priv.192.
CLONE_SUFFIX = re.compile(r"(\.(constprop|lto_priv|part|isra|cold|clone)(\.\d+)?)+$")
FLASH_TYPES = set("TtWwVv")  # .text (PROGMEM tables are in .text too)
DATA_TYPES = set("Dd")  # .data: flash (its initial values) and RAM
BSS_TYPES = set("BbSs")  # .bss / .noinit: RAM

TOOLCHAIN_LIBS = (  # (row name, file name as -print-file-name takes it)
    ("libm (avr-libc: soft float, math)", "libm.a"),
    ("libgcc (integer helpers)", None),  # -print-libgcc-file-name
    ("libc (avr-libc)", "libc.a"),
    ("device library (EEPROM)", "libatmega328p.a"),
)
STARTUP = "start-up and vectors"
OTHER = "other"


@dataclass
class Symbol:
    name: str  # demangled, clone suffixes kept
    mangled: str
    size: int
    kind: str  # nm's type letter
    library: str = OTHER

    @property
    def flash(self) -> int:
        return self.size if self.kind in FLASH_TYPES or self.kind in DATA_TYPES else 0

    @property
    def ram(self) -> int:
        return self.size if self.kind in DATA_TYPES or self.kind in BSS_TYPES else 0


@dataclass
class SizeReport:
    libraries: dict[str, dict[str, int]] = field(default_factory=dict)  # name -> {flash, ram}
    symbols: list[Symbol] = field(default_factory=list)

    def largest(self, n: int = 20) -> list[Symbol]:
        return sorted(self.symbols, key=lambda s: (-s.size, s.name))[:n]

    def as_dict(self, n: int = 20) -> dict:
        return {
            "libraries": self.libraries,
            "largest_symbols": [
                {
                    "name": s.name,
                    "library": s.library,
                    "bytes": s.size,
                    "in": "flash" if s.ram == 0 else ("ram" if s.flash == 0 else "flash+ram"),
                }
                for s in self.largest(n)
            ],
        }

    def render(self, n: int = 20) -> str:
        lines = [
            "by library (as linked: LTO inlines across libraries; a function counts where it was kept)",
            f"  {'library':<38} {'flash B':>8} {'RAM B':>7}",
        ]
        for name, row in sorted(self.libraries.items(), key=lambda kv: (-kv[1]["flash"], kv[0])):
            lines.append(f"  {name:<38} {row['flash']:>8,} {row['ram']:>7,}")
        total_flash = sum(r["flash"] for r in self.libraries.values())
        total_ram = sum(r["ram"] for r in self.libraries.values())
        lines.append(f"  {'total':<38} {total_flash:>8,} {total_ram:>7,}")
        lines.append(f"the {n} largest symbols")
        for s in self.largest(n):
            where = "RAM" if s.flash == 0 else ("flash+RAM" if s.ram else "flash")
            lines.append(f"  {s.size:>6,} B  {where:<9} {s.library:<10} {short_name(s.name)}")
        return "\n".join(lines)


def short_name(name: str, width: int = 90) -> str:
    """A demangled name without its parameter list's types, cut to width."""
    anon = "(anonymous namespace)"
    name = name.replace(anon, "\0")
    name = re.sub(r"\((?:[^()]|\([^()]*\))*\)", "()", name, count=1).replace("\0", anon)
    return name if len(name) <= width else name[: width - 3] + "..."


def _lines(cmd: list[str], env: dict | None, stdin: str | None = None) -> list[str]:
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env, input=stdin)
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed: {proc.stderr.strip()}")
    return proc.stdout.splitlines()


def defined_symbols(nm: str, path: Path, env: dict | None) -> set[str]:
    names = set()
    for line in _lines([nm, "-p", "--defined-only", str(path)], env):
        parts = line.split()
        if len(parts) == 3 and parts[1] in FLASH_TYPES | DATA_TYPES | BSS_TYPES | set("Rr"):
            names.add(CLONE_SUFFIX.sub("", parts[2]))
    return names


def elf_symbols(nm: str, cxxfilt: str, elf: Path, env: dict | None) -> list[Symbol]:
    rows = []
    for line in _lines([nm, "-p", "-S", "--defined-only", str(elf)], env):
        parts = line.split()
        if len(parts) == 4:
            _, size, kind, mangled = parts
            rows.append((mangled, int(size, 16), kind))
    # c++filt leaves a name with a clone suffix as it is: demangle the name, keep the suffix.
    bases = [CLONE_SUFFIX.sub("", m) for m, _, _ in rows]
    demangled = _lines([cxxfilt], env, "\n".join(bases) + "\n")
    return [
        Symbol(name=d + m[len(b) :], mangled=m, size=s, kind=k)
        for (m, s, k), b, d in zip(rows, bases, demangled)
        if k in FLASH_TYPES | DATA_TYPES | BSS_TYPES
    ]


def identifier(name: str) -> str:
    """The unqualified identifier of a demangled name: '(anonymous namespace)::rx_ring' -> rx_ring."""
    name = CLONE_SUFFIX.sub("", re.sub(r" \[clone [^]]*\]", "", name)).replace("(anonymous namespace)::", "")
    name = re.sub(r"^_GLOBAL__sub_I_", "", name)  # a file's static constructors, named by its first function
    base = name.split("(", 1)[0]
    return base.rsplit("::", 1)[-1].strip()


COMMENT_OR_STRING = re.compile(r'//[^\n]*|/\*.*?\*/|"(?:\\.|[^"\\])*"|;[^\n]*', re.S)


def code_of(path: Path) -> str:
    """A source file without its comments and strings (and an assembler file's ; comments)."""
    text = path.read_text(encoding="utf-8", errors="replace")
    if path.suffix != ".S":
        return COMMENT_OR_STRING.sub(lambda m: "" if not m.group(0).startswith(";") else m.group(0), text)
    return COMMENT_OR_STRING.sub("", text)


def defined_in(ident: str, texts: dict[str, str]) -> str | None:
    """The one library whose code defines `ident` at namespace scope (a line that starts in its
    first column: a variable `Type ident;`, `= ...`, `[...]`, `{...}`; a function `ident(...) {`),
    else the one that names it at all, else None."""
    if not ident:
        return None
    name = re.escape(ident)
    definition = re.compile(
        rf"^\S[^\n;(]*[\w>*&]\s+{name}\s*(\[[^]\n]*\]\s*)*(=|;|\{{)|"
        rf"^\S[^\n;(]*\b{name}\s*\([^;{{)]*\)\s*(const\s*)?\{{",
        re.M,
    )
    for pattern in (definition, re.compile(rf"\b{name}\b")):
        found = [lib for lib, text in texts.items() if pattern.search(text)]
        if len(found) == 1:
            return found[0]
        if found:
            return None
    return None


def by_namespace(name: str) -> str | None:
    if name.startswith("rovernav::core::"):
        return "core"
    if name.startswith("rovernav::hal::"):
        return "hal"
    if name.startswith("rovernav::"):
        return "link"
    return None


def attribute(symbols: list[Symbol], tables: list[tuple[str, set[str]]], sources: dict[str, list[Path]]) -> None:
    """Sets each symbol's library (see the module's doc)."""
    texts = {lib: "\n".join(code_of(p) for p in files) for lib, files in sources.items()}
    for s in symbols:
        # A file's static constructors (_GLOBAL__sub_I_<its first function>) go with that function.
        key = re.sub(r"^_GLOBAL__sub_I_", "", CLONE_SUFFIX.sub("", s.mangled))
        if key == "main" and any("setup" in names and "loop" in names for lib, names in tables if lib == "src"):
            s.library = "src"  # the Arduino core's main() with the shell's setup() and loop() inlined
            continue
        hit = next((lib for lib, names in tables if key in names), None)
        if hit is None:
            hit = by_namespace(re.sub(r"^\(anonymous namespace\)::", "", s.name))
        if hit is None:
            hit = defined_in(identifier(s.name), texts)
        s.library = hit or OTHER


def report(
    elf: Path,
    tools: dict[str, str],
    env: dict | None,
    project: list[tuple[str, list[Path]]],
    sources: dict[str, list[Path]],
    toolchain_libs: list[tuple[str, Path]],
    sections: dict[str, int],
) -> SizeReport:
    """tools: nm (an LTO-aware one: avr-gcc-nm), binutils nm and c++filt. project: (library, its
    archives or objects) in the link's order; sources: library -> its source files; sections:
    the ELF's section sizes (avr-size -A)."""
    symbols = elf_symbols(tools["nm"], tools["c++filt"], elf, env)
    tables = []
    for lib, files in project:
        names: set[str] = set()
        for f in files:
            names |= defined_symbols(tools["gcc-nm"], f, env)
        tables.append((lib, names))
    for lib, path in toolchain_libs:
        if path.is_file():
            tables.append((lib, defined_symbols(tools["nm"], path, env)))
    attribute(symbols, tables, sources)
    rep = SizeReport(symbols=symbols)
    for s in symbols:
        row = rep.libraries.setdefault(s.library, {"flash": 0, "ram": 0})
        row["flash"] += s.flash
        row["ram"] += s.ram
    flash = sections.get(".text", 0) + sections.get(".data", 0)
    ram = sections.get(".data", 0) + sections.get(".bss", 0) + sections.get(".noinit", 0)
    rest_flash = flash - sum(r["flash"] for r in rep.libraries.values())
    rest_ram = ram - sum(r["ram"] for r in rep.libraries.values())
    if rest_flash or rest_ram:
        rep.libraries[STARTUP] = {"flash": rest_flash, "ram": rest_ram}
    return rep
