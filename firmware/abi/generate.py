#!/usr/bin/env python3
"""Generate the C ABIs' struct layouts, for C and for Python's ctypes, from firmware/abi/abi.toml.

Writes, with a first line saying they are generated and from what:
  firmware/abi/rover_abi_gen.h        rover_abi.h's structs and constants (rover_abi.h includes it)
  tools/avrsim/unocore_abi_gen.h      the simavr harness's structs (tools/avrsim/unocore.c)
  host/rovernav/cores/abi_gen.py      both as ctypes.Structure classes

Each C header also gets <ABI>_STRUCT_SIZES and <ABI>_LAYOUT_WORDS, the initializers a library
reports its layout with (sizeof each struct; then the constants and offsetof every field), so that
the list of fields is not written a third time by hand.

    python3 firmware/abi/generate.py            write the outputs
    python3 firmware/abi/generate.py --check    exit 1 if a committed output drifted

Standard library only, like protocol/generate.py: it runs before anything is installed.
"""

from __future__ import annotations

import argparse
import re
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent.parent
DEFINITION = ROOT / "firmware" / "abi" / "abi.toml"
OUT_PY = ROOT / "host" / "rovernav" / "cores" / "abi_gen.py"
SOURCE = "firmware/abi/abi.toml"
ME = "firmware/abi/generate.py"

# type -> (C type, ctypes type)
TYPES = {
    "u8": ("uint8_t", "ctypes.c_uint8"),
    "i8": ("int8_t", "ctypes.c_int8"),
    "u16": ("uint16_t", "ctypes.c_uint16"),
    "i16": ("int16_t", "ctypes.c_int16"),
    "u32": ("uint32_t", "ctypes.c_uint32"),
    "i32": ("int32_t", "ctypes.c_int32"),
    "u64": ("uint64_t", "ctypes.c_uint64"),
    "i64": ("int64_t", "ctypes.c_int64"),
    "f32": ("float", "ctypes.c_float"),
    "const u8*": ("const uint8_t*", "ctypes.POINTER(ctypes.c_uint8)"),
}
IDENT = re.compile(r"^[a-z][a-z0-9_]*$")
MACRO = re.compile(r"^[A-Z][A-Z0-9_]*$")
CLASS = re.compile(r"^[A-Z][A-Za-z0-9]*$")


class DefinitionError(ValueError):
    """The definition breaks a rule; the message names the place."""


def load(path: Path = DEFINITION) -> dict:
    """The definition, checked: {abi name: {"version", "version_macro", "header", "what",
    "constants": [...], "structs": [...]}} in the file's order."""
    with open(path, "rb") as f:
        raw = tomllib.load(f)
    if not raw:
        raise DefinitionError("no ABI defined")
    macros: set[str] = set()
    classes: set[str] = set()
    headers: set[str] = set()
    for abi_name, abi in raw.items():
        where = f"[{abi_name}]"
        if not isinstance(abi, dict) or not IDENT.match(abi_name):
            raise DefinitionError(f"{where} is not a table named in lower_case")
        for key in ("what", "version", "version_macro", "header", "structs"):
            if key not in abi:
                raise DefinitionError(f"{where} lacks {key!r}")
        if not isinstance(abi["version"], int) or abi["version"] < 1:
            raise DefinitionError(f"{where} version must be a positive integer")
        if not MACRO.match(abi["version_macro"]) or not abi["version_macro"].endswith("_VERSION"):
            raise DefinitionError(
                f"{where} version_macro {abi['version_macro']!r} is not a macro name ending in _VERSION"
            )
        if not abi["header"].endswith("_gen.h") or abi["header"] in headers:
            raise DefinitionError(f"{where} header {abi['header']!r} must end in _gen.h and be its own")
        headers.add(abi["header"])
        consts: dict[str, int] = {}
        for c in abi.get("constants", []):
            name = c.get("name", "")
            if not MACRO.match(name) or name in macros:
                raise DefinitionError(f"{where} constant {name!r} is not a new macro name")
            if not isinstance(c.get("value"), int) or c["value"] < 0:
                raise DefinitionError(f"{where} constant {name} needs a non-negative integer value")
            if "names" in c and len(c["names"]) != c["value"]:
                raise DefinitionError(f"{where} constant {name} is {c['value']} but names {len(c['names'])}")
            macros.add(name)
            consts[name] = c["value"]
        macros.add(abi["version_macro"])
        structs: set[str] = set()
        for st in abi["structs"]:
            sname = st.get("name", "")
            swhere = f"{where} struct {sname!r}"
            if not IDENT.match(sname) or sname in structs:
                raise DefinitionError(f"{swhere}: not a new lower_case name")
            structs.add(sname)
            if not CLASS.match(st.get("python", "")) or st["python"] in classes:
                raise DefinitionError(f"{swhere}: python {st.get('python')!r} is not a new CamelCase class name")
            classes.add(st["python"])
            if not st.get("fields"):
                raise DefinitionError(f"{swhere} has no fields")
            seen: set[str] = set()
            for fd in st["fields"]:
                fname = fd.get("name", "")
                fwhere = f"{swhere} field {fname!r}"
                if not IDENT.match(fname) or fname in seen:
                    raise DefinitionError(f"{fwhere}: not a new lower_case name")
                seen.add(fname)
                if fd.get("type") not in TYPES:
                    raise DefinitionError(f"{fwhere}: type {fd.get('type')!r} is not one of {', '.join(TYPES)}")
                unit = fd.get("unit")
                if unit is not None and not fname.endswith("_" + unit):
                    raise DefinitionError(f"{fwhere}: its unit is {unit!r} but its name does not end in _{unit}")
                count = fd.get("count")
                if count is not None:
                    value = consts.get(count) if isinstance(count, str) else count
                    if not isinstance(value, int) or isinstance(value, bool) or value < 1:
                        raise DefinitionError(
                            f"{fwhere}: count {count!r} is neither a positive number nor a constant of [{abi_name}]"
                        )
                    if fd["type"].endswith("*"):
                        raise DefinitionError(f"{fwhere}: an array of pointers is not supported")
    return raw


def prefix(abi: dict) -> str:
    """ROVER_ABI_VERSION -> ROVER_ABI: the generated macros' and Python names' prefix."""
    return abi["version_macro"][: -len("_VERSION")]


def banner(comment_open: str, comment_close: str = "") -> str:
    return (
        f"{comment_open} GENERATED by {ME} from {SOURCE}. Do not edit: edit the definition and run "
        f"python3 {ME}{comment_close}\n"
    )


# ---------------------------------------------------------------------------- C


def c_field(fd: dict) -> str:
    ctype = TYPES[fd["type"]][0]
    count = f"[{fd['count']}]" if "count" in fd else ""
    decl = f"  {ctype} {fd['name']}{count};"
    return f"{decl:<34}/* {fd['doc']} */" if "doc" in fd else decl


def c_header(abi: dict) -> str:
    guard = "ROVERNAV_" + Path(abi["header"]).name.replace(".", "_").upper()
    p = prefix(abi)
    out = [
        banner("/*", " */"),
        f"/* The structs and constants of {abi['what']}. */\n",
        f"#ifndef {guard}\n#define {guard}\n",
        "#include <stddef.h>\n#include <stdint.h>\n\n",
        f"#define {abi['version_macro']} {abi['version']}\n",
    ]
    for c in abi.get("constants", []):
        line = f"#define {c['name']} {c['value']}"
        if "doc" in c or "names" in c:
            doc = c.get("doc", "")
            if "names" in c:
                doc += (": " if doc else "") + ", ".join(c["names"])
            line = f"{line:<33}/* {doc} */"
        out.append(line + "\n")
    for st in abi["structs"]:
        out.append(f"\n/* {st['doc']} */\n" if "doc" in st else "\n")
        out.append(f"typedef struct {st['name']} {{\n")
        out += [c_field(fd) + "\n" for fd in st["fields"]]
        out.append(f"}} {st['name']};\n")
    sizes = [f"sizeof({st['name']})" for st in abi["structs"]]
    words = (
        sizes
        + [c["name"] for c in abi.get("constants", [])]
        + [f"offsetof({st['name']}, {fd['name']})" for st in abi["structs"] for fd in st["fields"]]
    )
    out.append(
        "\n/* Initializers for a library to report its layout with, for a host to check its copy against:\n"
        " * sizeof each struct above, in order; and those, then the constants, then the offset of every\n"
        " * field in declaration order. */\n"
    )
    out.append(f"#define {p}_STRUCT_SIZES {', '.join(sizes)}\n")
    out.append(f"#define {p}_LAYOUT_WORDS \\\n" + ", \\\n".join(f"  {w}" for w in words) + "\n")
    out.append("\n#endif\n")
    return "".join(out)


# ---------------------------------------------------------------------------- Python


def q(text: str) -> str:
    """A Python string literal in double quotes."""
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def tup(items) -> str:
    """A Python tuple's source."""
    items = list(items)
    return f"({items[0]},)" if len(items) == 1 else f"({', '.join(items)})"


def py_field(fd: dict) -> str:
    ctype = TYPES[fd["type"]][1]
    if "count" in fd:
        ctype = f"{ctype} * {fd['count']}"
    line = f"        ({q(fd['name'])}, {ctype}),"
    return f"{line:<56}# {fd['doc']}" if "doc" in fd else line


def python_module(d: dict) -> str:
    out = [
        banner("#"),
        '"""The structs of the C ABIs the simulator loads, as ctypes.Structure classes (generated).\n\n',
        "Each class names its C struct in `_c_name_`; each ABI has its version, its constants and its\n",
        "structs in declaration order (<ABI>_STRUCTS), as the header's <ABI>_LAYOUT_WORDS lists them.\n",
        '"""\n',
        "import ctypes\n",
    ]
    for abi_name, abi in d.items():
        p = prefix(abi)
        out.append(f"\n# {'-' * 76} [{abi_name}]\n")
        out.append(f"# {abi['what']}\n\n")
        out.append(f"{abi['version_macro']} = {abi['version']}\n")
        for c in abi.get("constants", []):
            out.append(f"{c['name']} = {c['value']}" + (f"   # {c['doc']}" if "doc" in c else "") + "\n")
            if "names" in c:
                out.append(f"{c['name']}_NAMES = {tup(q(n) for n in c['names'])}\n")
        names = [c["name"] for c in abi.get("constants", [])]
        out.append(f"{p}_CONSTANTS = {{{', '.join(f'{q(n)}: {n}' for n in names)}}}\n")
        for st in abi["structs"]:
            doc = st.get("doc", "")
            out.append(f"\n\nclass {st['python']}(ctypes.Structure):\n")
            out.append(f'    """{doc}{" " if doc else ""}(C: {st["name"]})"""\n\n')
            out.append(f"    _c_name_ = {q(st['name'])}\n")
            out.append("    _fields_ = [\n")
            out += [py_field(fd) + "\n" for fd in st["fields"]]
            out.append("    ]\n")
        out.append(f"\n\n{p}_STRUCTS = {tup(st['python'] for st in abi['structs'])}\n")
    return "".join(out)


def outputs(d: dict) -> dict[Path, str]:
    files = {ROOT / abi["header"]: c_header(abi) for abi in d.values()}
    files[OUT_PY] = python_module(d)
    return files


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument(
        "--check", action="store_true", help="exit 1 if a committed output differs from what the definition gives"
    )
    args = ap.parse_args(argv)
    try:
        d = load()
    except (DefinitionError, tomllib.TOMLDecodeError) as exc:
        print(f"{SOURCE}: {exc}", file=sys.stderr)
        return 2
    drifted = []
    for path, text in outputs(d).items():
        current = path.read_text() if path.exists() else None
        if current == text:
            continue
        if args.check:
            drifted.append(str(path.relative_to(ROOT)))
        else:
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(text)
            print(f"wrote {path.relative_to(ROOT)}")
    if args.check:
        if drifted:
            print(f"generated files drifted from {SOURCE}: {', '.join(drifted)}\nrun: python3 {ME}", file=sys.stderr)
            return 1
        print(
            f"generated files match {SOURCE} ("
            + ", ".join(f"{abi['version_macro']} {abi['version']}" for abi in d.values())
            + ")"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
