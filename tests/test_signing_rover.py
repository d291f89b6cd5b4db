"""The rover's side of signed frames (firmware/lib/link/frame_auth.cpp), through the core's C ABI:
what a rover with a key takes and refuses, and a recorded session played back after a reset."""

from __future__ import annotations

from rovernav.cores import NativeCore
from rovernav.link import messages_gen as mg
from rovernav.link.framing import FrameDecoder, Signer, Verifier, cobs_decode, cobs_encode, crc16, encode_frame

KEY = bytes(range(100, 116))


class Bench:
    """A keyed rover core stepped at 100 Hz; what it says, checked with the key."""

    def __init__(self, counters=(0, 0)):
        self.core = NativeCore(key=KEY, counters=counters)
        self.t_ms = 0
        self.heard = FrameDecoder(Verifier(KEY, mg.SIGN_ROVER_TO_HOST))
        self.said: list = []
        self.stored = None
        self.step()

    def step(self, rx: bytes = b"", steps: int = 5):
        for i in range(steps):
            out = self.core.step(self.t_ms, gyro_rate_mdps=0, rx=rx if i == 0 else b"")
            self.said += [f.message for f in self.heard.feed(out.tx)]
            self.stored = self.core.take_persist() or self.stored
            self.t_ms += 10

    def acks(self) -> int:
        return sum(isinstance(m, mg.Ack) and m.msg_id == mg.Config.ID for m in self.said)


def config(value: int = 5) -> mg.Config:
    return mg.Config(param=mg.Param.STATUS_PERIOD_MS, value=200 + value)


def resigned_with_bit_flipped(frame: bytes) -> bytes:
    raw = bytearray(cobs_decode(frame[:-1]))
    raw[4] ^= 0x10
    raw[-2:] = crc16(bytes(raw[:-2])).to_bytes(2, "little")
    return cobs_encode(bytes(raw)) + b"\x00"


def test_a_keyed_rover_says_so_and_signs_what_it_says():
    b = Bench()
    hello = next(m for m in b.said if isinstance(m, mg.Hello))
    assert hello.signing == 1 and (hello.min_counter_hi << 32 | hello.min_counter_lo) > 0
    assert b.heard.counters.frames_ok >= 2 and b.heard.counters.unverified == 0


def test_only_frames_signed_with_its_key_and_a_fresh_counter_are_obeyed():
    b = Bench()
    host = Signer(KEY, mg.SIGN_HOST_TO_ROVER)
    good = encode_frame(config(1), 1, host)
    b.step(good)
    assert b.acks() == 1
    b.step(good)  # replayed
    b.step(encode_frame(config(2), 2))  # unsigned
    other = Signer(bytes(16), mg.SIGN_HOST_TO_ROVER)
    other.jump_past(host.last_counter + 1000)  # a fresh counter: only the tag can tell
    b.step(encode_frame(config(3), 3, other))  # another key
    b.step(resigned_with_bit_flipped(encode_frame(config(4), 4, host)))  # altered, CRC good
    older = encode_frame(config(5), 5, host)
    newer = encode_frame(config(6), 6, host)
    b.step(newer)
    b.step(older)  # reordered: older counter after newer
    b.step(encode_frame(config(7), 7, host)[:-6] + b"\x00")  # truncated
    assert b.acks() == 2  # the first and `newer` only
    assert b.core.auth_counters() == {"bad_tag": 2, "replayed": 2, "not_signed": 1, "unverified": 0}


def test_a_recorded_session_played_back_after_a_reset_is_refused():
    b = Bench()
    host = Signer(KEY, mg.SIGN_HOST_TO_ROVER)
    recording = [encode_frame(config(i), i, host) for i in range(3)]
    for frame in recording:
        b.step(frame)
    assert b.acks() == 3 and b.stored is not None
    again = Bench(counters=b.stored)  # the rover resets; its EEPROM kept the counters
    for frame in recording:
        again.step(frame)
    assert again.acks() == 0
    assert again.core.auth_counters()["replayed"] == 3
    # The real host learns the rover's new minimum from its signed HELLO and goes on.
    hello = next(m for m in again.said if isinstance(m, mg.Hello))
    host.jump_past((hello.min_counter_hi << 32 | hello.min_counter_lo) - 1)
    again.step(encode_frame(config(9), 9, host))
    assert again.acks() == 1


def test_a_rover_without_a_key_refuses_signed_frames_and_takes_unsigned_ones():
    core = NativeCore()
    heard = FrameDecoder()
    said = []
    for i, frame in enumerate(
        [encode_frame(config(1), 1, Signer(KEY, mg.SIGN_HOST_TO_ROVER)), encode_frame(config(2), 2)]
    ):
        out = core.step(10 * i, gyro_rate_mdps=0, rx=frame)
        said += [f.message for f in heard.feed(out.tx)]
    assert sum(isinstance(m, mg.Ack) for m in said) == 1
    assert core.auth_counters()["unverified"] == 1
    assert next(m for m in said if isinstance(m, mg.Hello)).signing == 0


def test_a_host_counter_that_jumps_is_stored_at_once_and_its_frames_refused_after_a_reset():
    # A host restarted with its clock an hour ahead: the rover stores the new counter at once
    # (not only when it next passes a multiple of 65,536), so a reset straight after it does not
    # let a recording of those frames back in.
    b = Bench()
    host = Signer(KEY, mg.SIGN_HOST_TO_ROVER)
    b.step(encode_frame(config(1), 1, host))
    ahead = Signer(KEY, mg.SIGN_HOST_TO_ROVER, clock=lambda: host._clock() + 3600)
    recording = [encode_frame(config(i), i, ahead) for i in range(2, 5)]
    for frame in recording:
        b.step(frame)
    assert b.acks() == 4
    stored_rx = b.stored[1]
    assert stored_rx >= int.from_bytes(cobs_decode(recording[0][:-1])[-14:-8], "little")
    again = Bench(counters=b.stored)
    for frame in recording:
        again.step(frame)
    assert again.acks() == 0 and again.core.auth_counters()["replayed"] == 3


def test_the_rovers_own_counter_never_repeats_across_resets():
    # Three boots, each from the counters the last one stored: every frame the rover signs has a
    # counter above every one before it (a host that heard them all would take each).
    heard: list[int] = []
    stored = (0, 0)
    for _boot in range(3):
        core = NativeCore(key=KEY, counters=stored)
        decoder = FrameDecoder(Verifier(KEY, mg.SIGN_ROVER_TO_HOST))
        counters = []
        for t in range(0, 2000, 10):
            counters += [f.counter for f in decoder.feed(core.step(t, gyro_rate_mdps=0).tx)]
            stored = core.take_persist() or stored
        assert len(counters) >= 5 and decoder.counters.dropped == 0
        assert counters == sorted(set(counters))
        assert not heard or counters[0] > heard[-1]
        heard += counters
