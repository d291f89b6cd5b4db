"""`rovernav provision`: store the link key on the rover, over its USB cable only.

A rover with no key takes a PROVISION frame only within [signing].provision_window_ms (5 s) of
a reset (firmware/lib/core/link_in.cpp): first use. Opening the Uno's USB serial port resets it
(the DTR line), a radio cannot; so this opens the port, waits for the HELLO the rover sends as
it boots, and only then sends the key. No HELLO of a fresh boot: the port did not reset the
rover (a radio, or a board without auto-reset), and nothing is sent, for PROVISION carries the
new key in the clear. The rover's ACK comes signed with the new key: checking its tag confirms
the rover holds exactly this key.

A rover that holds a key changes it (or forgets it) only with its owner's consent: the PROVISION
signed with the key it holds (`current_key`: its boot HELLO, signed with that key, is checked
first, so a wrong key file is named before anything is sent), or the consent pin
([signing].consent_pin, D7) held to GND while it reset. Without either it answers NACK
needs_consent, and this says the two ways in one line (NeedsConsent).

PROVISION carries the rover's fleet id too ([fleet]): 0 a lone rover (address 0, talks freely), k
= 1..MAX_ROVERS rover k of a fleet (address k - 1), which speaks only when spoken to. The rover's
boot HELLO comes at the address it holds (a rover of a fleet says it unasked: its reset opens a
grant), the PROVISION goes to that address, and the ACK comes from the new one, which confirms it.
"""

from __future__ import annotations

import time

from ..errors import InputError
from .errors import LinkError
from .framing import (
    CRC_BYTES,
    HEADER_BYTES,
    SIGNATURE_BYTES,
    FrameDecoder,
    Signer,
    Verifier,
    cobs_decode,
    crc16,
    encode_frame,
)
from .messages_gen import (
    MAX_ROVERS,
    PROTOCOL_VERSION,
    SIGN_CONSENT_PIN,
    SIGN_FLAG,
    SIGN_HOST_TO_ROVER,
    SIGN_PROVISION_WINDOW_MS,
    SIGN_ROVER_TO_HOST,
    VERSION_MASK,
    Ack,
    Heartbeat,
    Hello,
    Nack,
    NackReason,
    Provision,
    Role,
)
from .transport import Transport


class ProvisionError(LinkError):
    """The key was not stored; the message says why and what to do. exit_code: the command's."""

    exit_code = 1


class NeedsConsent(ProvisionError):
    """The rover holds a key and was given neither its key's signature nor the consent pin."""

    exit_code = 2

    def __init__(self, pin: int = SIGN_CONSENT_PIN):
        self.pin = pin
        super().__init__(
            f"the rover holds a link key and changes it only with its owner's consent: give the key it holds "
            f"with --current-key-file FILE, or hold pin D{pin} to GND (a jumper to a GND pin) while the rover "
            f"resets and run this again (opening the port resets it; take the jumper off afterwards)"
        )


class WrongCurrentKey(ProvisionError):
    """The rover's boot HELLO is signed, but not with the key given as its current one."""

    exit_code = 2


#: While it waits for the rover's answer, `provision` polls it this often (a fleet's rover speaks
#: only when polled) [s].
POLL_EVERY_S = 0.1


def check_fleet_id(fleet_id: int) -> int:
    """`fleet_id` if it is one (0: a lone rover; 1..MAX_ROVERS: rover k of a fleet), else InputError."""
    if isinstance(fleet_id, bool) or not isinstance(fleet_id, int) or not 0 <= fleet_id <= MAX_ROVERS:
        raise InputError(
            f"a fleet id is 0 (a lone rover) or 1..{MAX_ROVERS} (rover k of a fleet, address k - 1), got {fleet_id!r}"
        )
    return fleet_id


class _Refusals:
    """The rover's NACKs, read without checking a tag: a keyed rover signs its refusal with the key
    it holds, which the host may not have (that is why it refuses). A forged NACK can only make
    provisioning fail, as jamming the cable can; the ACK, which says a key was stored, is checked."""

    def __init__(self) -> None:
        self._buf = b""

    def feed(self, data: bytes) -> list[Nack]:
        *bodies, self._buf = (self._buf + data).split(b"\0")
        self._buf = self._buf[-256:]
        nacks = []
        for body in bodies:
            raw = cobs_decode(body) if body else None
            if (
                raw is None
                or len(raw) < HEADER_BYTES + CRC_BYTES
                or crc16(raw[:-CRC_BYTES]) != int.from_bytes(raw[-CRC_BYTES:], "little")
            ):
                continue
            end = len(raw) - CRC_BYTES - (SIGNATURE_BYTES if raw[0] & SIGN_FLAG else 0)
            if (
                raw[0] & VERSION_MASK == PROTOCOL_VERSION  # at any address: the rover's, old or new
                and raw[1] == Nack.ID
                and end - HEADER_BYTES == Nack.STRUCT.size
            ):
                nacks.append(Nack.unpack(raw[HEADER_BYTES:end]))
        return nacks


def provision(
    transport: Transport,
    key: bytes | None,
    boot_wait_s: float = 4.0,
    answer_wait_s: float = 2.0,
    clock=time.monotonic,
    *,
    current_key: bytes | None = None,
    wall_clock=time.time,
    fleet_id: int = 0,
) -> str:
    """Store `key` (16 bytes; None erases the rover's key) and `fleet_id` (0: a lone rover; k =
    1..MAX_ROVERS: rover k of a fleet, [fleet]) on the rover behind `transport`, which must have
    just reset it. `current_key`: the key the rover holds, to sign the PROVISION with (its owner's
    consent; ignored by a rover that holds none). `wall_clock` drives the signing counter
    (Signer). Returns a line saying what was done; raises ProvisionError."""
    for name, k in (("link key", key), ("current link key", current_key)):
        if k is not None and len(k) != 16:
            raise InputError(f"a {name} is 16 bytes, got {len(k)}")
    check_fleet_id(fleet_id)
    # Frames at any address: the rover's boot HELLO says the one it holds, its ACK the new one.
    plain = FrameDecoder(address=None)  # a keyed rover's HELLO is readable unchecked: enough to see it boot
    # ... and checked with the current key, when one is given: a wrong key file is named here
    checked = (
        FrameDecoder(Verifier(current_key, SIGN_ROVER_TO_HOST, require=False), address=None) if current_key else None
    )
    deadline = clock() + boot_wait_s
    hello: Hello | None = None
    address = 0
    hello_signed_by_current = False
    while hello is None and clock() < deadline:
        data = transport.read(256, timeout_s=0.05)
        if checked is not None:
            hello_signed_by_current |= any(
                isinstance(f.message, Hello) and f.message.role == Role.ROVER and f.counter is not None
                for f in checked.feed(data)
            )
        for frame in plain.feed(data):
            if isinstance(frame.message, Hello) and frame.message.role == Role.ROVER:
                hello, address = frame.message, frame.address
    if hello is None:
        raise ProvisionError(
            f"no rover booted on {transport} within {boot_wait_s:g} s of opening it, so the key was not sent. "
            "Provisioning needs the USB cable, whose opening resets the Uno; a radio cannot reset the rover. "
            "Plug the cable in (or press the rover's reset button just after starting this command) and run "
            "it again."
        )
    booted_at = clock()
    keyed = bool(hello.signing & 1)
    signer = None
    if keyed and current_key is not None:
        if not hello_signed_by_current:
            raise WrongCurrentKey(
                "the rover holds a link key, but not the one given with --current-key-file: "
                "its boot HELLO is not signed with it. Give the key file the rover was "
                "provisioned with"
            )
        signer = Signer(current_key, SIGN_HOST_TO_ROVER, clock=wall_clock)
        signer.jump_past((hello.min_counter_hi << 32 | hello.min_counter_lo) - 1)
    message = Provision(key=tuple(key) if key is not None else (0,) * 16, erase=int(key is None), fleet_id=fleet_id)
    transport.write(encode_frame(message, 0, signer, address=address))
    # The ACK of a stored key is signed with it (checked); a NACK comes as the rover signed before.
    answers = FrameDecoder(Verifier(key, SIGN_ROVER_TO_HOST, require=False) if key is not None else None, address=None)
    new_address = fleet_id - 1 if fleet_id else 0
    refusals = _Refusals()
    deadline = clock() + answer_wait_s
    # A rover of a fleet answers only when polled (a HEARTBEAT to it: [fleet]), at the address and
    # with the key it now holds; a lone rover takes the polls too and answers anyway.
    poller = None
    if key is not None and fleet_id:
        poller = Signer(key, SIGN_HOST_TO_ROVER, clock=wall_clock)
        poller.jump_past(signer.last_counter if signer is not None else 0)
        if hello.signing:  # past the least counter the rover takes (it keeps it across a new key)
            poller.jump_past((hello.min_counter_hi << 32 | hello.min_counter_lo) - 1)
    polled_at, polls = -1.0, 0
    while clock() < deadline:
        if fleet_id and clock() - polled_at >= POLL_EVERY_S:
            polled_at = clock()
            polls += 1
            poll = Heartbeat(host_time_ms=0, camera=0, scan_heard=0, path_id=0)
            transport.write(encode_frame(poll, polls & 0xFF, poller, address=new_address))
        data = transport.read(256, timeout_s=0.05)
        acks = [f for f in answers.feed(data) if isinstance(f.message, Ack) and f.message.msg_id == Provision.ID]
        for ack in acks:
            if key is not None and ack.counter is None:
                raise ProvisionError("the rover acknowledged the key unsigned: it does not hold it as sent")
            if ack.address != new_address:
                raise ProvisionError(
                    f"the rover acknowledged from address {ack.address}, not {new_address}: it does not hold "
                    f"fleet id {fleet_id} as sent (a firmware without fleets?)"
                )
            how = (
                " with its current key's signature"
                if signer is not None
                else f" with the consent pin (D{SIGN_CONSENT_PIN}) held at its reset: take the jumper off"
                if keyed
                else ""
            )
            fleet = (
                f"; it is rover {fleet_id} of a fleet (address {new_address}): it speaks only when spoken to"
                if fleet_id
                else ""
            )
            if key is None:
                return f"the rover's link key is erased{how}: it takes unsigned commands again{fleet}"
            return (
                f"stored the key on the rover (boot id {hello.boot_id}){how}; its answer is signed with it{fleet}. "
                "The host that commands it needs the same key file ([link] key_file)"
            )
        for m in refusals.feed(data):
            if m.msg_id != Provision.ID:
                continue
            if m.reason == NackReason.NEEDS_CONSENT:
                raise NeedsConsent(m.detail)
            if m.reason == NackReason.NOT_NOW:
                raise ProvisionError(
                    f"the rover refused: PROVISION came {m.detail} s after its reset, past its "
                    f"{SIGN_PROVISION_WINDOW_MS / 1000:g} s window. Run the command again"
                )
            try:
                reason = NackReason(m.reason).name.lower()
            except ValueError:
                reason = f"reason {m.reason}"
            raise ProvisionError(f"the rover refused the key ({reason})")
    waited = clock() - booted_at
    raise ProvisionError(
        f"the rover booted but did not answer PROVISION within {waited:.1f} s (a firmware without signing?)"
    )
