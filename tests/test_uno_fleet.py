"""A fleet's rover on the Uno image in simavr ([fleet] in protocol/messages.toml): the fleet id kept
in EEPROM with the link key (the key record's CRC xor the fleet id, so a record written before
fleets is a lone rover's), loaded at boot, the image's frames at its address, speaking only when
spoken to, and `rovernav provision --fleet-id` over USB storing it.

Builds the image and the harness when they are missing (conftest.py's uno_built), and skips when
the AVR toolchain or libsimavr-dev is not installed.
"""

from __future__ import annotations

import pytest
from tests.core_transport import CoreTransport

from rovernav.cores import uno
from rovernav.link import messages_gen as mg
from rovernav.link.framing import FrameDecoder, Signer, Verifier, cobs_decode, crc16, encode_frame

KEY = bytes(range(120, 136))


@pytest.fixture(scope="module")
def built(uno_built):
    return uno_built


def _frames(wire: bytes) -> list[bytes]:
    return [cobs_decode(body) for body in wire.split(b"\x00") if body]


def test_the_key_record_keeps_the_fleet_id_in_its_crc_and_a_lone_rovers_is_the_record_before_fleets():
    rec = b"\xa5" + KEY
    assert uno.link_key_record(KEY) == rec + crc16(rec).to_bytes(2, "little")  # as written before fleets
    for fleet_id in range(1, mg.MAX_ROVERS + 1):
        assert uno.link_key_record(KEY, fleet_id) == rec + (crc16(rec) ^ fleet_id).to_bytes(2, "little")
    blank = b"\xff" * 17
    assert uno.link_key_record(None, 2) == blank + (crc16(blank) ^ 2).to_bytes(2, "little")
    # an EEPROM never written (0xFF) is off by more than any fleet id: no key, a lone rover
    assert crc16(blank) ^ 0xFFFF > mg.MAX_ROVERS
    with pytest.raises(ValueError, match="fleet id"):
        uno.link_key_record(KEY, 5)


def test_the_image_loads_its_fleet_id_says_hello_at_its_address_and_speaks_only_in_grants(built):
    core = uno.UnoCore(boot_id=3, reset_cause=2, key=KEY, fleet_id=3)  # address 2
    try:
        board = uno.board_constants()
        assert core.eeprom(board.eeprom_link_addr, size=19) == uno.link_key_record(KEY, 3)
        port = CoreTransport(core)
        port.run_ms(2500)  # the image boots in about 1.6 s (the gyro's calibration)
        boot = _frames(port.from_rover)
        assert boot and {raw[0] for raw in boot} == {mg.PROTOCOL_VERSION | mg.SIGN_FLAG | 2 << mg.ADDRESS_SHIFT}
        heard = FrameDecoder(Verifier(KEY, mg.SIGN_ROVER_TO_HOST), address=2)
        said = [f.message for f in heard.feed(port.from_rover)]
        hello = next(m for m in said if isinstance(m, mg.Hello))
        assert hello.signing == 1 and [m.NAME for m in said] == ["hello", "event"]
        port.from_rover = b""
        port.run_ms(2000)  # ten STATUS periods: it says nothing unasked
        assert port.from_rover == b""
        host = Signer(KEY, mg.SIGN_HOST_TO_ROVER)
        host.jump_past((hello.min_counter_hi << 32 | hello.min_counter_lo) - 1)
        for seq in range(3):  # three grants: each at most 96 bytes, whole frames, a STATUS in each
            port.write(encode_frame(mg.Heartbeat(), seq, host, address=2))
            port.run_ms(150)
            assert 0 < len(port.from_rover) <= mg.GRANT_BYTES and port.from_rover.endswith(b"\x00")
            assert any(isinstance(f.message, mg.Status) for f in heard.feed(port.from_rover))
            port.from_rover = b""
        # a frame for rover 2 (address 1) opens nothing
        port.write(encode_frame(mg.Heartbeat(), 9, host, address=1))
        port.run_ms(300)
        assert port.from_rover == b""
        assert heard.counters.dropped == 0
    finally:
        core.close()


def test_provision_over_usb_stores_the_fleet_id_in_eeprom_and_the_image_boots_at_its_address(built):
    from rovernav.link.provision import provision

    core = uno.UnoCore(boot_id=3, reset_cause=2)  # no key, a lone rover: its EEPROM blank
    try:
        port = CoreTransport(core)
        line = provision(port, KEY, clock=port.clock, fleet_id=2)
        assert "rover 2 of a fleet (address 1)" in line
        port.run_ms(1000)  # the record goes to EEPROM a byte a step
        board = uno.board_constants()
        assert core.eeprom(board.eeprom_link_addr, size=19) == uno.link_key_record(KEY, 2)
        core.reset(2)
        port.from_rover = b""
        port.run_ms(2500)
        assert {raw[0] for raw in _frames(port.from_rover)} == {
            mg.PROTOCOL_VERSION | mg.SIGN_FLAG | 1 << mg.ADDRESS_SHIFT
        }
        hello = next(
            f.message
            for f in FrameDecoder(Verifier(KEY, mg.SIGN_ROVER_TO_HOST), address=1).feed(port.from_rover)
            if isinstance(f.message, mg.Hello)
        )
        assert hello.signing == 1
    finally:
        core.close()
