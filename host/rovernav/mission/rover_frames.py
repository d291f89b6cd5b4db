"""What the rover says, and what the mission does about it: its HELLO, the answers to requests,
its STATUS, its sonar readings (OBSTACLE) and its EVENTs (an arrival, a finished sweep, a fault).

`RoverFrames` is a part of `Mission` (core.py), kept apart by concern: its methods read and
change the mission's own state, and call the mission's means of acting (`_send`, `_request`,
`_fail`, `_configure`, `load_path`, ...). It is not used on its own.
"""

from __future__ import annotations

import math

from ..link import messages_gen as mg
from ..link.errors import Nacked, SchemaMismatch
from ..link.link import host_hello
from ..link.path_upload import Answer
from ..mapping import Echo, SonarReading
from .phases import HELLO_EVERY_S, Failure, Outcome, Phase

#: A sweep from within this of the last one's pose is from the same spot [mm, centidegrees].
SPOT_MM = 10
SPOT_CDEG = 100


class RoverFrames:
    """The mission's handling of the frames it takes from the rover (a base class of Mission)."""

    _last_echo: tuple[int, tuple[float, float]] | None = None  # the last echo heard: its range [mm], its point [m]

    def _handle(self, frame) -> None:
        if self._silent():
            self._heard_again_s = self._now
        self._last_heard_s = self._now
        self._heard_any = True
        m = frame.message
        if isinstance(m, mg.Hello) and m.role == mg.Role.ROVER and m.boot_id != self.rover_boot_id:
            self.quality.restart()  # a rover that restarted numbers its frames from 0 again
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
            self.on_event(
                self._now,
                f"rover restarted (boot id {self.rover_boot_id} -> {m.boot_id}); re-sending parameters and path",
            )
            self.rover_boot_id = m.boot_id
            self.requests.clear()
            self.upload = None
            self._send(host_hello(self.host_boot_id))
            resume = self.phase in (Phase.LOAD, Phase.RUN) and bool(self.legs) and not self.current_leg.reached
            self._configure()
            self._resume_leg = resume  # once configured: the same leg again, from where the rover is
            return
        if self.phase is Phase.HELLO:
            self.rover_boot_id = m.boot_id
            if self._hello_at < 0:
                # The rover's HELLO came before ours went out (it booted while this host was
                # starting): it takes no START until it has checked our schema, so say HELLO now.
                self._hello_at = self._now
                self._send(host_hello(self.host_boot_id))
            self.on_event(
                self._now,
                f"rover HELLO: boot id {m.boot_id}, firmware "
                f"{m.firmware_version >> 8}.{m.firmware_version & 0xFF}, schema ok",
            )
            self._configure()

    def _on_answer(self, m) -> None:
        if self.upload is not None and not self.done:
            answer = self.upload.answer(m)
            if answer is Answer.RESUME:
                self._send_chunks()  # from where the rover stopped, at once
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
                return  # a START for a path since replaced: its answer no longer matters
            if m.reason == mg.NackReason.SCHEMA_MISMATCH or (
                m.reason == mg.NackReason.NO_FIX and isinstance(message, mg.Start)
            ):
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
            self._fail(f"the rover refused {pending.message.NAME.upper()} {pending.tries} times", Failure.NOT_ANSWERED)
            return
        self.requests.again(pending)  # due RESEND_S after its last attempt (re-sent by _resend)

    def _say_hello_again(self) -> None:
        """The rover does not know this host (a NACK schema_mismatch, or STATUS without schema_ok):
        our HELLO was lost. Say it again (at most every HELLO_EVERY_S)."""
        if self._now - self._hello_at >= HELLO_EVERY_S:
            self._hello_at = self._now
            self.hellos_again += 1
            self._send(host_hello(self.host_boot_id))

    def _on_status(self, m: mg.Status) -> None:
        backed_out = (
            self.last_status is not None
            and self.last_status.state == mg.RoverState.BACK_OFF
            and m.state != mg.RoverState.BACK_OFF
        )
        self.last_status = m
        if backed_out and self.host_replan and self._leg_open() and not self.held:
            # The rover backed out to make room for a turn (TURN_REFUSED) and heads for its next
            # waypoint from off its path, along a line no planner chose.
            self.strategy.backed_out(self)
        self.quality.on_status(m, self.frames_sent, self._now)
        if self.phase is not Phase.HELLO and not m.flags & mg.StatusFlag.SCHEMA_OK:
            self._say_hello_again()
        # A STATUS after START was acknowledged that says the rover has arrived on this path:
        # the ARRIVED event itself was lost on the radio.
        if (
            m.state == mg.RoverState.ARRIVED
            and m.path_id == self.path_id
            and self._start_acked_for == self.path_id
            and self._leg_open()
        ):
            self._arrived()

    def _on_obstacle(self, m: mg.Obstacle) -> None:
        if m.scan_id != self._scan_latest:
            self._scan_latest, self._scan_echoes_heard, self._scan_echoes_seen = m.scan_id, 0, set()
            self._new_sweep_from((m.x_mm, m.y_mm, m.heading_cdeg))
        (self._scan_bearings if m.range_mm else self._scan_clear).add(m.bearing_cdeg)
        if m.range_mm:
            # The rover says each echo three times (its word is taken only on a sweep heard whole): once is enough.
            said = (m.bearing_cdeg, m.range_mm, m.x_mm, m.y_mm, m.heading_cdeg)
            if said in self._scan_echoes_seen:
                return
            self._scan_echoes_seen.add(said)
            self._scan_echoes_heard += 1
        reading = SonarReading(
            m.x_mm / 1000,
            m.y_mm / 1000,
            m.heading_cdeg / 100,
            m.bearing_cdeg / 100,
            m.range_mm / 1000 if m.range_mm else None,
            self.sonar_report_m,
            m.sd_mm / 1000,
        )
        if self._rover_echo(reading):  # a fleet's other rover, not an obstacle
            return
        if m.range_mm:
            echo = Echo(reading.x_m, reading.y_m, reading.heading_deg, reading.bearing_deg, reading.range_m)
            self._last_echo = (m.range_mm, self.map.point(echo))
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
            self._save_map()  # once a sweep, not once a reading: the file grows with the map
            self.recorder.host_map(self._now, self.map)
            if self._map_changed_at is not None:
                self._map_changed()
            self._scan_done(m.arg)
        elif kind is mg.EventKind.PATH_ACCEPTED:
            self._accepted_path_id = m.arg
            if self.upload is not None and self.upload.path_id == m.arg:
                self.upload.mark_complete()  # its last ACKs may be lost: this says it all
        elif kind is mg.EventKind.FAULT:
            self._fail(
                f"rover fault: {mg.FaultCode(m.arg).name.lower() if m.arg in mg.FaultCode._value2member_map_ else m.arg}",
                Failure.ROVER_FAULT,
            )
        elif kind is not None and kind is not mg.EventKind.WAYPOINT_REACHED:
            self.on_event(self._now, f"rover: {kind.name.lower()} (arg {m.arg})")
            if kind is mg.EventKind.REFLEX and self._leg_open() and self._last_echo and self._last_echo[0] == m.arg:
                # The reflex's echo (its OBSTACLE goes just before this EVENT): the leg plans round
                # it with the full margin (leg_plan.with_margin_round).
                self.current_leg.stopped_by.append(self._last_echo[1])
            if kind is mg.EventKind.TURN_REFUSED and self._leg_open():
                # Twice in one spot, and planned paths turn there no more this leg (Leg.refused_twice).
                self.current_leg.turns_refused_at.append((m.x_mm / 1000, m.y_mm / 1000))
                self.turn_refused(self._now)  # a fleet's rover: stopped as it begins to back out

    def _leg_open(self) -> bool:
        return self.phase in (Phase.LOAD, Phase.RUN) and bool(self.legs) and not self.current_leg.reached

    def _arrived(self) -> None:
        if self.held and (self.parked or self._aside_done):
            return  # a copy of the word it is home, or aside (fleet_control.py): no leg's end
        if self.aside_arrived():  # out of another rover's way (fleet_control.py), not at the leg's end
            return
        if self.path_rest:  # the end of a part of a long path: the next part, from here
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
        if len(self.legs) >= self.legs_to_drive and self.park():  # a fleet's rover waits at home (fleet_control.py)
            return
        self._held_since = None  # a leg done while held for another rover (fleet_control.py) is done
        leg = self.current_leg
        leg.finished_s, leg.reached = self._now, True
        self.on_event(self._now, f"leg {leg.index + 1} reached ({leg.goal[0]:.2f}, {leg.goal[1]:.2f}) m")
        self.record.save(len(self.legs))
        if len(self.legs) >= self.legs_to_drive:
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
            return  # a copy (the rover says SCAN_DONE three times), or a sweep none of whose readings came
        self._scan_done_for = self._scan_latest
        if self._scan_echoes_heard == echoes or self._heard_from_spot(echoes):
            self.scans_heard_whole += 1
            self.scan_heard = self._scan_latest
        else:
            self.scans_heard_part += 1

    def _new_sweep_from(self, pose: tuple[int, int, int]) -> None:
        """A sweep's first reading heard: from the spot of the sweeps before (within SPOT_MM and
        SPOT_CDEG: the rover swept again where it stands), or from a new one."""
        if self._spot is not None and (
            math.dist(pose[:2], self._spot[:2]) <= SPOT_MM and abs(pose[2] - self._spot[2]) <= SPOT_CDEG
        ):
            self._spot_echoes |= self._scan_bearings
        else:
            self._spot, self._spot_echoes = pose, set()
        self._scan_bearings, self._scan_clear = set(), set()

    def _heard_from_spot(self, echoes: int) -> bool:
        """Whether the host heard this sweep whole over the sweeps from this spot (a fleet's word:
        `heard_over_spot`): each bearing that echoed now heard echo in it or in a sweep from here
        before (and not heard clear now), as many as this one counted. On a radio that loses a
        signed OBSTACLE ~45 % of the time a sweep among many echoes is rarely heard whole in one
        go, and its rover, waiting for the host's word, swept again in one spot for 440 s (fleet,
        1 % loss and 0.1 % bit errors); what one sweep's lost copies miss, the sweeps before from
        the same spot said, and the map holds it."""
        if not self.heard_over_spot:
            return False
        bearings = self._scan_bearings | (self._spot_echoes - self._scan_clear)
        return len(bearings) == echoes

    def _map_changed(self) -> None:
        self._map_changed_at = None
        if self.host_replan and self._leg_open() and not self.held:
            self.strategy.map_changed(self)
