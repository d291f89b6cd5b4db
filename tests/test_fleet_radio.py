"""Issue 30's shared air, host side: frames routed to each rover's Link by the address in their
version byte, slots in turn, a slot only when the last rover's answer can be off the air."""

from __future__ import annotations

import pytest

from rovernav.fleet.radio import AIR_BYTES_PER_S, MAX_SLOT_FRAMES, MAX_WAIT_S, FleetRadio, frame_address, grant_air_s
from rovernav.link import messages_gen as mg
from rovernav.link.framing import Signer, cobs_decode, encode_frame
from rovernav.link.link import Link
from rovernav.link.transport import LoopbackTransport

KEYS = [bytes([k + 1] * 16) for k in range(4)]


def _heartbeat(ms: int = 0) -> mg.Heartbeat:
    return mg.Heartbeat(host_time_ms=ms, camera=0, scan_heard=0, path_id=0)


def _rover_says(wire, k: int, arg: int, signers: dict) -> None:
    """Rover k (address k) sends an EVENT, signed with its own key, as its firmware would."""
    signer = signers.setdefault(k, Signer(KEYS[k], mg.SIGN_ROVER_TO_HOST))
    event = mg.Event(kind=int(mg.EventKind.BOOT), arg=arg, time_ms=0, x_mm=0, y_mm=0)
    wire.write(encode_frame(event, arg & 0xFF, signer, address=k))


def test_frames_are_routed_by_their_address_and_each_link_reads_only_its_own():
    wire = LoopbackTransport()  # what is written comes back: as if each rover had spoken
    radio = FleetRadio(wire, 3)
    links = [Link(radio.ports[k], key=KEYS[k], address=k) for k in range(3)]
    signers: dict = {}
    for k, arg in ((2, 102), (0, 100), (1, 101), (2, 103)):
        _rover_says(wire, k, arg, signers)
    got = {k: [f.message.arg for f in links[k].messages()] for k in range(3)}
    assert got == {0: [100], 1: [101], 2: [102, 103]}
    assert radio.load[2].rx_frames == 2 and radio.unroutable == 0
    assert all(link.counters.dropped == 0 for link in links)


def test_a_frame_for_a_rover_the_fleet_does_not_have_is_dropped_and_counted():
    wire = LoopbackTransport()
    radio = FleetRadio(wire, 2)
    _rover_says(wire, 3, 1, {})
    assert radio.ports[0].read(100) == b"" and radio.ports[1].read(100) == b""
    assert radio.unroutable == 1


def test_the_address_sits_in_bits_5_and_6_of_the_version_byte():
    wire = LoopbackTransport()
    for k in range(mg.MAX_ROVERS):
        Link(wire, key=KEYS[k], address=k).send(_heartbeat())
        frame = wire.read(200)
        assert frame_address(frame[:-1]) == k
    assert frame_address(b"\x01\x00") is None  # a zero where the version byte would be


def test_slots_go_in_turn_each_ends_with_its_poll_and_waits_for_the_rovers_answer():
    wire = LoopbackTransport()
    radio = FleetRadio(wire, 3)
    links = [Link(radio.ports[k], key=KEYS[k], address=k) for k in range(3)]
    extra = {1: 4}  # rover 2 has four frames waiting: two go with its first poll, two with its next

    def fill(k: int, now_s: float) -> None:
        for reason in range(extra.pop(k, 0)):  # four different frames (one said again would replace its first)
            links[k].send(mg.Stop(reason=reason))
        links[k].send(_heartbeat(int(now_s * 1000)))  # the poll, last

    t, slots = 0.0, []
    while t < 1.0:
        k = radio.slot(t, fill)
        if k is not None:
            sent = wire.read(1 << 16)
            raws = [cobs_decode(b) for b in sent.split(b"\x00") if b]
            slots.append((round(t, 3), k, [r[1] for r in raws], len(sent)))
        t = round(t + 0.010, 3)
    assert [k for _, k, _, _ in slots[:6]] == [0, 1, 2, 0, 1, 2]  # in turn, rover 1 first
    for _, _k, ids, _ in slots:
        assert ids[-1] == mg.Heartbeat.ID  # the poll closes every slot
        assert len(ids) <= MAX_SLOT_FRAMES
    assert slots[1][2] == [mg.Stop.ID, mg.Stop.ID, mg.Heartbeat.ID] and slots[4][2][:2] == [mg.Stop.ID, mg.Stop.ID]
    # A slot starts only once the last one's frames, the modem's latency, the rover's turnaround and
    # its whole grant are over the air: never sooner, and no later than the next 10 ms step.
    for (t0, _, ids, n), (t1, _, _, _) in zip(slots, slots[1:]):
        least = n / AIR_BYTES_PER_S + grant_air_s(len(ids))
        assert least - 1e-9 <= t1 - t0 < least + 0.010 + 1e-9


def test_a_rover_whose_grants_come_back_full_gets_more_slots_but_nobody_waits_past_the_limit():
    wire = LoopbackTransport()
    radio = FleetRadio(wire, 3)
    links = [Link(radio.ports[k], key=KEYS[k], address=k) for k in range(3)]
    signers: dict = {}
    t, order, last = 0.0, [], {0: 0.0, 1: 0.0, 2: 0.0}
    worst_wait = 0.0
    while t < 3.0:
        k = radio.slot(t, lambda k, now: links[k].send(_heartbeat()))
        if k is not None:
            order.append(k)
            worst_wait = max(worst_wait, t - last[k])
            last[k] = t
            wire.read(1 << 16)
            if k == 2:  # rover 3 answers every grant with a full one: four 34-byte frames
                for i in range(4):
                    _rover_says(wire, 2, len(order) * 4 + i, signers)
        t = round(t + 0.010, 3)
    assert order.count(2) > 1.3 * order.count(0) and order.count(0) > 0 and order.count(1) > 0
    assert worst_wait <= MAX_WAIT_S + grant_air_s(1) + 0.02


def test_a_request_sent_again_before_its_first_went_out_takes_its_place():
    radio = FleetRadio(LoopbackTransport(), 2)
    link = Link(radio.ports[1], key=KEYS[1], address=1)
    link.send(mg.Config(param=int(mg.Param.DRIVE_PWM), value=150))
    link.send(mg.Config(param=int(mg.Param.DRIVE_PWM), value=150))  # the resend: the same id and payload
    link.send(mg.Config(param=int(mg.Param.DRIVE_PWM), value=160))  # another value: another frame
    assert radio.waiting(1) == 2 and radio.replaced == 1


def test_a_fleet_of_more_rovers_than_addresses_is_refused():
    with pytest.raises(ValueError, match="1 to 4 rovers"):
        FleetRadio(LoopbackTransport(), mg.MAX_ROVERS + 1)
