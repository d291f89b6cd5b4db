"""What the host has learned of the arena from the rover's sonar, kept across legs and runs.

The map is the planner's occupancy grid plus every echo folded into it. Saved as JSON:

    {"format": "rovernav-map", "version": 1,
     "echoes": [{"x_m", "y_m", "heading_deg", "bearing_deg", "range_m"}, ...]}

each echo as the rover reported it (its pose estimate when it pinged, the servo's bearing off
the heading, clockwise positive, and the range from the sensor). Reloading folds them in again,
so a later mission, or a restarted host, starts knowing what an earlier one found.
"""
from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

from ..planning import OccupancyGrid
from ..files import write_atomic
from ..errors import MapFileError

WALL_ECHO_M = 0.06    # an echo this close to the arena's border is the border itself
ECHO_DEPTH_M = 0.20   # an obstacle is taken to reach this far behind the face the sonar saw
ECHO_DEPTH_STEP_M = 0.04
KNOWN_ECHO_M = 0.08   # an echo this close to an obstacle already mapped is that obstacle (another face of it)
MAP_FORMAT, MAP_VERSION = "rovernav-map", 1
MAX_MAP_ECHOES = 100_000


@dataclasses.dataclass
class Echo:
    """A sonar report as the rover sent it."""

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


class LearnedMap:
    """The planner's grid and the echoes folded into it.

    `add(echo)` returns whether the map changed: echoes off the arena's wall (already mapped)
    and second looks at an obstacle the map holds are counted and not folded again, since a
    15-degree arc would smear the obstacle wider each time it is seen from a new place.
    """

    def __init__(self, grid: OccupancyGrid):
        self.grid = grid
        self.echoes: list[Echo] = []
        self.wall_echoes = 0
        self.repeat_echoes = 0

    def add(self, echo: Echo) -> bool:
        if self._is_wall(echo):
            self.wall_echoes += 1
            return False
        if self._is_known(echo):
            self.repeat_echoes += 1
            return False
        self.echoes.append(echo)
        self._fold(echo)
        return True

    def _fold(self, e: Echo) -> None:
        """Mark the echo's arc in the map, and arcs behind it to ECHO_DEPTH_M: the sonar sees an
        obstacle's near face only, and a map holding just that face lets a later path clip the
        obstacle's unseen body."""
        depth = 0.0
        while depth <= ECHO_DEPTH_M + 1e-9:
            self.grid.add_sonar_echo(e.x_m, e.y_m, e.heading_deg, e.bearing_deg, e.range_m + depth)
            depth += ECHO_DEPTH_STEP_M

    def point(self, e: Echo) -> tuple[float, float]:
        return e.point(self.grid.config.sonar_offset_m)

    def _is_known(self, e: Echo) -> bool:
        px, py = self.point(e)
        g = self.grid
        r = int(math.ceil(KNOWN_ECHO_M / g.resolution_m))
        ix, iy = int(px / g.resolution_m), int(py / g.resolution_m)
        window = g.raw[max(0, iy - r):iy + r + 1, max(0, ix - r):ix + r + 1]
        return bool(window.any())

    def _is_wall(self, e: Echo) -> bool:
        px, py = self.point(e)
        return min(px, py, self.grid.width_m - px, self.grid.height_m - py) < WALL_ECHO_M

    # ------------------------------------------------------------ files

    def to_json(self) -> dict:
        return {"format": MAP_FORMAT, "version": MAP_VERSION, "echoes": [dataclasses.asdict(e) for e in self.echoes]}

    def save(self, path: str | Path) -> None:
        """Write the map (atomically: a reader never sees half a file)."""
        write_atomic(Path(path), json.dumps(self.to_json(), indent=1, allow_nan=False) + "\n")

    def load(self, path: str | Path) -> int:
        """Fold a saved map's echoes into the grid; returns how many. MapFileError (naming the
        file and what is wrong) for anything that is not a valid map."""
        for echo in read_map_file(path):
            self.echoes.append(echo)
            self._fold(echo)
        return len(self.echoes)


def read_map_file(path: str | Path) -> list[Echo]:
    """The echoes of a map file, validated: MapFileError names the file, the entry and the key."""
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise MapFileError(f"cannot read map {path}: {exc}") from None
    if not isinstance(data, dict) or data.get("format") != MAP_FORMAT or data.get("version") != MAP_VERSION:
        raise MapFileError(f"{path} is not a rovernav map (want format {MAP_FORMAT!r}, version {MAP_VERSION})")
    raw = data.get("echoes")
    if not isinstance(raw, list):
        raise MapFileError(f"{path}: 'echoes' must be a list")
    if len(raw) > MAX_MAP_ECHOES:
        raise MapFileError(f"{path}: {len(raw)} echoes; at most {MAX_MAP_ECHOES} are read")
    names = [f.name for f in dataclasses.fields(Echo)]
    echoes = []
    for i, e in enumerate(raw):
        if not isinstance(e, dict) or sorted(e) != sorted(names):
            raise MapFileError(f"{path}: echoes[{i}] must have exactly the keys {', '.join(names)}")
        for k in names:
            v = e[k]
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise MapFileError(f"{path}: echoes[{i}].{k} must be a finite number, got {v!r}")
        if not 0 < e["range_m"] <= 4.0:
            raise MapFileError(f"{path}: echoes[{i}].range_m must be in (0, 4] m, got {e['range_m']!r}")
        echoes.append(Echo(**{k: float(e[k]) for k in names}))
    return echoes
