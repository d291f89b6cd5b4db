"""What a mission does differently as one of a fleet's (issue 30): its FIX goes out in its rover's
slot on the shared radio, its rover may be held still for another and let go again, and what it
plans round includes the other rovers.

`FleetControl` is a part of `Mission` (core.py), as `RoverFrames` and `LegControl` are: its
methods read and change the mission's own state. A lone rover's mission never calls them: every
default here leaves the mission as it was (`slot_fixes` False, no planning overlay, no echo
filter, never held).
"""

from __future__ import annotations

import math
from collections.abc import Callable

from ..angles import heading_cdeg
from ..link import messages_gen as mg
from ..planning.turns import REFUSED_HERE_M
from .legs import path_length_m
from .phases import Failure, Outcome, Phase

#: A held rover seen within this of where it was when held has stood still since [m] (the STOP
#: reaches it in its next slot, up to 0.3 s later: at 0.15 m/s it coasts ~5 cm; a rover carried
#: elsewhere is moved further).
STOOD_STILL_M = 0.10
#: A detection older than this is not sent as a FIX in a slot [s] (the camera's latency is 60 ms).
SLOT_FIX_MAX_AGE_S = 0.25
#: A path is over seen ground when the sonar has looked at every cell this near it [m]: the body's
#: half-diagonal (0.129 m, the reach of its corners in a turn) and 7 cm for the rover off its line.
SEEN_CORRIDOR_M = 0.20
#: A rover held as it began to back out of a refused turn is let go no sooner than this [s]: its
#: STOP goes in its next slot (up to ~0.7 s on three rovers' air), and its path is planned from
#: where it stopped, not from where it was still backing.
REFUSED_SETTLE_S = 1.5
#: A rover that has refused this many turns in a leg within the back-off distance of one another
#: is no longer held for them: it backs out and turns on its own, as a lone rover does (host and
#: rover disagreeing by a few degrees on a turn of about kBackOffMinTurnDeg, the host sent the
#: same turn every 3 s for 60 s and the fleet was stuck: seed 1 of the trial).
REFUSALS_HELD = 3


class FleetControl:
    """A fleet's hooks in a mission (a base class of Mission; the defaults change nothing)."""

    #: True: the camera's fixes wait for the rover's slot (`slot_frame`), the freshest one going.
    slot_fixes: bool = False
    #: The learned map with the other rovers drawn in, for this mission's planning (None: its own map).
    planning_map: Callable[[], object] | None = None
    #: Whether an echo the rover reports is another rover (then it is no obstacle for the map).
    echo_is_rover: Callable[[object], bool] | None = None
    _held_since: float | None = None
    held_why: str = ""  # why the rover was last held (hold's `why`)
    _slot_sent_for: float | None = None  # the detection (taken at) the last slot's FIX carried
    _aside_goal: tuple[float, float] | None = None  # where the rover is on its way to, out of another's way
    _aside_done = False
    _last_poll = "heartbeat"  # what the last slot's poll was
    _held_xy: tuple[float, float] | None = None  # where a rover held on a leg it had started stood then
    #: The path id whose START goes on from where a hold stopped the rover (START's resume: no sweep first).
    _resume_path_id: int | None = None
    _held_rest: list = []  # the waypoints the rover had still to reach when it was held  # ... it is there: when let go, its leg is planned afresh
    #: True (a fleet's rover): arrived home from its last leg, the rover waits there, its leg kept
    #: open, until `release_park` (every rover of the fleet has done its trips): while it waits it
    #: can still be sent aside, out of the way of a rover that must pass its berth, and back.
    park_at_end: bool = False
    _parked_at: float | None = None  # when the rover first arrived home from its last leg
    #: Why a fleet's rover gave up its trips (`give_up`), None while it has not.
    gave_up: str | None = None
    #: True (a fleet's rover): a sweep counts as heard whole when the sweeps from the same spot
    #: together said every echo it counted (RoverFrames._heard_from_spot).
    heard_over_spot: bool = False
    #: True (a fleet's rover): a path over ground the sonar has already looked at
    #: (`LearnedMap.seen_along`) is driven without the sweep every sweep_interval_mm (a CONFIG
    #: before its START); the sweeps before sharp turns, and the forward reflex, stay.
    sweep_seen_ground: bool = False
    _sweep_mm_said: int | None = None  # the sweep interval last sent (None: the configured one)
    _sweep_zero_for: int | None = None  # the path id over seen ground whose START waits for CONFIG 0
    paths_unswept: int = 0  # paths sent to be driven without the distance sweeps
    #: A fleet's rover [s] (None: never): a rover whose STATUS has said BLOCKED on its current
    #: path this long, neither held nor on its way aside, is sent its leg again, planned from where
    #: it stands. A rover blocked by its forward reflex whose own detour found no way waits for a
    #: new path; when the map did not change none came (seed 6: its reflex's echo was the corner of
    #: the box the sonar finds, 146 mm ahead, on a path the host had planned with the robot radius
    #: alone there and planned again the same after each sweep; since, what stopped the reflex keeps
    #: the full margin for the leg, leg_plan.with_margin_round, and seed 6 is whole).
    resend_blocked_s: float | None = None
    _blocked_since: float | None = None
    blocked_resends: int = 0
    #: True (a fleet's rover in the turn-care trial, fleet/host.py; off by default): a rover that
    #: refuses a turn (TURN_REFUSED: its corners have no room where it stands) is stopped at once
    #: (held) rather than left to back out and turn on its own: it backs out blind, into another
    #: rover (the traffic rules reserve the way ahead of a rover, not behind), and its line on from
    #: where it stopped backing was checked only once its STATUS said so, a second or more later on
    #: a fleet's air, after a corner had met the box it turned from. Planned afresh from where it
    #: stops (`refused_at` in `plan_from`).
    hold_on_refused: bool = False
    _settle_until: float | None = None  # a rover held on a refused turn is let go no sooner
    _back_out_path_id: int | None = None  # the path sent with PATH back_out (load_path)
    refusal_holds: int = 0
    echoes_of_rovers: int = 0
    holds: int = 0
    held_s: float = 0.0

    # ---------------------------------------------------------------- the slot

    def slot_frame(self, now_s: float) -> str:
        """The rover's slot on the shared radio has come: its poll, the slot's last frame, after
        which the rover may speak: a HEARTBEAT when one is due (heartbeat_hz), else its freshest
        FIX (its age counted to now), else a HEARTBEAT. Returns which ("heartbeat" or "fix")."""
        self._now = now_s
        d = self._last_detection
        fresh = (
            d is not None
            and d.x_m is not None
            and d.t_s != self._slot_sent_for
            and now_s - d.t_s < SLOT_FIX_MAX_AGE_S
            and self.phase is not Phase.HELLO
            and not self.done
        )
        # A HEARTBEAT when one is due, but never two polls running while a FIX waits: a FIX at
        # least every other slot (fixes matter more; the HEARTBEAT's word keeps a second longer).
        heartbeat_due = now_s - self._heartbeat_at >= self.heartbeat_period_s and self._last_poll == "fix"
        if not fresh or heartbeat_due:
            self.poll_frame(now_s)
            self._last_poll = "heartbeat"
            return "heartbeat"
        self._last_poll = "fix"
        self._slot_sent_for = d.t_s
        self._send(
            mg.Fix(
                x_mm=_mm(d.x_m),
                y_mm=_mm(d.y_m),
                heading_cdeg=heading_cdeg(d.heading_deg),
                age_ms=max(0, min(65535, round((now_s - d.t_s) * 1000))),
                sd_mm=self.fix_sd_mm,
                frame_seq=self.fixes_sent & 0xFFFF,
            )
        )
        self.fixes_sent += 1
        return "fix"

    def poll_frame(self, now_s: float) -> None:
        """A HEARTBEAT now, as the rover's poll."""
        self._now = now_s
        self._send_heartbeat(now_s)

    # ---------------------------------------------------------------- sweeps over seen ground

    def sweep_usual_mm(self) -> int:
        return self._param(mg.Param.SWEEP_INTERVAL_MM)

    def sweep_for_path(self, path) -> None:
        """`path` (whole) is being sent as path_id: the sweep interval it is driven with (see
        sweep_seen_ground). The usual interval, when the rover has 0, is sent at once, before the
        path's chunks (a running rover switches to a path once it has it whole); 0 waits for the
        whole path (`sweep_before_start`): sent before it, a rover still on its last path would
        drive the rest of that without its sweeps while the new one loads."""
        if not self.sweep_seen_ground or len(path) < 2:
            return
        usual = self.sweep_usual_mm()
        seen = self.map.seen_along(path, SEEN_CORRIDOR_M)
        self.paths_unswept += seen
        self._sweep_zero_for = self.path_id if seen else None
        if not seen and self._sweep_mm_said == 0:
            self._say_sweep(usual, f"sweeps every {usual} mm again: the path crosses ground not yet seen")

    def sweep_before_start(self) -> bool:
        """The path is whole on the rover and nothing is pending: the CONFIG sweep_interval_mm = 0
        that a path over seen ground waits for, sent before its START (which waits for the ACK).
        True when it was sent now."""
        if self._sweep_zero_for != self.path_id:
            return False
        self._sweep_zero_for = None
        if self._sweep_mm_said == 0:
            return False
        self._say_sweep(0, "over ground the sonar has seen: no sweeps on the way")
        return True

    def _say_sweep(self, value: int, why: str) -> None:
        interval = int(mg.Param.SWEEP_INTERVAL_MM)
        for pending in self.requests:
            if isinstance(pending.message, mg.Config) and pending.message.param == interval:
                self.requests.drop(pending)  # (an older value, re-sent after this one, would undo it)
        self._sweep_mm_said = value
        self._request(mg.Config(param=interval, value=value))
        self.on_event(self._now, why)

    def watch_blocked(self, now_s: float) -> bool:
        """The leg sent again to a rover blocked for good on its path (see resend_blocked_s):
        True when it was."""
        s = self.last_status
        blocked = (
            self.resend_blocked_s is not None
            and s is not None
            and s.state == mg.RoverState.BLOCKED
            and s.path_id == self.path_id
            and self._aside_goal is None
            and not self.held
        )
        if not blocked:
            self._blocked_since = None
            return False
        if self._blocked_since is None:
            self._blocked_since = now_s
        if now_s - self._blocked_since < self.resend_blocked_s:
            return False
        self._blocked_since = None
        self.blocked_resends += 1
        self.on_event(
            now_s, f"blocked on path {self.path_id} for {self.resend_blocked_s:g} s, no new path: its leg planned again"
        )
        deadline = self.current_leg.deadline_s
        self._resume()
        # The leg's deadline stands: a rover blocked again and again on the same way is late in the
        # end, and the late leg's bounded recoveries decide (a re-send is no progress).
        self.current_leg.deadline_s = deadline
        return True

    def turn_refused(self, now_s: float) -> None:
        """The rover refused a turn (TURN_REFUSED) and is backing out: held where the STOP finds
        it (see hold_on_refused)."""
        if not self.hold_on_refused or self.held or self.done or self.phase is not Phase.RUN or self.parked:
            return  # (a parked rover on its way back home is left as a lone rover is)
        here = self.current_leg.turns_refused_at[-1] if self.current_leg.turns_refused_at else None
        if here is not None and (
            sum(1 for r in self.current_leg.turns_refused_at if math.dist(r, here) <= REFUSED_HERE_M) > REFUSALS_HELD
        ):
            return  # refused there again and again: it backs out on its own
        if self._back_out_path_id == self.path_id:
            # The host asked this path's back-out (PATH back_out): the rover says TURN_REFUSED as it
            # begins it; stopped, it would back out part way and be asked again. Once only.
            self._back_out_path_id = None
            return
        self.refusal_holds += 1
        self.hold(now_s, "refused a turn: stopped as it backs out, to be planned afresh from there")
        self._settle_until = now_s + REFUSED_SETTLE_S

    def settling(self, now_s: float) -> bool:
        """Whether a rover held on a refused turn is still to be left standing (REFUSED_SETTLE_S)."""
        return self._settle_until is not None and now_s < self._settle_until

    # ---------------------------------------------------------------- held for another rover

    @property
    def held(self) -> bool:
        return self._held_since is not None

    @property
    def moving_leg(self) -> bool:
        """Whether the rover is on a leg it drives now (loading or running it, not held)."""
        return (
            self.phase in (Phase.LOAD, Phase.RUN) and bool(self.legs) and not self.current_leg.reached and not self.held
        )

    def hold(self, now_s: float, why: str) -> None:
        """Stop the rover where it is for another rover (STOP, replanning): its leg waits, its
        deadline with it, until `let_go`."""
        if self.held or self.done:
            return
        self._now = now_s
        self._held_rest = self.remaining_path()[1:]
        self._held_since = now_s
        self.held_why = why
        self._held_xy = self.rover_xy() if self.phase is Phase.RUN else None
        self.holds += 1
        self.upload = None
        for pending in self.requests:
            if isinstance(pending.message, (mg.Path, mg.Start)):
                self.requests.drop(pending)
        self._request(mg.Stop(reason=mg.StopReason.REPLANNING))
        self.on_event(now_s, f"held: {why}")

    def let_go(self, now_s: float, path: list[tuple[float, float]] | None = None, aside: bool = False) -> None:
        """The held rover goes on with its leg: on `path` (planned round the others), else
        replanned from where it stands. `aside`: the path only takes it out of another rover's
        way; arrived there, it is held again (its leg is not done)."""
        if not self.held:
            return
        self._now = now_s
        waited = now_s - self._held_since
        if self._parked_at is None:  # waiting at home for the fleet is no hold
            self.held_s += waited
        self._held_since = None
        if self.done or not self.legs or self.current_leg.reached:
            return
        leg = self.current_leg
        from_aside = self._aside_done
        if from_aside:  # from where it stood aside: the leg afresh (or on to another spot aside)
            self._aside_done = False
            path = path if aside else None
        leg.deadline_s += waited  # the wait is no lateness of the leg's
        self.on_event(now_s, f"let go after {waited:.1f} s")
        if path is None and self._aside_goal is not None:  # held on its way aside: on there, if it can
            aside, path = True, self.plan_from(self.rover_xy(), self._aside_goal, verdict=False)
            if path is None:
                self._held_since = now_s
                self.aside_blocked()
                return
        if path is None:
            path = self.strategy.leg_path(self, self.rover_xy(), leg.goal)
            if path is None:
                return
        if self.parked:  # out of another's way and back home: a drive of its own, with its own deadline
            leg.deadline_s = now_s + self.deadlines.leg_s(path_length_m(path))
        elif from_aside:
            # It gave way (its drive aside and its wait there are the traffic's, not the leg's):
            # the leg from there has at least the time of a leg of that length. Rover 3 of loss1
            # seed 4 gave way six times on one leg, failed it on its deadline standing in the
            # corridor, and held the other two for good.
            leg.deadline_s = max(leg.deadline_s, now_s + self.deadlines.leg_s(path_length_m(path)))
        resume = self._stood_still() and not aside and not self.parked
        self.strategy.start_leg(self, path)
        self._resume_path_id = self.path_id if resume else None
        self._aside_goal = tuple(path[-1]) if aside else None

    def _stood_still(self) -> bool:
        """Whether the rover, held on a leg it had started (and swept on), is where it stood then
        (the camera's word): its START goes on from there without a sweep first (START's resume).
        A sweep a hold interrupted is still due: the rover's own count of the distance since its
        last sweep asks for it at its first step on."""
        return self._held_xy is not None and math.dist(self._held_xy, self.rover_xy()) <= STOOD_STILL_M

    def start_resumes(self) -> int:
        """START's resume for the path being started (1: it goes on from a hold, see _stood_still)."""
        return int(self._resume_path_id is not None and self._resume_path_id == self.path_id)

    def steering_goal(self) -> tuple[float, float]:
        """Where the rover's path leads: its leg's goal, or the spot it is on its way to out of
        another rover's way (a path replanned on the way goes there too)."""
        return self.current_leg.goal if self._aside_goal is None else self._aside_goal

    def aside_blocked(self) -> None:
        """No way on to the spot it was sent aside to (the sonar found it blocked): it stops and
        waits where it is, as if it had arrived there."""
        self._aside_goal = None
        self.hold(self._now, "no way on to its spot aside: it waits where it is")
        self._aside_done = True
        if self.parked:
            self._held_rest = [self.current_leg.goal]

    def aside_arrived(self) -> bool:
        """The rover arrived where it was sent out of another's way: held there again."""
        if self._aside_goal is None:
            return False
        self._aside_goal = None
        self._aside_done = True
        self._held_since = self._now
        if self.parked:  # its way back home is what must come clear before it goes
            self._held_rest = [self.current_leg.goal]
        else:
            self.holds += 1
        self.on_event(self._now, "aside: waits there")
        return True

    # ---------------------------------------------------------------- parked at home

    @property
    def parked(self) -> bool:
        """Home from its last leg, waiting for the fleet (or sent aside from there, or on its way back)."""
        return self._parked_at is not None

    @property
    def parked_at_rest(self) -> bool:
        """Parked, and standing at its berth (not aside, not on its way)."""
        return self.parked and self.held and not self._aside_done and self._aside_goal is None

    @property
    def parked_waiting(self) -> bool:
        """Parked and standing, at its berth or at a spot aside it was sent to (not on its way)."""
        return self.parked and self.held and self._aside_goal is None

    def park(self) -> bool:
        """The last leg's end: a fleet's rover waits there for the fleet, its leg open (True), or
        ends its mission as a lone rover does (False)."""
        if not self.park_at_end:
            return False
        if self._parked_at is None:
            self._parked_at = self._now
            self.on_event(self._now, "home from its last trip: parked, waiting for the fleet")
        if self.phase is Phase.LOCATE:
            # Its legs were done where it stood (a site within the arrival radius of its berth): the
            # mission runs on, parked; left locating, each tick began another leg (arena 14 of the
            # fleet's 20: 2,072 legs in 58 s, and its trip not counted).
            self._set_phase(Phase.RUN)
        self._held_since = self._now
        self._held_rest = []
        self._aside_goal, self._aside_done = None, False
        return True

    def give_up(self, now_s: float, why: str) -> bool:
        """A leg late after its recoveries (`why`): a fleet's rover on its way to its site gives up
        its trips there and goes home, to wait with the fleet (parked, where the traffic rules can
        still send it aside), rather than end its mission where it stands, in the others' way: rover 3
        of loss1 seed 4 ended its mission in the corridor, and the other two were held behind it for
        good. Its mission ends failed once the fleet is done (`release_park`). False (the mission
        fails as a lone rover's does): a lone rover, a leg home, or a rover that gave up already."""
        if not self.park_at_end or self.parked or self.gave_up is not None or self.current_leg.index % 2:
            return False
        self.gave_up = why
        self.legs_to_drive = len(self.legs) + 1  # the leg home is its last
        self._aside_goal, self._aside_done = None, False
        self.on_event(now_s, f"{why}: it gives up its trips and goes home to wait for the fleet")
        self._next_leg()
        return True

    def release_park(self, now_s: float) -> None:
        """Every rover of the fleet has done its trips: the parked leg is done (when the rover first
        arrived home), and the mission with it."""
        if not self.parked_at_rest or self.done:
            return
        self._now = now_s
        arrived_s = self._parked_at
        self._parked_at = None
        self.park_at_end = False
        self._leg_done()
        self.current_leg.finished_s = arrived_s
        if self.gave_up is not None:  # home, but its trips were not all done
            self.outcome, self.failure, self.error = Outcome.FAILED, Failure.LEG_LATE, self.gave_up

    def rest_of_leg(self) -> list[tuple[float, float]]:
        """From where the rover is through the waypoints it has still to reach: those it had when
        it was held, while it is (a STOP ends the rover's path, and its STATUS says waypoint 0)."""
        if self.held:
            return [self.rover_xy(), *self._held_rest]
        return self.remaining_path()

    def held_for_s(self, now_s: float) -> float:
        return 0.0 if self._held_since is None else now_s - self._held_since

    def _planning_map(self):
        return self.map if self.planning_map is None else self.planning_map()

    def _rover_echo(self, reading) -> bool:
        """An echo another rover made (the fleet says so): counted, kept out of the map."""
        if self.echo_is_rover is not None and reading.range_m is not None and self.echo_is_rover(reading):
            self.echoes_of_rovers += 1
            return True
        return False


def _mm(v_m: float) -> int:
    return max(-32768, min(32767, round(v_m * 1000))) if math.isfinite(v_m) else 0
