"""RunLog: one run's channels, written to an MCAP file and, live, served on localhost.

A RunLog is the Mission's recorder (it receives the host's inputs and outputs, see
`rovernav.mission.core.Recorder`) and the runner's (camera frames, the simulator's truth, raw
radio bytes through `RecordingTransport`, events). It reads no clock: every call carries the
mission time, and a record's MCAP log time is the run's start (wall clock) plus that.

The file is written to a hidden partial name and renamed into place by `close()`, also when a
run is cut short (Ctrl-C, a crash): a log is worth most then. The foxglove-sdk does the
writing (zstd-compressed chunks) and the WebSocket server; `mcap` reads it back. What each
channel's messages hold is made in messages.py; here, what is logged when.

The live view's WebSocket subprotocol (LIVE_SUBPROTOCOL): the foxglove-sdk's server (`foxglove.
start_server`, checked with foxglove-sdk 0.30.3) takes only a client that offers
`foxglove.sdk.v1` in its Sec-WebSocket-Protocol header (0.30.3 also takes `foxglove.sdk.v1.1`),
and answers it with that name. A client that offers only `foxglove.websocket.v1` (older Foxglove
and Lichtblick builds, `@foxglove/ws-protocol`), or no subprotocol, gets "HTTP 400 Missing
expected sec-websocket-protocol header" and no connection. The name is a constant compiled into
the SDK's Rust handshake (rust/foxglove/src/websocket/handshake.rs, SUBPROTOCOL); `start_server`
has no argument to add another, so rovernav cannot make it accept `foxglove.websocket.v1`. The
messages are, for now, the same under both names (Foxglove renamed the protocol): a client that
offers both, `foxglove.sdk.v1` among them, connects. Use a Foxglove or Lichtblick build that
offers `foxglove.sdk.v1`, or open the run's MCAP file instead. tests/test_runlog.py's
test_the_live_view_accepts_only_the_sdk_subprotocol checks these four answers (sdk.v1 alone,
both names, websocket.v1 alone, none) against the installed SDK.
"""

from __future__ import annotations

import json
import logging
import math
import os
import time
from pathlib import Path

import numpy as np

from ..errors import RovernavError
from ..link import messages_gen as mg
from ..link.transport import Transport
from ..mission.core import Recorder
from .channels import (  # noqa: F401
    ARENA_FRAME,
    CHANNELS,
    DEFAULT_IMAGE_HZ,
    DEFAULT_LIVE_PORT,
    LOG_FORMAT,
    LOG_VERSION,
    META_RUN,
    json_schema,
    partial_path,
)
from .images import encode_jpeg
from .messages import (
    GrowingPoses,
    arena_scene,
    echo_scene,
    message_record,
    occupancy_grid,
    pose,
    poses_along,
    sent_frame,
    to_json,
)

log = logging.getLogger("rovernav.runlog")

#: The true pose is logged this often [s] (the simulator's step is 0.01 s).
TRUE_POSE_EVERY_S = 0.05
#: The driven path is republished this often [s], thinned to points this far apart [m].
DRIVEN_PATH_EVERY_S = 1.0
DRIVEN_PATH_STEP_M = 0.01
#: The simulated radio's counts are logged this often [s].
RADIO_EVERY_S = 1.0
#: Live only: the arena is republished this often [s] for viewers that join late.
LIVE_ARENA_EVERY_S = 2.0
#: Live only: the server's clock is moved on this often [s].
LIVE_TIME_EVERY_S = 0.1
#: The WebSocket subprotocol the live view speaks: the only one the foxglove-sdk's server takes
#: (see the module's docstring; a client offering only `foxglove.websocket.v1` gets HTTP 400).
LIVE_SUBPROTOCOL = "foxglove.sdk.v1"


class RunLogError(RovernavError):
    """The log cannot be written or served (a port in use, a folder that cannot be written)."""


class RunLog(Recorder):
    """The channels of one run. `path`: the MCAP file (None: no file); `live_port`: serve the
    channels over Foxglove's WebSocket protocol on 127.0.0.1 at that port (0: any free port;
    None: no server). `truth`: the simulator's true world may be shown (unknown obstacles,
    true pose)."""

    def __init__(
        self,
        path: str | Path | None,
        spec,
        *,
        source: str,
        scenario=None,
        truth: bool = False,
        live_port: int | None = None,
        image_hz: float = DEFAULT_IMAGE_HZ,
        meta: dict | None = None,
        context=None,
        topic_prefix: str = "",
        topics: set[str] | None = None,
        t0_ns: int | None = None,
    ):
        """`context`, `topic_prefix`, `topics`, `t0_ns`: one rover's channel set in a fleet's log
        (FleetRunLog): its channels, those of `topics` (None: all), named `topic_prefix` + topic
        in another log's `context` and clock; such a log writes no file of its own."""
        import foxglove
        from foxglove.channels import (
            CompressedImageChannel,
            GridChannel,
            LogChannel,
            PoseInFrameChannel,
            PosesInFrameChannel,
            SceneUpdateChannel,
        )

        self.path = Path(path) if path is not None else None
        self.partial = None if self.path is None else partial_path(self.path)
        self.truth = truth
        self.scenario = scenario
        self.sonar_offset_m = float(spec.planner["sonar_offset_m"])
        self.image_period_s = 1.0 / image_hz if image_hz > 0 else math.inf
        self.t0_ns = time.time_ns() if t0_ns is None else t0_ns
        self.t_s = 0.0
        self.counts: dict[str, int] = {c.topic: 0 for c in CHANNELS}
        self._n = 0
        self._next_image_s = 0.0
        self._next_true_s = 0.0
        self._next_driven_s = 0.0
        self._next_arena_s = 0.0
        self._next_time_s = 0.0
        self._driven: list[tuple[float, float, float]] = []
        self._driven_poses = GrowingPoses()
        self._radio = None  # the simulator's radio counts (watch_radio)
        self._next_radio_s = 0.0
        self._echoes = 0
        self._sent: tuple[int, int, int | None] | None = None  # the frame the host wrote last (id, seq, counter)
        self._closed = False
        self.ctx = foxglove.Context() if context is None else context
        typed = {
            "foxglove.CompressedImage": CompressedImageChannel,
            "foxglove.PoseInFrame": PoseInFrameChannel,
            "foxglove.PosesInFrame": PosesInFrameChannel,
            "foxglove.SceneUpdate": SceneUpdateChannel,
            "foxglove.Grid": GridChannel,
            "foxglove.Log": LogChannel,
        }
        self.channels = {}
        for c in CHANNELS:
            if (c.sim_only and not truth) or (topics is not None and c.topic not in topics):
                continue
            name = topic_prefix + c.topic
            if c.schema in typed:
                self.channels[c.topic] = typed[c.schema](name, context=self.ctx)
            else:
                schema = foxglove.Schema(
                    name=c.schema, encoding="jsonschema", data=json.dumps(json_schema(c.schema)).encode()
                )
                self.channels[c.topic] = foxglove.Channel(
                    name, schema=schema, message_encoding="json", context=self.ctx
                )
        self.writer = None
        if self.path is not None and context is None:
            try:
                self.path.parent.mkdir(parents=True, exist_ok=True)
                self.writer = foxglove.open_mcap(self.partial, allow_overwrite=True, context=self.ctx)
            except Exception as exc:  # the SDK raises its own error types
                raise RunLogError(f"cannot write the run log {self.path}: {exc}") from None
            run = {
                "format": LOG_FORMAT,
                "version": str(LOG_VERSION),
                "source": source,
                "started_unix_ns": str(self.t0_ns),
                "spec": spec.to_json(),
                "schema_hash": f"0x{mg.SCHEMA_HASH:08X}",
            }
            run.update({k: (v if isinstance(v, str) else json.dumps(v)) for k, v in (meta or {}).items()})
            self.writer.write_metadata(META_RUN, run)
        self.server = None
        if live_port is not None:
            try:
                # Speaks LIVE_SUBPROTOCOL ("foxglove.sdk.v1") only: the SDK has no way to take
                # "foxglove.websocket.v1" too (see the module's docstring).
                self.server = foxglove.start_server(
                    name="rovernav",
                    host="127.0.0.1",
                    port=live_port,
                    context=self.ctx,
                    capabilities=[foxglove.Capability.Time],
                )
            except Exception as exc:
                self.close()
                raise RunLogError(f"cannot serve the live view on 127.0.0.1:{live_port}: {exc}") from None
        if scenario is not None:
            self._arena(0.0)

    # ------------------------------------------------------------ plumbing

    @property
    def live_port(self) -> int | None:
        return None if self.server is None else self.server.port

    def _log(self, topic: str, t_s: float, message) -> None:
        ch = self.channels.get(topic)
        if ch is None or self._closed:
            return
        ch.log(message, log_time=self.t0_ns + max(0, round(t_s * 1e9)))
        self.counts[topic] += 1

    def _next_n(self) -> int:
        self._n += 1
        return self._n

    def set_time(self, t_s: float) -> None:
        """The run's time now (for the raw bytes the transport moves); live: the viewer's clock."""
        self.t_s = t_s
        if self._radio is not None and t_s >= self._next_radio_s:
            self._next_radio_s = t_s + RADIO_EVERY_S
            self._publish_radio(t_s)
        if self.server is not None:
            if t_s >= self._next_time_s:
                self._next_time_s = t_s + LIVE_TIME_EVERY_S
                self.server.broadcast_time(self.t0_ns + round(t_s * 1e9))
            if self.scenario is not None and t_s >= self._next_arena_s:
                self._arena(t_s)

    # ------------------------------------------------------------ the mission's recorder

    def host_input(self, kind: str, t_s: float, **data) -> None:
        self._log("/host/inputs", t_s, to_json({"n": self._next_n(), "t_s": t_s, "kind": kind, **data}))
        if kind == "detection" and data.get("x_m") is not None:
            from foxglove.messages import PoseInFrame

            self._log(
                "/camera/fix",
                t_s,
                PoseInFrame(
                    timestamp=self._stamp(t_s),
                    frame_id=ARENA_FRAME,
                    pose=pose(data["x_m"], data["y_m"], data["heading_deg"]),
                ),
            )
            if not self.truth:
                self._drive(t_s, data["x_m"], data["y_m"])

    def new_host(self, t_s: float, host_boot_id: int) -> None:
        """A new host process takes over (the simulator's --host-restart): replay starts a new Mission."""
        self.host_input("new_host", t_s, host_boot_id=host_boot_id)

    def host_rx(self, t_s: float, frame) -> None:
        m = frame.message
        self._log("/link/rover_to_host", t_s, to_json(message_record(m, frame.seq, self._next_n(), t_s, frame.counter)))
        if isinstance(m, mg.Status):
            self._status(t_s, m)

    def host_tx(self, t_s: float, message, seq: int) -> None:
        # A signed frame's counter is the Link's Signer's, put in the bytes as they were written:
        # RecordingTransport read it back from them (sent_frame). The mission tells of a frame
        # right after sending it; one that is not the frame written last gets no counter.
        sent, self._sent = self._sent, None
        counter = sent[2] if sent is not None and sent[:2] == (message.ID, seq) else None
        self._log("/link/host_to_rover", t_s, to_json(message_record(message, seq, self._next_n(), t_s, counter)))

    def host_event(self, t_s: float, text: str) -> None:
        self.event(t_s, text, source="host")

    def host_link(self, t_s: float, quality: dict) -> None:
        self._log("/host/link", t_s, to_json({"t_s": t_s, **quality}))

    def host_path(self, t_s: float, path_id: int, path) -> None:
        from foxglove.messages import PosesInFrame

        self._log(
            "/plan/path", t_s, PosesInFrame(timestamp=self._stamp(t_s), frame_id=ARENA_FRAME, poses=poses_along(path))
        )

    def host_sonar(self, t_s: float, reading, changed: bool) -> None:
        if reading.range_m is None:
            return
        self._echoes += 1
        self._log("/sonar/echo", t_s, echo_scene(reading, self.sonar_offset_m, self._echoes, self._stamp(t_s)))

    def host_map(self, t_s: float, learned_map) -> None:
        self._log("/map/occupancy", t_s, occupancy_grid(learned_map, self._stamp(t_s)))

    # ------------------------------------------------------------ the runner's

    def raw(self, direction: str, data: bytes) -> None:
        """Bytes through the host's transport: direction "host_to_rover" or "rover_to_host"."""
        if direction == "host_to_rover":
            self._sent = sent_frame(data)
        if data:
            self._log(
                f"/link/raw/{direction}",
                self.t_s,
                to_json({"t_s": self.t_s, "bytes": len(data), "hex": bytes(data).hex()}),
            )

    def watch_radio(self, counts) -> None:
        """Log `counts()` (the simulated radio's figures, sim/channel.radio_figures) on /sim/radio
        every RADIO_EVERY_S of run time, and once more at the end."""
        self._radio = counts

    def _publish_radio(self, t_s: float) -> None:
        figures = self._radio()
        self._log(
            "/sim/radio",
            t_s,
            to_json(
                {
                    "t_s": t_s,
                    "to_rover": figures["to_rover"],
                    "to_host": figures["to_host"],
                    "bursts": figures["bursts"],
                }
            ),
        )

    def camera_image(self, t_s: float, frame_bgr: np.ndarray) -> None:
        """A camera frame; kept when the image rate allows (the first, then every 1/image_hz s)."""
        if self.take_image(t_s):
            jpeg = encode_jpeg(frame_bgr)
            if jpeg is not None:
                self.camera_jpeg(t_s, jpeg)

    def take_image(self, t_s: float) -> bool:
        """Whether a frame taken at t_s is kept (the image rate allows it); True books it: the
        caller then logs it with `camera_jpeg` (the simulator's camera process encodes it)."""
        if t_s + 1e-9 < self._next_image_s:
            return False
        self._next_image_s = t_s + self.image_period_s
        return True

    def camera_jpeg(self, t_s: float, jpeg: bytes, taken_s: float | None = None) -> None:
        """A kept camera frame, already JPEG (`encode_jpeg`), logged at t_s; its stamp says when it
        was taken (taken_s, the simulator's: it logs a frame when the host gets it), else t_s."""
        from foxglove.messages import CompressedImage

        stamp = self._stamp(t_s if taken_s is None else taken_s)
        self._log("/camera/image", t_s, CompressedImage(timestamp=stamp, frame_id="camera", data=jpeg, format="jpeg"))

    def true_pose(self, t_s: float, x_m: float, y_m: float, heading_deg: float) -> None:
        """The simulated rover's pose (thinned to TRUE_POSE_EVERY_S)."""
        if t_s + 1e-9 < self._next_true_s:
            return
        self._next_true_s = t_s + TRUE_POSE_EVERY_S
        from foxglove.messages import PoseInFrame

        self._log(
            "/sim/true_pose",
            t_s,
            PoseInFrame(timestamp=self._stamp(t_s), frame_id=ARENA_FRAME, pose=pose(x_m, y_m, heading_deg)),
        )
        self._drive(t_s, x_m, y_m)

    def event(self, t_s: float, text: str, source: str = "sim", level: str = "info") -> None:
        from foxglove.messages import Log, LogLevel

        lv = {"info": LogLevel.Info, "warning": LogLevel.Warning, "error": LogLevel.Error}[level]
        if level == "info" and any(w in text for w in ("failed", "CRASH", "fault")):
            lv = LogLevel.Error
        self._log("/events", t_s, Log(timestamp=self._stamp(t_s), level=lv, message=text, name=source))

    def close(self, summary: dict | None = None) -> None:
        """End the log: the file renamed into place (also after an interrupted run)."""
        if self._closed:
            return
        if self._driven:
            self._publish_driven(self.t_s)
        if self._radio is not None:
            self._publish_radio(self.t_s)
        self._closed = True
        if self.server is not None:
            self.server.stop()
            self.server = None
        if self.writer is not None:
            if summary:
                self.writer.write_metadata("rovernav.summary", {k: json.dumps(v) for k, v in summary.items()})
            self.writer.close()
            self.writer = None
            os.replace(self.partial, self.path)

    # ------------------------------------------------------------ helpers

    def _stamp(self, t_s: float):
        from foxglove.messages import Timestamp

        ns = self.t0_ns + max(0, round(t_s * 1e9))
        return Timestamp(ns // 1_000_000_000, ns % 1_000_000_000)

    def _status(self, t_s: float, m: mg.Status) -> None:
        from foxglove.messages import PoseInFrame

        if m.flags & mg.StatusFlag.MISSION_ACTIVE or m.x_mm or m.y_mm:
            self._log(
                "/rover/estimate",
                t_s,
                PoseInFrame(
                    timestamp=self._stamp(t_s),
                    frame_id=ARENA_FRAME,
                    pose=pose(m.x_mm / 1000, m.y_mm / 1000, m.heading_cdeg / 100),
                ),
            )
        # The state by name ("drive"), and by number in state_code (a Plot panel plots numbers).
        state = (
            mg.RoverState(m.state).name.lower() if m.state in mg.RoverState._value2member_map_ else f"unknown {m.state}"
        )
        self._log("/rover/status", t_s, to_json({"t_s": t_s, **m.to_dict(), "state": state, "state_code": m.state}))

    def _drive(self, t_s: float, x_m: float, y_m: float) -> None:
        if not self._driven or math.dist(self._driven[-1][:2], (x_m, y_m)) >= DRIVEN_PATH_STEP_M:
            self._driven.append((x_m, y_m, t_s))
        if t_s >= self._next_driven_s:
            self._next_driven_s = t_s + DRIVEN_PATH_EVERY_S
            self._publish_driven(t_s)

    def _publish_driven(self, t_s: float) -> None:
        from foxglove.messages import PosesInFrame

        self._log(
            "/rover/driven_path",
            t_s,
            PosesInFrame(
                timestamp=self._stamp(t_s), frame_id=ARENA_FRAME, poses=self._driven_poses.poses(self._driven)
            ),
        )

    def _arena(self, t_s: float) -> None:
        self._next_arena_s = t_s + LIVE_ARENA_EVERY_S
        self._log("/arena", t_s, arena_scene(self.scenario, self.truth, self._stamp(t_s)))


class RecordingTransport(Transport):
    """The transport it wraps, handing every byte it moves to a RunLog (the raw channels)."""

    def __init__(self, inner: Transport, runlog: RunLog):
        super().__init__(inner.name)
        self.inner = inner
        self.runlog = runlog

    def __getattr__(self, name: str):
        # Anything else (a serial port's baud rate) is the wrapped transport's.
        if name == "inner":
            raise AttributeError(name)
        return getattr(self.inner, name)

    def _write(self, data: bytes) -> None:
        self.inner.write(data)
        self.runlog.raw("host_to_rover", data)

    def _read(self, max_bytes: int, timeout_s: float | None) -> bytes:
        data = self.inner.read(max_bytes, timeout_s)
        self.runlog.raw("rover_to_host", data)
        return data

    def _close(self) -> None:
        self.inner.close()
