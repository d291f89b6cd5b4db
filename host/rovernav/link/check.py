"""Say HELLO to a rover and show what it says: `rovernav link-check` against a real rover, and
`rovernav demo` against the Uno image in simavr."""

from __future__ import annotations

import os
import time

from . import messages_gen as mg


def describe(message) -> str:
    """One line for a message, with enum fields named (EVENT fault arg=gyro_silent ...)."""
    m = message
    if isinstance(m, mg.Event):
        kind = mg.EventKind(m.kind).name.lower() if m.kind in mg.EventKind._value2member_map_ else m.kind
        arg = (
            mg.FaultCode(m.arg).name.lower()
            if kind in ("fault", "fault_cleared") and m.arg in mg.FaultCode._value2member_map_
            else m.arg
        )
        return f"EVENT {kind} arg={arg} at {m.time_ms / 1000:.2f} s, ({m.x_mm}, {m.y_mm}) mm"
    if isinstance(m, mg.Status):
        state = mg.RoverState(m.state).name.lower() if m.state in mg.RoverState._value2member_map_ else m.state
        flags = "|".join(f.name.lower() for f in mg.StatusFlag if m.flags & f) or "-"
        fault = mg.FaultCode(m.fault).name.lower() if m.fault in mg.FaultCode._value2member_map_ else m.fault
        return (
            f"STATUS {state} fault={fault} flags={flags} pose=({m.x_mm}, {m.y_mm}) mm {m.heading_cdeg / 100:.1f} deg "
            f"sd=({m.sd_x_mm}, {m.sd_y_mm}) mm wp={m.waypoint_index} motors=({m.left_pwm}, {m.right_pwm}) "
            f"rx ok={m.rx_ok} bad_crc={m.rx_bad_crc}"
        )
    fields = " ".join(f"{k}={v}" for k, v in m.to_dict().items())
    return f"{m.NAME.upper()} {fields}"


def greet(link, hello_timeout_s: float, boot_id: int | None = None):
    """HELLO with the schema check (and the signing check, for a Link with a key); print what the
    rover said. Returns the rover's HELLO."""
    started = time.monotonic()
    boot_id = int.from_bytes(os.urandom(4), "little") if boot_id is None else boot_id
    hello = link.handshake(boot_id=boot_id, timeout_s=hello_timeout_s)
    print(
        f"rover says HELLO after {time.monotonic() - started:.2f} s: firmware "
        f"{hello.firmware_version >> 8}.{hello.firmware_version & 0xFF}, boot id {hello.boot_id}, "
        f"holds {hello.max_waypoints} waypoints, schema hash 0x{hello.schema_hash:08X} (matches ours)"
        + (", signed frames" if link.signer is not None else "")
    )
    return hello


def talk_to_rover(link, seconds: float, hello_timeout_s: float, listening_note: str = "") -> None:
    """HELLO (with the schema check), then print what the rover says for `seconds` while sending
    heartbeats (the host is alive, with no camera), then the link's counters. Shared by
    `link-check` (a real rover) and `demo` (the Uno image in simavr)."""
    greet(link, hello_timeout_s)
    print(f"listening for {seconds:g} s{listening_note}:")
    end = time.monotonic() + seconds
    next_heartbeat = 0.0
    while time.monotonic() < end:
        if time.monotonic() >= next_heartbeat:
            link.send(
                mg.Heartbeat(host_time_ms=int(time.monotonic() * 1000) & 0xFFFFFFFF, camera=mg.CameraState.NO_FRAMES)
            )
            next_heartbeat = time.monotonic() + 0.2
        frame = link.recv(timeout_s=min(0.05, max(0.0, end - time.monotonic())))
        if frame is not None:
            print(f"  seq {frame.seq:3d}  {describe(frame.message)}")
    c = link.counters
    signing = (
        f"; signed: refused {c.bad_tag} bad tag, {c.replayed} replayed, {c.not_signed} unsigned"
        if link.signer is not None
        else ""
    )
    print(
        f"link: {c.frames_ok} frames received; dropped {c.bad_crc} bad CRC, {c.overlong} overlong, "
        f"{c.unknown_id} unknown id, {c.malformed} malformed{signing}; sent {link.tx_frames} frames"
    )
