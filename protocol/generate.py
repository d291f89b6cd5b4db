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

# This file keeps the golden vectors' reference encoder and the command line; the definitions and the
# outputs are read and written by the modules of protocol/generator/ (its __init__.py lists them),
# found beside this file whether it is run as a script or loaded from its path (the tests).
if str(Path(__file__).resolve().parent) not in sys.path:
    sys.path.insert(0, str(Path(__file__).resolve().parent))

from generator.definition import (  # noqa: E402
    OUT_CPP,
    OUT_PY,
    OUT_VECTORS_H,
    OUT_VEHICLE_H,
    OUT_VEHICLE_PY,
    ROOT,
    TYPES,
    VECTORS,
    DefinitionError,
    load,
)
from generator.definition import schema_hash  # noqa: E402, F401  (the tests call generate.schema_hash)
from generator.emit_cpp import render_cpp, render_vectors_h  # noqa: E402
from generator.emit_python import render_py  # noqa: E402
from generator.emit_vehicle import render_vehicle_h, render_vehicle_py  # noqa: E402


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


def _version_byte(d: dict, address: int) -> int:
    """The version byte of a frame to or from the rover at `address` ([fleet]; 0: a lone rover)."""
    fleet = d["fleet"]
    if not 0 <= address < fleet["max_rovers"]:
        raise DefinitionError(f"address {address} is not 0..{fleet['max_rovers'] - 1}")
    return d["protocol"]["version"] | address << fleet["address_shift"]


def reference_frame(d: dict, message: dict, seq: int, fields: dict, address: int = 0) -> bytes:
    body = _reference_body(d, message, seq, fields, _version_byte(d, address))
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
        mi = int.from_bytes(padded[i : i + 8], "little")
        v0, v1, v2, v3 = v[0], v[1], v[2], v[3] ^ mi
        for _ in range(2):  # c = 2 compression rounds
            v0, v1, v2, v3 = _sip_round(v0, v1, v2, v3)
        v = (v0 ^ mi, v1, v2, v3)
    v0, v1, v2, v3 = v[0], v[1], v[2] ^ 0xFF, v[3]
    for _ in range(4):  # d = 4 finalisation rounds
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


def reference_signed_frame(
    d: dict, message: dict, seq: int, fields: dict, key: bytes, counter: int, direction: str, address: int = 0
) -> tuple[bytes, bytes, bytes]:
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
    body = _reference_body(d, message, seq, fields, _version_byte(d, address) | sig["flag"])
    body += counter.to_bytes(sig["counter_bytes"], "little")
    mac_input = bytes((sig[direction],)) + bytes(body)
    tag = reference_siphash24(key, mac_input)[: sig["tag_bytes"]]
    body += tag
    body += _crc16_ccitt_false(bytes(body)).to_bytes(2, "little")
    return _cobs(bytes(body)) + b"\x00", tag, mac_input


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
        frame, tag, mac_input = reference_signed_frame(
            d, by_name[s["message"]], s["seq"], s["fields"], bytes.fromhex(s["key_hex"]), s["counter"], s["direction"]
        )
        s["frame_hex"], s["tag_hex"], s["mac_input_hex"] = frame.hex(), tag.hex(), mac_input.hex()
    for a in vectors.get("addressed_frames", []):
        message = by_name[a["message"]]
        if message["direction"] not in (a["direction"], "both"):
            raise DefinitionError(f"addressed vector {a['name']}: {a['message']} is not sent {a['direction']}")
        if "key_hex" in a:
            frame, tag, mac_input = reference_signed_frame(
                d,
                message,
                a["seq"],
                a["fields"],
                bytes.fromhex(a["key_hex"]),
                a["counter"],
                a["direction"],
                a["address"],
            )
            a["frame_hex"], a["tag_hex"], a["mac_input_hex"] = frame.hex(), tag.hex(), mac_input.hex()
        else:
            a["frame_hex"] = reference_frame(d, message, a["seq"], a["fields"], a["address"]).hex()
    return vectors


def _uncobs(data: bytes) -> bytes:
    out, i = bytearray(), 0
    while i < len(data):
        code = data[i]
        out += data[i + 1 : i + code]
        i += code
        if code < 0xFF and i < len(data):
            out.append(0)
    return bytes(out)


def outputs(d: dict) -> dict[Path, str]:
    vectors = json.loads(VECTORS.read_text())
    return {
        OUT_CPP: render_cpp(d),
        OUT_PY: render_py(d),
        OUT_VECTORS_H: render_vectors_h(d, vectors),
        OUT_VEHICLE_H: render_vehicle_h(d),
        OUT_VEHICLE_PY: render_vehicle_py(d),
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument(
        "--check", action="store_true", help="exit 1 if a committed output differs from what the definition gives"
    )
    ap.add_argument(
        "--update-vectors", action="store_true", help="recompute frame_hex and bad frames in protocol/vectors.json"
    )
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
            print(
                "generated files drifted from protocol/messages.toml and protocol/vehicle.toml: "
                + ", ".join(drifted)
                + "\nrun: python3 protocol/generate.py",
                file=sys.stderr,
            )
            return 1
        print(f"generated files match the definition (schema hash 0x{d['schema_hash']:08X})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
