"""Signed frames on the host: the format in protocol/messages.toml [signing], the tag,
the counter, and every way a frame can be refused: forged, altered, reflected, replayed,
reordered, truncated, unsigned where signatures are required, or signed with no key to check it.
And the key file: made 0600, never overwritten by accident, refused when others can read it."""

from __future__ import annotations

import os
import stat
import time

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from tests.core_transport import firmware_hello

from rovernav.link import messages_gen as mg
from rovernav.link.framing import (
    MAX_FRAME,
    FrameDecoder,
    Signer,
    Verifier,
    cobs_decode,
    cobs_encode,
    crc16,
    encode_frame,
    frame_tag,
)
from rovernav.link.keys import KeyFileError, load_key_file, write_key_file
from rovernav.link.link import host_hello

KEY = bytes(range(16))
OTHER = bytes(range(1, 17))
H2R, R2H = mg.SIGN_HOST_TO_ROVER, mg.SIGN_ROVER_TO_HOST


def host_signer(t=1_800_000_000.0):
    return Signer(KEY, H2R, clock=lambda: t)


def rover_side(require=True):
    return FrameDecoder(Verifier(KEY, H2R, require=require))


def stop_frame(signer, seq=1):
    return encode_frame(mg.Stop(reason=1), seq, signer)


def test_a_signed_frame_is_12_bytes_longer_and_the_longest_fits_64_bytes():
    assert len(stop_frame(host_signer())) - len(encode_frame(mg.Stop(reason=1), 1)) == 12
    longest = max(mg.MESSAGES.values(), key=lambda c: c.STRUCT.size)
    assert len(encode_frame(longest(), 0, host_signer())) <= MAX_FRAME <= 64


def test_a_signed_frame_decodes_with_the_key_and_its_counter():
    d = rover_side()
    signer = host_signer()
    frames = d.feed(stop_frame(signer))
    assert len(frames) == 1 and frames[0].message == mg.Stop(reason=1)
    assert frames[0].counter == signer.last_counter == int((1_800_000_000 - mg.SIGN_EPOCH_UNIX_S) * 1000)


def test_the_counter_is_the_clock_in_ms_or_one_more_than_the_last():
    s = host_signer()
    a, b = s.next_counter(), s.next_counter()
    assert b == a + 1  # the clock stood still: still strictly increasing
    s.jump_past(a + 10_000)
    assert s.next_counter() == a + 10_001


def _resigned_crc(frame: bytes, change) -> bytes:
    """The frame with `change` applied to its raw body and a correct CRC again (what an attacker
    who knows the format but not the key can do)."""
    raw = bytearray(cobs_decode(frame[:-1]))
    body = bytearray(raw[:-2])
    body = change(body)
    return cobs_encode(bytes(body) + crc16(bytes(body)).to_bytes(2, "little")) + b"\x00"


def test_forged_altered_reflected_wrong_key_truncated_frames_are_refused():
    good = stop_frame(host_signer())
    cases = {
        "forged tag": lambda b: b[:-6] + bytearray(6),
        "altered payload": lambda b: b[:3] + bytearray([b[3] ^ 1]) + b[4:],
        "altered counter": lambda b: b[:-12] + (int.from_bytes(b[-12:-6], "little") + 1).to_bytes(6, "little") + b[-6:],
        "truncated": lambda b: b[:-1],
    }
    for what, change in cases.items():
        d = rover_side()
        assert d.feed(_resigned_crc(good, change)) == [], what
        assert d.counters.dropped == 1, what
    d = rover_side()
    assert d.feed(encode_frame(mg.Stop(reason=1), 1, Signer(KEY, R2H, clock=lambda: 1.8e9))) == []  # reflected
    assert d.counters.bad_tag == 1
    assert d.feed(encode_frame(mg.Stop(reason=1), 1, Signer(OTHER, H2R, clock=lambda: 1.8e9))) == []  # wrong key
    assert d.counters.bad_tag == 2


def test_replayed_and_reordered_frames_are_refused():
    signer, d = host_signer(), rover_side()
    first, second = stop_frame(signer, 1), stop_frame(signer, 2)
    assert len(d.feed(second)) == 1
    assert d.feed(first) == [] and d.counters.replayed == 1  # older counter: reordered
    assert d.feed(second) == [] and d.counters.replayed == 2  # the same again: replayed


def test_a_forged_frame_cannot_raise_the_counter():
    d = rover_side()
    big = encode_frame(mg.Stop(reason=1), 1, Signer(OTHER, H2R, clock=lambda: 4e9))
    assert d.feed(big) == [] and d.verifier.last_counter == -1


def test_unsigned_commands_are_refused_where_signatures_are_required_but_hello_is_not():
    d = rover_side()
    assert d.feed(encode_frame(mg.Stop(reason=1), 1)) == [] and d.counters.not_signed == 1
    hello = encode_frame(host_hello(1), 2)
    assert len(d.feed(hello)) == 1
    assert len(rover_side(require=False).feed(encode_frame(mg.Stop(reason=1), 3))) == 1


def test_a_signed_frame_with_no_key_to_check_it_is_dropped_and_counted():
    d = FrameDecoder()
    assert d.feed(stop_frame(host_signer())) == [] and d.counters.unverified == 1


def test_the_tag_is_siphash_of_the_direction_and_the_frame_up_to_the_counter():
    frame = stop_frame(host_signer())
    raw = cobs_decode(frame[:-1])
    signed_part, tag = raw[:-8], raw[-8:-2]
    assert raw[0] == mg.PROTOCOL_VERSION | mg.SIGN_FLAG
    assert tag == frame_tag(KEY, H2R, signed_part)


@settings(max_examples=300, deadline=None)
@given(pos=st.integers(0, 200), bit=st.integers(0, 7))
def test_no_single_bit_flip_of_a_signed_frame_is_accepted(pos, bit):
    good = stop_frame(host_signer())
    raw = bytearray(cobs_decode(good[:-1]))
    pos %= len(raw) - 2  # anywhere but the CRC, which is then made right again
    raw[pos] ^= 1 << bit
    body = bytes(raw[:-2])
    bad = cobs_encode(body + crc16(body).to_bytes(2, "little")) + b"\x00"
    d = rover_side()
    assert d.feed(bad) == []


def test_keygen_writes_a_0600_file_and_never_overwrites_by_accident(tmp_path):
    path = tmp_path / "link.key"
    key = write_key_file(path)
    assert stat.S_IMODE(path.stat().st_mode) == 0o600 and load_key_file(path) == key and len(key) == 16
    with pytest.raises(KeyFileError, match="exists"):
        write_key_file(path)
    assert load_key_file(path) == key
    assert write_key_file(path, force=True) != key


def test_a_key_file_others_can_read_or_that_is_not_a_key_is_refused(tmp_path):
    path = tmp_path / "link.key"
    write_key_file(path)
    os.chmod(path, 0o644)
    with pytest.raises(KeyFileError, match="others can read it"):
        load_key_file(path)
    os.chmod(path, 0o600)
    path.write_text("not hex at all\n")
    with pytest.raises(KeyFileError, match="32 hexadecimal digits"):
        load_key_file(path)
    with pytest.raises(KeyFileError, match="no such key file"):
        load_key_file(tmp_path / "missing.key")


# ---------------------------------------------------------------- the host's Link with a key

import threading  # noqa: E402

from rovernav.link.errors import SigningMismatch  # noqa: E402
from rovernav.link.link import Link  # noqa: E402
from rovernav.link.transport import PipeTransport  # noqa: E402


def _rover_answering(end, signing: int, min_counter: int = 0):
    """A stand-in rover end: answers the first HELLO it hears with its own (signed, as a rover
    with a key signs it), then keeps every frame the host sends (decoded with the key, when the
    rover has one)."""
    got, decoder = [], FrameDecoder(Verifier(KEY, H2R) if signing else None)
    signer = Signer(KEY, mg.SIGN_ROVER_TO_HOST) if signing else None

    def run():
        answered = False
        while True:
            try:
                data = end.read(256, timeout_s=0.05)
            except Exception:  # noqa: BLE001 - the host closed its end: the test is over
                return
            for frame in decoder.feed(data):
                got.append(frame)
                if isinstance(frame.message, mg.Hello) and not answered:
                    answered = True
                    end.write(
                        encode_frame(
                            firmware_hello(
                                boot_id=7,
                                signing=signing,
                                min_counter_lo=min_counter & 0xFFFFFFFF,
                                min_counter_hi=min_counter >> 32,
                            ),
                            0,
                            signer,
                        )
                    )

    threading.Thread(target=run, daemon=True).start()
    return got, decoder


def test_a_host_with_a_key_signs_every_command_after_the_rovers_minimum_counter():
    host_end, rover_end = PipeTransport.pair()
    minimum = 5 * 10**12  # far beyond the clock: the host's counter must jump past it
    got, decoder = _rover_answering(rover_end, signing=1, min_counter=minimum)
    link = Link(host_end, key=KEY)
    hello = link.handshake(boot_id=1, timeout_s=2.0)
    assert hello.signing == 1
    link.send(mg.Stop(reason=1))
    deadline = time.monotonic() + 2
    while not any(isinstance(f.message, mg.Stop) for f in got) and time.monotonic() < deadline:
        time.sleep(0.01)
    stop = next(f for f in got if isinstance(f.message, mg.Stop))
    assert stop.counter is not None and stop.counter >= minimum  # signed, and past the rover's minimum
    assert got[0].message.signing == 1 and got[0].counter is None  # our HELLO: unsigned, saying we sign
    link.close()


def test_a_host_with_a_key_refuses_a_rover_that_says_it_has_none():
    host_end, rover_end = PipeTransport.pair()
    _rover_answering(rover_end, signing=0)
    with pytest.raises(SigningMismatch, match="holds no link key"):
        Link(host_end, key=KEY).handshake(boot_id=1, timeout_s=2.0)


def test_a_host_without_the_key_is_told_the_rover_needs_it():
    host_end, rover_end = PipeTransport.pair()
    _rover_answering(rover_end, signing=1)
    with pytest.raises(SigningMismatch, match="refuses unsigned commands"):
        Link(host_end).handshake(boot_id=1, timeout_s=2.0)


def test_a_host_with_a_key_takes_only_the_rovers_signed_frames():
    host_end, rover_end = PipeTransport.pair()
    link = Link(host_end, key=KEY)
    rover = Signer(KEY, R2H, clock=lambda: 1.8e9)
    status = mg.Status(state=1)
    rover_end.write(encode_frame(status, 1))  # unsigned
    rover_end.write(encode_frame(status, 2, Signer(OTHER, R2H, clock=lambda: 1.8e9)))  # forged
    rover_end.write(encode_frame(status, 3, rover))  # the rover's
    frame = link.recv(timeout_s=1.0)
    assert frame is not None and frame.seq == 3 and frame.counter is not None
    c = link.counters
    assert (c.not_signed, c.bad_tag) == (1, 1)
    link.close()
