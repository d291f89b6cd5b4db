"""The mission: phases with deadlines, legs, and what the rover says, over any link.

The host is thin. It says HELLO and checks the schema, sends the rover its parameters, streams
camera fixes and heartbeats, has its strategy plan each leg and hand it to the rover, folds the
rover's sonar reports into the learned map, and, for an out-and-back mission, sends the rover
home on what it learned and repeats for the trips asked.

`Mission` never blocks and never reads a clock of its own: whoever runs it (the hardware loop
in `rovernav run`, the simulator in lockstep) calls `on_detection()` for each camera frame and
`tick(now_s)` often, with its own notion of time. Every phase has a deadline and a recovery
(see `Deadlines`): a mission ends by itself, reached or failed with the reason, and never
waits for ever.
"""
from __future__ import annotations

import dataclasses
import enum
import logging
import math
import os
from pathlib import Path
from typing import Callable

from ..errors import MissionFailed  # noqa: F401  (re-exported: the mission's failure as an exception)
from ..angles import heading_cdeg
from ..link import messages_gen as mg
from ..link.errors import LinkError, Nacked, SchemaMismatch
from ..link.link import host_hello
from ..link.path_upload import CHUNK_SPACING_S, Answer, PathUpload
from ..link.quality import LinkQuality
from ..link.requests import RequestTracker
from ..planning import NoPathError, OccupancyGrid, Unreachable, plan
from ..planning.turns import ahead_first, half_seen, turnable
from ..mapping import Echo, LearnedMap, SonarReading
from .legs import Deadlines, Leg, LegRecord, leg_goal, path_length_m
from .interface import Strategy
from .strategies import RovernavStrategy

log = logging.getLogger("rovernav.mission")

# Every exchange is made for a radio that loses frames (protocol/README.md, "Exchanges and
# their retry rules"): a request goes again after RESEND_S, and fails after MAX_TRIES attempts
# made while the rover is heard (an attempt while it is silent does not count: it is carrying
# on alone and answers once the radio is back). At 1 % of bytes lost a signed request and its
# answer get through together about half the time: 30 attempts fail together once in 10^7; 75
# (30 s) give a 5 % radio, where a PATH chunk and its ACK get through together 2 % of the time,
# a fair chance.
RESEND_S = 0.4        # an un-ACKed request goes again after this long
MAX_TRIES = 75        # ... this many times (30 s) while the rover is heard, then the mission fails
#: How far from a goal that an echo's arc covers the last tries may end their plan [m].
GOAL_SHIFT_M = 0.06
#: A path whose start lies this near the rover starts where it stands: its first turn is made
#: from the rover's heading, and is checked for room (rovernav.planning.turns.ahead_first) [m].
START_NEAR_M = 0.05
HELLO_EVERY_S = 0.25
SILENT_S = 1.0        # no frame from the rover for this long: the radio is down
CLOSE_S = 10.0        # an ended mission's STOP is re-sent until ACKed, for at most this long
LINK_LOG_S = 1.0          # the link's quality goes to the run log this often
HEARD_RECENTLY_S = 5.0    # a rover heard this recently is alive, if the radio is lossy
HELLO_ALIVE_FACTOR = 4    # no HELLO from a rover that is heard: the deadline is this many times longer
MAP_CHECK_S = 2.0     # the map changed and no SCAN_DONE came this long after: check the path anyway


# Frames handled in one tick at most: the rest wait for the next (at 57,600 baud about 100 frames
# arrive a second; a flood on a faster line must not starve the heartbeat and the deadlines).
MAX_FRAMES_PER_TICK = 256

class Phase(enum.Enum):
    HELLO = "hello"            # waiting for the rover's HELLO
    CONFIGURE = "configure"    # sending parameters
    LOCATE = "locate"          # waiting for the camera to see the rover
    LOAD = "load"              # a path is being sent
    RUN = "run"                # the rover follows the path
    DONE = "done"
    FAILED = "failed"


class Failure(enum.Enum):
    """Why a mission failed, as a kind a caller can act on (the message says it in words)."""

    NO_HELLO = "no_hello"              # the rover never said HELLO
    SCHEMA = "schema"                  # the rover was built from another protocol definition
    NOT_CONFIGURED = "not_configured"  # parameters not acknowledged in time
    NO_CAMERA = "no_camera"            # the camera does not see the rover
    NOT_LOADED = "not_loaded"          # a path and START not acknowledged in time
    REFUSED = "refused"                # the rover NACKed a command
    NOT_ANSWERED = "not_answered"      # a request unanswered after every try
    ROVER_FAULT = "rover_fault"        # the rover reported a fault (its gyro, ...)
    SILENT = "silent"                  # no frame from the rover for too long
    LEG_LATE = "leg_late"              # a leg not reached after its recoveries
    NO_PATH = "no_path"                # the planner's verdict: the goal cannot be reached
    FROM_OUTSIDE = "from_outside"      # ended by whoever runs the mission (a crash, an operator)


class Outcome(enum.Enum):
    RUNNING = "running"
    REACHED = "reached"        # every leg reached
    NO_PATH = "no_path"        # the planner says the goal cannot be reached on what is known
    FAILED = "failed"          # anything else: a refusal, a fault, silence, a deadline


@dataclasses.dataclass
class Detection:
    """A camera fix of the rover in arena coordinates (None fields: the rover was not seen)."""

    t_s: float
    x_m: float | None
    y_m: float | None
    heading_deg: float | None
    reason: str | None = None


class Recorder:
    """What a mission tells a run log (rovernav.runlog.RunLog), here doing nothing.

    Inputs, in the order they reach the mission: the ticks, the camera's detections, every frame
    it takes from the rover, and a failure imposed from outside; `rovernav replay` feeds these to
    a new Mission and compares its outputs: the frames it sends (and the events it reports)."""

    def host_input(self, kind: str, t_s: float, **data) -> None:
        pass

    def host_rx(self, t_s: float, frame) -> None:
        pass

    def host_tx(self, t_s: float, message, seq: int) -> None:
        pass

    def host_event(self, t_s: float, text: str) -> None:
        pass

    def host_path(self, t_s: float, path_id: int, path: list[tuple[float, float]]) -> None:
        pass

    def host_sonar(self, t_s: float, reading: SonarReading, changed: bool) -> None:
        pass

    def host_map(self, t_s: float, learned_map: LearnedMap) -> None:
        pass

    def host_link(self, t_s: float, quality: dict) -> None:
        """Frames through both ways (recent and whole-run) and frames sent again: once a second."""


class PlannedPath(list):
    """A path (waypoints [m]) that asks the rover to back out before its first turn on the spot
    (PATH back_out): the host's map has no room for its corners where it stands."""

    def __init__(self, points, back_out: bool = False) -> None:
        super().__init__(points)
        self.back_out = back_out


class Mission:
    """One mission over `link` (a rovernav.link.link.Link): `legs` legs alternating start -> target
    and target -> start (a reach mission is 1 leg; an out-and-back mission of N trips is 2N legs)."""

    def __init__(self, link, grid: OccupancyGrid, start_xy: tuple[float, float], target_xy: tuple[float, float],
                 legs: int = 1, rover_params: list | None = None, planner: str = "astar",
                 fix_sd_mm: int = 3, heartbeat_hz: float = 5.0, host_replan: bool = True,
                 on_event: Callable[[float, str], None] | None = None, map_file: str | Path | None = None,
                 state_file: str | Path | None = None, strategy: Strategy | None = None,
                 deadlines: Deadlines = Deadlines(), host_boot_id: int | None = None,
                 recorder: Recorder | None = None):
        self.link = link
        self.recorder = recorder or Recorder()
        self.map = LearnedMap(grid)
        self.start_xy = start_xy
        self.target_xy = target_xy
        self.legs_asked = legs
        self.strategy = strategy or RovernavStrategy()
        # The geometry the host plans with first, so that the rover's own detours keep the same
        # clearance; then the strategy's; then what the caller asks (which wins).
        self.rover_params = grid.config.rover_geometry() + self.strategy.rover_params() + list(rover_params or [])
        self.planner = planner
        self.fix_sd_mm = fix_sd_mm
        self.heartbeat_period_s = 1.0 / heartbeat_hz
        self.host_replan = host_replan
        self.deadlines = deadlines
        say = on_event or (lambda t, text: log.info("%.2f s %s", t, text))

        def on_event_recorded(t: float, text: str) -> None:
            self.recorder.host_event(t, text)
            say(t, text)
        self.on_event = on_event_recorded
        self.map_file = Path(map_file) if map_file else None   # kept up to date: a restarted host reloads it
        self.record = LegRecord(state_file)
        self.host_boot_id = int.from_bytes(os.urandom(4), "little") if host_boot_id is None else host_boot_id

        self.phase = Phase.HELLO
        self.outcome = Outcome.RUNNING
        self.error: str | None = None
        self.failure: Failure | None = None    # the kind of failure, with `error` in words
        self.cause: Exception | None = None   # the link error behind a failure, when there is one
        self.legs: list[Leg] = []
        self.path: list[tuple[float, float]] = []         # what the rover was last given
        self.path_rest: list[tuple[float, float]] = []    # the rest of a path longer than the rover holds
        # Path ids count up from a base drawn from this host's boot id: a restarted host's first
        # path must not carry the id of the path the rover holds from the host before it (the
        # rover takes a PATH chunk with the id and size of the one it holds as a repeat it has
        # already taken, ACKs it and waits for nothing more).
        self.path_id = (self.host_boot_id & 0xFF) << 8
        self.rover_boot_id: int | None = None
        self.last_status: mg.Status | None = None
        self.events: list[tuple[float, mg.Event]] = []
        self.nacks: list[mg.Nack] = []
        self.fixes_sent = 0
        self.replans = 0
        self.requests = RequestTracker(RESEND_S, MAX_TRIES)
        self.upload: PathUpload | None = None    # the path on its way to the rover
        self.sent: dict[str, int] = {}           # frames sent, by message kind
        self.frames_sent = 0
        self.quality = LinkQuality()             # frames through, both ways (link/quality.py)
        self.sent_again: dict[str, int] = {}     # ... of which re-sent for want of an answer
        self.hellos_again = 0                    # HELLOs said again because the rover did not know this host
        self._closed = False                     # the ended mission's STOP was ACKed (or given up on)
        self._done_at: float | None = None
        self._now = 0.0
        self._phase_since: float | None = None   # set by the first tick: the mission's clock starts there
        self._hello_at = -1e9
        self._heartbeat_at = -1e9
        self._last_detection: Detection | None = None
        self._last_frame_s: float | None = None
        self._start_sent_for: int | None = None    # path id the last START was sent for
        # A caller's hold on START (now_s -> True: not yet), the path loaded meanwhile: calibrate
        # rover keeps the rover still for its gyro's bias before its first run.
        self.hold_start: Callable[[float], bool] | None = None
        self._start_acked_for: int | None = None   # ... and acknowledged for
        self._accepted_path_id: int | None = None
        self._map_changed_at: float | None = None
        self._map_unsaved = False
        # The rover's sweeps as heard: the latest sweep's id and its echoes heard so far; the last
        # sweep heard whole (its SCAN_DONE and as many echoes as that counted) and planned with,
        # said in every HEARTBEAT (scan_heard): the rover trusts a path near its echoes only then.
        self._scan_latest: int | None = None
        self._scan_echoes_heard = 0
        self._scan_echoes_seen: set[tuple] = set()   # its echoes as said (each is said three times): a copy is dropped
        self._scan_done_for: int | None = None
        self.scan_heard = 0
        self.scans_heard_whole = 0
        self.scans_heard_part = 0
        self._resume_leg = False
        self._last_heard_s = 0.0
        self._heard_again_s = 0.0   # when the rover was last heard after a silence (a radio outage)
        self._heard_any = False     # any valid frame from the rover yet
        self._chunk_at = -1e9        # when the last PATH chunk went out
        self._link_logged_at = -1e9

    # ---------------------------------------------------------------- views

    @property
    def grid(self) -> OccupancyGrid:
        return self.map.grid

    @property
    def echoes(self) -> list[Echo]:
        return self.map.echoes

    def _param(self, param: mg.Param) -> int:
        """A rover parameter as this mission configures it (the protocol's default otherwise)."""
        return dict(self.rover_params).get(param, mg.PARAMS[param].default)

    @property
    def sonar_report_m(self) -> float:
        """The range within which the rover reports echoes: a reading without one is clear to it."""
        return self._param(mg.Param.SONAR_REPORT_MM) / 1000.0

    @property
    def done(self) -> bool:
        """The mission has ended, reached or failed (its STOP may still be on its way: `finished`)."""
        return self.phase in (Phase.DONE, Phase.FAILED)

    @property
    def finished(self) -> bool:
        """Ended, and the rover has acknowledged the STOP that ended it (or CLOSE_S has passed
        trying): whoever runs the mission ticks it until then."""
        return self.done and (self._closed or not self.requests)

    @property
    def current_leg(self) -> Leg:
        return self.legs[-1]

    @property
    def arrival_radius_m(self) -> float:
        """The rover's arrival radius (its ARRIVAL_RADIUS_MM parameter, as configured)."""
        return self._param(mg.Param.ARRIVAL_RADIUS_MM) / 1000.0

    # ---------------------------------------------------------------- inputs

    def on_detection(self, detection: Detection, now_s: float) -> None:
        """A camera frame was processed; send its fix if the rover was seen."""
        self.recorder.host_input("detection", now_s, taken_s=detection.t_s, x_m=detection.x_m, y_m=detection.y_m,
                                 heading_deg=detection.heading_deg, reason=detection.reason)
        self._last_frame_s = now_s
        if self.done:
            return
        if detection.x_m is None:
            self._last_detection = detection if self._last_detection is None else self._last_detection
            return
        self._last_detection = detection
        if self.phase is Phase.HELLO:
            return
        age_ms = max(0, min(65535, round((now_s - detection.t_s) * 1000)))
        self._send(mg.Fix(x_mm=_mm(detection.x_m), y_mm=_mm(detection.y_m),
                          heading_cdeg=heading_cdeg(detection.heading_deg),
                              age_ms=age_ms, sd_mm=self.fix_sd_mm, frame_seq=self.fixes_sent & 0xFFFF))
        self.fixes_sent += 1

    def tick(self, now_s: float) -> None:
        """Advance: read what the rover said, re-send what is unanswered, move the phases on."""
        self.recorder.host_input("tick", now_s)
        self._now = now_s
        if self._phase_since is None:
            self._phase_since = self._last_heard_s = now_s
            self.recorder.host_map(now_s, self.map)   # the map the mission starts from
        for _ in range(MAX_FRAMES_PER_TICK):   # a flood cannot hold one tick forever
            if self.finished:
                break
            frame = self.link.recv(timeout_s=0)
            if frame is None:
                break
            self.recorder.host_rx(now_s, frame)
            if self.done:
                self._on_answer(frame.message)   # only the STOP's ACK matters now
            else:
                self._handle(frame)
        if self.done:
            self._close(now_s)
            return
        if now_s - self._link_logged_at >= LINK_LOG_S:
            self._link_logged_at = now_s
            q = self.quality
            self.recorder.host_link(now_s, {
                "to_rover_pct": None if q.recent("to_rover") is None else round(100 * q.recent("to_rover"), 2),
                "to_host_pct": None if q.recent("to_host") is None else round(100 * q.recent("to_host"), 2),
                **self.link_summary()})
        if now_s - self._heartbeat_at >= self.heartbeat_period_s:
            self._heartbeat_at = now_s
            self._send(mg.Heartbeat(host_time_ms=int(now_s * 1000) & 0xFFFFFFFF, camera=self._camera_state(),
                                    scan_heard=self.scan_heard, path_id=self.path_id & 0xFFFF))
        if self.phase is not Phase.HELLO and now_s - self._last_heard_s > self.deadlines.silent_s:
            self._fail(f"no word from the rover for {self.deadlines.silent_s:.0f} s", Failure.SILENT)
            return
        self._resend(now_s)
        if self.done:
            return
        if self._map_changed_at is not None and now_s - self._map_changed_at > MAP_CHECK_S:
            self._save_map()
            self._map_changed()   # the SCAN_DONE event was lost
        self._advance(now_s)

    def _advance(self, now_s: float) -> None:
        """The phase machine: what each phase waits for, and its deadline."""
        d = self.deadlines
        in_phase_s = now_s - self._phase_since
        if self.phase is Phase.HELLO:
            # A rover that is heard (its STATUS gets through, its HELLO has not yet) is on a lossy
            # radio, not a dead one: it is given up to HELLO_ALIVE_FACTOR times the deadline.
            heard = self._heard_any and now_s - self._last_heard_s < HEARD_RECENTLY_S
            if in_phase_s > d.hello_s * (HELLO_ALIVE_FACTOR if heard else 1):
                self._fail(f"no HELLO from the rover within {in_phase_s:.0f} s"
                           + (" (other frames of its came through: the radio loses most frames)" if heard else ""),
                           Failure.NO_HELLO)
            elif now_s - self._hello_at >= HELLO_EVERY_S:
                self._hello_at = now_s
                self._send(host_hello(self.host_boot_id))
        elif self.phase is Phase.CONFIGURE:
            if not self.requests:
                self._set_phase(Phase.LOCATE)
            elif self._waited_s(now_s) > d.configure_s and not self._silent():
                self._fail(f"the rover did not take its parameters within {d.configure_s:.0f} s", Failure.NOT_CONFIGURED)
        if self.phase is Phase.LOCATE:
            if self._rover_seen():
                if self._resume_leg:
                    self._resume_leg = False
                    self._resume()
                else:
                    self._next_leg()
            elif in_phase_s > d.locate_s:
                self._fail(f"the camera has not seen the rover for {d.locate_s:.0f} s", Failure.NO_CAMERA)
        if self.phase is Phase.LOAD:
            if self.upload is not None and self.upload.complete and not self.requests:
                if self._start_sent_for != self.path_id:
                    if self.hold_start is None or not self.hold_start(now_s):
                        self._start_sent_for = self.path_id
                        self._request(mg.Start(path_id=self.path_id))
                elif self._start_acked_for == self.path_id:
                    self._set_phase(Phase.RUN)
            elif self._waited_s(now_s) > d.load_s and not self._silent():
                self._fail(f"the rover did not take path {self.path_id} within {d.load_s:.0f} s", Failure.NOT_LOADED)
        if self.phase is Phase.RUN and self.legs:
            self._watch_leg(now_s)

    def _watch_leg(self, now_s: float) -> None:
        """The leg's deadline, and an arrival that only the rover's STATUS shows (its ARRIVED event
        was lost): the recovery is to re-plan from where the rover is and send the leg again."""
        leg = self.current_leg
        if now_s <= leg.deadline_s:
            return
        if leg.recoveries >= self.deadlines.leg_recoveries:
            self._fail(f"leg {leg.index + 1} not reached after {now_s - leg.started_s:.0f} s "
                       f"and {leg.recoveries} re-sends", Failure.LEG_LATE)
            return
        leg.recoveries += 1
        self.on_event(now_s, f"leg {leg.index + 1} is late: re-planning from where the rover is "
                             f"(recovery {leg.recoveries} of {self.deadlines.leg_recoveries})")
        self._resume()

    # ---------------------------------------------------------------- what the rover says

    def _handle(self, frame) -> None:
        if self._silent():
            self._heard_again_s = self._now
        self._last_heard_s = self._now
        self._heard_any = True
        m = frame.message
        if isinstance(m, mg.Hello) and m.role == mg.Role.ROVER and m.boot_id != self.rover_boot_id:
            self.quality.restart()   # a rover that restarted numbers its frames from 0 again
        self.quality.on_frame(frame.seq, self._now)
        if isinstance(m, mg.Hello):
            self._on_hello(m)
        elif isinstance(m, (mg.Ack, mg.Nack)):
            self._on_answer(m)
        elif isinstance(m, mg.Status):
            self._on_status(m)
        elif isinstance(m, mg.Obstacle):
            self._on_obstacle(m)
        elif isinstance(m, mg.Event):
            self._on_event(m)

    def _on_hello(self, m: mg.Hello) -> None:
        if m.role != mg.Role.ROVER:
            return
        if m.schema_hash != mg.SCHEMA_HASH:
            self.cause = SchemaMismatch(mg.SCHEMA_HASH, m.schema_hash)
            self._fail(str(self.cause), Failure.SCHEMA)
            return
        if self.rover_boot_id is not None and m.boot_id != self.rover_boot_id and self.phase is not Phase.HELLO:
            # The rover restarted: it forgot its parameters and its path. Bring it back.
            self.on_event(self._now, f"rover restarted (boot id {self.rover_boot_id} -> {m.boot_id}); "
                                     "re-sending parameters and path")
            self.rover_boot_id = m.boot_id
            self.requests.clear()
            self.upload = None
            self._send(host_hello(self.host_boot_id))
            resume = self.phase in (Phase.LOAD, Phase.RUN) and bool(self.legs) and not self.current_leg.reached
            self._configure()
            self._resume_leg = resume   # once configured: the same leg again, from where the rover is
            return
        if self.phase is Phase.HELLO:
            self.rover_boot_id = m.boot_id
            if self._hello_at < 0:
                # The rover's HELLO came before ours went out (it booted while this host was
                # starting): it takes no START until it has checked our schema, so say HELLO now.
                self._hello_at = self._now
                self._send(host_hello(self.host_boot_id))
            self.on_event(self._now, f"rover HELLO: boot id {m.boot_id}, firmware "
                                     f"{m.firmware_version >> 8}.{m.firmware_version & 0xFF}, schema ok")
            self._configure()

    def _on_answer(self, m) -> None:
        if self.upload is not None and not self.done:
            answer = self.upload.answer(m)
            if answer is Answer.RESUME:
                self._send_chunks()   # from where the rover stopped, at once
                return
            if answer is Answer.REFUSED:
                self.nacks.append(m)
                self.cause = Nacked(mg.Path.NAME, m.reason, m.detail)
                self._fail(str(self.cause), Failure.REFUSED)
                return
            if answer is Answer.TAKEN:
                return
        pending = self.requests.answer(m)
        if pending is None:
            return
        message = pending.message
        if isinstance(m, mg.Nack):
            if isinstance(message, mg.Start) and message.path_id != self.path_id:
                return   # a START for a path since replaced: its answer no longer matters
            if m.reason == mg.NackReason.SCHEMA_MISMATCH or (m.reason == mg.NackReason.NO_FIX
                                                             and isinstance(message, mg.Start)):
                # The rover does not know this host (our HELLO was lost), or has not had a fix
                # yet (FIXes were lost): say HELLO again, and ask again; the attempts still count.
                if m.reason == mg.NackReason.SCHEMA_MISMATCH:
                    self._say_hello_again()
                self._ask_again(pending)
                return
            self.nacks.append(m)
            self.cause = Nacked(message.NAME, m.reason, m.detail)
            self._fail(str(self.cause), Failure.REFUSED)
        elif isinstance(message, mg.Start):
            self._start_acked_for = message.path_id
        elif isinstance(message, mg.Stop) and self.done:
            self._closed = True

    def _ask_again(self, pending) -> None:
        """A refused request goes again, with its attempt counted, once its resend time comes."""
        if self.requests.exhausted(pending):
            self._fail(f"the rover refused {pending.message.NAME.upper()} {pending.tries} times",
                       Failure.NOT_ANSWERED)
            return
        self.requests.again(pending)   # due RESEND_S after its last attempt (re-sent by _resend)

    def _say_hello_again(self) -> None:
        """The rover does not know this host (a NACK schema_mismatch, or STATUS without schema_ok):
        our HELLO was lost. Say it again (at most every HELLO_EVERY_S)."""
        if self._now - self._hello_at >= HELLO_EVERY_S:
            self._hello_at = self._now
            self.hellos_again += 1
            self._send(host_hello(self.host_boot_id))

    def _on_status(self, m: mg.Status) -> None:
        backed_out = (self.last_status is not None and self.last_status.state == mg.RoverState.BACK_OFF
                      and m.state != mg.RoverState.BACK_OFF)
        self.last_status = m
        if backed_out and self.host_replan and self._leg_open():
            # The rover backed out to make room for a turn (TURN_REFUSED) and heads for its next
            # waypoint from off its path, along a line no planner chose.
            self.strategy.backed_out(self)
        self.quality.on_status(m, self.frames_sent, self._now)
        if self.phase is not Phase.HELLO and not m.flags & mg.StatusFlag.SCHEMA_OK:
            self._say_hello_again()
        # A STATUS after START was acknowledged that says the rover has arrived on this path:
        # the ARRIVED event itself was lost on the radio.
        if (m.state == mg.RoverState.ARRIVED and m.path_id == self.path_id
                and self._start_acked_for == self.path_id and self._leg_open()):
            self._arrived()

    def _on_obstacle(self, m: mg.Obstacle) -> None:
        if m.scan_id != self._scan_latest:
            self._scan_latest, self._scan_echoes_heard, self._scan_echoes_seen = m.scan_id, 0, set()
        if m.range_mm:
            # The rover says each echo three times (its word is taken only on a sweep heard whole): once is enough.
            said = (m.bearing_cdeg, m.range_mm, m.x_mm, m.y_mm, m.heading_cdeg)
            if said in self._scan_echoes_seen:
                return
            self._scan_echoes_seen.add(said)
            self._scan_echoes_heard += 1
        reading = SonarReading(m.x_mm / 1000, m.y_mm / 1000, m.heading_cdeg / 100, m.bearing_cdeg / 100,
                               m.range_mm / 1000 if m.range_mm else None, self.sonar_report_m, m.sd_mm / 1000)
        changed = self.map.add(reading)
        self.recorder.host_sonar(self._now, reading, changed)
        self._map_unsaved = True
        if m.range_mm and self.legs:
            self.current_leg.obstacles_found += 1
        if changed:
            # The rover is stopped for its sweep: replan once when the sweep is done, not per reading.
            self._map_changed_at = self._now

    def _on_event(self, m: mg.Event) -> None:
        self.events.append((self._now, m))
        kind = mg.EventKind(m.kind) if m.kind in mg.EventKind._value2member_map_ else None
        if kind is mg.EventKind.ARRIVED:
            # Whatever the phase: a rover may arrive before the host has seen START's ACK (a leg
            # that was nearly done), and that arrival must not be lost.
            if self._start_sent_for == self.path_id and self._leg_open():
                self._arrived()
        elif kind is mg.EventKind.SCAN_DONE:
            self._save_map()   # once a sweep, not once a reading: the file grows with the map
            self.recorder.host_map(self._now, self.map)
            if self._map_changed_at is not None:
                self._map_changed()
            self._scan_done(m.arg)
        elif kind is mg.EventKind.PATH_ACCEPTED:
            self._accepted_path_id = m.arg
            if self.upload is not None and self.upload.path_id == m.arg:
                self.upload.mark_complete()   # its last ACKs may be lost: this says it all
        elif kind is mg.EventKind.FAULT:
            self._fail(f"rover fault: {mg.FaultCode(m.arg).name.lower() if m.arg in mg.FaultCode._value2member_map_ else m.arg}",
                       Failure.ROVER_FAULT)
        elif kind is not None and kind is not mg.EventKind.WAYPOINT_REACHED:
            self.on_event(self._now, f"rover: {kind.name.lower()} (arg {m.arg})")
            if kind is mg.EventKind.TURN_REFUSED and self._leg_open():
                # Twice in one spot, and planned paths turn there no more this leg (Leg.refused_twice).
                self.current_leg.turns_refused_at.append((m.x_mm / 1000, m.y_mm / 1000))

    def _leg_open(self) -> bool:
        return self.phase in (Phase.LOAD, Phase.RUN) and bool(self.legs) and not self.current_leg.reached

    def _arrived(self) -> None:
        if self.path_rest:   # the end of a part of a long path: the next part, from here
            rest = self.path_rest
            self.on_event(self._now, f"part of the path done: the next {len(rest)} of its waypoints")
            self.load_path([self.path[-1]] + rest)
            return
        if not self.strategy.on_arrived(self):
            return
        self._leg_done()

    def _save_map(self) -> None:
        if self.map_file is not None and self._map_unsaved:
            self.map.save(self.map_file)
            self._map_unsaved = False

    def _leg_done(self) -> None:
        self._save_map()
        leg = self.current_leg
        leg.finished_s, leg.reached = self._now, True
        self.on_event(self._now, f"leg {leg.index + 1} reached ({leg.goal[0]:.2f}, {leg.goal[1]:.2f}) m")
        self.record.save(len(self.legs))
        if len(self.legs) >= self.legs_asked:
            self._set_phase(Phase.DONE)
            self.outcome = Outcome.REACHED
            self._end_with_stop(mg.StopReason.MISSION_DONE)
        else:
            self._next_leg()

    def _scan_done(self, echoes: int) -> None:
        """A sweep's SCAN_DONE: the host's word that it heard the sweep whole, once its map holds every
        echo the sweep counted and the path was checked against them (_map_changed, just before).
        A host that does not replan gives its word too: it heard, and keeps its path."""
        if self._scan_latest is None or self._scan_latest == self._scan_done_for:
            return   # a copy (the rover says SCAN_DONE three times), or a sweep none of whose readings came
        self._scan_done_for = self._scan_latest
        if self._scan_echoes_heard == echoes:
            self.scans_heard_whole += 1
            self.scan_heard = self._scan_latest
        else:
            self.scans_heard_part += 1

    def _map_changed(self) -> None:
        self._map_changed_at = None
        if self.host_replan and self._leg_open():
            self.strategy.map_changed(self)

    # ---------------------------------------------------------------- doing things

    def _set_phase(self, phase: Phase) -> None:
        if phase is not self.phase:
            self.phase = phase
            self._phase_since = self._now

    def _configure(self) -> None:
        self._set_phase(Phase.CONFIGURE)
        for param, value in self.rover_params:
            self._request(mg.Config(param=int(param), value=int(value)))

    def _next_leg(self) -> None:
        index = len(self.legs)
        goal = leg_goal(self.start_xy, self.target_xy, index)
        leg = Leg(index=index, goal=goal, started_s=self._now)
        self.legs.append(leg)
        here = self.rover_xy()
        if math.dist(here, goal) <= self.arrival_radius_m:
            # Already there: a leg that is done at once is done (the rover would not move).
            self.on_event(self._now, f"leg {index + 1}: the rover is already within "
                                     f"{self.arrival_radius_m * 1000:.0f} mm of ({goal[0]:.2f}, {goal[1]:.2f}) m")
            self._leg_done()
            return
        path = self.strategy.leg_path(self, here, goal)
        if path is None:
            return
        leg.planned_length_m = path_length_m(path)
        leg.deadline_s = self._now + self.deadlines.leg_s(leg.planned_length_m)
        self.on_event(self._now, f"leg {index + 1}{self.strategy.note}: {len(path)} waypoints, "
                                 f"{leg.planned_length_m:.2f} m to ({goal[0]:.2f}, {goal[1]:.2f}) m")
        self.strategy.start_leg(self, path)

    def _resume(self) -> None:
        """The current leg again, from where the rover is (after a rover restart or a late leg)."""
        leg = self.current_leg
        path = self.strategy.leg_path(self, self.rover_xy(), leg.goal)
        if path is None:
            return
        leg.deadline_s = self._now + self.deadlines.leg_s(path_length_m(path))
        self.strategy.start_leg(self, path)

    def load_path(self, path: list[tuple[float, float]]) -> None:
        """Send `path` under a new id; START follows once the rover has it whole.

        The rover holds MAX_WAYPOINTS: a longer path goes in parts, the first MAX_WAYPOINTS now and
        the rest, from the last of them, when the rover says it has arrived there (`_arrived`)."""
        back_out = int(getattr(path, "back_out", False))
        path, self.path_rest = list(path[:mg.MAX_WAYPOINTS]), list(path[mg.MAX_WAYPOINTS:])
        self.path = path
        self.path_id = (self.path_id + 1) & 0xFFFF
        self.recorder.host_path(self._now, self.path_id, path)
        self._accepted_path_id = None
        self._set_phase(Phase.LOAD)
        # What was on its way for an earlier path no longer matters: its chunks, and its START
        # (which, arriving late, would restart a leg the rover has finished).
        for pending in self.requests:
            if isinstance(pending.message, (mg.Path, mg.Start)):
                self.requests.drop(pending)
        self.upload = PathUpload(self.path_id, [(_mm(x), _mm(y)) for x, y in path], RESEND_S, back_out)
        self._send_chunks()

    def _send_chunks(self, count: bool = True) -> None:
        """The upload's next due chunk, at most one every CHUNK_SPACING_S (path_upload.py)."""
        if self._now - self._chunk_at < CHUNK_SPACING_S:
            return
        for message in self.upload.due(self._now)[:1]:
            self._chunk_at = self._now
            self.upload.sent(message, self._send(message, again=self.upload.frames_sent > 0), self._now, count=count)

    def replanned(self, path: list[tuple[float, float]], what: str,
                  why: str = "the sonar found the path blocked") -> None:
        """A strategy replanned the current leg (after the map changed, or `why`)."""
        self.replans += 1
        leg = self.current_leg
        leg.replans += 1
        leg.deadline_s = max(leg.deadline_s, self._now + self.deadlines.leg_s(path_length_m(path)))
        self.on_event(self._now, f"{why}: replanned ({what}, {path_length_m(path):.2f} m)")

    def plan_from(self, start: tuple[float, float], goal: tuple[float, float], verdict: bool = True
                  ) -> list[tuple[float, float]] | None:
        """A* from `start` to `goal`, simplified; None when there is none (the mission has then
        ended with the no-path verdict and the planner's reason, unless `verdict` is False: a
        check that may keep the path the rover has).

        Before that verdict: from the nearest free cell when the rover stands inside an inflated
        margin (close to what it has just found), and, round what only the sonar has seen, with
        the robot radius alone (the log-odds map already places an echo anywhere across its
        cone, so the sonar's placement margin counts it twice). Each on the careful map first, then
        on the open map, whose silence also clears the cells the cone's edge only cuts
        (rovernav.mapping.learned_map): careful, open, careful with the radius alone, open with
        the radius alone. A target is unreachable only
        when the obstacles enclose it even then.
        """
        reason = None
        lenient = self.map.lenient_grid()
        opened: list = []
        # The turn at the start counts from the rover's heading when the path starts where it stands.
        heading = self.rover_heading_deg() if math.dist(start, self.rover_xy()) <= START_NEAR_M else None
        cfg = self.grid.config
        echoes = self.echoes

        def grids():
            # The careful map, then the open one (built only when the careful map found no way),
            # each with the full margin before either with the radius alone.
            yield self.grid
            opened.extend(self.map.open_grids())
            yield opened[0] if opened else None
            yield lenient
            yield opened[1] if len(opened) > 1 else None

        # A goal the known obstacles leave free but an echo's arc covers (the home the rover left,
        # beside a box whose corner echoed at the cone's edge) is reached from the nearest free
        # cell within GOAL_SHIFT_M, in the last tries only: too short a way to pass any wall.
        goal_known_free = self.map.known_grid.is_free(*goal)
        for grid in grids():
            if grid is None:
                continue
            last_tries = grid is lenient or (len(opened) > 1 and grid is opened[1])
            shifted = self._nearest_free(goal, grid, GOAL_SHIFT_M) if last_tries and goal_known_free else None
            for origin in (start, self._nearest_free(start, grid)):
                if origin is None:
                    continue
                for end in (goal, shifted):
                    if end is None:
                        continue
                    try:
                        result = plan(grid, origin, end, planner=self.planner)
                    except NoPathError as exc:
                        # The most telling reason: that no route joins them, over a blocked start.
                        if reason is None or isinstance(exc, Unreachable):
                            reason = exc
                        continue
                    # Where a bend asks for a turn the body's corners cannot make, the bend moves; a
                    # spot where the rover refused a turn twice in this leg has no room either.
                    refused = self.current_leg.refused_twice() if self.legs else []
                    hidden = half_seen(grid, echoes, cfg.sonar_offset_m, cfg.sonar_cone_deg)
                    waypoints, moved, left = turnable(grid, result.waypoints, refused, hidden)
                    if grid is lenient:
                        self.on_event(self._now, "planned with the robot radius alone round what only the sonar has seen")
                    elif grid is not self.grid:
                        self.on_event(self._now, "planned on the open map (silence clears the cone's edges too)")
                    if end is not goal:
                        self.on_event(self._now, f"the goal lies within an echo's arc: planned to "
                                                 f"{math.dist(end, goal) * 100:.0f} cm from it, then straight on")
                    if moved or left:
                        self.on_event(self._now, f"turns: moved {moved} waypoint{'s' if moved != 1 else ''} "
                                                 f"where the body can turn" + (f", {left} without room near" if left else ""))
                    path = [tuple(p) for p in waypoints] + ([] if end is goal else [tuple(goal)])
                    path = path if origin is start else [start] + path
                    if heading is not None:
                        # The first turn, from the heading the rover has where it stands.
                        path, ahead = ahead_first(grid, path, heading, hidden)
                        if ahead > 0:
                            self.on_event(self._now, "no room to turn where the rover stands: "
                                                     "it drives straight on to turn first")
                        elif ahead < 0:
                            # Its own memory may have let go of what the map holds: the path
                            # asks it to back out the way it came before it turns (PATH back_out).
                            path = PlannedPath(path, back_out=True)
                            self.on_event(self._now, "no room to turn where the rover stands, none "
                                                     "straight ahead: it backs out first")
                    return path
        if verdict:
            self._fail(f"no path to ({goal[0]:.2f}, {goal[1]:.2f}) m: {reason}", Failure.NO_PATH)
        return None

    def _nearest_free(self, xy: tuple[float, float], grid: OccupancyGrid, max_m: float = 0.3
                      ) -> tuple[float, float] | None:
        if grid.is_free(*xy):
            return None   # the start itself is free: nothing nearer to try
        step = grid.resolution_m
        for ring in range(1, int(max_m / step) + 1):
            r = ring * step
            for k in range(max(8, ring * 8)):
                a = 2 * math.pi * k / max(8, ring * 8)
                p = (xy[0] + r * math.cos(a), xy[1] + r * math.sin(a))
                if grid.contains(*p) and grid.is_free(*p):
                    return p
        return None

    def remaining_path(self) -> list[tuple[float, float]]:
        """From where the rover is through the waypoints it has still to reach."""
        if not self.path:
            return []
        wp = self.last_status.waypoint_index if self.last_status else 0
        return [self.rover_xy()] + self.path[min(wp, len(self.path) - 1):] + self.path_rest

    def _send(self, message, again: bool = False) -> int:
        seq = self.link.send(message)
        self.recorder.host_tx(self._now, message, seq)
        self.sent[message.NAME] = self.sent.get(message.NAME, 0) + 1
        self.frames_sent += 1
        if again:
            self.sent_again[message.NAME] = self.sent_again.get(message.NAME, 0) + 1
        return seq

    def _request(self, message) -> None:
        self.requests.sent(message, self._send(message), self._now)

    def _waited_s(self, now_s: float) -> float:
        """How long the rover has had to answer in this phase: since the phase began, or since it
        was heard again after a silence (it answers what was re-sent meanwhile once the radio is
        back, a signed frame a step: not in the same instant as its first STATUS)."""
        return now_s - max(self._phase_since, self._heard_again_s)

    def _silent(self) -> bool:
        return self._now - self._last_heard_s > SILENT_S

    def _resend(self, now_s: float) -> None:
        # While the rover says nothing at all (no STATUS either: the radio is down), a request is
        # re-sent but its tries are not counted: the rover is carrying on alone, and will answer
        # when the radio is back. Only a long silence ends the mission (see tick).
        silent = self._silent()
        for pending in self.requests.due(now_s):
            if self.requests.exhausted(pending) and not silent:
                self._fail(f"the rover did not answer {pending.message.NAME.upper()} after {pending.tries} tries",
                           Failure.NOT_ANSWERED)
                return
            self.requests.resent(pending, self._send(pending.message, again=True), now_s, count=not silent)
        if self.upload is not None and not self.upload.complete:
            if self.upload.tries() >= MAX_TRIES and not silent:
                self._fail(f"the rover did not take path {self.upload.path_id} after {self.upload.tries()} tries "
                           f"of a chunk ({self.upload.taken} of {self.upload.chunks} chunks taken)",
                           Failure.NOT_ANSWERED)
                return
            self._send_chunks(count=not silent)

    def _fail(self, why: str, failure: Failure) -> None:
        if self.phase is Phase.FAILED:
            return
        self._save_map()
        self.error = why
        self.failure = failure
        self.outcome = Outcome.NO_PATH if failure is Failure.NO_PATH else Outcome.FAILED
        self._set_phase(Phase.FAILED)
        self.on_event(self._now, f"mission failed: {why}")
        try:
            self._end_with_stop(mg.StopReason.HOST_SHUTDOWN)
        except LinkError:
            self._closed = True   # the link itself is what failed: nothing more to tell the rover

    def _end_with_stop(self, reason: int) -> None:
        """The mission has ended: STOP, re-sent until the rover ACKs it (see `_close`); nothing
        else is asked of the rover any more."""
        self.requests.clear()
        self.upload = None
        self._done_at = self._now
        self._request(mg.Stop(reason=reason))

    def _close(self, now_s: float) -> None:
        """An ended mission: the STOP again while unanswered, for at most CLOSE_S. A rover that
        never hears it drives on by dead reckoning and stops safely (HOLD) once that has gone as far
        as its estimate can vouch for (its failsafe)."""
        if self.finished:
            return
        if now_s - (self._done_at if self._done_at is not None else now_s) > CLOSE_S:
            self._closed = True
            self.on_event(now_s, f"the rover did not acknowledge STOP within {CLOSE_S:.0f} s")
            return
        for pending in self.requests.due(now_s):
            self.requests.resent(pending, self._send(pending.message, again=True), now_s)

    def fail(self, why: str) -> None:
        """End the mission from outside (an operator, or the simulator's time limit)."""
        self.recorder.host_input("fail", self._now, why=why)
        self._fail(why, Failure.FROM_OUTSIDE)

    def status_line(self) -> str:
        """One line on how the mission goes: phase, the rover's state and leg, the link both ways."""
        st = self.last_status
        rover = "-"
        if st is not None:
            state = mg.RoverState(st.state).name.lower() if st.state in mg.RoverState._value2member_map_ else st.state
            rover = f"{state} wp {st.waypoint_index} at ({st.x_mm / 1000:.2f}, {st.y_mm / 1000:.2f}) m"
        legs = f"leg {len(self.legs)}/{self.legs_asked}" if self.legs else f"0/{self.legs_asked} legs"
        again = sum(self.sent_again.values())
        return f"{self.phase.value}, {legs}, rover {rover}; {self.quality.line()}; {again} frames sent again"

    def link_summary(self) -> dict:
        """What the link did, for report.json and the run log: frames through both ways, and the
        frames the host sent and sent again, per message kind."""
        return {**self.quality.summary(), "host_sent": dict(sorted(self.sent.items())),
                "host_sent_again": dict(sorted(self.sent_again.items())), "hellos_again": self.hellos_again,
                "sweeps_heard": {"whole": self.scans_heard_whole, "part": self.scans_heard_part}}

    @property
    def heard_any(self) -> bool:
        """Whether any valid frame from the rover came (its HELLO or not)."""
        return self._heard_any

    def _rover_seen(self) -> bool:
        d = self._last_detection
        return d is not None and d.x_m is not None and self._now - d.t_s < 1.0

    def rover_heading_deg(self) -> float | None:
        """The rover's heading by its own estimate (0 up the arena, clockwise) [deg]; None before
        its first STATUS. Its turns are made from this heading, not from the camera's."""
        if self.last_status is None:
            return None
        return self.last_status.heading_cdeg / 100.0

    def rover_xy(self) -> tuple[float, float]:
        """Where the rover is: the camera's last fix (if recent), else its own estimate, else the start."""
        d = self._last_detection
        if d is not None and d.x_m is not None and self._now - d.t_s < 0.5:
            return (d.x_m, d.y_m)
        if self.last_status is not None:
            return (self.last_status.x_mm / 1000, self.last_status.y_mm / 1000)
        return self.start_xy

    def _camera_state(self) -> int:
        if self._last_frame_s is None or self._now - self._last_frame_s > 0.5:
            return mg.CameraState.NO_FRAMES
        d = self._last_detection
        if d is None or d.x_m is None or self._now - d.t_s > 0.5:
            return mg.CameraState.NO_ROVER
        return mg.CameraState.OK

    # ---------------------------------------------------------------- persistence

    def restore_state(self) -> int:
        """A restarted host: take up the mission at the leg the last host had reached (from
        state_file; the rover's HELLO and STATUS then say the rest). Returns the legs done."""
        done = min(self.record.load(), self.legs_asked)
        for i in range(done):
            self.legs.append(Leg(index=i, goal=leg_goal(self.start_xy, self.target_xy, i), started_s=self._now,
                                 finished_s=self._now, reached=True))
        return done

    def save_map(self, path: str | Path) -> None:
        """Write what the sonar found (see rovernav.mapping.learned_map for the format)."""
        self.map.save(path)

    def load_map(self, path: str | Path) -> int:
        """Fold a saved map's echoes into the grid; returns how many. MapFileError if it is not a map."""
        return self.map.load(path)


def _mm(v_m: float) -> int:
    return max(-32768, min(32767, round(v_m * 1000)))
