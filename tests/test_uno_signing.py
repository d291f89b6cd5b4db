"""Signed frames on the Uno image in simavr: a link key provisioned over USB, kept in EEPROM and
signed with after a reset, the counter resumed from its newest whole slot, and the owner's
consent (the pin held) before a stranger's key is taken.

Builds the image (tools/build_uno.py) and the harness (make -C tools/avrsim unocore) when they
are missing (conftest.py's uno_built), and skips (saying which Debian package is missing) when the
AVR toolchain or libsimavr-dev is not installed.
"""

from __future__ import annotations

import pytest

from rovernav.cores import uno
from rovernav.link import messages_gen as mg
from rovernav.link.framing import FrameDecoder


@pytest.fixture(scope="module")
def built(uno_built):
    """The Uno image and its simavr harness, built (conftest's uno_built; skips without the tools)."""
    return uno_built


def test_the_image_takes_a_key_over_usb_stores_it_in_eeprom_and_signs_with_it_after_a_reset(built):
    from tests.core_transport import CoreTransport

    from rovernav.link.framing import FrameDecoder, Signer, Verifier, encode_frame
    from rovernav.link.provision import provision

    key = bytes(range(200, 216))
    core = uno.UnoCore(boot_id=3, reset_cause=2)  # the USB port opened: an external reset
    try:
        port = CoreTransport(core)
        assert provision(port, key, clock=port.clock).startswith("stored the key")  # no key yet: first use
        port.run_ms(1000)  # the EEPROM record goes a byte a step, never waiting for the EEPROM
        board = uno.board_constants()
        assert core.eeprom(board.eeprom_link_addr, size=19) == uno.link_key_record(key)
        # After a reset the image loads the key: its HELLO says it signs, signed with the key, and
        # it obeys only what the key signs.
        core.reset(2)
        port.from_rover = b""
        port.run_ms(2500)  # the image boots in about 1.6 s (the gyro's calibration)
        heard = FrameDecoder(Verifier(key, mg.SIGN_ROVER_TO_HOST))
        hello = next(f for f in heard.feed(port.from_rover) if isinstance(f.message, mg.Hello))
        assert hello.counter is not None and hello.message.signing == 1
        host = Signer(key, mg.SIGN_HOST_TO_ROVER)
        host.jump_past((hello.message.min_counter_hi << 32 | hello.message.min_counter_lo) - 1)
        port.from_rover = b""
        port.write(encode_frame(mg.Stop(reason=0), 9))  # unsigned: refused
        port.write(encode_frame(mg.Stop(reason=0), 10, host))  # signed: obeyed
        port.run_ms(300)
        acks = [f.message.seq for f in heard.feed(port.from_rover) if isinstance(f.message, mg.Ack)]
        assert acks == [10] and heard.counters.dropped == 0
    finally:
        core.close()


@pytest.mark.parametrize(
    "slots, expected_rx",
    [
        ([(1000, 5000, 5, True), (9999, 99999, 6, False)], 5000),  # the newer slot torn (bad CRC): the other
        ([(1000, 5000, 5, True), (2000, 9000, 6, True)], 9000),  # both whole: the newer age
        ([(2000, 9000, 255, True), (3000, 12000, 0, True)], 12000),  # ages wrap: 0 follows 255
        ([(1, 2, 3, False), (4, 5, 6, False)], 0),  # none whole: from zero
    ],
)
def test_the_image_resumes_from_the_newest_whole_counter_slot(built, slots, expected_rx):
    from rovernav.link.framing import FrameDecoder, Verifier, crc16

    key = bytes(range(100, 116))
    core = uno.UnoCore(boot_id=3, reset_cause=1)
    try:
        base = uno.board_constants().eeprom_link_addr
        core.eeprom(base, uno.link_key_record(key))
        for i, (tx, rx, age, whole) in enumerate(slots):
            rec = tx.to_bytes(6, "little") + rx.to_bytes(6, "little") + bytes((age,))
            crc = crc16(rec) ^ (0 if whole else 0x5A5A)
            core.eeprom(base + 19 + 15 * i, rec + crc.to_bytes(2, "little"))
        heard = FrameDecoder(Verifier(key, mg.SIGN_ROVER_TO_HOST))
        frames = []
        for k in range(1, 260):
            frames += heard.feed(core.step(k * 10, gyro_rate_mdps=0).tx)
        hello = next(f for f in frames if isinstance(f.message, mg.Hello))
        assert (
            hello.message.min_counter_hi << 32 | hello.message.min_counter_lo
        ) == expected_rx + mg.SIGN_RESET_MARGIN + 1
        # ... and it stored the resumed counters at once, in the slot it did not take
        stored = [core.eeprom(base + 19 + 15 * i, size=15) for i in range(2)]
        whole = [s for s in stored if crc16(s[:13]) == int.from_bytes(s[13:], "little")]
        assert any(int.from_bytes(s[6:12], "little") == expected_rx + mg.SIGN_RESET_MARGIN for s in whole)
    finally:
        core.close()


# ---------------------------------------------------------------- the owner's consent on the image

OWNER_KEY = bytes(range(120, 136))
STRANGER_KEY = bytes(range(7, 23))


def _boot_events(frames) -> list[int]:
    return [f.message.arg for f in frames if isinstance(f.message, mg.Event) and f.message.kind == mg.EventKind.BOOT]


def _recording_port(core):
    """A CoreTransport that also keeps every byte the host read (`heard`)."""
    from tests.core_transport import CoreTransport

    class Recording(CoreTransport):
        heard = b""

        def _read(self, max_bytes, timeout_s):
            data = super()._read(max_bytes, timeout_s)
            self.heard += data
            return data

    return Recording(core)


def test_a_keyed_image_refuses_a_strangers_provision_after_power_on_brown_out_and_watchdog_resets_and_takes_it_with_the_pin_held(
    built,
):
    from rovernav.link.framing import Verifier
    from rovernav.link.provision import NeedsConsent, provision

    core = uno.UnoCore(boot_id=5, reset_cause=0x01, key=OWNER_KEY)  # power-on, the owner's key in EEPROM
    board = uno.board_constants()
    try:
        port = _recording_port(core)
        for cause in (None, 0x04, 0x08):  # power-on (the first boot), brown-out, watchdog
            if cause is not None:
                core.reset(cause)  # MCUSR as each reset leaves it
                port.from_rover = b""
            with pytest.raises(NeedsConsent) as info:
                provision(port, STRANGER_KEY, clock=port.clock)
            assert info.value.pin == board.pin_consent == mg.SIGN_CONSENT_PIN
            port.run_ms(500)
            assert core.eeprom(board.eeprom_link_addr, size=19) == uno.link_key_record(OWNER_KEY)
        # A jumper from D7 to GND, then a reset (the USB port opened): the image reads the pin as it
        # starts, says so in its boot EVENT, and takes an unsigned key.
        core.hold_consent_pin(True)
        core.reset(0x02)
        port.from_rover = port.heard = b""
        line = provision(port, STRANGER_KEY, clock=port.clock)
        assert "consent pin (D7)" in line
        booted = FrameDecoder(Verifier(OWNER_KEY, mg.SIGN_ROVER_TO_HOST, require=False)).feed(port.heard)
        port.run_ms(1000)  # the EEPROM record goes a byte a step
        assert core.eeprom(board.eeprom_link_addr, size=19) == uno.link_key_record(STRANGER_KEY)
        # The jumper off again: after the next reset the pin reads high, and the new key holds.
        core.hold_consent_pin(False)
        core.reset(0x01)
        port.from_rover = port.heard = b""
        with pytest.raises(NeedsConsent):
            provision(port, OWNER_KEY, clock=port.clock)
        port.run_ms(200)
        after = FrameDecoder(Verifier(STRANGER_KEY, mg.SIGN_ROVER_TO_HOST, require=False)).feed(
            port.heard + port.from_rover
        )
    finally:
        core.close()
    assert mg.SIGN_CONSENT_RESET_BIT | 0x02 in _boot_events(booted)
    assert _boot_events(after) == [0x01]


def test_a_keyed_image_takes_a_new_key_signed_with_its_current_one_and_signs_with_it_after_a_reset(built):
    from tests.core_transport import CoreTransport

    from rovernav.link.framing import Signer, Verifier, encode_frame
    from rovernav.link.provision import provision

    core = uno.UnoCore(boot_id=5, reset_cause=0x01, key=OWNER_KEY)
    board = uno.board_constants()
    try:
        port = CoreTransport(core)
        line = provision(port, STRANGER_KEY, clock=port.clock, current_key=OWNER_KEY)
        assert "current key's signature" in line
        port.run_ms(1000)
        assert core.eeprom(board.eeprom_link_addr, size=19) == uno.link_key_record(STRANGER_KEY)
        core.reset(0x01)
        port.from_rover = b""
        port.run_ms(2500)
        heard = FrameDecoder(Verifier(STRANGER_KEY, mg.SIGN_ROVER_TO_HOST))
        hello = next(f for f in heard.feed(port.from_rover) if isinstance(f.message, mg.Hello))
        host = Signer(STRANGER_KEY, mg.SIGN_HOST_TO_ROVER)
        host.jump_past((hello.message.min_counter_hi << 32 | hello.message.min_counter_lo) - 1)
        port.from_rover = b""
        port.write(encode_frame(mg.Stop(reason=0), 21, Signer(OWNER_KEY, mg.SIGN_HOST_TO_ROVER)))  # the old key
        port.write(encode_frame(mg.Stop(reason=0), 22, host))  # the new one
        port.run_ms(300)
        acks = [f.message.seq for f in heard.feed(port.from_rover) if isinstance(f.message, mg.Ack)]
    finally:
        core.close()
    assert acks == [22]
