"""The C++ outputs of messages.toml: firmware/lib/link/messages_gen.h (render_cpp: constants, enums,
the parameters' packed table, a struct per message) and firmware/test/test_link/vectors_gen.h
(render_vectors_h: the golden vectors of vectors.json as tables and test cases)."""

from __future__ import annotations

from .definition import (
    CRC_BYTES,
    HEADER_BYTES,
    TYPES,
    WIRE_TYPES,
    DefinitionError,
    banner,
    camel,
    param_scale,
    payload_size,
)

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
    out = [
        "/// Where each parameter's value lies in the rover's store of kParamBytes bytes, by id - 1 (0xFF: no\n"
        "/// such parameter). A value takes the least width its limits allow, little-endian, the widest first:\n"
        "/// int32 from 0, then uint16 from kParamAtU16, int16 from kParamAtI16, uint8 from kParamAtU8 and\n"
        "/// int8 from kParamAtI8 (param_width, param_signed). Its default, min and max lie in kParamLimits\n"
        "/// at 3 x its offset, in its width. In flash on the AVR.\n",
        "enum : uint8_t {\n"
        f"  kParamBytes = {size},\n  kParamAtU16 = {starts['u16']},\n  kParamAtI16 = {starts['i16']},\n"
        f"  kParamAtU8 = {starts['u8']},\n  kParamAtI8 = {starts['i8']},\n  kParamNone = 0xFF\n}};\n",
        f"static const uint8_t kParamOffset[{max_id}] ROVERNAV_PROGMEM = {{\n",
    ]
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
            limits[at : at + width] = prm[key].to_bytes(width, "little", signed=signed)
    out.append(f"static const uint8_t kParamLimits[{len(limits)}] ROVERNAV_PROGMEM = {{\n")
    for pid in sorted(by_id, key=lambda i: offsets[i]):
        prm = by_id[pid]
        name, width, signed = param_kind(prm)
        at = 3 * offsets[pid]
        row = ", ".join(f"0x{b:02X}" for b in limits[at : at + 3 * width])
        out.append(f"  {row},  // {pid} {prm['name']}: {prm['default']}, {prm['min']}..{prm['max']}\n")
    out.append("};\n")
    printed = bytes(
        int(b, 16) for line in out if line.startswith("  0x") for b in line.split("//")[0].replace(",", " ").split()
    )
    assert printed == bytes(limits), "kParamLimits printed out of order"
    out.append(
        "\n/// The width in bytes, and the sign, of the value stored at `offset`.\n"
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
        "  return true;\n}\n\n"
    )
    return "".join(out)


def render_cpp(d: dict) -> str:
    p = d["protocol"]
    max_raw = HEADER_BYTES + p["max_payload"] + CRC_BYTES
    out = [
        banner("//"),
        "#pragma once\n",
        "#include <stdint.h>\n",
        '#include "progmem.h"\n',
        '#include "vehicle_gen.h"  // the vehicle\'s facts (kUartBufferBytes, kSonarMaxRangeMm, ...)\n',
        '#include "wire_layout.h"\n\n',
        "namespace rovernav {\n\n",
        f"enum : uint8_t {{ kProtocolVersion = {p['version']} }};\n",
        f"static const uint32_t kSchemaHash = 0x{d['schema_hash']:08X}UL;\n",
        f"enum : uint8_t {{\n  kMaxPayload = {p['max_payload']},\n  kMaxRawFrame = {max_raw},  // header + payload + CRC\n"
        f"  kMaxWaypoints = {p['max_waypoints']},\n  kWaypointsPerChunk = {p['waypoints_per_chunk']}\n}};\n\n",
    ]
    sig = d["signing"]
    by_name = {m["name"]: m["id"] for m in d["messages"]}
    out.append(
        "// Signed frames ([signing] in protocol/messages.toml).\n"
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
        + " || ".join(f"id == 0x{by_name[n]:02X}" for n in sig.get("unsigned", []))
        + ";\n}\n\n"
    )
    fleet = d["fleet"]
    out.append(
        "// A fleet ([fleet] in protocol/messages.toml): a rover's address in bits kAddressShift.. of the\n"
        "// version byte, and a fleet rover's grant to speak (bytes, and ms from the step that opened it).\n"
        f"enum : uint8_t {{\n  kMaxRovers = {fleet['max_rovers']},\n  kAddressShift = {fleet['address_shift']},\n"
        f"  kAddressMask = 0x{(fleet['max_rovers'] - 1) << fleet['address_shift']:02X},\n"
        f"  kVersionMask = 0x{(1 << fleet['address_shift']) - 1:02X},\n"
        f"  kGrantBytes = {fleet['grant_bytes']},\n  kGrantMs = {fleet['grant_ms']}\n}};\n\n"
    )
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
    out.append(
        "/// A parameter's scale, from its name: the wire's integer is the working value times this\n"
        "/// (_x100: 100, _x1000 and _permille: 1000; 1 for the rest). For constants only.\n"
        "constexpr uint16_t param_scale(Param p) {\n  return "
        + "".join(f"p == Param::{camel(prm['name'])} ? {param_scale(prm['name'])} :\n         " for prm in scaled)
        + "1;\n}\n\n"
    )
    out.append(render_param_table(d))
    out.append(
        "namespace msg {\n\n"
        "// Each message's bytes are its payload on the wire (fields in order, little-endian, no\n"
        "// padding: wire_layout.h), so encoding and decoding are one copy.\n\n"
    )
    for m in d["messages"]:
        out.append(f"/// {m['doc']} ({m['direction'].replace('_', ' ')})\n")
        out.append(f"struct {camel(m['name'])} {{\n")
        out.append(f"  enum : uint8_t {{ kId = 0x{m['id']:02X}, kPayloadSize = {payload_size(m)} }};\n")
        for f in m["fields"]:
            ctype = WIRE_TYPES.get(f["type"], TYPES[f["type"]][2])
            arr = f"[{f['count']}]" if "count" in f else ""
            unit = f" [{f['unit']}]" if f.get("unit") else ""
            out.append(f"  {ctype} {f['name']}{arr};  ///<{unit} {f.get('doc', '')}\n".replace(" \n", "\n"))
        out.append(
            "  /// Writes kPayloadSize bytes to p.\n"
            "  void encode(uint8_t* p) const { wire::copy(p, this, kPayloadSize); }\n"
            "  /// Reads kPayloadSize bytes from p.\n"
            "  void decode(const uint8_t* p) { wire::copy(this, p, kPayloadSize); }\n"
            "};\n"
        )
        out.append(
            f"static_assert(sizeof({camel(m['name'])}) == {camel(m['name'])}::kPayloadSize, "
            f'"{m["name"]}: its layout is its payload");\n\n'
        )
    out.append("}  // namespace msg\n\n")
    # A table in flash, searched: the compiler turns a switch over these ids into a lookup table
    # in the Uno's SRAM.
    out.append(
        "/// Message ids and payload sizes, in flash.\n"
        f"static const uint8_t kPayloadSizes[{len(d['messages'])}][2] ROVERNAV_PROGMEM = {{\n"
    )
    for m in d["messages"]:
        out.append(f"  {{0x{m['id']:02X}, {payload_size(m)}}},  // {m['name']}\n")
    out.append("};\n\n")
    out.append(
        "/// Payload size of message `id`, or -1 if no message has that id.\n"
        "inline int16_t payload_size(uint8_t id) {\n"
        "  for (uint8_t i = 0; i < sizeof kPayloadSizes / sizeof kPayloadSizes[0]; ++i) {\n"
        "    if (flash_read_u8(&kPayloadSizes[i][0]) == id) return flash_read_u8(&kPayloadSizes[i][1]);\n"
        "  }\n  return -1;\n}\n\n}  // namespace rovernav\n"
    )
    return "".join(out)


# ---------------------------------------------------------------- golden vectors for C++


def _hex_bytes(data: bytes) -> str:
    return ", ".join(f"0x{b:02X}" for b in data)


def render_vectors_h(d: dict, vectors: dict) -> str:
    by_name = {m["name"]: m for m in d["messages"]}
    out = [
        banner("//").replace("protocol/messages.toml", "protocol/messages.toml and protocol/vectors.json"),
        "// The tables (kGoldenFrames, kBadFrames) are always defined. With ROVERNAV_GOLDEN_TEST_CASES\n"
        "// defined, one TEST_CASE per golden frame follows; the includer then provides\n"
        "// check_golden_encode(msg, seq, frame, len) and decode_golden<Msg>(frame, len, seq).\n",
        "#pragma once\n#include <stdint.h>\n\n",
    ]
    tables_at = len(out)
    out.append("#ifdef ROVERNAV_GOLDEN_TEST_CASES\n")
    for v in vectors["frames"]:
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
    tables.append(
        "// Signed frames (vectors.json signed_frames): the key, the counter (little-endian, as on the wire),\n"
        "// the direction byte, the frame's bytes on the wire (delimiter included), its tag, and what the tag\n"
        "// is SipHash-2-4 of (the direction byte, then version|flag .. counter).\n"
        f"struct SignedVector {{ const char* name; uint8_t direction; uint8_t msg_id; uint8_t key[16]; "
        f"uint8_t counter[{sig['counter_bytes']}]; const uint8_t* wire; uint8_t wire_len; "
        f"uint8_t tag[{sig['tag_bytes']}]; const uint8_t* mac_input; uint8_t mac_input_len; }};\n"
    )
    signed = vectors.get("signed_frames", [])
    for i, s in enumerate(signed):
        tables.append(f"static const uint8_t kSignedWire{i}[] = {{{_hex_bytes(bytes.fromhex(s['frame_hex']))}}};\n")
        tables.append(
            f"static const uint8_t kSignedMacInput{i}[] = {{{_hex_bytes(bytes.fromhex(s['mac_input_hex']))}}};\n"
        )
    tables.append(f"static const SignedVector kSignedVectors[{max(1, len(signed))}] = {{\n")
    for i, s in enumerate(signed):
        counter = s["counter"].to_bytes(sig["counter_bytes"], "little")
        tables.append(
            f'  {{"{s["name"]}", {sig[s["direction"]]}, 0x{by_name[s["message"]]["id"]:02X},\n'
            f"   {{{_hex_bytes(bytes.fromhex(s['key_hex']))}}},\n"
            f"   {{{_hex_bytes(counter)}}},  // {s['counter']}\n"
            f"   kSignedWire{i}, sizeof kSignedWire{i}, {{{_hex_bytes(bytes.fromhex(s['tag_hex']))}}},\n"
            f"   kSignedMacInput{i}, sizeof kSignedMacInput{i}}},\n"
        )
    tables.append("};\n\n")
    addressed = vectors.get("addressed_frames", [])
    tables.append(
        "// Frames of a fleet (vectors.json addressed_frames): the rover's address in the version byte; signed\n"
        "// ones with their key and counter (little-endian, as on the wire); the bytes on the wire, delimiter included.\n"
        f"struct AddressedVector {{ const char* name; uint8_t direction; uint8_t address; uint8_t msg_id; bool is_signed; "
        f"uint8_t key[16]; uint8_t counter[{sig['counter_bytes']}]; const uint8_t* wire; uint8_t wire_len; }};\n"
    )
    for i, a in enumerate(addressed):
        tables.append(f"static const uint8_t kAddressedWire{i}[] = {{{_hex_bytes(bytes.fromhex(a['frame_hex']))}}};\n")
    tables.append(f"static const AddressedVector kAddressedVectors[{max(1, len(addressed))}] = {{\n")
    for i, a in enumerate(addressed):
        signed_ = "key_hex" in a
        key = bytes.fromhex(a["key_hex"]) if signed_ else bytes(16)
        counter = (a["counter"] if signed_ else 0).to_bytes(sig["counter_bytes"], "little")
        tables.append(
            f'  {{"{a["name"]}", {sig[a["direction"]]}, {a["address"]}, 0x{by_name[a["message"]]["id"]:02X}, '
            f"{'true' if signed_ else 'false'},\n"
            f"   {{{_hex_bytes(key)}}},\n"
            f"   {{{_hex_bytes(counter)}}},\n"
            f"   kAddressedWire{i}, sizeof kAddressedWire{i}}},\n"
        )
    tables.append("};\n\n")
    tables.append(
        "// Every parameter as the definition gives it, written from its numbers (not from the rover's\n"
        "// packed table, which test_params checks against this).\n"
        "struct ParamSpec { uint8_t id; int32_t def, lo, hi; };\n"
        "static const ParamSpec kParamSpecs[] = {\n"
    )
    for prm in sorted(d.get("params", []), key=lambda x: x["id"]):
        tables.append(f"  {{{prm['id']}, {prm['default']}L, {prm['min']}L, {prm['max']}L}},  // {prm['name']}\n")
    tables.append("};\n")
    out[tables_at:tables_at] = tables + ["\n"]
    return "".join(out)
