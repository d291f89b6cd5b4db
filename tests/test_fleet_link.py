"""A fleet on one radio, the host's side ([fleet] in protocol/messages.toml): the constants generated
from the definition, the addressed golden vectors (protocol/vectors.json `addressed_frames`) made and
read by the host's framing, a Link's address (every frame it sends carries it, frames of other
addresses are dropped and counted apart), and a Link talking to the rover's firmware core
(NativeCore, its C ABI) provisioned as rover k of a fleet, which speaks only when spoken to."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import pytest
from tests.core_transport import CoreTransport

from rovernav.cores import NativeCore
from rovernav.link import messages_gen as mg
from rovernav.link.errors import LinkTimeout
from rovernav.link.framing import FrameDecoder, Signer, Verifier, cobs_decode, encode_frame
from rovernav.link.link import Link
from rovernav.link.transport import PipeTransport

ROOT = Path(__file__).resolve().parent.parent
VECTORS = json.loads((ROOT / "protocol" / "vectors.json").read_text())
ADDRESSED = VECTORS["addressed_frames"]
DIRECTIONS = {"host_to_rover": mg.SIGN_HOST_TO_ROVER, "rover_to_host": mg.SIGN_ROVER_TO_HOST}
KEY = bytes(range(30, 46))


def _generator():
    spec = importlib.util.spec_from_file_location("rovernav_protocol_generate_fleet", ROOT / "protocol" / "generate.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


generate = _generator()


def _message(v: dict):
    cls = mg.MESSAGES_BY_NAME[v["message"]]
    return cls(**{k: tuple(x) if isinstance(x, list) else x for k, x in v["fields"].items()})


def _signer(v: dict) -> Signer | None:
    if "key_hex" not in v:
        return None
    signer = Signer(bytes.fromhex(v["key_hex"]), DIRECTIONS[v["direction"]], clock=lambda: float(mg.SIGN_EPOCH_UNIX_S))
    signer.jump_past(v["counter"] - 1)
    return signer


def _version_bytes(wire: bytes) -> list[int]:
    """The version byte of every frame in `wire`."""
    return [cobs_decode(body)[0] for body in wire.split(b"\x00") if body]


# ---------------------------------------------------------------- the definition, generated


def test_the_fleet_constants_are_the_definitions():
    fleet = generate.load()["fleet"]
    assert (mg.MAX_ROVERS, mg.ADDRESS_SHIFT, mg.GRANT_BYTES, mg.GRANT_MS) == (
        fleet["max_rovers"],
        fleet["address_shift"],
        fleet["grant_bytes"],
        fleet["grant_ms"],
    )
    assert (mg.MAX_ROVERS, mg.ADDRESS_SHIFT, mg.ADDRESS_MASK, mg.VERSION_MASK) == (4, 5, 0x60, 0x1F)
    assert (mg.GRANT_BYTES, mg.GRANT_MS) == (128, 20)
    assert mg.ADDRESS_MASK & mg.SIGN_FLAG == 0 and mg.ADDRESS_MASK & mg.PROTOCOL_VERSION == 0
    header = (ROOT / "firmware/lib/link/messages_gen.h").read_text()
    for line in ("kMaxRovers = 4", "kAddressShift = 5", "kAddressMask = 0x60", "kGrantBytes = 128", "kGrantMs = 20"):
        assert line in header
    assert [f.name for f in mg.Provision.FIELDS][-1] == "fleet_id"  # appended, never reordered


def test_the_schema_hash_covers_the_fleet_and_the_generator_refuses_address_bits_that_overlap(tmp_path):
    d = generate.load()
    base = generate.schema_hash(d)
    d["fleet"]["grant_bytes"] += 1
    assert generate.schema_hash(d) != base
    text = (ROOT / "protocol/messages.toml").read_text()
    for edit, complaint in (
        (("address_shift = 5", "address_shift = 6"), "apart from \\[signing\\].flag"),
        (("max_rovers = 4 ", "max_rovers = 3 "), "power of two"),
        (("grant_bytes = 128", "grant_bytes = 40"), "largest signed frame"),
    ):
        assert edit[0] in text
        bad = tmp_path / "messages.toml"
        bad.write_text(text.replace(*edit))
        with pytest.raises(generate.DefinitionError, match=complaint):
            generate.load(bad)


# ---------------------------------------------------------------- the addressed vectors


def test_the_addressed_vectors_cover_every_kind():
    assert {v["direction"] for v in ADDRESSED} == set(DIRECTIONS)
    assert {("key_hex" in v) for v in ADDRESSED} == {True, False}
    assert all(v["address"] != 0 for v in ADDRESSED)  # address 0 is the golden frames'
    d = generate.load()
    assert generate.update_vectors(d, json.loads(json.dumps(VECTORS)))["addressed_frames"] == ADDRESSED


@pytest.mark.parametrize("v", ADDRESSED, ids=[v["name"] for v in ADDRESSED])
def test_the_host_makes_each_addressed_vector_byte_for_byte_and_reads_it_only_at_its_address(v):
    wire = bytes.fromhex(v["frame_hex"])
    assert encode_frame(_message(v), v["seq"], _signer(v), address=v["address"]) == wire
    version = _version_bytes(wire)[0]
    assert (version & mg.ADDRESS_MASK) >> mg.ADDRESS_SHIFT == v["address"]
    verifier = lambda: Verifier(bytes.fromhex(v["key_hex"]), DIRECTIONS[v["direction"]]) if "key_hex" in v else None  # noqa: E731
    for listen in range(mg.MAX_ROVERS):
        dec = FrameDecoder(verifier(), address=listen)
        frames = dec.feed(wire)
        if listen == v["address"]:
            assert [(f.message, f.address) for f in frames] == [(_message(v), v["address"])]
        else:
            assert frames == [] and dec.counters.other_address == 1
            assert dec.counters.dropped == 0 and dec.counters.bad_tag == 0  # not damage, and no tag checked
    anywhere = FrameDecoder(verifier(), address=None)
    assert [f.address for f in anywhere.feed(wire)] == [v["address"]]


def test_address_zero_frames_are_the_lone_rovers_byte_for_byte():
    for v in VECTORS["frames"]:
        assert encode_frame(_message(v), v["seq"], address=0).hex() == v["frame_hex"]
        assert encode_frame(_message(v), v["seq"]).hex() == v["frame_hex"]


@pytest.mark.parametrize("bad", [-1, 4, 7, True, 1.0, None])
def test_an_address_outside_the_fleet_is_refused_naming_the_range(bad):
    with pytest.raises(ValueError, match=r"address is 0\.\.3"):
        encode_frame(mg.Stop(), 0, address=bad)
    if bad is not None:  # a decoder for address None takes every address's frames
        with pytest.raises(ValueError, match=r"address is 0\.\.3"):
            FrameDecoder(address=bad)
    with pytest.raises(ValueError, match=r"address is 0\.\.3"):
        Link(PipeTransport.pair()[0], address=bad)


# ---------------------------------------------------------------- a Link's address


def test_a_link_frames_everything_at_its_address_and_drops_other_addresses_apart_from_damage():
    a, b = PipeTransport.pair()
    host = Link(a, address=2, key=KEY)
    try:
        host.send(mg.Fix(x_mm=5))
        host.send(mg.Hello(role=mg.Role.HOST))  # unsigned, addressed all the same
        wire = b.read(4096, timeout_s=1.0)
        assert _version_bytes(wire) == [mg.PROTOCOL_VERSION | 2 << mg.ADDRESS_SHIFT | mg.SIGN_FLAG, 0x41]
        # the rovers answer: rover 3 (address 2) and rover 2 (address 1), both signed with the key
        rover = Signer(KEY, mg.SIGN_ROVER_TO_HOST)
        b.write(encode_frame(mg.Ack(msg_id=mg.Fix.ID, seq=0), 7, rover, address=1))
        b.write(encode_frame(mg.Ack(msg_id=mg.Fix.ID, seq=0), 8, rover, address=2))
        frame = host.recv(timeout_s=1.0)
        assert frame is not None and frame.seq == 8 and frame.address == 2
        assert host.recv(timeout_s=0.1) is None
        c = host.counters
        assert c.other_address == 1 and c.frames_ok == 1 and c.dropped == 0
    finally:
        host.close()


def test_a_lone_rovers_link_is_address_zero_and_sends_what_it_always_sent():
    a, b = PipeTransport.pair()
    host = Link(a)
    try:
        assert host.address == 0
        host.send(mg.Stop(reason=1))
        assert b.read(4096, timeout_s=1.0) == encode_frame(mg.Stop(reason=1), 0)
    finally:
        host.close()


# ---------------------------------------------------------------- the firmware core as rover k of a fleet


def _bytes_by_step(core: NativeCore, t0_ms: int, ms: int, rx: bytes = b"") -> list[tuple[int, bytes]]:
    said = []
    for t in range(t0_ms, t0_ms + ms, 10):
        out = core.step(t, gyro_rate_mdps=0, rx=rx if t == t0_ms else b"")
        if out.tx:
            said.append((t, out.tx))
    return said


@pytest.mark.parametrize("keyed", [False, True])
def test_a_fleet_core_says_its_boot_frames_then_speaks_only_in_the_grant_a_frame_to_it_opens(keyed):
    core = NativeCore(key=KEY if keyed else None, fleet_id=3)  # address 2
    try:
        assert core.fleet_id == 3
        boot = _bytes_by_step(core, 0, 2000)
        assert boot and all(t <= mg.GRANT_MS for t, _ in boot)  # the reset's grant only
        assert sum(len(b) for _, b in boot) <= mg.GRANT_BYTES
        heard = FrameDecoder(Verifier(KEY, mg.SIGN_ROVER_TO_HOST) if keyed else None, address=2)
        names = [f.message.NAME for _, b in boot for f in heard.feed(b)]
        assert names == ["hello", "event"]
        signer = Signer(KEY, mg.SIGN_HOST_TO_ROVER) if keyed else None
        # a frame for rover 2 (address 1) opens nothing
        assert _bytes_by_step(core, 2000, 500, encode_frame(mg.Heartbeat(), 1, signer, address=1)) == []
        # one for it: a grant, of whole frames (its STATUS waiting since)
        said = _bytes_by_step(core, 2500, 500, encode_frame(mg.Heartbeat(), 2, signer, address=2))
        assert said and said[0][0] == 2500 and all(t - 2500 <= mg.GRANT_MS for t, _ in said)
        assert sum(len(b) for _, b in said) <= mg.GRANT_BYTES and all(b.endswith(b"\x00") for _, b in said)
        assert any(isinstance(f.message, mg.Status) for _, b in said for f in heard.feed(b))
        assert heard.counters.dropped == 0
    finally:
        core.close()


def test_a_lone_core_talks_unasked_as_before():
    core = NativeCore(key=KEY)
    try:
        assert core.fleet_id == 0
        said = _bytes_by_step(core, 0, 2000)
        heard = FrameDecoder(Verifier(KEY, mg.SIGN_ROVER_TO_HOST), address=0)
        assert sum(isinstance(f.message, mg.Status) for _, b in said for f in heard.feed(b)) >= 9
    finally:
        core.close()


def test_a_link_at_the_rovers_address_shakes_hands_and_commands_it_and_one_at_another_does_not():
    port = CoreTransport(NativeCore(key=KEY, fleet_id=4))  # address 3
    # It answers only when polled: a Link on its own polls behind each frame (polls=True).
    link = Link(port, key=KEY, address=3, clock=lambda: mg.SIGN_EPOCH_UNIX_S + port.clock(), polls=True)
    hello = link.handshake(boot_id=5, timeout_s=2.0)
    assert hello.role == mg.Role.ROVER and hello.signing == 1
    ack = link.request(mg.Config(param=mg.Param.STATUS_PERIOD_MS, value=400))
    assert ack.address == 3 and ack.message.msg_id == mg.Config.ID
    assert link.counters.dropped == 0

    port = CoreTransport(NativeCore(key=KEY, fleet_id=4))
    stranger = Link(port, key=KEY, address=1, clock=lambda: mg.SIGN_EPOCH_UNIX_S + port.clock())
    with pytest.raises(LinkTimeout):
        stranger.handshake(boot_id=5, timeout_s=1.0)
    assert stranger.counters.other_address >= 1  # it heard the rover's boot HELLO, at address 3
    assert port.core.auth_counters() == {"bad_tag": 0, "replayed": 0, "not_signed": 0, "unverified": 0}


@pytest.mark.parametrize("bad", [-1, 5, True])
def test_a_core_with_a_fleet_id_outside_0_to_4_is_refused(bad):
    with pytest.raises(ValueError, match="fleet id"):
        NativeCore(fleet_id=bad)


def test_the_rover_nacks_a_provision_whose_fleet_id_is_past_4_and_keeps_its_own():
    core = NativeCore(fleet_id=2)  # address 1, no key: it takes an unsigned PROVISION soon after boot
    try:
        _bytes_by_step(core, 0, 100)
        frame = encode_frame(mg.Provision(key=tuple(range(16)), fleet_id=5), 9, address=1)
        frame += encode_frame(
            mg.Heartbeat(host_time_ms=0, camera=0, scan_heard=0, path_id=0), 10, address=1
        )  # the poll
        said = _bytes_by_step(core, 100, 100, frame)
        answers = [f.message for _, b in said for f in FrameDecoder(address=1).feed(b)]
        nack = next(m for m in answers if isinstance(m, mg.Nack))
        assert (nack.msg_id, nack.seq, nack.reason, nack.detail) == (mg.Provision.ID, 9, mg.NackReason.BAD_VALUE, 3)
        assert core.take_key_change() is None and core.fleet_id == 2
    finally:
        core.close()
