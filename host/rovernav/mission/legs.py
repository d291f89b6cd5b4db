"""Legs, their goals and deadlines, and the record of legs done that a restarted host reads."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

from ..files import write_atomic
from ..planning.turns import REFUSED_NEAR_M


def legs_per_trip(kind: str) -> int:
    """Legs in one trip of a mission of `kind` (a scenario's [mission] kind): out and back, or one."""
    return 2 if kind == "out-and-back" else 1


def leg_goal(start_xy: tuple[float, float], target_xy: tuple[float, float], index: int) -> tuple[float, float]:
    """Where leg `index` (from 0) ends: legs alternate start -> target and target -> start."""
    return target_xy if index % 2 == 0 else start_xy


def leg_origin(start_xy: tuple[float, float], target_xy: tuple[float, float], index: int) -> tuple[float, float]:
    """Where leg `index` begins when every earlier leg was reached."""
    return start_xy if index % 2 == 0 else target_xy


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
    deadline_s: float = math.inf  # when the host steps in if the leg is still not done
    recoveries: int = 0  # times the host re-sent the leg after its deadline
    turns_refused_at: list[tuple[float, float]] = dataclasses.field(default_factory=list)  # TURN_REFUSED's spots [m]
    stopped_by: list[tuple[float, float]] = dataclasses.field(default_factory=list)  # what the reflex met [m]

    def refused_twice(self) -> list[tuple[float, float]]:
        """The spots where the rover refused a turn twice in this leg (within REFUSED_NEAR_M): a
        path that turns there again is no way for it (once may be a memory the next sweep clears)."""
        spots = self.turns_refused_at
        return [
            p
            for i, p in enumerate(spots)
            if any(math.dist(p, q) <= REFUSED_NEAR_M for j, q in enumerate(spots) if j != i)
        ]


@dataclasses.dataclass(frozen=True)
class Deadlines:
    """How long each phase may take before the host steps in (seconds of mission time).

    Every wait of the mission is bounded by one of these; none is the simulator's --max-time.
    A phase's recovery comes first (HELLO and requests are re-sent, a late leg is re-planned
    from where the rover is and sent again); the mission fails, saying which phase and why,
    when the recovery does not help.
    """

    hello_s: float = 30.0  # no HELLO from the rover
    configure_s: float = 30.0  # parameters not all acknowledged
    locate_s: float = 60.0  # the camera does not see the rover
    load_s: float = 30.0  # path and START not acknowledged (while the rover is heard)
    leg_base_s: float = 90.0  # a leg: this much ...
    leg_per_m_s: float = 60.0  # ... plus this per metre of planned path (the seed's pace is ~45 s/m)
    leg_recoveries: int = 2  # re-plans and re-sends of a late leg before the mission fails
    silent_s: float = 120.0  # no frame at all from the rover: the mission is over

    def leg_s(self, planned_length_m: float) -> float:
        return self.leg_base_s + self.leg_per_m_s * max(0.0, planned_length_m)


class LegRecord:
    """How many legs are done, kept in a small JSON file so that a restarted host takes up the
    mission where the last one was ({"legs_done": N}). No file: nothing is kept."""

    def __init__(self, path: str | Path | None):
        self.path = Path(path) if path else None

    def save(self, legs_done: int) -> None:
        if self.path is not None:
            write_atomic(self.path, json.dumps({"legs_done": legs_done}) + "\n")

    def load(self) -> int:
        if self.path is None or not self.path.exists():
            return 0
        try:
            done = json.loads(self.path.read_text(encoding="utf-8")).get("legs_done", 0)
        except (OSError, ValueError, AttributeError):
            return 0
        return done if isinstance(done, int) and done >= 0 else 0


def path_length_m(path) -> float:
    return sum(math.dist(a, b) for a, b in zip(path, path[1:]))


def round_trips_done(legs: list[Leg], home_at_last: bool = False) -> int:
    """Round trips done: out to the site and home, both legs reached (`home_at_last`: the last
    leg's rover is home, parked there for its fleet). A leg given up (FleetControl.give_up) and the
    leg home after it are no trip."""
    home = [leg.reached for leg in legs]
    if home_at_last and legs:
        home[-1] = True
    return sum(1 for i in range(1, len(legs), 2) if home[i] and legs[i - 1].reached)
