"""The Python output of messages.toml: host/rovernav/link/messages_gen.py (render_py: constants,
enums, the parameters, a dataclass per message)."""

from __future__ import annotations

from .definition import CRC_BYTES, HEADER_BYTES, TYPES, banner, camel, param_scale


def render_py(d: dict) -> str:
    p = d["protocol"]
    out = [
        banner("#"),
        '"""The link protocol\'s messages, enums and parameters (generated)."""\n',
        "from __future__ import annotations\n\n",
        "import dataclasses\nimport enum\nimport struct\nfrom typing import ClassVar\n\n",
        "from ..vehicle_gen import UART_BUFFER_BYTES  # noqa: F401  (a vehicle fact; the link reads it here)\n",
        "from .schema import FieldSpec, Message, ParamSpec\n\n",
        f"PROTOCOL_VERSION = {p['version']}\n",
        f"SCHEMA_HASH = 0x{d['schema_hash']:08X}\n",
        "# Signed frames ([signing] in protocol/messages.toml)\n",
        f"SIGN_FLAG = 0x{d['signing']['flag']:02X}\n",
        f"SIGN_COUNTER_BYTES = {d['signing']['counter_bytes']}\n",
        f"SIGN_TAG_BYTES = {d['signing']['tag_bytes']}\n",
        f"SIGN_EPOCH_UNIX_S = {d['signing']['epoch_unix_s']}\n",
        f"SIGN_PERSIST_STEP = {d['signing']['persist_step']}\n",
        f"SIGN_RESET_MARGIN = {d['signing']['reset_margin']}\n",
        f"SIGN_PROVISION_WINDOW_MS = {d['signing']['provision_window_ms']}\n",
        f"SIGN_HOST_TO_ROVER = {d['signing']['host_to_rover']}\n",
        f"SIGN_ROVER_TO_HOST = {d['signing']['rover_to_host']}\n",
        f"SIGN_CONSENT_PIN = {d['signing']['consent_pin']}\n",
        f"SIGN_CONSENT_RESET_BIT = 0x{d['signing']['consent_reset_bit']:02X}\n",
        "SIGN_UNSIGNED_IDS = frozenset({"
        + ", ".join(f"0x{m['id']:02X}" for m in d["messages"] if m["name"] in d["signing"].get("unsigned", []))
        + "})\n",
        "# A fleet ([fleet] in protocol/messages.toml): a rover's address in bits ADDRESS_SHIFT.. of the version\n"
        "# byte (ADDRESS_MASK; VERSION_MASK the version's bits), and a fleet rover's grant to speak\n"
        f"MAX_ROVERS = {d['fleet']['max_rovers']}\n",
        f"ADDRESS_SHIFT = {d['fleet']['address_shift']}\n",
        f"ADDRESS_MASK = 0x{(d['fleet']['max_rovers'] - 1) << d['fleet']['address_shift']:02X}\n",
        f"VERSION_MASK = 0x{(1 << d['fleet']['address_shift']) - 1:02X}\n",
        f"GRANT_BYTES = {d['fleet']['grant_bytes']}\n",
        f"GRANT_MS = {d['fleet']['grant_ms']}\n",
        f"MAX_SIGNED_RAW_FRAME = {HEADER_BYTES + p['max_payload'] + CRC_BYTES + d['signing']['counter_bytes'] + d['signing']['tag_bytes']}\n",
        f"MAX_PAYLOAD = {p['max_payload']}\n",
        f"MAX_RAW_FRAME = {HEADER_BYTES + p['max_payload'] + CRC_BYTES}\n",
        f"MAX_WAYPOINTS = {p['max_waypoints']}\n",
        f"WAYPOINTS_PER_CHUNK = {p['waypoints_per_chunk']}\n",
        "\n",
    ]
    for e in d.get("enums", []):
        base = "enum.IntFlag" if e.get("bitmask") else "enum.IntEnum"
        out.append(f'\nclass {camel(e["name"])}({base}):\n    """{e.get("doc", "")}"""\n\n')
        for v in e["values"]:
            out.append(f"    {v['name'].upper()} = {v['value']}\n")
            if v.get("doc"):
                out.append(f'    """{v["doc"]}"""\n')
    out.append('\n\nclass Param(enum.IntEnum):\n    """Parameters set by CONFIG."""\n\n')
    for prm in d.get("params", []):
        out.append(f"    {prm['name'].upper()} = {prm['id']}\n")
    out.append("\n\nPARAMS: dict[Param, ParamSpec] = {\n")
    for prm in d.get("params", []):
        scale = param_scale(prm["name"])
        out.append(
            f"    Param.{prm['name'].upper()}: ParamSpec({prm['id']}, {prm['name']!r}, {prm['unit']!r}, "
            f"{prm['default']}, {prm['min']}, {prm['max']}, {prm['doc']!r}"
            + (f", scale={scale}" if scale != 1 else "")
            + "),\n"
        )
    out.append("}\n")
    for m in d["messages"]:
        fmt = "<" + "".join(TYPES[f["type"]][1] * f.get("count", 1) for f in m["fields"])
        out.append(f'\n\n@dataclasses.dataclass\nclass {camel(m["name"])}(Message):\n    """{m["doc"]}"""\n\n')
        out.append(
            f"    ID: ClassVar[int] = 0x{m['id']:02X}\n    NAME: ClassVar[str] = {m['name']!r}\n"
            f"    DIRECTION: ClassVar[str] = {m['direction']!r}\n"
            f"    STRUCT: ClassVar[struct.Struct] = struct.Struct({fmt!r})\n"
            "    FIELDS: ClassVar[tuple[FieldSpec, ...]] = (\n"
        )
        for f in m["fields"]:
            out.append(
                f"        FieldSpec({f['name']!r}, {f['type']!r}, {f.get('count', 0)}, "
                f"{f.get('unit', '')!r}, {f.get('doc', '')!r}),\n"
            )
        out.append("    )\n\n")
        for f in m["fields"]:
            if "count" in f:
                out.append(f"    {f['name']}: tuple[int, ...] = {tuple([0] * f['count'])!r}\n")
            else:
                out.append(f"    {f['name']}: int = 0\n")
    out.append("\n\nMESSAGES: dict[int, type[Message]] = {\n")
    for m in d["messages"]:
        out.append(f"    0x{m['id']:02X}: {camel(m['name'])},\n")
    out.append("}\nMESSAGES_BY_NAME: dict[str, type[Message]] = {cls.NAME: cls for cls in MESSAGES.values()}\n")
    return "".join(out)
