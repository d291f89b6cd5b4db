"""Mission control: the host's side of a run, the same against the simulator and the radio.

The host is thin. It says HELLO and checks the schema, sends the rover its parameters, streams
camera fixes and heartbeats, plans the global path and sends it, folds the rover's sonar
reports into the map, replans and resends when the path is blocked, and, for an out-and-back
mission, sends the rover home on what it learned and repeats for the trips asked.

`Mission` never blocks and never reads a clock of its own: whoever runs it (the hardware loop
in `rovernav run`, the simulator in lockstep) calls `on_detection()` for each camera frame and
`tick(now_s)` often, with its own notion of time. Requests that need an ACK are re-sent until
answered, and a rover that restarts (new boot id in HELLO) is brought back up to date.
"""
from __future__ import annotations

import dataclasses
import enum
import json
import logging
import math
from pathlib import Path
from typing import Callable

from .link import messages_gen as mg
from .link.errors import LinkError, Nacked, ProtocolError, SchemaMismatch
from .planning import NoPathError, OccupancyGrid, plan

log = logging.getLogger("rovernav.mission")

RESEND_S = 0.4        # an un-ACKed request goes again after this long
MAX_TRIES = 8         # ... this many times, then the mission fails
HELLO_EVERY_S = 0.5
SILENT_S = 1.0              # no frame from the rover for this long: the radio is down
GIVE_UP_SILENT_S = 120.0    # ... for this long: the mission is over
WALL_ECHO_M = 0.06    # an echo this close to the arena's border is the border itself
ECHO_DEPTH_M = 0.20   # an obstacle is taken to reach this far behind the face the sonar saw
ECHO_DEPTH_STEP_M = 0.04
KNOWN_ECHO_M = 0.08   # an echo this close to an obstacle already mapped is that obstacle (another face of it)


class MissionFailed(LinkError):
    """The mission cannot go on: the rover refused it, faulted, or stopped answering."""


class Phase(enum.Enum):
    HELLO = "hello"            # waiting for the rover's HELLO
    CONFIGURE = "configure"    # sending parameters
    LOCATE = "locate"          # waiting for the camera to see the rover
    LOAD = "load"              # a path is being sent
    RUN = "run"                # the rover follows the path
    DONE = "done"
    FAILED = "failed"


@dataclasses.dataclass
class Leg:
    """One leg of the mission: to the target, or back to the start (an out-and-back trip has two)."""

    index: int
    goal: tuple[float, float]
    started_s: float
    finished_s: float | None = None
    reached: bool = False
    replans: int = 0
    planned_length_m: float = 0.0
    obstacles_found: int = 0


@dataclasses.dataclass
class Echo:
    """A sonar report as the rover sent it, kept to save and reload the learned map."""

    x_m: float
    y_m: float
    heading_deg: float
    bearing_deg: float
    range_m: float

    def point(self, sonar_offset_m: float) -> tuple[float, float]:
        """Where the beam's axis meets the echo's range (the sensor sits sonar_offset_m ahead)."""
        h = math.radians(self.heading_deg)
        sx, sy = self.x_m + sonar_offset_m * math.sin(h), self.y_m + sonar_offset_m * math.cos(h)
        b = math.radians(self.heading_deg + self.bearing_deg)
        return sx + self.range_m * math.sin(b), sy + self.range_m * math.cos(b)


@dataclasses.dataclass
class Detection:
    """A camera fix of the rover in arena coordinates (None fields: the rover was not seen)."""

    t_s: float
    x_m: float | None
    y_m: float | None
    heading_deg: float | None
    reason: str | None = None


class Mission:
    """One mission over `link` (a rovernav.link.link.Link): `legs` legs alternating start -> target and
    target -> start (a reach mission is 1 leg; an out-and-back mission of N trips is 2N legs)."""

    def __init__(self, link, grid: OccupancyGrid, start_xy: tuple[float, float], target_xy: tuple[float, float],
                 legs: int = 1, rover_params: list | None = None, planner: str = "astar",
                 fix_sd_mm: int = 3, heartbeat_hz: float = 5.0, host_replan: bool = True,
                 on_event: Callable[[float, str], None] | None = None, map_file: str | Path | None = None,
                 state_file: str | Path | None = None):
        self.link = link
        self.grid = grid
        self.start_xy = start_xy
        self.target_xy = target_xy
        self.legs_asked = legs
        self.rover_params = list(rover_params or [])
        self.planner = planner
        self.fix_sd_mm = fix_sd_mm
        self.heartbeat_period_s = 1.0 / heartbeat_hz
        self.host_replan = host_replan
        self.on_event = on_event or (lambda t, text: log.info("%.2f s %s", t, text))
        self.map_file = Path(map_file) if map_file else None   # kept up to date: a restarted host reloads it
        self.state_file = Path(state_file) if state_file else None   # the legs done, for a restarted host

        self.phase = Phase.HELLO
        self.error: str | None = None
        self.legs: list[Leg] = []
        self.echoes: list[Echo] = []
        self.path: list[tuple[float, float]] = []
        self.path_id = 0
        self.rover_boot_id: int | None = None
        self.last_status: mg.Status | None = None
        self.events: list[tuple[float, mg.Event]] = []
        self.nacks: list[mg.Nack] = []
        self.fixes_sent = 0
        self.replans = 0
        self.wall_echoes = 0
        self.repeat_echoes = 0
        self._now = 0.0
        self._pending: dict[int, tuple[object, float, int]] = {}  # seq -> (message, sent_at, tries)
        self._hello_at = -1e9
        self._heartbeat_at = -1e9
        self._last_detection: Detection | None = None
        self._last_frame_s: float | None = None
        self._start_sent = False
        self._accepted_path_id: int | None = None
        self._map_changed_at: float | None = None
        self._resume_leg = False
        self._last_heard_s = 0.0

    # ---------------------------------------------------------------- inputs

    def on_detection(self, detection: Detection, now_s: float) -> None:
        """A camera frame was processed; send its fix if the rover was seen."""
        self._last_frame_s = now_s
        if detection.x_m is None:
            self._last_detection = detection if self._last_detection is None else self._last_detection
            return
        self._last_detection = detection
        if self.phase in (Phase.HELLO,):
            return
        age_ms = max(0, min(65535, round((now_s - detection.t_s) * 1000)))
        heading_cdeg = round(((detection.heading_deg + 180.0) % 360.0 - 180.0) * 100)
        if heading_cdeg == -18000:
            heading_cdeg = 18000
        self.link.send(mg.Fix(x_mm=_mm(detection.x_m), y_mm=_mm(detection.y_m), heading_cdeg=heading_cdeg,
                              age_ms=age_ms, sd_mm=self.fix_sd_mm, frame_seq=self.fixes_sent & 0xFFFF))
        self.fixes_sent += 1

    def tick(self, now_s: float) -> None:
        """Advance: read what the rover said, re-send what is unanswered, move the phases on."""
        self._now = now_s
        while True:
            frame = self.link.recv(timeout_s=0)
            if frame is None:
                break
            self._handle(frame)
        if self.phase in (Phase.DONE, Phase.FAILED):
            return
        if now_s - self._heartbeat_at >= self.heartbeat_period_s:
            self._heartbeat_at = now_s
            self.link.send(mg.Heartbeat(host_time_ms=int(now_s * 1000) & 0xFFFFFFFF, camera=self._camera_state()))
        self._resend(now_s)
        if self._map_changed_at is not None and now_s - self._map_changed_at > 2.0:
            self._check_path()  # the SCAN_DONE event was lost
        if self.phase is Phase.HELLO and now_s - self._hello_at >= HELLO_EVERY_S:
            self._hello_at = now_s
            self.link.send(mg.Hello(schema_hash=mg.SCHEMA_HASH, boot_id=0x484F5354, firmware_version=0x0001,
                                    role=mg.Role.HOST, max_waypoints=0))
        elif self.phase is Phase.CONFIGURE and not self._pending:
            self.phase = Phase.LOCATE
        if self.phase is Phase.LOCATE and self._rover_seen():
            if self._resume_leg:
                self._resume_leg = False
                path = self._replan_from_rover()
                if path is not None:
                    self._start_sent = False
                    self.phase = Phase.LOAD
                    self._send_path(path)
            else:
                self._begin_trip()
        if self.phase is Phase.LOAD and not self._pending and self._accepted_path_id == self.path_id:
            if not self._start_sent:
                self._request(mg.Start(path_id=self.path_id))
                self._start_sent = True
            else:
                self.phase = Phase.RUN

    @property
    def done(self) -> bool:
        return self.phase in (Phase.DONE, Phase.FAILED)

    # ---------------------------------------------------------------- what the rover says

    def _handle(self, frame) -> None:
        self._last_heard_s = self._now
        m = frame.message
        if isinstance(m, mg.Hello):
            self._on_hello(m)
        elif isinstance(m, (mg.Ack, mg.Nack)):
            self._on_answer(m)
        elif isinstance(m, mg.Status):
            self.last_status = m
        elif isinstance(m, mg.Obstacle):
            self._on_obstacle(m)
        elif isinstance(m, mg.Event):
            self._on_event(m)

    def _on_hello(self, m: mg.Hello) -> None:
        if m.role != mg.Role.ROVER:
            return
        if m.schema_hash != mg.SCHEMA_HASH:
            self._fail(str(SchemaMismatch(mg.SCHEMA_HASH, m.schema_hash)))
            return
        if self.rover_boot_id is not None and m.boot_id != self.rover_boot_id and self.phase is not Phase.HELLO:
            # The rover restarted: it forgot its parameters and its path. Bring it back.
            self.on_event(self._now, f"rover restarted (boot id {self.rover_boot_id} -> {m.boot_id}); "
                                     "re-sending parameters and path")
            self.rover_boot_id = m.boot_id
            self._pending.clear()
            self.link.send(mg.Hello(schema_hash=mg.SCHEMA_HASH, boot_id=0x484F5354, firmware_version=0x0001,
                                    role=mg.Role.HOST, max_waypoints=0))
            resume = self.phase in (Phase.LOAD, Phase.RUN) and bool(self.legs) and not self.legs[-1].reached
            self._configure()
            self._resume_leg = resume   # once configured: the same leg again, from where the rover is
            return
        if self.phase is Phase.HELLO:
            self.rover_boot_id = m.boot_id
            self.on_event(self._now, f"rover HELLO: boot id {m.boot_id}, firmware "
                                     f"{m.firmware_version >> 8}.{m.firmware_version & 0xFF}, schema ok")
            self._configure()

    def _on_answer(self, m) -> None:
        pending = self._pending.pop(m.seq, None)
        if pending is None:
            return
        if isinstance(m, mg.Nack):
            self.nacks.append(m)
            message = pending[0]
            self._fail(str(Nacked(message.NAME, m.reason, m.detail)))

    def _on_obstacle(self, m: mg.Obstacle) -> None:
        echo = Echo(m.x_mm / 1000, m.y_mm / 1000, m.heading_cdeg / 100, m.bearing_cdeg / 100, m.range_mm / 1000)
        if self._is_wall(echo):
            self.wall_echoes += 1   # the arena's border is already in the map
            return
        if self._is_known(echo):
            # A second look at an obstacle the map already holds (a known box, or one found on an
            # earlier pass): its 15-degree arc would only smear the obstacle wider each time it is
            # seen from a new place, and close corridors the last trip drove through.
            self.repeat_echoes += 1
            return
        self.echoes.append(echo)
        self._fold(echo)
        if self.map_file is not None:
            self.save_map(self.map_file)
        if self.legs:
            self.legs[-1].obstacles_found += 1
        # The rover is stopped for its sweep: replan once when the sweep is done, not per echo.
        self._map_changed_at = self._now

    def _fold(self, e: Echo) -> None:
        """Mark the echo's arc in the map, and arcs behind it to ECHO_DEPTH_M: the sonar sees an
        obstacle's near face only, and a map holding just that face lets a later path clip the
        obstacle's unseen body (as a rover that lost its own memory, or its radio, then would)."""
        depth = 0.0
        while depth <= ECHO_DEPTH_M + 1e-9:
            self.grid.add_sonar_echo(e.x_m, e.y_m, e.heading_deg, e.bearing_deg, e.range_m + depth)
            depth += ECHO_DEPTH_STEP_M

    def _echo_point(self, e: Echo) -> tuple[float, float]:
        return e.point(self.grid.config.sonar_offset_m)

    def _is_known(self, e: Echo) -> bool:
        """Whether the map already has an obstacle within KNOWN_ECHO_M of the echo's point."""
        px, py = self._echo_point(e)
        g = self.grid
        r = int(math.ceil(KNOWN_ECHO_M / g.resolution_m))
        ix, iy = int(px / g.resolution_m), int(py / g.resolution_m)
        window = g.raw[max(0, iy - r):iy + r + 1, max(0, ix - r):ix + r + 1]
        return bool(window.any())

    def _is_wall(self, e: Echo) -> bool:
        """Whether the echo's beam axis meets the arena's border (within WALL_ECHO_M): the wall,
        which the map has from the start. Folding it in again only narrows corridors."""
        px, py = self._echo_point(e)
        return min(px, py, self.grid.width_m - px, self.grid.height_m - py) < WALL_ECHO_M

    def _check_path(self) -> None:
        """After the map changed: replan from where the rover is if the rest of its path is blocked."""
        self._map_changed_at = None
        remaining = self._remaining_path()
        if not (self.host_replan and self.phase in (Phase.LOAD, Phase.RUN) and remaining):
            return
        if not self.grid.path_blocked(remaining):
            return
        new = self._replan_from_rover()
        if new is not None:
            self.replans += 1
            self.legs[-1].replans += 1
            self.on_event(self._now, f"the sonar found the path blocked: replanned ({len(new)} waypoints, "
                                     f"{_length(new):.2f} m)")
            self._send_path(new)

    def _on_event(self, m: mg.Event) -> None:
        self.events.append((self._now, m))
        kind = mg.EventKind(m.kind) if m.kind in mg.EventKind._value2member_map_ else None
        if kind is mg.EventKind.ARRIVED and self.phase is Phase.RUN and self.legs:
            trip = self.legs[-1]
            trip.finished_s, trip.reached = self._now, True
            self.on_event(self._now, f"leg {trip.index + 1} reached ({trip.goal[0]:.2f}, {trip.goal[1]:.2f}) m")
            if self.state_file is not None:
                self.state_file.write_text(json.dumps({"legs_done": len(self.legs)}) + "\n", encoding="utf-8")
            if len(self.legs) >= self.legs_asked:
                self.phase = Phase.DONE
                self.link.send(mg.Stop(reason=mg.StopReason.MISSION_DONE))
            else:
                self._begin_trip()
        elif kind is mg.EventKind.SCAN_DONE:
            if self._map_changed_at is not None:
                self._check_path()
        elif kind is mg.EventKind.PATH_ACCEPTED:
            self._accepted_path_id = m.arg
        elif kind is mg.EventKind.FAULT:
            self._fail(f"rover fault: {mg.FaultCode(m.arg).name.lower() if m.arg in mg.FaultCode._value2member_map_ else m.arg}")
        elif kind is not None and kind not in (mg.EventKind.WAYPOINT_REACHED, mg.EventKind.SCAN_DONE):
            self.on_event(self._now, f"rover: {kind.name.lower()} (arg {m.arg})")

    # ---------------------------------------------------------------- doing things

    def _configure(self) -> None:
        self.phase = Phase.CONFIGURE
        for param, value in self.rover_params:
            self._request(mg.Config(param=int(param), value=int(value)))

    def _begin_trip(self) -> None:
        index = len(self.legs)
        goal = self.target_xy if index % 2 == 0 else self.start_xy
        self.legs.append(Leg(index=index, goal=goal, started_s=self._now))
        path = self._leg_path(self._rover_xy(), goal)
        if path is None:
            return
        self.legs[-1].planned_length_m = _length(path)
        self.on_event(self._now, f"leg {index + 1}{self.LEG_NOTE}: {len(path)} waypoints, {_length(path):.2f} m to "
                                 f"({goal[0]:.2f}, {goal[1]:.2f}) m")
        self._start_leg(path)

    # The two steps a strategy may change (sim/seed_strategy.py does).
    LEG_NOTE = ""

    def _leg_path(self, start, goal) -> list[tuple[float, float]] | None:
        """The path of a new leg: A*, simplified."""
        return self._plan_from(start, goal)

    def _start_leg(self, path: list[tuple[float, float]]) -> None:
        """Send a new leg's path; the rover needs it and a START."""
        self._start_sent = False
        self.phase = Phase.LOAD
        self._send_path(path)

    def _send_path(self, path: list[tuple[float, float]]) -> None:
        if len(path) > mg.MAX_WAYPOINTS:
            path = path[:mg.MAX_WAYPOINTS - 1] + [path[-1]]  # the rover replans the rest on arrival
        self.path = path
        self.path_id = (self.path_id + 1) & 0xFFFF
        self._accepted_path_id = None
        if self.phase is not Phase.RUN:
            self.phase = Phase.LOAD
        n = mg.WAYPOINTS_PER_CHUNK
        for first in range(0, len(path), n):
            chunk = path[first:first + n]
            xs = tuple(_mm(x) for x, _ in chunk) + (0,) * (n - len(chunk))
            ys = tuple(_mm(y) for _, y in chunk) + (0,) * (n - len(chunk))
            self._request(mg.Path(path_id=self.path_id, total=len(path), first_index=first, count=len(chunk),
                                  x_mm=xs, y_mm=ys))

    def _plan_from(self, start: tuple[float, float], goal: tuple[float, float]) -> list[tuple[float, float]] | None:
        try:
            result = plan(self.grid, start, goal, planner=self.planner)
        except NoPathError as exc:
            # Close to a newly found obstacle the rover may stand inside its inflated margin:
            # plan from the nearest free cell and let the first leg back out to it.
            free = self._nearest_free(start)
            if free is None:
                self._fail(f"no path to ({goal[0]:.2f}, {goal[1]:.2f}) m: {exc}")
                return None
            try:
                result = plan(self.grid, free, goal, planner=self.planner)
            except NoPathError as exc2:
                self._fail(f"no path to ({goal[0]:.2f}, {goal[1]:.2f}) m: {exc2}")
                return None
            return [start] + [tuple(p) for p in result.waypoints]
        return [tuple(p) for p in result.waypoints]

    def _replan_from_rover(self) -> list[tuple[float, float]] | None:
        if not self.legs:
            return None
        return self._plan_from(self._rover_xy(), self.legs[-1].goal)

    def _nearest_free(self, xy: tuple[float, float], max_m: float = 0.3) -> tuple[float, float] | None:
        step = self.grid.resolution_m
        for ring in range(1, int(max_m / step) + 1):
            r = ring * step
            for k in range(max(8, ring * 8)):
                a = 2 * math.pi * k / max(8, ring * 8)
                p = (xy[0] + r * math.cos(a), xy[1] + r * math.sin(a))
                if self.grid.contains(*p) and self.grid.is_free(*p):
                    return p
        return None

    def _remaining_path(self) -> list[tuple[float, float]]:
        if not self.path:
            return []
        wp = self.last_status.waypoint_index if self.last_status else 0
        here = self._rover_xy()
        return [here] + self.path[min(wp, len(self.path) - 1):]

    def _request(self, message) -> None:
        seq = self.link.send(message)
        self._pending[seq] = (message, self._now, 1)

    def _resend(self, now_s: float) -> None:
        # While the rover says nothing at all (no STATUS either: the radio is down), a request is
        # re-sent but its tries are not counted: the rover is carrying on alone, and will answer
        # when the radio is back. Only a long silence ends the mission.
        silent = now_s - self._last_heard_s > SILENT_S
        if self._pending and now_s - self._last_heard_s > GIVE_UP_SILENT_S:
            self._fail(f"no word from the rover for {GIVE_UP_SILENT_S:.0f} s")
            return
        for seq, (message, sent_at, tries) in list(self._pending.items()):
            if now_s - sent_at < RESEND_S:
                continue
            del self._pending[seq]
            if tries >= MAX_TRIES and not silent:
                self._fail(f"the rover did not answer {message.NAME.upper()} after {tries} tries")
                return
            new_seq = self.link.send(message)
            self._pending[new_seq] = (message, now_s, tries if silent else tries + 1)

    def _fail(self, why: str) -> None:
        if self.phase is Phase.FAILED:
            return
        self.error = why
        self.phase = Phase.FAILED
        self.on_event(self._now, f"mission failed: {why}")
        try:
            self.link.send(mg.Stop(reason=mg.StopReason.HOST_SHUTDOWN))
        except LinkError:
            pass

    def _rover_seen(self) -> bool:
        d = self._last_detection
        return d is not None and d.x_m is not None and self._now - d.t_s < 1.0

    def _rover_xy(self) -> tuple[float, float]:
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

    # ---------------------------------------------------------------- the learned map

    def restore_state(self) -> int:
        """A restarted host: take up the mission at the leg the last host had reached (from
        state_file; the rover's HELLO and STATUS then say the rest). Returns the legs done."""
        if self.state_file is None or not self.state_file.exists():
            return 0
        done = int(json.loads(self.state_file.read_text(encoding="utf-8")).get("legs_done", 0))
        for i in range(min(done, self.legs_asked)):
            goal = self.target_xy if i % 2 == 0 else self.start_xy
            self.legs.append(Leg(index=i, goal=goal, started_s=self._now, finished_s=self._now, reached=True))
        return done

    def save_map(self, path: str | Path) -> None:
        """Write what the sonar found (every echo), so a later mission starts knowing it."""
        data = {"format": "rovernav-map", "version": 1,
                "echoes": [dataclasses.asdict(e) for e in self.echoes]}
        Path(path).write_text(json.dumps(data, indent=1) + "\n", encoding="utf-8")

    def load_map(self, path: str | Path) -> int:
        """Fold a saved map's echoes into the grid; returns how many."""
        try:
            data = json.loads(Path(path).read_text(encoding="utf-8"))
        except (OSError, json.JSONDecodeError) as exc:
            raise ProtocolError(f"cannot read map {path}: {exc}") from None
        if data.get("format") != "rovernav-map" or data.get("version") != 1:
            raise ProtocolError(f"{path} is not a rovernav map (format/version)")
        for e in data["echoes"]:
            echo = Echo(**e)
            self.echoes.append(echo)
            self._fold(echo)
        return len(data["echoes"])


def _mm(v_m: float) -> int:
    return max(-32768, min(32767, round(v_m * 1000)))


def _length(path) -> float:
    return sum(math.dist(a, b) for a, b in zip(path, path[1:]))
