"""The link's exceptions: catch LinkError for anything the radio or the rover did wrong."""

from __future__ import annotations

from ..errors import InputError, RovernavError


class LinkError(RovernavError):
    """Base of every link failure."""


class LinkTimeout(LinkError):
    """Nothing (or not the awaited answer) arrived within the timeout."""


class LinkClosed(LinkError):
    """The transport was closed, by us or by the other end."""


class PortError(LinkError):
    """A port could not be opened: missing, busy, or not a serial device."""


class PortSpecError(PortError, InputError):
    """A port or transport spec that cannot name anything (blank, control characters, an unknown
    scheme, a bad baud rate): an input error, refused before any device is touched. Also a
    ValueError, as the transport layer's argument errors have always been."""


class ProtocolError(LinkError):
    """The other end spoke, but not as the protocol says."""


class SchemaMismatch(ProtocolError):
    """The two ends were built from different protocol definitions."""

    def __init__(self, ours: int, theirs: int, who: str = "rover"):
        self.ours, self.theirs = ours, theirs
        super().__init__(
            f"the {who} was built from another protocol definition: its schema hash is 0x{theirs:08X}, "
            f"ours is 0x{ours:08X}. Rebuild and flash the firmware from this checkout "
            f"(pio run -e uno -t upload), or run the host version that matches it."
        )


class SigningMismatch(ProtocolError):
    """One end signs its commands and the other does not: the host has a link key and the rover
    none (or says so), or the rover holds a key the host was not given."""


class Nacked(ProtocolError):
    """The rover refused a command; `reason` is a NackReason."""

    def __init__(self, message_name: str, reason: int, detail: int):
        from .messages_gen import NackReason

        self.reason, self.detail = reason, detail
        try:
            rname = NackReason(reason).name.lower()
        except ValueError:
            rname = f"reason {reason}"
        super().__init__(f"rover refused {message_name}: {rname} (detail {detail})")
