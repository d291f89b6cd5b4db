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

Here: the phase machine, the ticks and the camera's fixes, and the means of acting (requests,
paths, STOP). Apart: what the rover says (rover_frames.py, a base class of Mission), the legs
started, resumed, watched and replanned (leg_control.py, another base), a leg's path
(leg_plan.py), the phases and timings (phases.py), the run log's interface (recorder.py), and
what a strategy may see of the mission (interface.py).
"""

from __future__ import annotations

import logging
import math
import os
from collections.abc import Callable
from pathlib import Path

from ..angles import heading_cdeg
from ..errors import MissionFailed  # noqa: F401  (re-exported: the mission's failure as an exception)
from ..link import messages_gen as mg
from ..link.errors import LinkError
from ..link.link import host_hello
from ..link.path_upload import CHUNK_SPACING_S, PathUpload
from ..link.quality import LinkQuality
from ..link.requests import RequestTracker
from ..mapping import Echo, LearnedMap
from ..planning import OccupancyGrid
from .fleet_control import FleetControl
from .interface import Strategy
from .leg_control import LegControl
from .legs import Deadlines, Leg, LegRecord
from .phases import (
    CLOSE_S,
    HEARD_RECENTLY_S,
    HELLO_ALIVE_FACTOR,
    HELLO_EVERY_S,
    LINK_LOG_S,
    MAP_CHECK_S,
    MAX_FRAMES_PER_TICK,
    MAX_TRIES,
    RESEND_S,
    SILENT_S,
    Detection,
    Failure,
    Outcome,
    Phase,
)
from .recorder import Recorder
from .rover_frames import RoverFrames
from .strategies import RovernavStrategy

log = logging.getLogger("rovernav.mission")

FIX_SLACK_S = 0.005  # [mission] fix_hz: a frame this early for its FIX's turn is on time (see Mission)


class Mission(RoverFrames, LegControl, FleetControl):
    """One mission over `link` (a rovernav.link.link.Link): `legs` legs alternating start -> target
    and target -> start (a reach mission is 1 leg; an out-and-back mission of N trips is 2N legs)."""

    def __init__(
        self,
        link,
        grid: OccupancyGrid,
        start_xy: tuple[float, float],
        target_xy: tuple[float, float],
        legs: int = 1,
        rover_params: list | None = None,
        planner: str = "astar",
        fix_sd_mm: int = 3,
        heartbeat_hz: float = 5.0,
        fix_hz: float = 0.0,
        host_replan: bool = True,
        on_event: Callable[[float, str], None] | None = None,
        map_file: str | Path | None = None,
        state_file: str | Path | None = None,
        strategy: Strategy | None = None,
        deadlines: Deadlines = Deadlines(),
        host_boot_id: int | None = None,
        recorder: Recorder | None = None,
    ):
        self.link = link
        self.recorder = recorder or Recorder()
        self.map = LearnedMap(grid)
        self.start_xy = start_xy
        self.target_xy = target_xy
        self.legs_asked = legs
        self.legs_to_drive = legs  # fewer, when a fleet's rover gives up its trips (FleetControl.give_up)
        self.strategy = strategy or RovernavStrategy()
        # The geometry the host plans with first, so that the rover's own detours keep the same
        # clearance; then the strategy's; then what the caller asks (which wins).
        self.rover_params = grid.config.rover_geometry() + self.strategy.rover_params() + list(rover_params or [])
        self.planner = planner
        self.fix_sd_mm = fix_sd_mm
        self.heartbeat_period_s = 1.0 / heartbeat_hz
        # At most fix_hz FIXes a second (0: every frame that sees the rover). A frame that comes within
        # FIX_SLACK_S of its turn counts as on time: frames reach the host on the loop's ticks, and
        # without it 10 Hz at 30 frames a second would alias down to 7.5.
        self.fix_period_s = 1.0 / fix_hz if fix_hz > 0 else 0.0
        self._last_fix_s = -math.inf
        self.host_replan = host_replan
        self.deadlines = deadlines
        say = on_event or (lambda t, text: log.info("%.2f s %s", t, text))

        def on_event_recorded(t: float, text: str) -> None:
            self.recorder.host_event(t, text)
            say(t, text)

        self.on_event = on_event_recorded
        self.map_file = Path(map_file) if map_file else None  # kept up to date: a restarted host reloads it
        self.record = LegRecord(state_file)
        self.host_boot_id = int.from_bytes(os.urandom(4), "little") if host_boot_id is None else host_boot_id

        self.phase = Phase.HELLO
        self.outcome = Outcome.RUNNING
        self.error: str | None = None
        self.failure: Failure | None = None  # the kind of failure, with `error` in words
        self.cause: Exception | None = None  # the link error behind a failure, when there is one
        self.legs: list[Leg] = []
        self.path: list[tuple[float, float]] = []  # what the rover was last given
        self.path_rest: list[tuple[float, float]] = []  # the rest of a path longer than the rover holds
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
        self.upload: PathUpload | None = None  # the path on its way to the rover
        self.sent: dict[str, int] = {}  # frames sent, by message kind
        self.frames_sent = 0
        self.quality = LinkQuality()  # frames through, both ways (link/quality.py)
        self.sent_again: dict[str, int] = {}  # ... of which re-sent for want of an answer
        self.hellos_again = 0  # HELLOs said again because the rover did not know this host
        self._closed = False  # the ended mission's STOP was ACKed (or given up on)
        self._done_at: float | None = None
        self._now = 0.0
        self._phase_since: float | None = None  # set by the first tick: the mission's clock starts there
        self._hello_at = -1e9
        self._heartbeat_at = -1e9
        self._last_detection: Detection | None = None
        self._last_frame_s: float | None = None
        self._start_sent_for: int | None = None  # path id the last START was sent for
        # A caller's hold on START (now_s -> True: not yet), the path loaded meanwhile: calibrate
        # rover keeps the rover still for its gyro's bias before its first run.
        self.hold_start: Callable[[float], bool] | None = None
        self._start_acked_for: int | None = None  # ... and acknowledged for
        self._accepted_path_id: int | None = None
        self._map_changed_at: float | None = None
        self._map_unsaved = False
        # The rover's sweeps as heard: the latest sweep's id and its echoes heard so far; the last
        # sweep heard whole (its SCAN_DONE and as many echoes as that counted) and planned with,
        # said in every HEARTBEAT (scan_heard): the rover trusts a path near its echoes only then.
        self._scan_latest: int | None = None
        self._scan_echoes_heard = 0
        self._scan_echoes_seen: set[tuple] = set()  # its echoes as said (each is said three times): a copy is dropped
        self._scan_done_for: int | None = None
        # The sweeps from one spot (a rover that sweeps again where it stands): what each bearing
        # echoed in them, and what this sweep has said clear (rover_frames._scan_done).
        self._spot: tuple[int, int, int] | None = None
        self._spot_echoes: set[int] = set()
        self._scan_bearings: set[int] = set()
        self._scan_clear: set[int] = set()
        self.scan_heard = 0
        self.scans_heard_whole = 0
        self.scans_heard_part = 0
        self._resume_leg = False
        self._last_heard_s = 0.0
        self._heard_again_s = 0.0  # when the rover was last heard after a silence (a radio outage)
        self._heard_any = False  # any valid frame from the rover yet
        self._chunk_at = -1e9  # when the last PATH chunk went out
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
        self.recorder.host_input(
            "detection",
            now_s,
            taken_s=detection.t_s,
            x_m=detection.x_m,
            y_m=detection.y_m,
            heading_deg=detection.heading_deg,
            reason=detection.reason,
        )
        self._last_frame_s = now_s
        if self.done:
            return
        if detection.x_m is None:
            self._last_detection = detection if self._last_detection is None else self._last_detection
            return
        self._last_detection = detection
        if self.phase is Phase.HELLO or self.slot_fixes:  # a fleet's FIX waits for its slot (slot_frame)
            return
        if now_s - self._last_fix_s < self.fix_period_s - FIX_SLACK_S:
            return
        self._last_fix_s = now_s
        age_ms = max(0, min(65535, round((now_s - detection.t_s) * 1000)))
        self._send(
            mg.Fix(
                x_mm=_mm(detection.x_m),
                y_mm=_mm(detection.y_m),
                heading_cdeg=heading_cdeg(detection.heading_deg),
                age_ms=age_ms,
                sd_mm=self.fix_sd_mm,
                frame_seq=self.fixes_sent & 0xFFFF,
            )
        )
        self.fixes_sent += 1

    def tick(self, now_s: float) -> None:
        """Advance: read what the rover said, re-send what is unanswered, move the phases on."""
        self.recorder.host_input("tick", now_s)
        self._now = now_s
        if self._phase_since is None:
            self._phase_since = self._last_heard_s = now_s
            self.recorder.host_map(now_s, self.map)  # the map the mission starts from
        for _ in range(MAX_FRAMES_PER_TICK):  # a flood cannot hold one tick forever
            if self.finished:
                break
            frame = self.link.recv(timeout_s=0)
            if frame is None:
                break
            self.recorder.host_rx(now_s, frame)
            if self.done:
                self._on_answer(frame.message)  # only the STOP's ACK matters now
            else:
                self._handle(frame)
        if self.done:
            self._close(now_s)
            return
        if now_s - self._link_logged_at >= LINK_LOG_S:
            self._link_logged_at = now_s
            q = self.quality
            self.recorder.host_link(
                now_s,
                {
                    "to_rover_pct": None if q.recent("to_rover") is None else round(100 * q.recent("to_rover"), 2),
                    "to_host_pct": None if q.recent("to_host") is None else round(100 * q.recent("to_host"), 2),
                    **self.link_summary(),
                },
            )
        # (A fleet's HEARTBEAT is its rover's poll when due: fleet_control.py's slot_frame.)
        if not self.slot_fixes and now_s - self._heartbeat_at >= self.heartbeat_period_s:
            self._send_heartbeat(now_s)
        if self.phase is not Phase.HELLO and now_s - self._last_heard_s > self.deadlines.silent_s:
            self._fail(f"no word from the rover for {self.deadlines.silent_s:.0f} s", Failure.SILENT)
            return
        self._resend(now_s)
        if self.done:
            return
        if self._map_changed_at is not None and now_s - self._map_changed_at > MAP_CHECK_S:
            self._save_map()
            self._map_changed()  # the SCAN_DONE event was lost
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
                self._fail(
                    f"no HELLO from the rover within {in_phase_s:.0f} s"
                    + (" (other frames of its came through: the radio loses most frames)" if heard else ""),
                    Failure.NO_HELLO,
                )
            elif now_s - self._hello_at >= HELLO_EVERY_S:
                self._hello_at = now_s
                self._send(host_hello(self.host_boot_id))
        elif self.phase is Phase.CONFIGURE:
            if not self.requests:
                self._set_phase(Phase.LOCATE)
            elif self._waited_s(now_s) > d.configure_s and not self._silent():
                self._fail(
                    f"the rover did not take its parameters within {d.configure_s:.0f} s", Failure.NOT_CONFIGURED
                )
        if self.phase is Phase.LOCATE:
            if self._rover_seen():
                if self._resume_leg:
                    self._resume_leg = False
                    self._resume()
                else:
                    self._next_leg()
            elif in_phase_s > d.locate_s:
                self._fail(f"the camera has not seen the rover for {d.locate_s:.0f} s", Failure.NO_CAMERA)
        if self.held:  # stopped for another rover (fleet_control.py): its leg waits
            return
        if self.phase is Phase.LOAD:
            if self.upload is not None and self.upload.complete and not self.requests:
                if self._start_sent_for != self.path_id:
                    # (A CONFIG a path over seen ground waits for goes first: START follows its ACK.)
                    if not self.sweep_before_start() and (self.hold_start is None or not self.hold_start(now_s)):
                        self._start_sent_for = self.path_id
                        self._request(mg.Start(path_id=self.path_id, resume=self.start_resumes()))
                elif self._start_acked_for == self.path_id:
                    self._set_phase(Phase.RUN)
            elif self._waited_s(now_s) > d.load_s and not self._silent():
                self._fail(f"the rover did not take path {self.path_id} within {d.load_s:.0f} s", Failure.NOT_LOADED)
        if self.phase is Phase.RUN and self.legs:
            self._watch_leg(now_s)

    # ---------------------------------------------------------------- doing things

    def _set_phase(self, phase: Phase) -> None:
        if phase is not self.phase:
            self.phase = phase
            self._phase_since = self._now

    def _configure(self) -> None:
        self._set_phase(Phase.CONFIGURE)
        for param, value in self.rover_params:
            self._request(mg.Config(param=int(param), value=int(value)))
        self._sweep_mm_said = None
        if self.sweep_seen_ground and mg.Param.SWEEP_INTERVAL_MM not in dict(self.rover_params):
            # Said whatever the configuration: a rover keeps its parameters from one host to the
            # next, and an earlier fleet host may have left it sweeping never (sweep_for_path).
            self._request(mg.Config(param=int(mg.Param.SWEEP_INTERVAL_MM), value=self.sweep_usual_mm()))

    def load_path(self, path: list[tuple[float, float]]) -> None:
        """Send `path` under a new id; START follows once the rover has it whole.

        The rover holds MAX_WAYPOINTS: a longer path goes in parts, the first MAX_WAYPOINTS now and
        the rest, from the last of them, when the rover says it has arrived there (`_arrived`)."""
        back_out = int(getattr(path, "back_out", False))
        self._back_out_path_id = None  # (set below when this path asks the rover to back out)
        whole = list(path)
        path, self.path_rest = list(path[: mg.MAX_WAYPOINTS]), list(path[mg.MAX_WAYPOINTS :])
        self.path = path
        self.path_id = (self.path_id + 1) & 0xFFFF
        if back_out:
            self._back_out_path_id = self.path_id  # its TURN_REFUSED is the back-out asked for
        self.recorder.host_path(self._now, self.path_id, path)
        self._accepted_path_id = None
        self._set_phase(Phase.LOAD)
        # What was on its way for an earlier path no longer matters: its chunks, and its START
        # (which, arriving late, would restart a leg the rover has finished).
        for pending in self.requests:
            if isinstance(pending.message, (mg.Path, mg.Start)):
                self.requests.drop(pending)
        self.sweep_for_path(whole)
        self.upload = PathUpload(self.path_id, [(_mm(x), _mm(y)) for x, y in path], RESEND_S, back_out)
        self._send_chunks()

    def _send_chunks(self, count: bool = True) -> None:
        """The upload's next due chunk, at most one every CHUNK_SPACING_S (path_upload.py)."""
        if self._now - self._chunk_at < CHUNK_SPACING_S:
            return
        for message in self.upload.due(self._now)[:1]:
            self._chunk_at = self._now
            self.upload.sent(message, self._send(message, again=self.upload.frames_sent > 0), self._now, count=count)

    def _send_heartbeat(self, now_s: float) -> None:
        """A HEARTBEAT: the host's time, the camera, the sweep heard whole and the path."""
        self._heartbeat_at = now_s
        self._send(
            mg.Heartbeat(
                host_time_ms=int(now_s * 1000) & 0xFFFFFFFF,
                camera=self._camera_state(),
                scan_heard=self.scan_heard,
                path_id=self.path_id & 0xFFFF,
            )
        )

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
                self._fail(
                    f"the rover did not answer {pending.message.NAME.upper()} after {pending.tries} tries",
                    Failure.NOT_ANSWERED,
                )
                return
            self.requests.resent(pending, self._send(pending.message, again=True), now_s, count=not silent)
        if self.upload is not None and not self.upload.complete:
            if self.upload.tries() >= MAX_TRIES and not silent:
                self._fail(
                    f"the rover did not take path {self.upload.path_id} after {self.upload.tries()} tries "
                    f"of a chunk ({self.upload.taken} of {self.upload.chunks} chunks taken)",
                    Failure.NOT_ANSWERED,
                )
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
            self._closed = True  # the link itself is what failed: nothing more to tell the rover

    def _end_with_stop(self, reason: int) -> None:
        """The mission has ended: STOP, re-sent until the rover ACKs it (see `_close`); nothing
        else is asked of the rover any more."""
        self.requests.clear()
        self.upload = None
        self._done_at = self._now
        self._request(mg.Stop(reason=reason))
        if self._sweep_mm_said == 0:  # told to sweep never on seen ground: the usual again
            self._request(mg.Config(param=int(mg.Param.SWEEP_INTERVAL_MM), value=self.sweep_usual_mm()))

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
        return {
            **self.quality.summary(),
            "host_sent": dict(sorted(self.sent.items())),
            "host_sent_again": dict(sorted(self.sent_again.items())),
            "hellos_again": self.hellos_again,
            "sweeps_heard": {"whole": self.scans_heard_whole, "part": self.scans_heard_part},
        }

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

    def save_map(self, path: str | Path) -> None:
        """Write what the sonar found (see rovernav.mapping.learned_map for the format)."""
        self.map.save(path)

    def load_map(self, path: str | Path) -> int:
        """Fold a saved map's echoes into the grid; returns how many. MapFileError if it is not a map."""
        return self.map.load(path)


def _mm(v_m: float) -> int:
    return max(-32768, min(32767, round(v_m * 1000)))
