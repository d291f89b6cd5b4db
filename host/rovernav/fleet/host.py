"""A fleet's host (issue 30): one mission per rover, one map, one radio, one camera.

Each rover has its own `Mission` (the one `rovernav run` gives a lone rover: its HELLO, its
parameters, its legs between its start and its site, its replanning), over its own `Link`
(its own key, its own address on the shared radio). What they share:

- **the air** (`FleetRadio`): each mission's frames wait for its rover's slot; the slot carries its
  freshest FIX; a rover speaks only in its slot;
- **the map**: one `LearnedMap`, fed by every rover's sonar (a box one rover found is known to
  all), and a rover whose path the map now blocks is replanned, whoever found it;
- **the traffic** (`Traffic`): the rovers plan round each other and wait for each other.

Whoever runs it (the simulator; one day `rovernav run` with one camera and one radio) calls
`on_frame` with each camera frame's detections, `tick(now_s)` once a frame, and `air(now_s)`
every 10 ms step, the radio's slots being shorter than a frame.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from ..link import messages_gen as mg
from ..link.link import Link
from ..mission import Detection, Mission
from ..mission.spec import MissionSpec, start_host
from .radio import FleetRadio
from .traffic import Traffic

#: How often the other rovers' paths are checked against a map another rover changed [s].
MAP_SHARE_S = 0.5
#: The seen-ground trial (`FleetHost(seen_ground_trial=True)`, off by default: docs/results.md, "A
#: fleet under one camera"): a rover Blocked on its path this long, with no new path, is sent its
#: leg again [s] (`Mission.resend_blocked_s`).
RESEND_BLOCKED_S = 9.0
#: The turn-care trial (`FleetHost(turn_care_trial=True)`, off by default: docs/results.md, "A
#: fleet under one camera"): a rover that refuses a turn is held at once and planned afresh from
#: where it stops (`Mission.hold_on_refused`); a rover that gave way waits until the other has
#: passed (`Traffic.give_way_wait`); no spot aside on an active rover's berth or site while there
#: is another (`Traffic.berth_rule`).
#: A fleet rover's parameters beside the configuration's, for its share of the air (about 4.5
#: slots of 128 bytes a second with three rovers, where a lone rover says 490-509 B/s): STATUS once
#: a second (64 bytes each; the camera says where it is), fixes allowed further apart (its slot
#: rather than every camera frame), a slower sweep and echoes reported within the seed's 0.4 m
#: (each echo is said three times, 102 bytes: at the usual 90 ms a step a sweep says ~1,100 B/s,
#: what its 128-byte TX queue cannot hold is lost, the host never hears the sweep whole and the
#: rover, waiting for its word, sweeps again; measured on fleet-out-and-back, 3 rovers: 19-33
#: frames dropped a rover and every sweep heard whole at 400 ms a step and STATUS every second,
#: against 56-135 dropped and sweeps heard in part at 300 ms and every 500 ms).
FLEET_ROVER_PARAMS = (
    (mg.Param.STATUS_PERIOD_MS, 1000),
    (mg.Param.FIX_TIMEOUT_MS, 1000),
    (mg.Param.SWEEP_STEP_MS, 400),
    (mg.Param.SONAR_REPORT_MM, 400),
)


def fleet_specs(scenario, cfg, rovers: int, host_boot_id: int, own=None) -> list[MissionSpec]:
    """Each rover's mission: from its start (its berth at the base) to its site and back, with the
    configuration's parameters and a fleet rover's (FLEET_ROVER_PARAMS); its host boot id
    `host_boot_id` + 16 k. `own`: each rover's own parameters over those (rover 1's first: a
    mapping of Param to raw value, its motors' calibration, say; fewer than the rovers: the rest
    have none). ScenarioError (one line) when the scenario has too few starts."""
    pairs = scenario.fleet_legs(rovers)
    params = [(p, v) for p, v in cfg.rover_params() if p not in dict(FLEET_ROVER_PARAMS)]
    params += list(FLEET_ROVER_PARAMS)
    specs = []
    for k, (start, site) in enumerate(pairs):
        mine = dict(own[k]) if own and k < len(own) else {}
        theirs = [(p, mine.pop(p, v)) for p, v in params] + sorted(mine.items())
        specs.append(
            MissionSpec.for_run(
                scenario, cfg, rover_params=theirs, start_xy=start, target_xy=site, host_boot_id=host_boot_id + 16 * k
            )
        )
    return specs


class FleetHost:
    def __init__(
        self,
        specs: list[MissionSpec],
        radio: FleetRadio,
        keys: list[bytes | None],
        workdir: Path,
        *,
        clock: Callable[[], float] | None = None,
        on_event: Callable[[int, float, str], None] | None = None,
        recorders: list | None = None,
        seen_ground_trial: bool = False,
        turn_care_trial: bool = False,
    ):
        if len(specs) != radio.rovers or len(keys) != radio.rovers:
            raise ValueError(f"{len(specs)} missions and {len(keys)} keys for a radio of {radio.rovers} rovers")
        self.radio = radio
        say = on_event or (lambda k, t, text: None)
        signing = {} if clock is None else {"clock": clock}  # (None: the Link's own, the wall clock)
        self.links = [Link(radio.ports[k], key=keys[k], address=k, **signing) for k in range(radio.rovers)]
        self.missions: list[Mission] = []
        for k, spec in enumerate(specs):
            folder = Path(workdir) / f"rover{k + 1}"
            folder.mkdir(parents=True, exist_ok=True)
            recorder = None if recorders is None else recorders[k]  # rover k's channels of the run log
            m = start_host(
                spec, self.links[k], folder, on_event=lambda t, text, k=k: say(k, t, text), recorder=recorder
            )
            self.missions.append(m)
        shared = self.missions[0].map
        for m in self.missions[1:]:
            m.map = shared  # one map: what any rover's sonar finds, every rover plans round
        self.map = shared
        self.traffic = Traffic(self.missions, on_event=lambda t, text: say(-1, t, text))
        if turn_care_trial:  # a rover that gave way waits for the other to pass; spots aside off berths
            self.traffic.give_way_wait = self.traffic.berth_rule = True
        for k, m in enumerate(self.missions):
            m.slot_fixes = True
            m.park_at_end = True
            m.heard_over_spot = True
            if turn_care_trial:  # a refused turn held at once, and planned afresh from there
                m.hold_on_refused = True
            if seen_ground_trial:  # paths over seen ground unswept, and the blocked watch
                m.sweep_seen_ground = True
                m.resend_blocked_s = RESEND_BLOCKED_S
            m.planning_map = lambda k=k: self.traffic.planning_map(k)
            m.echo_is_rover = lambda reading, k=k: self.traffic.echo_is_rover(k, reading)
        self._map_version = shared.grid.version
        self._map_checked_s = 0.0

    @property
    def finished(self) -> bool:
        return all(m.finished for m in self.missions)

    def on_frame(self, detections: list[Detection], now_s: float) -> None:
        """One camera frame: rover k's detection (found or not, with why) to mission k."""
        for m, d in zip(self.missions, detections):
            m.on_detection(d, now_s)

    def on_seen(self, seen, taken_s: float, now_s: float) -> list[int]:
        """A FleetLocator's frame (vision/fleet.py's FleetDetection, taken at taken_s): rover k's
        pose, or why it was not found, to mission k. Returns the rovers (0-based) not found."""
        detections, lost = [], []
        for k in range(len(self.missions)):
            pose = seen.rovers.get(k + 1)
            if pose is None:
                lost.append(k)
                detections.append(Detection(taken_s, None, None, None, seen.reasons.get(k + 1)))
            else:
                detections.append(Detection(taken_s, pose.x_m, pose.y_m, pose.heading_deg))
        self.on_frame(detections, now_s)
        return lost

    def tick(self, now_s: float) -> None:
        """Every mission reads its rover's frames and acts; the traffic rules; the shared map."""
        self.radio.pump()
        for m in self.missions:
            m.tick(now_s)
        self.traffic.tick(now_s)
        if all(m.done or m.parked_at_rest for m in self.missions):
            for m in self.missions:  # every rover has done its trips: the parked ones' missions end
                m.release_park(now_s)
        version = self.map.grid.version
        if version != self._map_version and now_s - self._map_checked_s >= MAP_SHARE_S:
            # Another rover's sonar changed the map: each rover's path checked against it (its own
            # rover's sweep already checked it, and a second look at a clear path changes nothing).
            self._map_version, self._map_checked_s = version, now_s
            for m in self.missions:
                if m.host_replan and not m.held and m.moving_leg and m.phase.value == "run":
                    m.strategy.map_changed(m)

    def air(self, now_s: float) -> int | None:
        """A slot on the radio when the air is free (see FleetRadio.slot)."""
        return self.radio.slot(now_s, self._fill)

    def _fill(self, k: int, now_s: float) -> None:
        """Rover k's slot: what waits for it, then its poll last (its freshest FIX, else a
        HEARTBEAT): the rover speaks after the poll, when the host's frames are off the air."""
        m = self.missions[k]
        if not m.finished:
            m.slot_frame(now_s)

    def fail(self, why: str) -> None:
        for m in self.missions:
            if not m.done:
                m.fail(why)
