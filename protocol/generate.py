#!/usr/bin/env python3
"""Generate the link protocol code from protocol/messages.toml, and the vehicle's facts from
protocol/vehicle.toml.

Writes, with a banner naming this file and the definition:
  firmware/lib/link/messages_gen.h       C++ structs, enums, parameter limits
  host/rovernav/link/messages_gen.py     Python dataclasses and enums
  firmware/test/test_link/vectors_gen.h  the golden vectors as C++ test cases
  firmware/lib/link/vehicle_gen.h        the vehicle's facts as C++ constants
  host/rovernav/vehicle_gen.py           the vehicle's facts as Python constants

    python3 protocol/generate.py                 write the outputs
    python3 protocol/generate.py --check         exit 1 if a committed output drifted
    python3 protocol/generate.py --update-vectors  recompute frame_hex (and the signed frames' bytes
                                                   and tags) in vectors.json

Standard library only: it runs before anything is installed.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

# The generator's modules (protocol/generator/) lie beside this file: found whether it is run as a
# script or loaded from its path (the tests).
if str(Path(__file__).resolve().parent) not in sys.path:
    sys.path.insert(0, str(Path(__file__).resolve().parent))

from generator.definition import (  # noqa: E402
    CRC_BYTES, HEADER_BYTES, OUT_CPP, OUT_PY, OUT_VECTORS_H, OUT_VEHICLE_H, OUT_VEHICLE_PY, ROOT, TYPES, VECTORS,
    WIRE_TYPES, DefinitionError, banner, camel, load, param_scale, payload_size)
from generator.definition import schema_hash  # noqa: E402, F401  (the tests call generate.schema_hash)


# ---------------------------------------------------------------- reference encoder
# Written apart from the host runtime on purpose: the golden vectors it produces are
# checked against both the C++ and the Python implementation.

def _crc16_ccitt_false(data: bytes) -> int:
    crc = 0xFFFF
    for byte in data:
        crc ^= byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) if crc & 0x8000 else (crc << 1)
            crc &= 0xFFFF
    return crc


def _cobs(data: bytes) -> bytes:
    out, block, after_full_block = bytearray(), bytearray(), False
    for byte in data:
        after_full_block = False
        if byte == 0:
            out += bytes([len(block) + 1]) + block
            block = bytearray()
        else:
            block.append(byte)
            if len(block) == 254:
                out += b"\xff" + block
                block, after_full_block = bytearray(), True
    if not after_full_block:  # data ending on a full block needs no final code byte
        out += bytes([len(block) + 1]) + block
    return bytes(out)


def _reference_body(d: dict, message: dict, seq: int, fields: dict, version: int) -> bytearray:
    """version, msg_id, seq and the payload, each field little-endian in order."""
    body = bytearray([version, message["id"], seq])
    for f in message["fields"]:
        size, _, _, lo, hi = TYPES[f["type"]]
        values = fields[f["name"]] if "count" in f else [fields[f["name"]]]
        if len(values) != f.get("count", 1):
            raise DefinitionError(f"vector for {message['name']}.{f['name']}: wrong element count")
        for v in values:
            if not lo <= v <= hi:
                raise DefinitionError(f"vector for {message['name']}.{f['name']}: {v} out of range")
            body += int(v).to_bytes(size, "little", signed=lo < 0)
    return body


def reference_frame(d: dict, message: dict, seq: int, fields: dict) -> bytes:
    body = _reference_body(d, message, seq, fields, d["protocol"]["version"])
    body += _crc16_ccitt_false(bytes(body)).to_bytes(2, "little")
    return _cobs(bytes(body)) + b"\x00"


# SipHash-2-4, written from the paper's definition (Aumasson and Bernstein, "SipHash: a fast
# short-input PRF", 2012, section 2), not from either runtime, and checked against the paper's
# test vector (its appendix A) before it signs anything.
_U64 = (1 << 64) - 1


def _rotl64(x: int, b: int) -> int:
    return ((x << b) | (x >> (64 - b))) & _U64


def _sip_round(v0: int, v1: int, v2: int, v3: int) -> tuple[int, int, int, int]:
    """One SipRound: the paper's two half-rounds side by side (add, rotate, xor; v0 and v2 rotated by 32)."""
    v0 = (v0 + v1) & _U64
    v2 = (v2 + v3) & _U64
    v1 = _rotl64(v1, 13) ^ v0
    v3 = _rotl64(v3, 16) ^ v2
    v0 = _rotl64(v0, 32)
    v2 = (v2 + v1) & _U64
    v0 = (v0 + v3) & _U64
    v1 = _rotl64(v1, 17) ^ v2
    v3 = _rotl64(v3, 21) ^ v0
    v2 = _rotl64(v2, 32)
    return v0, v1, v2, v3


def reference_siphash24(key: bytes, m: bytes) -> bytes:
    """SipHash-2-4 of m under the 16-byte key: the 64-bit result's 8 bytes, little-endian."""
    if len(key) != 16:
        raise ValueError("a SipHash key is 16 bytes")
    k0, k1 = int.from_bytes(key[:8], "little"), int.from_bytes(key[8:], "little")
    # Initialisation: the key xor the constants "somepseudorandomlygeneratedbytes".
    v = (k0 ^ 0x736F6D6570736575, k1 ^ 0x646F72616E646F6D, k0 ^ 0x6C7967656E657261, k1 ^ 0x7465646279746573)
    # m is parsed as w = ceil((b + 1) / 8) little-endian words, the last one holding m's last
    # 0-7 bytes, then zeros, then b mod 256 in its top byte.
    b = len(m)
    padded = m + bytes(-(b + 1) % 8) + bytes((b % 256,))
    for i in range(0, len(padded), 8):
        mi = int.from_bytes(padded[i:i + 8], "little")
        v0, v1, v2, v3 = v[0], v[1], v[2], v[3] ^ mi
        for _ in range(2):                      # c = 2 compression rounds
            v0, v1, v2, v3 = _sip_round(v0, v1, v2, v3)
        v = (v0 ^ mi, v1, v2, v3)
    v0, v1, v2, v3 = v[0], v[1], v[2] ^ 0xFF, v[3]
    for _ in range(4):                          # d = 4 finalisation rounds
        v0, v1, v2, v3 = _sip_round(v0, v1, v2, v3)
    return (v0 ^ v1 ^ v2 ^ v3).to_bytes(8, "little")


# The paper's appendix A: key 00 01 .. 0f, message 00 01 .. 0e (15 bytes), SipHash-2-4 =
# 0xa129ca6149be45e5 (so its bytes, little-endian, are e5 45 be 49 61 ca 29 a1).
SIPHASH_PAPER_VECTOR = (bytes(range(16)), bytes(range(15)), 0xA129CA6149BE45E5)


def check_reference_siphash() -> None:
    key, m, expected = SIPHASH_PAPER_VECTOR
    got = int.from_bytes(reference_siphash24(key, m), "little")
    if got != expected:
        raise AssertionError(f"reference SipHash-2-4 gives 0x{got:016x} on the paper's vector, not 0x{expected:016x}")


def reference_signed_frame(d: dict, message: dict, seq: int, fields: dict, key: bytes, counter: int,
                           direction: str) -> tuple[bytes, bytes, bytes]:
    """A signed frame ([signing]): its bytes on the wire (delimiter included), its tag, and what
    the tag is SipHash-2-4 of (the direction byte, then version|flag .. counter)."""
    sig = d["signing"]
    if direction not in ("host_to_rover", "rover_to_host"):
        raise DefinitionError(f"signed vector for {message['name']}: direction {direction!r}")
    if message["direction"] not in (direction, "both"):
        raise DefinitionError(f"signed vector: {message['name']} is not sent {direction}")
    if not 0 <= counter < 1 << (8 * sig["counter_bytes"]):
        raise DefinitionError(f"signed vector for {message['name']}: counter {counter} out of range")
    check_reference_siphash()
    body = _reference_body(d, message, seq, fields, d["protocol"]["version"] | sig["flag"])
    body += counter.to_bytes(sig["counter_bytes"], "little")
    mac_input = bytes((sig[direction],)) + bytes(body)
    tag = reference_siphash24(key, mac_input)[:sig["tag_bytes"]]
    body += tag
    body += _crc16_ccitt_false(bytes(body)).to_bytes(2, "little")
    return _cobs(bytes(body)) + b"\x00", tag, mac_input


# ---------------------------------------------------------------- C++

# A parameter's storage on the rover: the least width its limits allow, in this order (the widest
# first, so that a value's width and sign follow from where it lies in the store).
PARAM_KINDS = (("i32", 4, True), ("u16", 2, False), ("i16", 2, True), ("u8", 1, False), ("i8", 1, True))


def param_kind(prm: dict) -> tuple[str, int, bool]:
    """(name, width, signed): the narrowest kind that holds min..max."""
    for name, width, signed in reversed(PARAM_KINDS):
        lo, hi = TYPES[name][3], TYPES[name][4]
        if lo <= prm["min"] and prm["max"] <= hi:
            return name, width, signed
    return PARAM_KINDS[0]


def param_layout(d: dict) -> tuple[dict[int, int], dict[str, int], int]:
    """Each parameter's byte offset in the store (by id), where each kind's region begins, and
    the store's size."""
    offsets, starts, at = {}, {}, 0
    for name, width, _ in PARAM_KINDS:
        starts[name] = at
        for prm in sorted(d.get("params", []), key=lambda x: x["id"]):
            if param_kind(prm)[0] == name:
                offsets[prm["id"]] = at
                at += width
    return offsets, starts, at


def render_param_table(d: dict) -> str:
    max_id = max(x["id"] for x in d["params"])
    by_id = {x["id"]: x for x in d["params"]}
    offsets, starts, size = param_layout(d)
    if size * 3 > 0xFFFF or size >= 0xFF:
        raise DefinitionError("[[params]]: the parameters need more than 254 bytes on the rover")
    out = ["/// Where each parameter's value lies in the rover's store of kParamBytes bytes, by id - 1 (0xFF: no\n"
           "/// such parameter). A value takes the least width its limits allow, little-endian, the widest first:\n"
           "/// int32 from 0, then uint16 from kParamAtU16, int16 from kParamAtI16, uint8 from kParamAtU8 and\n"
           "/// int8 from kParamAtI8 (param_width, param_signed). Its default, min and max lie in kParamLimits\n"
           "/// at 3 x its offset, in its width. In flash on the AVR.\n",
           "enum : uint8_t {\n"
           f"  kParamBytes = {size},\n  kParamAtU16 = {starts['u16']},\n  kParamAtI16 = {starts['i16']},\n"
           f"  kParamAtU8 = {starts['u8']},\n  kParamAtI8 = {starts['i8']},\n  kParamNone = 0xFF\n}};\n",
           f"static const uint8_t kParamOffset[{max_id}] ROVERNAV_PROGMEM = {{\n"]
    for pid in range(1, max_id + 1):
        prm = by_id.get(pid)
        if prm:
            kind = param_kind(prm)[0]
            out.append(f"  {offsets[pid]},  // {pid} {prm['name']} ({kind})\n")
        else:
            out.append(f"  kParamNone,  // {pid} unused\n")
    out.append("};\n")
    limits = bytearray(3 * size)
    for pid, prm in by_id.items():
        name, width, signed = param_kind(prm)
        for k, key in enumerate(("default", "min", "max")):
            at = 3 * offsets[pid] + k * width
            limits[at:at + width] = prm[key].to_bytes(width, "little", signed=signed)
    out.append(f"static const uint8_t kParamLimits[{len(limits)}] ROVERNAV_PROGMEM = {{\n")
    for pid in sorted(by_id, key=lambda i: offsets[i]):
        prm = by_id[pid]
        name, width, signed = param_kind(prm)
        at = 3 * offsets[pid]
        row = ", ".join(f"0x{b:02X}" for b in limits[at:at + 3 * width])
        out.append(f"  {row},  // {pid} {prm['name']}: {prm['default']}, {prm['min']}..{prm['max']}\n")
    out.append("};\n")
    printed = bytes(int(b, 16) for line in out if line.startswith("  0x") for b in line.split("//")[0].replace(",", " ").split())
    assert printed == bytes(limits), "kParamLimits printed out of order"
    out.append("\n/// The width in bytes, and the sign, of the value stored at `offset`.\n"
               "inline uint8_t param_width(uint8_t offset) {\n"
               "  return offset < kParamAtU16 ? 4 : (offset < kParamAtU8 ? 2 : 1);\n}\n"
               "inline bool param_signed(uint8_t offset) {\n"
               "  return offset < kParamAtU16 || (offset >= kParamAtI16 && offset < kParamAtU8) || offset >= kParamAtI8;\n}\n"
               "/// The integer of `width` little-endian bytes at p (in flash if from_flash), sign-extended if\n"
               "/// is_signed. One copy for the store and the limits (noinline: LTO would paste it everywhere).\n"
               "__attribute__((noinline)) inline int32_t param_load(const uint8_t* p, uint8_t width, bool is_signed, bool from_flash) {\n"
               "  uint8_t b[4];\n"
               "  uint8_t fill = 0;\n"
               "  for (uint8_t i = 0; i < 4; ++i) {\n"
               "    if (i < width) {\n"
               "      b[i] = from_flash ? flash_read_u8(p + i) : p[i];\n"
               "      fill = is_signed && (b[i] & 0x80u) ? 0xFF : 0;\n"
               "    } else {\n"
               "      b[i] = fill;\n"
               "    }\n"
               "  }\n"
               "  return static_cast<int32_t>(static_cast<uint32_t>(b[0]) | static_cast<uint32_t>(b[1]) << 8 |\n"
               "                              static_cast<uint32_t>(b[2]) << 16 | static_cast<uint32_t>(b[3]) << 24);\n}\n\n"
               "/// Default and limits of parameter `id`; false if there is no such parameter.\n"
               "inline bool param_limits(uint8_t id, int32_t& def, int32_t& lo, int32_t& hi) {\n"
               "  if (id == 0 || id > kParamMaxId) return false;\n"
               "  const uint8_t at = flash_read_u8(&kParamOffset[id - 1]);\n"
               "  if (at == kParamNone) return false;\n"
               "  const uint8_t w = param_width(at);\n"
               "  const bool sgn = param_signed(at);\n"
               "  int32_t* const to[3] = {&def, &lo, &hi};\n"
               "  for (uint8_t k = 0; k < 3; ++k) *to[k] = param_load(kParamLimits + 3 * at + k * w, w, sgn, true);\n"
               "  return true;\n}\n\n")
    return "".join(out)


def render_cpp(d: dict) -> str:
    p = d["protocol"]
    max_raw = HEADER_BYTES + p["max_payload"] + CRC_BYTES
    out = [banner("//"), "#pragma once\n", "#include <stdint.h>\n", '#include "progmem.h"\n',
           '#include "vehicle_gen.h"  // the vehicle\'s facts (kUartBufferBytes, kSonarMaxRangeMm, ...)\n',
           '#include "wire_layout.h"\n\n',
           "namespace rovernav {\n\n",
           f"enum : uint8_t {{ kProtocolVersion = {p['version']} }};\n",
           f"static const uint32_t kSchemaHash = 0x{d['schema_hash']:08X}UL;\n",
           f"enum : uint8_t {{\n  kMaxPayload = {p['max_payload']},\n  kMaxRawFrame = {max_raw},  // header + payload + CRC\n"
           f"  kMaxWaypoints = {p['max_waypoints']},\n  kWaypointsPerChunk = {p['waypoints_per_chunk']}\n}};\n\n"]
    sig = d["signing"]
    by_name = {m["name"]: m["id"] for m in d["messages"]}
    out.append("// Signed frames ([signing] in protocol/messages.toml).\n"
               f"enum : uint8_t {{\n  kSignFlag = 0x{sig['flag']:02X},\n  kSignCounterBytes = {sig['counter_bytes']},\n"
               f"  kSignTagBytes = {sig['tag_bytes']},\n  kSignHostToRover = {sig['host_to_rover']},\n"
               f"  kSignRoverToHost = {sig['rover_to_host']},\n"
               f"  kSignConsentPin = {sig['consent_pin']},  // held to GND at a reset: consent to an unsigned PROVISION\n"
               f"  kMaxSignedRawFrame = {max_raw + sig['counter_bytes'] + sig['tag_bytes']}  // a signed frame, CRC included\n}};\n"
               f"static const uint32_t kSignEpochUnixS = {sig['epoch_unix_s']}UL;\n"
               f"static const uint32_t kSignResetMargin = {sig['reset_margin']}UL;\n"
               f"static const uint32_t kSignPersistStep = {sig['persist_step']}UL;\n"
               f"static const uint16_t kSignProvisionWindowMs = {sig['provision_window_ms']};\n"
               f"/// The reset cause bit (Rover::begin, the boot EVENT) that says the consent pin was held to GND.\n"
               f"static const uint16_t kSignConsentResetBit = 0x{sig['consent_reset_bit']:02X};\n"
               "/// Whether a rover with a key takes host message `id` unsigned.\n"
               "inline bool may_be_unsigned(uint8_t id) {\n  return "
               + " || ".join(f"id == 0x{by_name[n]:02X}" for n in sig.get("unsigned", [])) + ";\n}\n\n")
    for e in d.get("enums", []):
        out.append(f"/// {e.get('doc', '')}\n")
        if e.get("bitmask"):
            out.append(f"struct {camel(e['name'])} {{\n  enum : uint16_t {{\n")
        else:
            out.append(f"enum class {camel(e['name'])} : uint8_t {{\n")
        for v in e["values"]:
            doc = f"  ///< {v['doc']}" if v.get("doc") else ""
            indent = "    " if e.get("bitmask") else "  "
            out.append(f"{indent}{camel(v['name'])} = {v['value']},{doc}\n")
        out.append("  };\n};\n\n" if e.get("bitmask") else "};\n\n")
    out.append("/// Parameters set by CONFIG.\nenum class Param : uint8_t {\n")
    for prm in d.get("params", []):
        out.append(f"  {camel(prm['name'])} = {prm['id']},  ///< [{prm['unit']}] {prm['doc']}\n")
    out.append("};\n")
    out.append(f"enum : uint8_t {{ kParamMaxId = {max(x['id'] for x in d['params'])} }};\n\n")
    scaled = [prm for prm in d.get("params", []) if param_scale(prm["name"]) != 1]
    out.append("/// A parameter's scale, from its name: the wire's integer is the working value times this\n"
               "/// (_x100: 100, _x1000 and _permille: 1000; 1 for the rest). For constants only.\n"
               "constexpr uint16_t param_scale(Param p) {\n  return "
               + "".join(f"p == Param::{camel(prm['name'])} ? {param_scale(prm['name'])} :\n         "
                         for prm in scaled) + "1;\n}\n\n")
    out.append(render_param_table(d))
    out.append("namespace msg {\n\n"
               "// Each message's bytes are its payload on the wire (fields in order, little-endian, no\n"
               "// padding: wire_layout.h), so encoding and decoding are one copy.\n\n")
    for m in d["messages"]:
        out.append(f"/// {m['doc']} ({m['direction'].replace('_', ' ')})\n")
        out.append(f"struct {camel(m['name'])} {{\n")
        out.append(f"  enum : uint8_t {{ kId = 0x{m['id']:02X}, kPayloadSize = {payload_size(m)} }};\n")
        for f in m["fields"]:
            ctype = WIRE_TYPES.get(f["type"], TYPES[f["type"]][2])
            arr = f"[{f['count']}]" if "count" in f else ""
            unit = f" [{f['unit']}]" if f.get("unit") else ""
            out.append(f"  {ctype} {f['name']}{arr};  ///<{unit} {f.get('doc', '')}\n".replace(" \n", "\n"))
        out.append("  /// Writes kPayloadSize bytes to p.\n"
                   "  void encode(uint8_t* p) const { wire::copy(p, this, kPayloadSize); }\n"
                   "  /// Reads kPayloadSize bytes from p.\n"
                   "  void decode(const uint8_t* p) { wire::copy(this, p, kPayloadSize); }\n"
                   "};\n")
        out.append(f"static_assert(sizeof({camel(m['name'])}) == {camel(m['name'])}::kPayloadSize, "
                   f"\"{m['name']}: its layout is its payload\");\n\n")
    out.append("}  // namespace msg\n\n")
    # A table in flash, searched: the compiler turns a switch over these ids into a lookup table
    # in the Uno's SRAM.
    out.append("/// Message ids and payload sizes, in flash.\n"
               f"static const uint8_t kPayloadSizes[{len(d['messages'])}][2] ROVERNAV_PROGMEM = {{\n")
    for m in d["messages"]:
        out.append(f"  {{0x{m['id']:02X}, {payload_size(m)}}},  // {m['name']}\n")
    out.append("};\n\n")
    out.append("/// Payload size of message `id`, or -1 if no message has that id.\n"
               "inline int16_t payload_size(uint8_t id) {\n"
               "  for (uint8_t i = 0; i < sizeof kPayloadSizes / sizeof kPayloadSizes[0]; ++i) {\n"
               "    if (flash_read_u8(&kPayloadSizes[i][0]) == id) return flash_read_u8(&kPayloadSizes[i][1]);\n"
               "  }\n  return -1;\n}\n\n}  // namespace rovernav\n")
    return "".join(out)


# ---------------------------------------------------------------- Python

def render_py(d: dict) -> str:
    p = d["protocol"]
    out = [banner("#"), '"""The link protocol\'s messages, enums and parameters (generated)."""\n',
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
           "SIGN_UNSIGNED_IDS = frozenset({" + ", ".join(
               f"0x{m['id']:02X}" for m in d["messages"] if m["name"] in d["signing"].get("unsigned", [])) + "})\n",
           f"MAX_SIGNED_RAW_FRAME = {HEADER_BYTES + p['max_payload'] + CRC_BYTES + d['signing']['counter_bytes'] + d['signing']['tag_bytes']}\n",
           f"MAX_PAYLOAD = {p['max_payload']}\n",
           f"MAX_RAW_FRAME = {HEADER_BYTES + p['max_payload'] + CRC_BYTES}\n",
           f"MAX_WAYPOINTS = {p['max_waypoints']}\n",
           f"WAYPOINTS_PER_CHUNK = {p['waypoints_per_chunk']}\n",
           "\n"]
    for e in d.get("enums", []):
        base = "enum.IntFlag" if e.get("bitmask") else "enum.IntEnum"
        out.append(f"\nclass {camel(e['name'])}({base}):\n    \"\"\"{e.get('doc', '')}\"\"\"\n\n")
        for v in e["values"]:
            out.append(f"    {v['name'].upper()} = {v['value']}\n")
            if v.get("doc"):
                out.append(f"    \"\"\"{v['doc']}\"\"\"\n")
    out.append("\n\nclass Param(enum.IntEnum):\n    \"\"\"Parameters set by CONFIG.\"\"\"\n\n")
    for prm in d.get("params", []):
        out.append(f"    {prm['name'].upper()} = {prm['id']}\n")
    out.append("\n\nPARAMS: dict[Param, ParamSpec] = {\n")
    for prm in d.get("params", []):
        scale = param_scale(prm["name"])
        out.append(f"    Param.{prm['name'].upper()}: ParamSpec({prm['id']}, {prm['name']!r}, {prm['unit']!r}, "
                   f"{prm['default']}, {prm['min']}, {prm['max']}, {prm['doc']!r}"
                   + (f", scale={scale}" if scale != 1 else "") + "),\n")
    out.append("}\n")
    for m in d["messages"]:
        fmt = "<" + "".join(TYPES[f["type"]][1] * f.get("count", 1) for f in m["fields"])
        out.append(f"\n\n@dataclasses.dataclass\nclass {camel(m['name'])}(Message):\n    \"\"\"{m['doc']}\"\"\"\n\n")
        out.append(f"    ID: ClassVar[int] = 0x{m['id']:02X}\n    NAME: ClassVar[str] = {m['name']!r}\n"
                   f"    DIRECTION: ClassVar[str] = {m['direction']!r}\n"
                   f"    STRUCT: ClassVar[struct.Struct] = struct.Struct({fmt!r})\n"
                   "    FIELDS: ClassVar[tuple[FieldSpec, ...]] = (\n")
        for f in m["fields"]:
            out.append(f"        FieldSpec({f['name']!r}, {f['type']!r}, {f.get('count', 0)}, "
                       f"{f.get('unit', '')!r}, {f.get('doc', '')!r}),\n")
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


# ---------------------------------------------------------------- golden vectors for C++

def _hex_bytes(data: bytes) -> str:
    return ", ".join(f"0x{b:02X}" for b in data)


def render_vectors_h(d: dict, vectors: dict) -> str:
    by_name = {m["name"]: m for m in d["messages"]}
    out = [banner("//").replace("protocol/messages.toml", "protocol/messages.toml and protocol/vectors.json"),
           "// The tables (kGoldenFrames, kBadFrames) are always defined. With ROVERNAV_GOLDEN_TEST_CASES\n"
           "// defined, one TEST_CASE per golden frame follows; the includer then provides\n"
           "// check_golden_encode(msg, seq, frame, len) and decode_golden<Msg>(frame, len, seq).\n",
           "#pragma once\n#include <stdint.h>\n\n"]
    tables_at = len(out)
    out.append("#ifdef ROVERNAV_GOLDEN_TEST_CASES\n")
    for i, v in enumerate(vectors["frames"]):
        m = by_name[v["message"]]
        cls = f"rovernav::msg::{camel(m['name'])}"
        frame = bytes.fromhex(v["frame_hex"])
        out.append(f'TEST_CASE("golden frame {v["name"]} ({m["name"]}) encodes and decodes byte for byte") {{\n')
        out.append(f"  static const uint8_t frame[] = {{{_hex_bytes(frame)}}};\n  {cls} m{{}};\n")
        for f in m["fields"]:
            if "count" in f:
                for j, x in enumerate(v["fields"][f["name"]]):
                    out.append(f"  m.{f['name']}[{j}] = {x};\n")
            else:
                out.append(f"  m.{f['name']} = {v['fields'][f['name']]}{'UL' if f['type'] == 'u32' else ''};\n")
        out.append(f"  check_golden_encode(m, {v['seq']}, frame, sizeof frame);\n")
        out.append(f"  const {cls} d = decode_golden<{cls}>(frame, sizeof frame, {v['seq']});\n")
        for f in m["fields"]:
            if "count" in f:
                for j in range(f["count"]):
                    out.append(f"  CHECK(d.{f['name']}[{j}] == m.{f['name']}[{j}]);\n")
            else:
                out.append(f"  CHECK(d.{f['name']} == m.{f['name']});\n")
        out.append("}\n\n")
    out.append("#endif  // ROVERNAV_GOLDEN_TEST_CASES\n")
    tables = []
    tables.append("struct BadFrame { const char* name; const char* counter; const uint8_t* bytes; uint8_t len; };\n")
    for i, b in enumerate(vectors["bad_frames"]):
        tables.append(f"static const uint8_t kBad{i}[] = {{{_hex_bytes(bytes.fromhex(b['hex']))}}};\n")
    tables.append("static const BadFrame kBadFrames[] = {\n")
    for i, b in enumerate(vectors["bad_frames"]):
        tables.append(f'  {{"{b["name"]}", "{b["counter"]}", kBad{i}, sizeof kBad{i}}},\n')
    tables.append("};\n\n")
    tables.append("struct GoldenFrame { const char* name; const uint8_t* bytes; uint8_t len; };\n")
    for i, v in enumerate(vectors["frames"]):
        tables.append(f"static const uint8_t kGolden{i}[] = {{{_hex_bytes(bytes.fromhex(v['frame_hex']))}}};\n")
    tables.append("static const GoldenFrame kGoldenFrames[] = {\n")
    for i, v in enumerate(vectors["frames"]):
        tables.append(f'  {{"{v["name"]}", kGolden{i}, sizeof kGolden{i}}},\n')
    tables.append("};\n\n")
    sig = d["signing"]
    tables.append("// Signed frames (vectors.json signed_frames): the key, the counter (little-endian, as on the wire),\n"
                  "// the direction byte, the frame's bytes on the wire (delimiter included), its tag, and what the tag\n"
                  "// is SipHash-2-4 of (the direction byte, then version|flag .. counter).\n"
                  f"struct SignedVector {{ const char* name; uint8_t direction; uint8_t msg_id; uint8_t key[16]; "
                  f"uint8_t counter[{sig['counter_bytes']}]; const uint8_t* wire; uint8_t wire_len; "
                  f"uint8_t tag[{sig['tag_bytes']}]; const uint8_t* mac_input; uint8_t mac_input_len; }};\n")
    signed = vectors.get("signed_frames", [])
    for i, s in enumerate(signed):
        tables.append(f"static const uint8_t kSignedWire{i}[] = {{{_hex_bytes(bytes.fromhex(s['frame_hex']))}}};\n")
        tables.append(f"static const uint8_t kSignedMacInput{i}[] = {{{_hex_bytes(bytes.fromhex(s['mac_input_hex']))}}};\n")
    tables.append(f"static const SignedVector kSignedVectors[{max(1, len(signed))}] = {{\n")
    for i, s in enumerate(signed):
        counter = s["counter"].to_bytes(sig["counter_bytes"], "little")
        tables.append(f'  {{"{s["name"]}", {sig[s["direction"]]}, 0x{by_name[s["message"]]["id"]:02X},\n'
                      f'   {{{_hex_bytes(bytes.fromhex(s["key_hex"]))}}},\n'
                      f'   {{{_hex_bytes(counter)}}},  // {s["counter"]}\n'
                      f'   kSignedWire{i}, sizeof kSignedWire{i}, {{{_hex_bytes(bytes.fromhex(s["tag_hex"]))}}},\n'
                      f'   kSignedMacInput{i}, sizeof kSignedMacInput{i}}},\n')
    tables.append("};\n\n")
    tables.append("// Every parameter as the definition gives it, written from its numbers (not from the rover's\n"
                  "// packed table, which test_params checks against this).\n"
                  "struct ParamSpec { uint8_t id; int32_t def, lo, hi; };\n"
                  "static const ParamSpec kParamSpecs[] = {\n")
    for prm in sorted(d.get("params", []), key=lambda x: x["id"]):
        tables.append(f"  {{{prm['id']}, {prm['default']}L, {prm['min']}L, {prm['max']}L}},  // {prm['name']}\n")
    tables.append("};\n")
    out[tables_at:tables_at] = tables + ["\n"]
    return "".join(out)


# ---------------------------------------------------------------- vectors.json

def update_vectors(d: dict, vectors: dict) -> dict:
    """Recompute every frame_hex from its fields, and the bad frames from the good ones."""
    by_name = {m["name"]: m for m in d["messages"]}
    for v in vectors["frames"]:
        v["frame_hex"] = reference_frame(d, by_name[v["message"]], v["seq"], v["fields"]).hex()
    first = bytes.fromhex(vectors["frames"][0]["frame_hex"])
    raw = bytearray(_uncobs(first[:-1]))
    bad = []
    flipped = bytearray(raw)
    flipped[4] ^= 0x01
    bad.append({"name": "payload byte changed", "counter": "bad_crc", "hex": (_cobs(bytes(flipped)) + b"\0").hex()})

    def reframe(body: bytes) -> bytes:
        body = bytes(body)
        return _cobs(body + _crc16_ccitt_false(body).to_bytes(2, "little")) + b"\0"

    unknown = bytearray(raw[:-2])
    unknown[1] = 0xEE
    bad.append({"name": "unknown message id", "counter": "unknown_id", "hex": reframe(unknown).hex()})
    short = bytearray(raw[:-3])
    bad.append({"name": "payload one byte short", "counter": "malformed", "hex": reframe(short).hex()})
    version = bytearray(raw[:-2])
    version[0] = 0x7F
    bad.append({"name": "wrong protocol version", "counter": "malformed", "hex": reframe(version).hex()})
    bad.append({"name": "too short for a header", "counter": "malformed", "hex": (_cobs(b"\x01\x02") + b"\0").hex()})
    bad.append({"name": "COBS block runs past the delimiter", "counter": "malformed", "hex": "05112233" + "00"})
    bad.append({"name": "longer than any frame", "counter": "overlong", "hex": ("41" * 70) + "00"})
    vectors["bad_frames"] = bad
    for s in vectors.get("signed_frames", []):
        frame, tag, mac_input = reference_signed_frame(d, by_name[s["message"]], s["seq"], s["fields"],
                                                       bytes.fromhex(s["key_hex"]), s["counter"], s["direction"])
        s["frame_hex"], s["tag_hex"], s["mac_input_hex"] = frame.hex(), tag.hex(), mac_input.hex()
    return vectors


def _uncobs(data: bytes) -> bytes:
    out, i = bytearray(), 0
    while i < len(data):
        code = data[i]
        out += data[i + 1:i + code]
        i += code
        if code < 0xFF and i < len(data):
            out.append(0)
    return bytes(out)


# ---------------------------------------------------------------- the vehicle's facts

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
    out = [banner("//", "protocol/vehicle.toml"),
           "// The rover's and the board's facts: one definition for the firmware (core, hal, shell), the\n"
           "// host and the simulator. Derived values (half-widths, diagonals) are computed from these.\n",
           "#pragma once\n#include <stdint.h>\n\nnamespace rovernav {\n\n"]
    for f in d["vehicle_facts"]:
        ctype, suffix = _cpp_type(f["value"])
        out.append(_wrap(f["doc"], "/// "))
        out.append(f"constexpr {ctype} k{camel(f['name'])} = {f['value']}{suffix};\n")
    out.append("\n}  // namespace rovernav\n")
    return "".join(out)


def render_vehicle_py(d: dict) -> str:
    out = [banner("#", "protocol/vehicle.toml"),
           '"""The rover\'s and the board\'s facts (generated from protocol/vehicle.toml).\n\n'
           "One definition for the firmware, the host and the simulator; each name ends in its unit.\n"
           'Derived values (metres, half-widths, diagonals) are computed from these where they are used.\n"""\n']
    for f in d["vehicle_facts"]:
        out.append("\n" + _wrap(f["doc"], "#: "))
        out.append(f"{f['name'].upper()} = {f['value']}\n")
    out.append("\nFACTS: dict[str, int] = {\n")
    for f in d["vehicle_facts"]:
        out.append(f"    {f['name']!r}: {f['name'].upper()},\n")
    out.append("}\n")
    return "".join(out)


def outputs(d: dict) -> dict[Path, str]:
    vectors = json.loads(VECTORS.read_text())
    return {OUT_CPP: render_cpp(d), OUT_PY: render_py(d), OUT_VECTORS_H: render_vectors_h(d, vectors),
            OUT_VEHICLE_H: render_vehicle_h(d), OUT_VEHICLE_PY: render_vehicle_py(d)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--check", action="store_true", help="exit 1 if a committed output differs from what the definition gives")
    ap.add_argument("--update-vectors", action="store_true", help="recompute frame_hex and bad frames in protocol/vectors.json")
    args = ap.parse_args(argv)
    try:
        d = load()
    except DefinitionError as exc:
        print(f"protocol/messages.toml or protocol/vehicle.toml: {exc}", file=sys.stderr)
        return 2
    if args.update_vectors:
        vectors = update_vectors(d, json.loads(VECTORS.read_text()))
        VECTORS.write_text(json.dumps(vectors, indent=1) + "\n")
        print(f"updated {VECTORS.relative_to(ROOT)}")
    drifted = []
    for path, text in outputs(d).items():
        current = path.read_text() if path.exists() else None
        if current != text:
            if args.check:
                drifted.append(str(path.relative_to(ROOT)))
            else:
                path.parent.mkdir(parents=True, exist_ok=True)
                path.write_text(text)
                print(f"wrote {path.relative_to(ROOT)}")
    if args.check:
        vectors = json.loads(VECTORS.read_text())
        if update_vectors(d, json.loads(VECTORS.read_text())) != vectors:
            drifted.append(str(VECTORS.relative_to(ROOT)) + " (its computed bytes: run --update-vectors)")
        if drifted:
            print("generated files drifted from protocol/messages.toml and protocol/vehicle.toml: " + ", ".join(drifted)
                  + "\nrun: python3 protocol/generate.py", file=sys.stderr)
            return 1
        print(f"generated files match the definition (schema hash 0x{d['schema_hash']:08X})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
