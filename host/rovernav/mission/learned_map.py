"""What the host has learned of the arena from the rover's sonar, kept across legs and runs.

Every reading the rover reports (an echo, or a ping with no echo within its report range) goes
into a log-odds occupancy grid (rovernav.mapping.SonarMap); the planner's grid then avoids the
known obstacles and the cells believed occupied, both inflated by the robot radius + sonar
margin. No reading is dropped.

Saved as JSON (version 2):

    {"format": "rovernav-map", "version": 2,
     "readings": [{"x_m", "y_m", "heading_deg", "bearing_deg", "range_m", "max_range_m", "sd_m"}, ...]}

each reading as the rover reported it: its pose estimate when it pinged, the servo's bearing off
the heading (clockwise positive), the range from the sensor (null: no echo within max_range_m)
and the one-sigma of its position. Reloading replays them, so a later mission or a restarted
host has the same map as the one that saved it. Version 1 files (echoes only) are read too.
"""
from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

from ..errors import MapFileError
from ..files import write_atomic
from ..mapping import SonarMap, SonarReading
from ..planning import OccupancyGrid

MAP_FORMAT, MAP_VERSION = "rovernav-map", 2
MAX_MAP_READINGS = 200_000


@dataclasses.dataclass
class Echo:
    """A sonar echo as the rover sent it (for reports and pictures)."""

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
    """The planner's grid (known obstacles) combined with a log-odds map of what the sonar saw.

    `add(reading)` returns whether the planner's map changed (a cell crossed the occupied
    threshold), which is when the mission looks at its path again.
    """

    def __init__(self, grid: OccupancyGrid):
        self.grid = grid
        cfg = grid.config
        self.sonar = SonarMap(grid.width_m, grid.height_m, grid.resolution_m, cfg.sonar_offset_m, known=grid.raw)
        self._base_raw = grid.raw.copy()
        self._base_inflated = grid.inflated.copy()

    @property
    def readings(self) -> list[SonarReading]:
        return self.sonar.readings

    @property
    def echoes(self) -> list[Echo]:
        return [Echo(r.x_m, r.y_m, r.heading_deg, r.bearing_deg, r.range_m) for r in self.sonar.readings
                if r.range_m is not None]

    def add(self, reading: SonarReading) -> bool:
        changed = self.sonar.update(reading) > 0
        if changed:
            self._apply()
        return changed

    def _apply(self) -> None:
        g = self.grid
        g.raw = self._base_raw | self.sonar.occupied
        g.inflated = self._base_inflated | self.sonar.inflated(g.config.inflation_m)
        g.version += 1

    def lenient_grid(self) -> OccupancyGrid | None:
        """The planner's grid with what only the sonar has seen inflated by the robot radius alone
        (None when the sonar has found nothing, so there is nothing to be lenient about)."""
        occupied = self.sonar.occupied
        if not occupied.any():
            return None
        g = self.grid.copy()
        g.inflated = self._base_inflated | self.sonar.inflated(g.config.robot_radius_m)
        return g

    def point(self, e: Echo) -> tuple[float, float]:
        return e.point(self.grid.config.sonar_offset_m)

    # ------------------------------------------------------------ files

    def to_json(self) -> dict:
        return {"format": MAP_FORMAT, "version": MAP_VERSION,
                "readings": [dataclasses.asdict(r) for r in self.sonar.readings]}

    def save(self, path: str | Path) -> None:
        """Write the map (atomically: a reader never sees half a file)."""
        write_atomic(Path(path), json.dumps(self.to_json(), indent=1, allow_nan=False) + "\n")

    def load(self, path: str | Path) -> int:
        """Replay a saved map's readings; returns how many. MapFileError (naming the file, the entry
        and the key) for anything that is not a valid map."""
        readings = read_map_file(path)
        for r in readings:
            self.sonar.update(r)
        self._apply()
        return len(readings)


def read_map_file(path: str | Path) -> list[SonarReading]:
    """The readings of a map file, validated."""
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
        raise MapFileError(f"cannot read map {path}: {exc}") from None
    if not isinstance(data, dict) or data.get("format") != MAP_FORMAT or data.get("version") not in (1, 2):
        raise MapFileError(f"{path} is not a rovernav map (want format {MAP_FORMAT!r}, version 1 or 2)")
    key = "echoes" if data["version"] == 1 else "readings"
    raw = data.get(key)
    if not isinstance(raw, list):
        raise MapFileError(f"{path}: {key!r} must be a list")
    if len(raw) > MAX_MAP_READINGS:
        raise MapFileError(f"{path}: {len(raw)} {key}; at most {MAX_MAP_READINGS} are read")
    out = []
    for i, e in enumerate(raw):
        where = f"{path}: {key}[{i}]"
        if not isinstance(e, dict):
            raise MapFileError(f"{where} must be an object")
        if data["version"] == 1:
            e = {**e, "max_range_m": 0.4, "sd_m": 0.0}
        names = [f.name for f in dataclasses.fields(SonarReading)]
        if sorted(e) != sorted(names):
            raise MapFileError(f"{where} must have exactly the keys {', '.join(names)}")
        for k in names:
            v = e[k]
            if k == "range_m" and v is None:
                continue
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise MapFileError(f"{where}.{k} must be a finite number, got {v!r}")
        if e["range_m"] is not None and not 0 < e["range_m"] <= 4.0:
            raise MapFileError(f"{where}.range_m must be in (0, 4] m or null, got {e['range_m']!r}")
        if not 0 < e["max_range_m"] <= 4.0 or e["sd_m"] < 0:
            raise MapFileError(f"{where}: max_range_m must be in (0, 4] m and sd_m >= 0")
        out.append(SonarReading(**{k: (None if e[k] is None else float(e[k])) for k in names}))
    return out
