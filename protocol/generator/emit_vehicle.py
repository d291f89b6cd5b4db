"""The outputs of vehicle.toml: firmware/lib/link/vehicle_gen.h and host/rovernav/vehicle_gen.py, the
vehicle's facts as C++ and as Python constants."""

from __future__ import annotations

from .definition import banner, camel


def _cpp_type(value: int) -> tuple[str, str]:
    return ("uint16_t", "") if value <= 0xFFFF else ("uint32_t", "UL")


def _wrap(text: str, prefix: str, width: int = 100) -> str:
    lines, line = [], ""
    for word in text.split():
        if line and len(prefix) + len(line) + 1 + len(word) > width:
            lines.append(prefix + line)
            line = word
        else:
            line = f"{line} {word}" if line else word
    lines.append(prefix + line)
    return "\n".join(lines) + "\n"


def render_vehicle_h(d: dict) -> str:
    out = [
        banner("//", "protocol/vehicle.toml"),
        "// The rover's and the board's facts: one definition for the firmware (core, hal, shell), the\n"
        "// host and the simulator. Derived values (half-widths, diagonals) are computed from these.\n",
        "#pragma once\n#include <stdint.h>\n\nnamespace rovernav {\n\n",
    ]
    for f in d["vehicle_facts"]:
        ctype, suffix = _cpp_type(f["value"])
        out.append(_wrap(f["doc"], "/// "))
        out.append(f"constexpr {ctype} k{camel(f['name'])} = {f['value']}{suffix};\n")
    out.append("\n}  // namespace rovernav\n")
    return "".join(out)


def render_vehicle_py(d: dict) -> str:
    out = [
        banner("#", "protocol/vehicle.toml"),
        '"""The rover\'s and the board\'s facts (generated from protocol/vehicle.toml).\n\n'
        "One definition for the firmware, the host and the simulator; each name ends in its unit.\n"
        'Derived values (metres, half-widths, diagonals) are computed from these where they are used.\n"""\n',
    ]
    for f in d["vehicle_facts"]:
        out.append("\n" + _wrap(f["doc"], "#: "))
        out.append(f"{f['name'].upper()} = {f['value']}\n")
    out.append("\nFACTS: dict[str, int] = {\n")
    for f in d["vehicle_facts"]:
        out.append(f"    {f['name']!r}: {f['name'].upper()},\n")
    out.append("}\n")
    return "".join(out)
