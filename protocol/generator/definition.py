"""Reading and checking the definitions: protocol/messages.toml and protocol/vehicle.toml.

load() returns the definition as a dict (the vehicle's facts in it, parameter limits that name a
fact replaced by its value, the schema hash added) or raises DefinitionError naming the bad entry.
Also here: the paths of the definitions and of the generated files, the wire's integer types, and
the helpers every emitter uses (camel, param_scale, payload_size, banner).
"""

from __future__ import annotations

import binascii
import json
import re
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent.parent
DEFINITION = ROOT / "protocol" / "messages.toml"
VEHICLE = ROOT / "protocol" / "vehicle.toml"
VECTORS = ROOT / "protocol" / "vectors.json"
OUT_CPP = ROOT / "firmware" / "lib" / "link" / "messages_gen.h"
OUT_PY = ROOT / "host" / "rovernav" / "link" / "messages_gen.py"
OUT_VECTORS_H = ROOT / "firmware" / "test" / "test_link" / "vectors_gen.h"
OUT_VEHICLE_H = ROOT / "firmware" / "lib" / "link" / "vehicle_gen.h"
OUT_VEHICLE_PY = ROOT / "host" / "rovernav" / "vehicle_gen.py"

# A vehicle fact's name ends in its unit.
FACT_UNITS = ("_mm", "_ms", "_cdeg", "_baud", "_bytes")
# The vehicle's facts that change the meaning of bytes on the wire, and the table of the schema
# hash's input each was hashed under before it moved to vehicle.toml (so that the move left the
# hash as it was): the sonar's range is a parameter's limit, the buffer bounds the largest frame.
WIRE_FACTS = {"uart_buffer_bytes": "protocol", "sonar_max_range_mm": "sensors"}

# type -> (bytes, struct code, C++ type, min, max)
TYPES = {
    "u8": (1, "B", "uint8_t", 0, 0xFF),
    "i8": (1, "b", "int8_t", -0x80, 0x7F),
    "u16": (2, "H", "uint16_t", 0, 0xFFFF),
    "i16": (2, "h", "int16_t", -0x8000, 0x7FFF),
    "u32": (4, "I", "uint32_t", 0, 0xFFFFFFFF),
    "i32": (4, "i", "int32_t", -0x80000000, 0x7FFFFFFF),
}
# A message field's C++ type: its integer as little-endian bytes (firmware/lib/link/wire_layout.h),
# so that a message struct is laid out as its payload.
WIRE_TYPES = {"u16": "wire::u16le", "i16": "wire::i16le", "u32": "wire::u32le", "i32": "wire::i32le"}
HEADER_BYTES = 3  # version, msg_id, seq
CRC_BYTES = 2
IDENT = re.compile(r"^[a-z][a-z0-9_]*$")


class DefinitionError(ValueError):
    """The definition breaks a rule; the message names the place."""


def camel(name: str) -> str:
    return "".join(part.capitalize() for part in name.split("_"))


def param_scale(name: str) -> int:
    """A parameter's scale, from its name: the wire's integer is the working value times this
    (pid_kp_x100: 100, speed_mm_s_per_pwm_x1000: 1000, right_bias_permille: 1000; else 1)."""
    m = re.search(r"_x(\d+)$", name)
    if m:
        return int(m.group(1))
    return 1000 if name.endswith("_permille") else 1


def payload_size(message: dict) -> int:
    return sum(TYPES[f["type"]][0] * f.get("count", 1) for f in message["fields"])


def load_vehicle(path: Path = VEHICLE) -> list[dict]:
    """Read and validate the vehicle's facts: each a name ending in its unit, a positive integer
    and a doc line; raise DefinitionError naming the bad entry."""
    with open(path, "rb") as fh:
        v = tomllib.load(fh)
    facts = v.get("fact")
    if not isinstance(facts, list) or not facts or set(v) != {"fact"}:
        raise DefinitionError("vehicle.toml must hold [[fact]] entries and nothing else")
    seen: set[str] = set()
    for f in facts:
        name = f.get("name", "?")
        if not isinstance(name, str) or not IDENT.match(name) or name in seen:
            raise DefinitionError(f"fact {name!r}: bad or repeated name")
        seen.add(name)
        if not name.endswith(FACT_UNITS):
            raise DefinitionError(f"fact {name}: its name must end in its unit ({', '.join(FACT_UNITS)})")
        value = f.get("value")
        if not isinstance(value, int) or isinstance(value, bool) or not 0 < value < 1 << 31:
            raise DefinitionError(f"fact {name}: value must be an integer 1..2^31-1")
        if not isinstance(f.get("doc"), str) or not f["doc"].strip():
            raise DefinitionError(f"fact {name}: a doc line is missing")
        if set(f) != {"name", "value", "doc"}:
            raise DefinitionError(f"fact {name}: only name, value and doc")
    for name in WIRE_FACTS:
        if name not in seen:
            raise DefinitionError(f"fact {name} is missing (the wire depends on it)")
    return facts


def load(path: Path = DEFINITION, vehicle_path: Path | None = None) -> dict:
    """Read and validate the definition and the vehicle's facts (vehicle.toml beside `path`, else
    the repository's); raise DefinitionError naming the bad entry."""
    with open(path, "rb") as fh:
        d = tomllib.load(fh)
    if vehicle_path is None:
        vehicle_path = path.with_name("vehicle.toml") if path.with_name("vehicle.toml").exists() else VEHICLE
    d["vehicle_facts"] = load_vehicle(vehicle_path)
    vehicle = d["vehicle"] = {f["name"]: f["value"] for f in d["vehicle_facts"]}
    for table in ("sensors", "body"):
        if table in d:
            raise DefinitionError(f"[{table}] moved to protocol/vehicle.toml")
    proto = d.get("protocol", {})
    if "uart_buffer_bytes" in proto:
        raise DefinitionError("[protocol].uart_buffer_bytes moved to protocol/vehicle.toml")
    for key in ("version", "max_payload", "max_waypoints", "waypoints_per_chunk"):
        if not isinstance(proto.get(key), int):
            raise DefinitionError(f"[protocol].{key} must be an integer")
    seen_ids: dict[int, str] = {}
    seen_names: set[str] = set()
    for m in d.get("messages", []):
        name = m.get("name", "?")
        if not IDENT.match(name) or name in seen_names:
            raise DefinitionError(f"message {name!r}: bad or repeated name")
        seen_names.add(name)
        mid = m.get("id")
        if not isinstance(mid, int) or not 0 < mid < 256 or mid in seen_ids:
            raise DefinitionError(f"message {name}: id {mid!r} is not a free byte (1..255)")
        seen_ids[mid] = name
        if m.get("direction") not in ("host_to_rover", "rover_to_host", "both"):
            raise DefinitionError(f"message {name}: direction must be host_to_rover, rover_to_host or both")
        fnames = set()
        for f in m.get("fields", []):
            if f.get("type") not in TYPES:
                raise DefinitionError(f"message {name}.{f.get('name')}: unknown type {f.get('type')!r}")
            if not IDENT.match(f.get("name", "")) or f["name"] in fnames:
                raise DefinitionError(f"message {name}: bad or repeated field {f.get('name')!r}")
            fnames.add(f["name"])
            if "count" in f and (not isinstance(f["count"], int) or f["count"] < 2):
                raise DefinitionError(f"message {name}.{f['name']}: count must be an integer >= 2")
        if payload_size(m) > proto["max_payload"]:
            raise DefinitionError(
                f"message {name}: payload {payload_size(m)} bytes > max_payload {proto['max_payload']}"
            )
    sig = d.get("signing")
    if not isinstance(sig, dict):
        raise DefinitionError("[signing] is missing")
    for key in (
        "flag",
        "counter_bytes",
        "tag_bytes",
        "epoch_unix_s",
        "persist_step",
        "reset_margin",
        "provision_window_ms",
        "host_to_rover",
        "rover_to_host",
        "consent_pin",
        "consent_reset_bit",
    ):
        if not isinstance(sig.get(key), int) or isinstance(sig.get(key), bool) or sig[key] < 0:
            raise DefinitionError(f"[signing].{key} must be a non-negative integer")
    if not 0 < sig["tag_bytes"] <= 8 or not 0 < sig["counter_bytes"] <= 8:
        raise DefinitionError("[signing]: tag_bytes and counter_bytes must be 1..8 (a SipHash tag is 8 bytes)")
    if sig["flag"] & proto["version"] or not 0 < sig["flag"] < 256:
        raise DefinitionError("[signing].flag must be a byte whose bits are free in [protocol].version")
    if sig["persist_step"] != 65536:
        raise DefinitionError("[signing].persist_step must be 65536: the rover compares the counters' bytes 2-5")
    if sig["reset_margin"] <= sig["persist_step"]:
        raise DefinitionError("[signing].reset_margin must exceed persist_step: a counter would repeat after a reset")
    if not sig["consent_pin"] <= 19:
        raise DefinitionError("[signing].consent_pin must be an Uno pin, 0..19 (A0-A5 are 14-19)")
    bit = sig["consent_reset_bit"]
    if bit < 0x10 or bit > 0x8000 or bit & (bit - 1):
        raise DefinitionError("[signing].consent_reset_bit must be one bit above MCUSR's reset flags (0x10..0x8000)")
    for name in sig.get("unsigned", []):
        if name not in seen_names:
            raise DefinitionError(f"[signing].unsigned: no message {name!r}")
    if max_encoded_frame(proto["max_payload"] + sig["counter_bytes"] + sig["tag_bytes"]) > vehicle["uart_buffer_bytes"]:
        raise DefinitionError(
            f"a signed frame of max_payload bytes would pass vehicle.toml's uart_buffer_bytes "
            f"({vehicle['uart_buffer_bytes']}) on the wire"
        )
    fleet = d.get("fleet")
    if not isinstance(fleet, dict):
        raise DefinitionError("[fleet] is missing")
    for key in ("max_rovers", "address_shift", "grant_bytes", "grant_ms"):
        least = 0 if key == "grant_ms" else 1  # grant_ms 0: the step that opened the grant only
        if not isinstance(fleet.get(key), int) or isinstance(fleet.get(key), bool) or fleet[key] < least:
            raise DefinitionError(f"[fleet].{key} must be a whole number, {least} or more")
    rovers = fleet["max_rovers"]
    if rovers & (rovers - 1) or rovers < 2:
        raise DefinitionError("[fleet].max_rovers must be a power of two, 2 or more: the addresses fill their bits")
    mask = (rovers - 1) << fleet["address_shift"]
    if mask > 0xFF or mask & sig["flag"] or proto["version"] >= 1 << fleet["address_shift"]:
        raise DefinitionError(
            "[fleet]: the address bits (max_rovers - 1) << address_shift must lie in the version byte, "
            "above [protocol].version's bits and apart from [signing].flag"
        )
    if (
        not max_encoded_frame(proto["max_payload"] + sig["counter_bytes"] + sig["tag_bytes"])
        <= fleet["grant_bytes"]
        <= 0xFF
    ):
        raise DefinitionError(
            "[fleet].grant_bytes must let the largest signed frame through, and be at most 255 (the rover "
            "counts it in a byte)"
        )
    if fleet["grant_ms"] > 250:
        raise DefinitionError("[fleet].grant_ms must be at most 250: a grant is one slot of the host's round")
    enum_names = set()
    for e in d.get("enums", []):
        if not IDENT.match(e.get("name", "")) or e["name"] in enum_names:
            raise DefinitionError(f"enum {e.get('name')!r}: bad or repeated name")
        enum_names.add(e["name"])
        values = [v["value"] for v in e["values"]]
        if len(set(values)) != len(values):
            raise DefinitionError(f"enum {e['name']}: repeated value")
    pids = set()
    for p in d.get("params", []):
        if p["id"] in pids or not 0 < p["id"] < 256:
            raise DefinitionError(f"param {p['name']}: id {p['id']} repeated or not 1..255")
        pids.add(p["id"])
        for key in ("min", "default", "max"):  # a default or limit may name a vehicle's fact
            if isinstance(p[key], str):
                if p[key] not in vehicle:
                    raise DefinitionError(f"param {p['name']}: {key} {p[key]!r} is not a fact of protocol/vehicle.toml")
                p[key] = vehicle[p[key]]
        if not p["min"] <= p["default"] <= p["max"]:
            raise DefinitionError(f"param {p['name']}: default {p['default']} outside [{p['min']}, {p['max']}]")
    d["schema_hash"] = schema_hash(d)
    return d


def max_encoded_frame(body_payload: int) -> int:
    """Bytes on the wire of a frame whose payload (and signature) is `body_payload` bytes: the
    header, the CRC, COBS's overhead and the delimiter."""
    raw = HEADER_BYTES + body_payload + CRC_BYTES
    return raw + (raw + 253) // 254 + 1


def schema_hash(d: dict) -> int:
    """CRC-32 (the zlib polynomial) of everything that changes the meaning of bytes on the wire.

    Documentation is left out, so a reworded `doc` does not split a fleet; names, ids,
    types, units, enum values and parameter ids and limits are in.
    """
    wire_facts: dict[str, dict] = {}
    for name, table in WIRE_FACTS.items():
        wire_facts.setdefault(table, {})[name] = d["vehicle"][name]
    canon = {
        "protocol": {**d["protocol"], **wire_facts["protocol"]},
        "messages": [
            {
                "name": m["name"],
                "id": m["id"],
                "direction": m["direction"],
                "fields": [[f["name"], f["type"], f.get("count", 1), f.get("unit", "")] for f in m["fields"]],
            }
            for m in d["messages"]
        ],
        "enums": [
            {"name": e["name"], "values": [[v["name"], v["value"]] for v in e["values"]]} for e in d.get("enums", [])
        ],
        "params": [[p["id"], p["name"], p["unit"], p["min"], p["max"]] for p in d.get("params", [])],
        "signing": {k: v for k, v in d["signing"].items()},
        "fleet": dict(d["fleet"]),
        "sensors": wire_facts["sensors"],
    }
    text = json.dumps(canon, sort_keys=True, separators=(",", ":"))
    return binascii.crc32(text.encode()) & 0xFFFFFFFF


def banner(comment: str, source: str = "protocol/messages.toml") -> str:
    return (
        f"{comment} GENERATED by protocol/generate.py from {source}. Do not edit:\n"
        f"{comment} change the definition and run `python3 protocol/generate.py`.\n"
    )
