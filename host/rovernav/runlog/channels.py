"""The run log's channels: topic, schema, and what each carries.

Foxglove's well-known schemas (protobuf, `foxglove.*`) where one fits, so that Foxglove shows
them with no extension: poses and paths in the 3D panel, the camera in an Image panel, the map
as a Grid, events in the Log panel. The link's frames and the host's inputs are ours: JSON
with a JSON schema (the Raw Messages panel shows them; plots reach into their fields).

Positions are in the frame "arena": metres, origin at the arena's bottom-left corner, x right,
y up, z up (the scenario's axes). Headings (0 = +y, clockwise) become the usual yaw about z.
"""

from __future__ import annotations

import dataclasses

LOG_FORMAT = "rovernav.run-log"
LOG_VERSION = 1
#: The MCAP metadata record that holds the run: format, version, the mission spec, ...
META_RUN = "rovernav.run"
#: The frame every position is in.
ARENA_FRAME = "arena"


def partial_path(path):
    """Where a log is written until it is closed and renamed to `path`: a hidden name beside it."""
    return path.with_name(f".{path.stem}.partial{path.suffix}")


#: Default rate of the camera images kept in the log (the fixes are all kept).
DEFAULT_IMAGE_HZ = 2.0
#: Default port of the live view (Foxglove's own default).
DEFAULT_LIVE_PORT = 8765


@dataclasses.dataclass(frozen=True)
class ChannelSpec:
    topic: str
    schema: str  # a Foxglove schema name, or ours (JSON)
    what: str
    sim_only: bool = False
    json_schema: dict | None = None  # for our JSON channels


_FRAME_FIELDS = {
    "n": {"type": "integer", "description": "order among the host's inputs and outputs"},
    "t_s": {"type": "number", "description": "mission time [s]"},
    "type": {"type": "string", "description": "message name (protocol/messages.toml)"},
    "id": {"type": "integer"},
    "seq": {"type": "integer"},
    "payload_hex": {"type": "string", "description": "the message's payload bytes"},
    "fields": {"type": "object", "description": "the decoded message"},
    "counter": {"type": ["integer", "null"], "description": "a signed frame's counter"},
}

_JSON = {
    "rovernav.LinkFrame": {"type": "object", "title": "rovernav.LinkFrame", "properties": _FRAME_FIELDS},
    "rovernav.RawBytes": {
        "type": "object",
        "title": "rovernav.RawBytes",
        "properties": {"t_s": {"type": "number"}, "hex": {"type": "string"}, "bytes": {"type": "integer"}},
    },
    "rovernav.HostInput": {
        "type": "object",
        "title": "rovernav.HostInput",
        "properties": {
            "n": {"type": "integer"},
            "t_s": {"type": "number"},
            "kind": {"type": "string", "enum": ["tick", "detection", "fail", "new_host"]},
        },
    },
    "rovernav.Sample": {
        "type": "object",
        "title": "rovernav.Sample",
        "properties": {
            "t_s": {"type": "number", "description": "mission time [s]"},
            "state": {"type": "string", "description": "the rover's state by name (idle, rotate, drive, scan, ...)"},
            "state_code": {"type": "integer", "description": "the same state as its number (RoverState), to plot"},
        },
    },
    "rovernav.Radio": {
        "type": "object",
        "title": "rovernav.Radio",
        "properties": {
            "t_s": {"type": "number", "description": "mission time [s]"},
            "to_rover": {
                "type": "object",
                "description": "host to rover, counts since the start: bytes_sent, "
                "bytes_lost, bytes_corrupted, frames_sent, frames_damaged, "
                "frames (by message kind: sent, damaged), ...",
            },
            "to_host": {"type": "object", "description": "rover to host, the same counts"},
            "bursts": {"type": ["object", "null"], "description": "bursts begun so far and the time in them"},
        },
    },
    "rovernav.LinkQuality": {
        "type": "object",
        "title": "rovernav.LinkQuality",
        "properties": {
            "t_s": {"type": "number", "description": "mission time [s]"},
            "to_rover_pct": {"type": ["number", "null"], "description": "frames through host to rover, last 10 s [%]"},
            "to_host_pct": {"type": ["number", "null"], "description": "frames through rover to host, last 10 s [%]"},
            "host_to_rover": {"type": "object", "description": "since the start: frames_sent, frames_arrived, success"},
            "rover_to_host": {"type": "object", "description": "the same, rover to host"},
            "host_sent_again": {"type": "object", "description": "frames the host sent again, by message kind"},
            "sweeps_heard": {
                "type": "object",
                "description": "the rover's sweeps whose SCAN_DONE the host heard: whole "
                "(every echo it counted heard too, so HEARTBEAT's scan_heard names it) or part",
            },
        },
    },
}

CHANNELS: tuple[ChannelSpec, ...] = (
    ChannelSpec("/link/host_to_rover", "rovernav.LinkFrame", "every frame the host sent, decoded"),
    ChannelSpec("/link/rover_to_host", "rovernav.LinkFrame", "every frame the host took from the rover, decoded"),
    ChannelSpec("/link/raw/host_to_rover", "rovernav.RawBytes", "the bytes the host wrote to the radio"),
    ChannelSpec(
        "/link/raw/rover_to_host",
        "rovernav.RawBytes",
        "the bytes the host read from the radio (noise and refused frames included)",
    ),
    ChannelSpec(
        "/host/inputs",
        "rovernav.HostInput",
        "what `rovernav replay` feeds the mission again: ticks, camera detections, failures from outside",
    ),
    ChannelSpec("/camera/image", "foxglove.CompressedImage", "the camera's frames, JPEG, thinned (--log-image-hz)"),
    ChannelSpec("/camera/fix", "foxglove.PoseInFrame", "where the host's vision located the rover"),
    ChannelSpec("/rover/estimate", "foxglove.PoseInFrame", "the rover's own estimate, from its STATUS"),
    ChannelSpec(
        "/rover/status",
        "rovernav.Sample",
        "the rover's STATUS: its state by name (state_code: its number, to plot), speeds, sd",
    ),
    ChannelSpec(
        "/host/link",
        "rovernav.LinkQuality",
        "frames through both ways as the host measures them (last 10 s and since the start), and the frames "
        "it sent again by kind (1 Hz)",
    ),
    ChannelSpec("/sim/true_pose", "foxglove.PoseInFrame", "the simulated rover's true pose (20 Hz)", sim_only=True),
    ChannelSpec(
        "/sim/radio",
        "rovernav.Radio",
        "the simulated radio's counts so far, each way: bytes sent, lost and corrupted, frames sent and "
        "damaged by message kind, bursts (1 Hz)",
        sim_only=True,
    ),
    ChannelSpec(
        "/rover/driven_path",
        "foxglove.PosesInFrame",
        "the path driven so far (true pose in the simulator, the camera's fixes on hardware), once a second",
    ),
    ChannelSpec("/plan/path", "foxglove.PosesInFrame", "each path the host sent the rover"),
    ChannelSpec(
        "/arena",
        "foxglove.SceneUpdate",
        "the arena: known obstacles grey, unknown ones red (simulator only), start and target",
    ),
    ChannelSpec(
        "/map/occupancy",
        "foxglove.Grid",
        "the host's learned map after each sweep: occupied_pct (log-odds as percent) and inflated",
    ),
    ChannelSpec("/sonar/echo", "foxglove.SceneUpdate", "each sonar echo the rover reported: the beam and the hit"),
    ChannelSpec("/events", "foxglove.Log", "what happened, in words: the mission, the rover's events, faults, crashes"),
)


def json_schema(name: str) -> dict:
    return _JSON[name]
