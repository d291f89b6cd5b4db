"""Reading the Uno image's ELF file: its section headers (how much SRAM its static data takes)
and its symbol table (which function each flash word belongs to, for the profile).

Plain `struct` reading of a 32-bit little-endian ELF (avr-gcc's output); names are demangled
with avr-c++filt (or c++filt) when one is installed.
"""

from __future__ import annotations

import dataclasses
import re
import shutil
import struct
import subprocess
from pathlib import Path

from .uno_harness import UnoSetupError


def _elf_sections(elf: Path) -> tuple[bytes, list[tuple[str, tuple]]]:
    """The ELF's bytes and its section headers as (name, (sh_name, type, flags, addr, offset,
    size, link, info, addralign, entsize))."""
    data = elf.read_bytes()
    if data[:4] != b"\x7fELF" or data[4] != 1 or data[5] != 1:
        raise UnoSetupError(f"{elf} is not a 32-bit little-endian ELF (an AVR image?)")
    (shoff,) = struct.unpack_from("<I", data, 0x20)
    shentsize, shnum, shstrndx = struct.unpack_from("<HHH", data, 0x2E)
    sections = [struct.unpack_from("<IIIIIIIIII", data, shoff + i * shentsize) for i in range(shnum)]
    names_off = sections[shstrndx][4]

    def name(sec) -> str:
        start = names_off + sec[0]
        return data[start : data.index(b"\0", start)].decode("ascii", "replace")

    return data, [(name(sec), sec) for sec in sections]


def static_ram_end(elf: Path) -> int:
    """The first SRAM address above .data, .bss and .noinit (where the heap, and the stack's
    deepest reach, would begin), from the ELF's section headers."""
    _, sections = _elf_sections(elf)
    end = 0x100  # the 328P's SRAM starts at 0x100
    for name, sec in sections:
        addr, size = sec[3], sec[5]
        if name in (".data", ".bss", ".noinit") and 0x800000 <= addr < 0x810000:
            end = max(end, addr - 0x800000 + size)
    return end


# ---------------------------------------------------------------------------- the symbol map

NO_SYMBOL = "(no symbol)"

# ATmega328P interrupt vectors (datasheet table 12-6), by number; 0 is RESET.
VECTORS_328P = (
    "RESET",
    "INT0",
    "INT1",
    "PCINT0",
    "PCINT1",
    "PCINT2",
    "WDT",
    "TIMER2_COMPA",
    "TIMER2_COMPB",
    "TIMER2_OVF",
    "TIMER1_CAPT",
    "TIMER1_COMPA",
    "TIMER1_COMPB",
    "TIMER1_OVF",
    "TIMER0_COMPA",
    "TIMER0_COMPB",
    "TIMER0_OVF",
    "SPI_STC",
    "USART_RX",
    "USART_UDRE",
    "USART_TX",
    "ADC",
    "EE_READY",
    "ANALOG_COMP",
    "TWI",
    "SPM_READY",
)


@dataclasses.dataclass(frozen=True)
class FunctionMap:
    """Which function each flash word of the image belongs to, from its symbol table."""

    names: list[str]  # demangled; the last one is NO_SYMBOL
    raw_names: list[str]  # as in the symbol table (the first of several entry points)
    starts: list[int]  # first byte address (0xFFFFFFFF for NO_SYMBOL)
    func_of_word: list[int]  # index into names, for each flash word of .text
    entry_words: list[int]  # 1 where a function's symbol (or another entry point of it) starts
    vector_handlers: dict[int, str]  # vector number -> the name of the function it jumps to

    @property
    def no_symbol(self) -> int:
        return len(self.names) - 1


def _demangle(names: list[str]) -> list[str]:
    for tool in ("avr-c++filt", "c++filt"):
        path = shutil.which(tool)
        if path is None:
            continue
        try:
            out = subprocess.run(
                [path], input="\n".join(names) + "\n", capture_output=True, text=True, timeout=30, check=True
            ).stdout.splitlines()
        except (OSError, subprocess.SubprocessError):
            continue
        if len(out) == len(names):
            return out
    return list(names)


def function_map(elf: Path) -> FunctionMap:
    """The functions of .text from the ELF's symbol table.

    - A sized symbol (FUNC or NOTYPE) covers [value, value + size), or up to the next sized
      symbol or hidden global label if that comes first (avr-ld's relaxation shrinks CALLs to
      RCALLs after avr-libc's sizes were taken).
    - An unsized label (the startup code's, __vectors, __bad_interrupt) covers from its address
      to the next symbol. Where several symbols share an address, a sized one wins, then a
      global, then a weak one.
    - A global unsized symbol (default visibility) inside a sized one is another entry point of
      it (avr-libc: __subsf3 flips a sign and falls into __addsf3; __floatunsisf and __floatsisf
      share their code): the function is named after both, "__subsf3 / __addsf3", and the code
      from there to the next symbol is the function's too.
    - A local label ('.do_clear_bss_loop'), and code past a sized symbol's end without a symbol
      of its own (avr-libc's special cases), belong to the function before them, as avr-objdump
      names them.
    - What no symbol covers (progmem tables) is NO_SYMBOL.

    With LTO, a function inlined into another has no symbol: its cycles are its caller's."""
    data, sections = _elf_sections(elf)
    text_idx = next((i for i, (name, _) in enumerate(sections) if name == ".text"), None)
    symtab = next((sec for name, sec in sections if sec[1] == 2), None)  # SHT_SYMTAB
    if text_idx is None or symtab is None:
        raise UnoSetupError(f"{elf} has no .text or no symbol table: cannot profile it (was it stripped?)")
    text = sections[text_idx][1]
    text_end = text[3] + text[5]
    strtab = sections[symtab[6]][1]
    syms, boundaries = [], set()
    for off in range(symtab[4], symtab[4] + symtab[5], 16):
        st_name, value, size, info, other, shndx = struct.unpack_from("<IIIBBH", data, off)
        if shndx != text_idx or value >= text_end:
            continue
        kind, bind = info & 0xF, info >> 4
        start = strtab[4] + st_name
        name = data[start : data.index(b"\0", start)].decode("ascii", "replace")
        if not name:
            continue
        boundaries.add(value)
        if kind in (0, 2):  # NOTYPE, FUNC; OBJECT (tables in flash) only bounds the labels
            rank = (size > 0, bind == 1, bind == 2, not name.startswith("."), other & 3 == 0)
            syms.append((value, size, rank, name))
    best: dict[int, tuple] = {}
    for sym in sorted(syms, key=lambda t: (t[0], t[3])):
        if sym[0] not in best or sym[2] > best[sym[0]][2]:
            best[sym[0]] = sym
    nwords = (text_end + 1) // 2
    owner = [-1] * nwords
    chosen = sorted(best.values())
    starts_sorted = sorted(boundaries) + [text_end]
    # a sized range ends at the next sized symbol, or at a hidden global label (libgcc's _exit):
    # avr-ld's relaxation shrinks CALLs to RCALLs after avr-libc's sizes were taken
    sized_starts = sorted(v for v, size, r, _n in chosen if size > 0 or (r[1] or r[2]) and not r[4]) + [text_end]
    for i, (value, size, _rank, _name) in enumerate(chosen):
        if size > 0:
            end = min(value + size, next(b for b in sized_starts if b > value))
            for w in range(value // 2, min(nwords, (end + 1) // 2)):
                if owner[w] < 0:
                    owner[w] = i
    entry_words = [0] * nwords
    alias_of: dict[int, list[str]] = {}  # chosen index of a function -> its other entry points
    for i, (value, size, rank, name) in enumerate(chosen):
        if size > 0:
            continue
        w = value // 2
        host = owner[w] if w < nwords else -1
        if host >= 0 and chosen[host][0] != value and rank[1] and rank[3] and rank[4]:
            alias_of.setdefault(host, []).append(name)  # another entry point: code of its host
            entry_words[w] = 1
        elif name.startswith(".") and w > 0 and owner[w - 1] >= 0:
            host = owner[w - 1]  # a local label goes on its function
        else:
            host = i
        end = next(b for b in starts_sorted if b > value)
        for w in range(value // 2, min(nwords, (end + 1) // 2)):
            if owner[w] < 0:
                owner[w] = host
    # code between a sized function's end and the next symbol (avr-libc's special cases, jumped
    # to from the next function) is the function's before it, as avr-objdump names it
    boundary_words = {b // 2 for b in boundaries}
    for w in range(1, nwords):
        if owner[w] < 0 and owner[w - 1] >= 0 and w not in boundary_words:
            owner[w] = owner[w - 1]
    used = sorted(set(o for o in owner if o >= 0))
    index = {old: new for new, old in enumerate(used)}
    raw = [chosen[i][3] for i in used] + [NO_SYMBOL]
    starts = [chosen[i][0] for i in used] + [0xFFFFFFFF]
    func_of_word = [index[o] if o >= 0 else len(used) for o in owner]
    for i in used:
        entry_words[chosen[i][0] // 2] = 1
    aliases = {index[host]: names for host, names in alias_of.items() if host in index}
    demangled = _demangle(raw[:-1])
    names = [" / ".join([d] + _demangle(aliases[f])) if f in aliases else d for f, d in enumerate(demangled)]
    names.append(NO_SYMBOL)
    handlers = {}
    all_names = {s[3]: s for s in syms}
    for v in range(1, len(VECTORS_328P)):
        sym = all_names.get(f"__vector_{v}")
        handlers[v] = f"__vector_{v}" if sym and sym[1] > 0 and sym[2][1] else "__bad_interrupt"
    return FunctionMap(names, raw, starts, func_of_word, entry_words, handlers)


def short_name(name: str) -> str:
    """A demangled name without its parameters, clone suffixes, anonymous namespaces and the
    rovernav namespace: 'rovernav::core::Rover::step(...) [clone .constprop.3]' -> 'core::Rover::step'."""
    n = re.sub(r"( \[clone [^\]]*\])+$", "", name).replace("(anonymous namespace)::", "")
    n = re.sub(r"\s+const$", "", n)
    if n.endswith(")"):
        depth = 0
        for i in range(len(n) - 1, -1, -1):
            depth += {")": 1, "(": -1}.get(n[i], 0)
            if depth == 0:
                if i > 0:
                    n = n[:i]
                break
    return re.sub(r"^rovernav::", "", n)
