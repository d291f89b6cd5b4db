"""`rovernav provision`: store the link key on the rover, over its USB cable only.

The rover takes a PROVISION frame only within [signing].provision_window_ms (5 s) of a reset
(firmware/lib/core/link_in.cpp). Opening the Uno's USB serial port resets it (the DTR line), a
radio cannot; so this opens the port, waits for the HELLO the rover sends as it boots, and only
then sends the key. No HELLO of a fresh boot: the port did not reset the rover (a radio, or a
board without auto-reset), and nothing is sent. The rover's ACK comes signed with the new key:
checking its tag confirms the rover holds exactly this key.
"""
from __future__ import annotations

import time

from ..errors import InputError
from .errors import LinkError
from .framing import FrameDecoder, Verifier, encode_frame
from .messages_gen import (SIGN_PROVISION_WINDOW_MS, SIGN_ROVER_TO_HOST, Ack, Hello, Nack, NackReason, Provision,
                           Role)
from .transport import Transport


class ProvisionError(LinkError):
    """The key was not stored; the message says why and what to do."""


def provision(transport: Transport, key: bytes | None, boot_wait_s: float = 4.0,
              answer_wait_s: float = 2.0, clock=time.monotonic) -> str:
    """Store `key` (16 bytes; None erases the rover's key) on the rover behind `transport`, which
    must have just reset it. Returns a line saying what was done; raises ProvisionError."""
    if key is not None and len(key) != 16:
        raise InputError(f"a link key is 16 bytes, got {len(key)}")
    plain = FrameDecoder()   # a keyed rover's HELLO is readable unchecked: enough to see it boot
    deadline = clock() + boot_wait_s
    hello: Hello | None = None
    while hello is None and clock() < deadline:
        for frame in plain.feed(transport.read(256, timeout_s=0.05)):
            if isinstance(frame.message, Hello) and frame.message.role == Role.ROVER:
                hello = frame.message
    if hello is None:
        raise ProvisionError(
            f"no rover booted on {transport} within {boot_wait_s:g} s of opening it, so the key was not sent. "
            "Provisioning needs the USB cable, whose opening resets the Uno; a radio cannot reset the rover. "
            "Plug the cable in (or press the rover's reset button just after starting this command) and run "
            "it again.")
    booted_at = clock()
    message = Provision(key=tuple(key) if key is not None else (0,) * 16, erase=int(key is None))
    transport.write(encode_frame(message, 0))
    # The ACK of a stored key is signed with it (checked); a NACK comes as the rover signed before.
    answers = FrameDecoder(Verifier(key, SIGN_ROVER_TO_HOST, require=False) if key is not None else None)
    deadline = clock() + answer_wait_s
    while clock() < deadline:
        for frame in answers.feed(transport.read(256, timeout_s=0.05)):
            m = frame.message
            if isinstance(m, Ack) and m.msg_id == Provision.ID:
                if key is not None and frame.counter is None:
                    raise ProvisionError("the rover acknowledged the key unsigned: it does not hold it as sent")
                if key is None:
                    return "the rover's link key is erased: it takes unsigned commands again"
                return (f"stored the key on the rover (boot id {hello.boot_id}); its answer is signed with it. "
                        "The host that commands it needs the same key file ([link] key_file)")
            if isinstance(m, Nack) and m.msg_id == Provision.ID:
                if m.reason == NackReason.NOT_NOW:
                    raise ProvisionError(f"the rover refused: PROVISION came {m.detail} s after its reset, past its "
                                         f"{SIGN_PROVISION_WINDOW_MS / 1000:g} s window. Run the command again")
                raise ProvisionError(f"the rover refused the key ({NackReason(m.reason).name.lower()})")
    waited = clock() - booted_at
    raise ProvisionError(f"the rover booted but did not answer PROVISION within {waited:.1f} s "
                         "(a firmware without signing?)")
