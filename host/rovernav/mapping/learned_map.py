"""What the host has learned of the arena from the rover's sonar, kept across legs and runs.

Every reading the rover reports (an echo, or a ping with no echo within its report range) goes
into a log-odds occupancy grid (rovernav.mapping.SonarMap); the planner's grid then avoids the
known obstacles and the cells believed occupied, both inflated by the robot radius + sonar
margin. No reading is dropped.

Two maps of the same readings. The careful one (the planner's) lets silence clear only the cells
whose centre lies in the cone, so that a box's corner a later ping only grazes stays an obstacle
(after a radio outage the rover once clipped such a corner of the Figure 4.8 box). The open one
lets silence clear every cell the cone touches, as the map always did; it carves the arcs'
edges out of narrow passages, and the mission plans on it only when the careful map finds no
way (rovernav.mission.leg_plan.plan_leg), so a target is 'unreachable' only when the open
map encloses it too (the README's "The host's map" has what each cost and bought, measured).

Saved as JSON (version 2):

    {"format": "rovernav-map", "version": 2,
     "readings": [{"x_m", "y_m", "heading_deg", "bearing_deg", "range_m", "max_range_m", "sd_m"}, ...]}

each reading as the rover reported it: its pose estimate when it pinged, the servo's bearing off
the heading (clockwise positive), the range from the sensor (null: no echo within max_range_m)
and the one-sigma of its position. Reloading replays them, so a later mission or a restarted
host has the same map as the one that saved it. Version 1 files (echoes only) are read too.

A file is read strictly, and refused with a one-line MapFileError naming the file, the entry
and the key before anything is replayed: a regular UTF-8 file of at most MAX_MAP_BYTES,
JSON with exactly these keys (no NaN or infinity anywhere), at most MAX_MAP_READINGS
readings, each value a finite number within what the link can carry (positions within
+-32.767 m, and within ARENA_MARGIN_M of the arena the map is loaded into; angles within
+-360 degrees; ranges in (0, 4] m; sd_m in [0, 65.535] m), and no more replay work than
MAX_REPLAY_CELLS (readings x grid cells).
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import stat
from pathlib import Path

import numpy as np

from ..errors import MapFileError
from ..files import write_atomic
from ..planning import OccupancyGrid
from .sonar_map import SensorModel, SonarMap, SonarReading, echo_point

MAP_FORMAT, MAP_VERSION = "rovernav-map", 2
#: Readings a file may hold: a long mission sweeps a few thousand; replaying this many takes
#: about 20 s on the 2.4 x 1.8 m arena.
MAX_MAP_READINGS = 200_000
#: Bytes a map file may have: MAX_MAP_READINGS as this module writes them (about 190 bytes
#: each) with room to spare; checked before the file is read.
MAX_MAP_BYTES = 64 * 1024 * 1024
#: Replay work allowed, readings x cells of the grid they are replayed into (each reading
#: compares the whole grid): a few seconds. Only a large map on a very large arena meets it.
MAX_REPLAY_CELLS = 4_000_000_000
#: How far outside the arena a reading's position may be (a pose estimate that strayed off
#: the edge) before the file is taken for a map of another arena [m].
ARENA_MARGIN_M = 2.0
#: What the link can carry (OBSTACLE: i16 mm positions, i16 centidegrees, u16 mm sd) and the
#: sonar's reach.
MAX_POSITION_M = 32.767
MAX_ANGLE_DEG = 360.0
MAX_RANGE_M = 4.0
MAX_SD_M = 65.535


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
        return echo_point(self.x_m, self.y_m, self.heading_deg, self.bearing_deg, self.range_m, sonar_offset_m)


class LearnedMap:
    """The planner's grid (known obstacles) combined with a log-odds map of what the sonar saw.

    `add(reading)` returns whether the planner's map changed (a cell crossed the occupied
    threshold), which is when the mission looks at its path again.
    """

    def __init__(self, grid: OccupancyGrid):
        self.grid = grid
        cfg = grid.config
        # The cone the configuration sends the rover (sonar_cone_deg), not a fixed one.
        self.sonar = SonarMap(
            grid.width_m,
            grid.height_m,
            grid.resolution_m,
            cfg.sonar_offset_m,
            model=SensorModel(cone_deg=cfg.sonar_cone_deg),
            known=grid.raw,
        )
        self.open_sonar = SonarMap(
            grid.width_m,
            grid.height_m,
            grid.resolution_m,
            cfg.sonar_offset_m,
            model=SensorModel(cone_deg=cfg.sonar_cone_deg, clear_cut_cells=True),
            known=grid.raw,
        )
        self._base_raw = grid.raw.copy()
        self._base_inflated = grid.inflated.copy()
        self.known_grid = grid.copy()  # the known obstacles alone, inflated as the planner's grid is

    @property
    def readings(self) -> list[SonarReading]:
        return self.sonar.readings

    @property
    def echoes(self) -> list[Echo]:
        return [
            Echo(r.x_m, r.y_m, r.heading_deg, r.bearing_deg, r.range_m)
            for r in self.sonar.readings
            if r.range_m is not None
        ]

    def add(self, reading: SonarReading) -> bool:
        """Fold a reading into both maps; whether a path may need checking again: the careful map
        changed (the planner's grid), or the open map newly holds a cell occupied. A path planned
        on the open map (through a gap the careful map closes) is blocked only there; a second echo
        of a box's corner that the open map's silence had cleared puts it back there alone, and
        without a replan the rover went on along the old path into that corner (the fleet on a
        radio losing 1 % of its bytes, seed 3)."""
        self.open_sonar.update(reading)
        changed = self.sonar.update(reading) > 0
        if changed:
            self._apply()
        return changed or self.open_sonar.closed_cells > 0

    def _apply(self) -> None:
        g = self.grid
        g.raw = self._base_raw | self.sonar.occupied
        g.inflated = self._base_inflated | self.sonar.inflated(g.config.inflation_m)
        g.version += 1

    def lenient_grid(self) -> OccupancyGrid | None:
        """The planner's grid with what only the sonar has seen inflated by the robot radius alone
        (None when the sonar has found nothing, so there is nothing to be lenient about)."""
        return self._sonar_grid(self.sonar, self.grid.config.robot_radius_m)

    def open_grids(self) -> list[OccupancyGrid]:
        """The open map's grids (its silence clears the cells the cone's edge only cuts too):
        [inflated as the planner's grid is, by the robot radius alone]; empty when it believes
        nothing open that the careful map does not."""
        if not (self.sonar.occupied & ~self.open_sonar.occupied).any():
            return []
        return [
            self._sonar_grid(self.open_sonar, self.grid.config.inflation_m, always=True),
            self._sonar_grid(self.open_sonar, self.grid.config.robot_radius_m, always=True),
        ]

    def _sonar_grid(self, sonar: SonarMap, radius_m: float, always: bool = False) -> OccupancyGrid | None:
        occupied = sonar.occupied
        if not always and not occupied.any():
            return None
        g = self.grid.copy()
        g.raw = self._base_raw | occupied
        g.inflated = self._base_inflated | sonar.inflated(radius_m)
        return g

    def point(self, e: Echo) -> tuple[float, float]:
        return e.point(self.grid.config.sonar_offset_m)

    def seen_along(self, path, corridor_m: float) -> bool:
        """Whether the sonar has looked at all the ground within `corridor_m` of `path` (a
        polyline, metres): every cell there whose centre is in the arena the sonar has heard
        clear (its log-odds at or below a silent reading's step), or lies within the planner's
        margin of an obstacle (known, or believed occupied: the inside and the far side of a box
        no sonar sees, and no path goes), and the path itself keeps out of those margins. Ground
        no sweep has looked at is not seen."""
        sonar = self.sonar
        seen = self.grid.inflated | (sonar.logodds <= sonar.model.free_logodds)
        res = sonar.resolution_m
        k = int(math.ceil(corridor_m / res))
        pts = _along(path, res / 2)
        if not all(self.grid.is_free(x, y) for x, y in pts):
            return False  # a squeeze through the planner's margins (the open map, the radius alone)
        for x, y in pts:
            c0, c1 = max(int(x / res) - k, 0), min(int(x / res) + k + 1, sonar.nx)
            r0, r1 = max(int(y / res) - k, 0), min(int(y / res) + k + 1, sonar.ny)
            if c0 >= c1 or r0 >= r1:
                continue
            near = np.hypot(sonar.xs[c0:c1][None, :] - x, sonar.ys[r0:r1][:, None] - y) <= corridor_m
            if (near & ~seen[r0:r1, c0:c1]).any():
                return False
        return True

    # ------------------------------------------------------------ files

    def to_json(self) -> dict:
        return {
            "format": MAP_FORMAT,
            "version": MAP_VERSION,
            "readings": [dataclasses.asdict(r) for r in self.sonar.readings],
        }

    def save(self, path: str | Path) -> None:
        """Write the map (atomically: a reader never sees half a file)."""
        write_atomic(Path(path), json.dumps(self.to_json(), indent=1, allow_nan=False) + "\n")

    def load(self, path: str | Path) -> int:
        """Replay a saved map's readings; returns how many. MapFileError (naming the file, the entry
        and the key) for anything that is not a valid map of this arena; nothing is replayed then."""
        return self.replay(read_map_file(path, self.grid))

    def replay(self, readings: list[SonarReading]) -> int:
        """Fold readings in (e.g. those read_map_file returned); returns how many."""
        for r in readings:
            self.sonar.update(r)
            self.open_sonar.update(r)
        self._apply()
        return len(readings)


def _along(path, step_m: float) -> list[tuple[float, float]]:
    """Points along a polyline, at most step_m apart, its ends included."""
    out = [(float(path[0][0]), float(path[0][1]))]
    for a, b in zip(path, path[1:]):
        n = max(1, int(math.ceil(math.dist(a, b) / step_m)))
        out += [(a[0] + (b[0] - a[0]) * i / n, a[1] + (b[1] - a[1]) * i / n) for i in range(1, n + 1)]
    return out


def _shown(path: str | Path) -> str:
    """The file's name for a one-line message (control characters escaped)."""
    text = str(path)
    return repr(text) if any(ord(c) < 32 or ord(c) == 127 for c in text) else text


def _short(value: object) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def check_map_path(path: str | Path) -> Path:
    """A map file the run may write at its end: not blank, not a folder or a device, in a folder
    that exists and can be written to. MapFileError otherwise (checked before a run starts,
    so it does not fail at its end)."""
    text = str(path)
    if not text.strip():
        raise MapFileError("an empty map file name")
    path = Path(path)
    name = _shown(path)
    if path.is_dir() or text.endswith(("/", "\\")):
        raise MapFileError(f"{name}: is a folder, not a map file")
    if path.exists() and not path.is_file():
        raise MapFileError(f"{name}: not a regular file, so no map can be saved there")
    folder = path.parent
    if not folder.is_dir():
        raise MapFileError(f"{name}: no folder {_shown(folder)} to save the learned map in")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise MapFileError(
            f"{name}: the folder {_shown(folder)} cannot be written to, so the learned map could not be saved"
        )
    return path


def _read_bounded(path: Path, name: str) -> str:
    """The text of a regular UTF-8 file of at most MAX_MAP_BYTES (size checked before reading)."""

    def cannot(exc: Exception) -> MapFileError:
        if isinstance(exc, FileNotFoundError):
            return MapFileError(f"{name}: no such map file")
        if isinstance(exc, IsADirectoryError):
            return MapFileError(f"{name}: is a folder, not a map file")
        # ValueError: a NUL in the name
        return MapFileError(f"{name}: cannot read the map file: {getattr(exc, 'strerror', None) or exc}")

    try:
        st = os.stat(path)
    except (OSError, ValueError) as exc:
        raise cannot(exc) from None
    if stat.S_ISDIR(st.st_mode):
        raise MapFileError(f"{name}: is a folder, not a map file")
    if not stat.S_ISREG(st.st_mode):
        raise MapFileError(f"{name}: not a regular file (a device or a pipe), so not a map file")
    if st.st_size > MAX_MAP_BYTES:
        raise MapFileError(
            f"{name}: {st.st_size:,} bytes; a map file is at most {MAX_MAP_BYTES:,} ({MAX_MAP_READINGS:,} readings)"
        )
    try:
        with open(path, "rb") as f:
            data = f.read(MAX_MAP_BYTES + 1)
    except (OSError, ValueError) as exc:
        raise cannot(exc) from None
    if len(data) > MAX_MAP_BYTES:  # it grew while we looked
        raise MapFileError(f"{name}: more than {MAX_MAP_BYTES:,} bytes; a map file is at most that")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise MapFileError(f"{name}: not a UTF-8 text file (byte {exc.start}), so not a map file") from None


def read_map_file(path: str | Path, grid: OccupancyGrid | None = None) -> list[SonarReading]:
    """The readings of a map file, validated (see the module docstring); with `grid`, also
    against the arena they will be replayed into. MapFileError, one line naming the file, the
    entry and the key, for anything else."""
    name = _shown(path)
    text = _read_bounded(Path(path), name)
    if not text.strip():
        raise MapFileError(f"{name}: is empty, not a rovernav map")
    try:
        data = json.loads(text)  # NaN and Infinity parse, and are refused below where they stand
    except RecursionError:
        raise MapFileError(f"{name}: not a rovernav map: JSON nested too deeply") from None
    except ValueError as exc:  # JSONDecodeError, or an integer of thousands of digits
        why = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        if "digits" in why and not isinstance(exc, json.JSONDecodeError):
            why = "a number with thousands of digits"
        raise MapFileError(f"{name}: not a rovernav map: not valid JSON ({why})") from None
    if not isinstance(data, dict) or data.get("format") != MAP_FORMAT:
        raise MapFileError(
            f'{name} is not a rovernav map (want a JSON object with "format": {MAP_FORMAT!r}, "version": 1 or 2)'
        )
    version = data.get("version")
    if isinstance(version, bool) or version not in (1, 2):
        raise MapFileError(f"{name}: a rovernav map of version {_short(version)}; this rovernav reads versions 1 and 2")
    key = "echoes" if version == 1 else "readings"
    extra = sorted(str(k) for k in data if k not in ("format", "version", key))
    if extra:
        raise MapFileError(
            f"{name}: unknown key{'s' if len(extra) > 1 else ''} "
            f"{', '.join(_short(k) for k in extra[:5])} in a version {version} map "
            f"(it has format, version and {key})"
        )
    if key not in data:
        raise MapFileError(f"{name}: no {key!r} list in a version {version} map")
    raw = data[key]
    if not isinstance(raw, list):
        raise MapFileError(f"{name}: {key!r} must be a list, got {type(raw).__name__}")
    if len(raw) > MAX_MAP_READINGS:
        raise MapFileError(f"{name}: {len(raw):,} {key}; at most {MAX_MAP_READINGS:,} are read")
    if grid is not None:
        cells = int(grid.raw.size)
        if len(raw) * cells > MAX_REPLAY_CELLS:
            raise MapFileError(
                f"{name}: {len(raw):,} {key} on a grid of {cells:,} cells is more replay work than "
                f"allowed; at most {MAX_REPLAY_CELLS // cells:,} on this arena"
            )
    names = [f.name for f in dataclasses.fields(SonarReading)]
    wanted = names if version == 2 else names[:5]
    out = []
    for i, e in enumerate(raw):
        where = f"{name}: {key}[{i}]"
        if not isinstance(e, dict):
            raise MapFileError(f"{where} must be an object with the keys {', '.join(wanted)}, got {type(e).__name__}")
        if sorted(e) != sorted(wanted):
            raise MapFileError(f"{where} must have exactly the keys {', '.join(wanted)}")
        v: dict[str, float | None] = {}
        for k in wanted:
            value = e[k]
            if k == "range_m" and value is None and version == 2:
                v[k] = None
                continue
            try:
                if isinstance(value, bool) or not isinstance(value, (int, float)):
                    raise TypeError
                number = float(value)
            except (TypeError, OverflowError):
                number = math.nan
            if not math.isfinite(number):
                raise MapFileError(f"{where}.{k} must be a finite number, got {_short(value)}")
            v[k] = number
        if version == 1:
            v["max_range_m"], v["sd_m"] = 0.4, 0.0
        for k in ("x_m", "y_m"):
            if abs(v[k]) > MAX_POSITION_M:  # type: ignore[arg-type]
                raise MapFileError(f"{where}.{k} must be within +-{MAX_POSITION_M} m, got {_short(e[k])}")
        for k in ("heading_deg", "bearing_deg"):
            if abs(v[k]) > MAX_ANGLE_DEG:  # type: ignore[arg-type]
                raise MapFileError(f"{where}.{k} must be within +-{MAX_ANGLE_DEG:g} degrees, got {_short(e[k])}")
        if v["range_m"] is not None and not 0 < v["range_m"] <= MAX_RANGE_M:
            raise MapFileError(f"{where}.range_m must be in (0, {MAX_RANGE_M:g}] m or null, got {_short(e['range_m'])}")
        if not 0 < v["max_range_m"] <= MAX_RANGE_M:  # type: ignore[operator]
            raise MapFileError(f"{where}.max_range_m must be in (0, {MAX_RANGE_M:g}] m, got {_short(e['max_range_m'])}")
        if not 0 <= v["sd_m"] <= MAX_SD_M:  # type: ignore[operator]
            raise MapFileError(f"{where}.sd_m must be in [0, {MAX_SD_M}] m, got {_short(e['sd_m'])}")
        if grid is not None:
            x, y = v["x_m"], v["y_m"]
            if not (
                -ARENA_MARGIN_M <= x <= grid.width_m + ARENA_MARGIN_M  # type: ignore[operator]
                and -ARENA_MARGIN_M <= y <= grid.height_m + ARENA_MARGIN_M
            ):  # type: ignore[operator]
                raise MapFileError(
                    f"{where}: the rover at ({x:g}, {y:g}) m is more than {ARENA_MARGIN_M:g} m outside "
                    f"the {grid.width_m:g} x {grid.height_m:g} m arena: a map of another arena?"
                )
        out.append(SonarReading(**v))  # type: ignore[arg-type]
    return out
