"""Scenario files: the arena, the start, the target, the mission and the obstacles (TOML, version 1).

    name = "seed-small-obstacles"     # optional; defaults to the file's stem
    version = 1                       # required; only 1 is understood
    description = "..."               # optional
    [arena]     width_m, height_m                     (> 0)
    [start]     x_m, y_m, heading_deg = 0             (on the arena; 0° = +y, clockwise positive)
    [target]    x_m, y_m                              (on the arena)
    [mission]   kind = "reach" | "out-and-back", trips = 1   (optional table; trips ≥ 1)
    [[obstacles]]  x_m, y_m (centre), w_m, h_m (size > 0), known = true      (axis-aligned boxes)
    [[walls]]      x0_m, y0_m, x1_m, y1_m (the centre line's ends, apart), thickness_m (> 0),
                   known = true                                               (optional)
    [[posts]]      x_m, y_m (centre), radius_m (> 0), known = true            (optional)
    [[starts]]     x_m, y_m, heading_deg = 0: a fleet's more starts (rovers 2, 3, ...; rover 1
                   starts at [start]); optional, apart from each other by a body's diagonal
    [[sites]]      x_m, y_m: a fleet's more sites (rover k shuttles between its start and site
                   k of [target] and these, in turn); optional
    [generated]    optional: how `rovernav arenas` made the file (see below)

Metres and degrees; origin at the arena's bottom-left corner, x right, y up. `known = false`
obstacles exist only in the world: the planner learns them through the sonar. Every problem
raises `ScenarioError` (a ValueError) naming the file and the key, e.g.
"seed.toml: obstacles[2].w_m must be a number > 0, got -0.1". Unknown keys are refused, so
a misspelt key cannot be silently ignored. As for boxes, nothing requires a wall or a post to lie
on the arena (the part off it is simply outside the arena's wall).

A wall is the rectangle swept by its thickness across the segment from (x0_m, y0_m) to
(x1_m, y1_m): `thickness_m` wide, centred on the segment, with square ends flush with the end
points (a wall drawn from the arena's edge starts at the edge; where two walls meet in an L,
extend one by half the thickness to close the outer corner). A post is a round pillar (a
disk in plan). Boxes, walls and posts are all obstacles: `Scenario.shapes` lists every one.

A generated arena (rovernav.evaluation.arenas) carries its labels; none of them changes the mission:

    [generated]   family (text), seed (whole ≥ 0), index (whole ≥ 0), solvable (true/false),
                  passage_width_m (optional, > 0: the narrow_passage family's gap)
    [generated.difficulty]   closest_obstacle_m, mean_clearance_m, dispersion,
                  characteristic_dimension_m, narrowest_dimension_m (numbers ≥ 0), score (0 to 1), band ("easy",
                  "medium" or "hard"); optional: optimal_length_m, detour_ratio (numbers ≥ 0),
                  known_path_blocked (true/false)

It is exposed as `Scenario.generated`, a plain dict of the same keys (None without the table).

The shared scenarios live in `../shared/scenarios/` beside the repository (override with the
environment variable ROVERNAV_SCENARIO_DIR); `load_scenario` takes their name or any path.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import tomllib
from pathlib import Path
from typing import Any, ClassVar

from .errors import InputError
from .scenario_reader import DIFFICULTY_BANDS, ScenarioError, _generated, _Reader  # noqa: F401  (re-exported)
from .validate import MAX_ARENA_M, MAX_TRIPS, read_text_file, show
from .vehicle_gen import BODY_LENGTH_MM, BODY_WIDTH_MM

FORMAT_VERSION = 1
MISSION_KINDS = ("reach", "out-and-back")
DEFAULT_SCENARIO = "out-and-back"


# A shape's centre or a wall's end may sit this far outside the arena (a wall along its edge).
_EDGE_M = 0.05
# Two starts nearer than a body's diagonal would let two rovers touch, whatever their headings.
START_SPACING_M = math.hypot(BODY_LENGTH_MM, BODY_WIDTH_MM) / 1000.0


@dataclasses.dataclass(frozen=True)
class Arena:
    width_m: float
    height_m: float


@dataclasses.dataclass(frozen=True)
class Pose:
    x_m: float
    y_m: float
    heading_deg: float = 0.0

    @property
    def xy(self) -> tuple[float, float]:
        return (self.x_m, self.y_m)


@dataclasses.dataclass(frozen=True)
class Target:
    x_m: float
    y_m: float

    @property
    def xy(self) -> tuple[float, float]:
        return (self.x_m, self.y_m)


@dataclasses.dataclass(frozen=True)
class Mission:
    kind: str = "reach"
    trips: int = 1


@dataclasses.dataclass(frozen=True)
class Obstacle:
    """An axis-aligned box: centre (x_m, y_m), size (w_m, h_m)."""

    x_m: float
    y_m: float
    w_m: float
    h_m: float
    known: bool = True

    kind: ClassVar[str] = "box"

    def distance_m(self, x_m: float, y_m: float) -> float:
        """Distance from the point to the box (0 inside it)."""
        return math.hypot(max(abs(x_m - self.x_m) - self.w_m / 2, 0.0), max(abs(y_m - self.y_m) - self.h_m / 2, 0.0))

    def describe(self) -> str:
        return f"box at ({self.x_m:.2f}, {self.y_m:.2f}) m, {self.w_m:.2f} x {self.h_m:.2f} m"


@dataclasses.dataclass(frozen=True)
class Wall:
    """A straight wall: the rectangle `thickness_m` wide centred on the segment from (x0_m, y0_m)
    to (x1_m, y1_m), its ends square and flush with those points."""

    x0_m: float
    y0_m: float
    x1_m: float
    y1_m: float
    thickness_m: float
    known: bool = True

    kind: ClassVar[str] = "wall"

    @property
    def length_m(self) -> float:
        return math.hypot(self.x1_m - self.x0_m, self.y1_m - self.y0_m)

    @property
    def axis_aligned(self) -> bool:
        """Whether the wall runs along x or y (it is then an axis-aligned box)."""
        return self.x0_m == self.x1_m or self.y0_m == self.y1_m

    def frame(self) -> tuple[float, float, float, float, float, float]:
        """(centre x, centre y, unit vector along x, y, half length, half thickness) [m]."""
        length = self.length_m
        ux, uy = (self.x1_m - self.x0_m) / length, (self.y1_m - self.y0_m) / length
        return ((self.x0_m + self.x1_m) / 2, (self.y0_m + self.y1_m) / 2, ux, uy, length / 2, self.thickness_m / 2)

    def corners(self) -> tuple[tuple[float, float], ...]:
        """The rectangle's 4 corners [m], in order round it."""
        cx, cy, ux, uy, a, b = self.frame()
        return tuple(
            (cx + s * a * ux - t * b * uy, cy + s * a * uy + t * b * ux)
            for s, t in ((1, 1), (1, -1), (-1, -1), (-1, 1))
        )

    def distance_m(self, x_m: float, y_m: float) -> float:
        """Distance from the point to the wall's rectangle (0 inside it)."""
        cx, cy, ux, uy, a, b = self.frame()
        dx, dy = x_m - cx, y_m - cy
        along, across = dx * ux + dy * uy, -dx * uy + dy * ux
        return math.hypot(max(abs(along) - a, 0.0), max(abs(across) - b, 0.0))

    def describe(self) -> str:
        return (
            f"from ({self.x0_m:.2f}, {self.y0_m:.2f}) to ({self.x1_m:.2f}, {self.y1_m:.2f}) m, "
            f"{self.thickness_m:.2f} m thick"
        )


@dataclasses.dataclass(frozen=True)
class Post:
    """A round post (a pillar, a table leg): centre (x_m, y_m), radius_m."""

    x_m: float
    y_m: float
    radius_m: float
    known: bool = True

    kind: ClassVar[str] = "post"

    def distance_m(self, x_m: float, y_m: float) -> float:
        """Distance from the point to the post (0 inside it)."""
        return max(math.hypot(x_m - self.x_m, y_m - self.y_m) - self.radius_m, 0.0)

    def describe(self) -> str:
        return f"at ({self.x_m:.2f}, {self.y_m:.2f}) m, radius {self.radius_m:.3f} m"


Shape = Obstacle | Wall | Post


@dataclasses.dataclass(frozen=True)
class Scenario:
    name: str
    arena: Arena
    start: Pose
    target: Target
    mission: Mission
    obstacles: tuple[Obstacle, ...]
    description: str = ""
    version: int = FORMAT_VERSION
    path: Path | None = None
    walls: tuple[Wall, ...] = ()
    posts: tuple[Post, ...] = ()
    # The [generated] table of a generated arena, else None (a dict: left out of the hash).
    generated: dict | None = dataclasses.field(default=None, hash=False)
    more_starts: tuple[Pose, ...] = ()  # [[starts]]: a fleet's rovers 2, 3, ...
    more_sites: tuple[Target, ...] = ()  # [[sites]]

    @property
    def starts(self) -> tuple[Pose, ...]:
        """Every rover's start: [start] (rover 1), then [[starts]]."""
        return (self.start, *self.more_starts)

    @property
    def sites(self) -> tuple[Target, ...]:
        """Every site: [target], then [[sites]]."""
        return (self.target, *self.more_sites)

    def fleet_legs(self, rovers: int) -> list[tuple[tuple[float, float], tuple[float, float]]]:
        """Each rover's (start, site) for a fleet of `rovers`: rover k starts at starts[k - 1] and
        shuttles to sites[(k - 1) % len(sites)]. ScenarioError (one line) when the scenario names
        fewer starts than rovers."""
        starts = self.starts
        if not 1 <= rovers <= len(starts):
            where = self.path or self.name
            raise ScenarioError(
                f"{where}: {rovers} rovers but the scenario names {len(starts)} start"
                f"{'s' if len(starts) != 1 else ''} ([start] and [[starts]]): one a rover"
            )
        sites = self.sites
        return [(starts[k].xy, sites[k % len(sites)].xy) for k in range(rovers)]

    @property
    def known_obstacles(self) -> tuple[Obstacle, ...]:
        return tuple(o for o in self.obstacles if o.known)

    @property
    def unknown_obstacles(self) -> tuple[Obstacle, ...]:
        return tuple(o for o in self.obstacles if not o.known)

    @property
    def shapes(self) -> tuple[Shape, ...]:
        """Every obstacle of every kind: the boxes, then the walls, then the posts (each has
        `kind`, `known`, `distance_m(x, y)` and `describe()`)."""
        return (*self.obstacles, *self.walls, *self.posts)

    @property
    def known_shapes(self) -> tuple[Shape, ...]:
        return tuple(o for o in self.shapes if o.known)

    @property
    def unknown_shapes(self) -> tuple[Shape, ...]:
        return tuple(o for o in self.shapes if not o.known)


# --- finding scenarios -----------------------------------------------------------------------

REPO_SCENARIOS = Path(__file__).resolve().parents[2] / "scenarios"
SHARED_SCENARIOS = Path(__file__).resolve().parents[3] / "shared" / "scenarios"


def scenario_dir() -> Path:
    """The scenarios: $ROVERNAV_SCENARIO_DIR, else the repository's scenarios/ folder.

    scenarios/ holds copies of the team's shared arenas (../shared/scenarios), so that a fresh
    clone has them; tests/test_scenario.py fails if the copies drift from the shared originals.
    """
    env = os.environ.get("ROVERNAV_SCENARIO_DIR")
    if env:
        return Path(env)
    return REPO_SCENARIOS


def scenario_names() -> list[str]:
    """Names of the shared scenarios (their file stems), sorted."""
    d = scenario_dir()
    return sorted(p.stem for p in d.glob("*.toml")) if d.is_dir() else []


def resolve_scenario(name_or_path: str | os.PathLike[str]) -> Path:
    """The file for a shared scenario's name, or the given path when it names a file."""
    candidate = Path(name_or_path)
    try:
        if candidate.exists() and not candidate.is_dir():
            return candidate  # a file, or a device or pipe that read_text_file refuses by name
    except (OSError, ValueError) as exc:
        raise ScenarioError(f"{show(candidate)}: {getattr(exc, 'strerror', None) or exc}") from None
    text = str(name_or_path)
    if candidate.suffix != ".toml" and "/" not in text and os.sep not in text:
        shared = scenario_dir() / f"{text}.toml"
        if shared.is_file():
            return shared
        names = ", ".join(scenario_names()) or f"none found in {scenario_dir()}"
        raise ScenarioError(f"no scenario named {text!r} (shared scenarios: {names})")
    raise ScenarioError(f"{text}: no such scenario file")


def load_scenario(name_or_path: str | os.PathLike[str]) -> Scenario:
    """Load and validate a scenario by shared name or path."""
    path = resolve_scenario(name_or_path)
    try:
        text = read_text_file(path, "scenario file")
    except InputError as exc:
        raise ScenarioError(str(exc)) from None
    if len(text) > 10_000_000:
        raise ScenarioError(f"{path}: {len(text):,} characters is not a scenario file (the limit is 10,000,000)")
    return parse_scenario(text, source=path)


def default_scenario() -> Scenario:
    """The research aim's scenario: out to the target and back to base, twice."""
    return load_scenario(DEFAULT_SCENARIO)


# --- parsing -------------------------------------------------------------------------------


def parse_scenario(text: str, source: str | os.PathLike[str] = "<scenario>") -> Scenario:
    """Parse scenario TOML text; `source` (a path or label) starts every error message."""
    r = _Reader(str(source))
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{source}: not valid TOML: {exc}") from exc
    r.only(
        doc,
        "",
        (
            "name",
            "version",
            "description",
            "arena",
            "start",
            "target",
            "mission",
            "obstacles",
            "walls",
            "posts",
            "starts",
            "sites",
            "generated",
        ),
    )

    if "version" not in doc:
        raise r.fail("version", f"is missing (this reader understands version {FORMAT_VERSION})")
    version = doc["version"]
    if isinstance(version, bool) or version != FORMAT_VERSION:
        raise r.fail("version", f"is {version!r}; this reader understands version {FORMAT_VERSION}")
    name = doc.get("name", Path(str(source)).stem)
    if not isinstance(name, str) or not name:
        raise r.fail("name", f"must be a non-empty string, got {name!r}")
    description = doc.get("description", "")
    if not isinstance(description, str):
        raise r.fail("description", f"must be a string, got {description!r}")

    arena_t = r.table(doc, "arena")
    r.only(arena_t, "arena.", ("width_m", "height_m"))
    arena = Arena(
        r.number(arena_t, "arena.", "width_m", positive=True), r.number(arena_t, "arena.", "height_m", positive=True)
    )
    for key, side in (("width_m", arena.width_m), ("height_m", arena.height_m)):
        if side > MAX_ARENA_M:
            raise r.fail(f"arena.{key}", f"= {side:g} m: an arena's side is at most {MAX_ARENA_M:g} m")

    def on_arena(table: dict[str, Any], prefix: str) -> tuple[float, float]:
        x = r.number(table, prefix, "x_m")
        y = r.number(table, prefix, "y_m")
        if not 0.0 <= x <= arena.width_m:
            raise r.fail(f"{prefix}x_m", f"= {x} is outside the arena (0 to {arena.width_m} m)")
        if not 0.0 <= y <= arena.height_m:
            raise r.fail(f"{prefix}y_m", f"= {y} is outside the arena (0 to {arena.height_m} m)")
        return x, y

    start_t = r.table(doc, "start")
    r.only(start_t, "start.", ("x_m", "y_m", "heading_deg"))
    start = Pose(*on_arena(start_t, "start."), r.number(start_t, "start.", "heading_deg", default=0.0))

    target_t = r.table(doc, "target")
    r.only(target_t, "target.", ("x_m", "y_m"))
    target = Target(*on_arena(target_t, "target."))

    mission_t = r.table(doc, "mission", required=False)
    r.only(mission_t, "mission.", ("kind", "trips"))
    kind = mission_t.get("kind", "reach")
    if kind not in MISSION_KINDS:
        raise r.fail("mission.kind", f"must be one of {', '.join(MISSION_KINDS)}, got {kind!r}")
    trips = mission_t.get("trips", 1)
    if isinstance(trips, bool) or not isinstance(trips, int) or not 1 <= trips <= MAX_TRIPS:
        raise r.fail("mission.trips", f"must be a whole number from 1 to {MAX_TRIPS}, got {trips!r}")
    mission = Mission(kind, trips)

    obstacles = []
    for prefix, o, known in r.array(doc, "obstacles", ("x_m", "y_m", "w_m", "h_m", "known")):
        obstacles.append(
            Obstacle(
                r.number(o, prefix, "x_m"),
                r.number(o, prefix, "y_m"),
                r.number(o, prefix, "w_m", positive=True),
                r.number(o, prefix, "h_m", positive=True),
                known,
            )
        )
    walls = []
    for prefix, o, known in r.array(doc, "walls", ("x0_m", "y0_m", "x1_m", "y1_m", "thickness_m", "known")):
        wall = Wall(
            *(r.number(o, prefix, k) for k in ("x0_m", "y0_m", "x1_m", "y1_m")),
            r.number(o, prefix, "thickness_m", positive=True),
            known,
        )
        if not wall.length_m > 0:
            raise r.fail(
                prefix[:-1],
                f"has no length: both ends at ({wall.x0_m}, {wall.y0_m}) (x0_m, y0_m and x1_m, y1_m must differ)",
            )
        walls.append(wall)
    posts = []
    for prefix, o, known in r.array(doc, "posts", ("x_m", "y_m", "radius_m", "known")):
        posts.append(
            Post(
                r.number(o, prefix, "x_m"),
                r.number(o, prefix, "y_m"),
                r.number(o, prefix, "radius_m", positive=True),
                known,
            )
        )

    more_starts = []
    for prefix, o, _known in r.array(doc, "starts", ("x_m", "y_m", "heading_deg")):
        more_starts.append(Pose(*on_arena(o, prefix), r.number(o, prefix, "heading_deg", default=0.0)))
    more_sites = []
    for prefix, o, _known in r.array(doc, "sites", ("x_m", "y_m")):
        more_sites.append(Target(*on_arena(o, prefix)))
    # Two rovers cannot stand where their bodies would touch, whatever their headings.
    starts_named = [("start", start)] + [(f"starts[{i}]", p) for i, p in enumerate(more_starts)]
    for i, (a_name, a) in enumerate(starts_named):
        for b_name, b in starts_named[:i]:
            gap = math.hypot(a.x_m - b.x_m, a.y_m - b.y_m)
            if gap < START_SPACING_M:
                raise r.fail(
                    a_name,
                    f"({a.x_m:g}, {a.y_m:g}) m overlaps {b_name} ({b.x_m:g}, {b.y_m:g}) m: two rovers' starts must "
                    f"be {START_SPACING_M:.2f} m apart at least (a body's diagonal), got {gap:.2f} m",
                )

    # Every shape on the arena (its centre, a wall's ends); the start and the target in the open.
    def within(prefix: str, points) -> None:
        for x, y in points:
            if not (-_EDGE_M <= x <= arena.width_m + _EDGE_M and -_EDGE_M <= y <= arena.height_m + _EDGE_M):
                raise r.fail(
                    prefix,
                    f"lies outside the arena ({x:g}, {y:g} m; the arena is {arena.width_m:g} x {arena.height_m:g} m)",
                )

    for i, o in enumerate(obstacles):
        within(f"obstacles[{i}]", [(o.x_m, o.y_m)])
    for i, w in enumerate(walls):
        within(f"walls[{i}]", [(w.x0_m, w.y0_m), (w.x1_m, w.y1_m)])
    for i, p in enumerate(posts):
        within(f"posts[{i}]", [(p.x_m, p.y_m)])
    places = [("start", (start.x_m, start.y_m)), ("target", (target.x_m, target.y_m))]
    places += [(f"starts[{i}]", p.xy) for i, p in enumerate(more_starts)]
    places += [(f"sites[{i}]", p.xy) for i, p in enumerate(more_sites)]
    for what, (x, y) in places:
        for kind, shapes in (("obstacles", obstacles), ("walls", walls), ("posts", posts)):
            for i, shape in enumerate(shapes):
                if shape.distance_m(x, y) <= 0.0:
                    raise r.fail(what, f"({x:g}, {y:g}) m is inside {kind}[{i}] ({shape.describe()})")

    generated = _generated(r, doc) if "generated" in doc else None

    path = Path(source) if not str(source).startswith("<") else None
    return Scenario(
        name=name,
        arena=arena,
        start=start,
        target=target,
        mission=mission,
        obstacles=tuple(obstacles),
        description=description,
        version=version,
        path=path,
        walls=tuple(walls),
        posts=tuple(posts),
        generated=generated,
        more_starts=tuple(more_starts),
        more_sites=tuple(more_sites),
    )


def scenario_toml(scenario: Scenario) -> str:
    """The scenario as a version-1 file: `parse_scenario` of it gives the same Scenario (every
    number written exactly, the [generated] table and the path left out). A run log keeps this."""

    def num(v: float) -> str:
        return repr(float(v))

    def text(s: str) -> str:
        return json.dumps(s, ensure_ascii=False)  # a TOML basic string is a JSON string

    lines = [f"name = {text(scenario.name)}", f"version = {FORMAT_VERSION}"]
    if scenario.description:
        lines.append(f"description = {text(scenario.description)}")
    a, s, t, m = scenario.arena, scenario.start, scenario.target, scenario.mission
    lines += [
        "",
        "[arena]",
        f"width_m = {num(a.width_m)}",
        f"height_m = {num(a.height_m)}",
        "",
        "[start]",
        f"x_m = {num(s.x_m)}",
        f"y_m = {num(s.y_m)}",
        f"heading_deg = {num(s.heading_deg)}",
        "",
        "[target]",
        f"x_m = {num(t.x_m)}",
        f"y_m = {num(t.y_m)}",
        "",
        "[mission]",
        f"kind = {text(m.kind)}",
        f"trips = {int(m.trips)}",
    ]
    for key, shapes in (("obstacles", scenario.obstacles), ("walls", scenario.walls), ("posts", scenario.posts)):
        for shape in shapes:
            lines += ["", f"[[{key}]]"]
            for f in dataclasses.fields(shape):
                value = getattr(shape, f.name)
                lines.append(f"{f.name} = {('true' if value else 'false') if isinstance(value, bool) else num(value)}")
    for p in scenario.more_starts:
        lines += ["", "[[starts]]", f"x_m = {num(p.x_m)}", f"y_m = {num(p.y_m)}", f"heading_deg = {num(p.heading_deg)}"]
    for p in scenario.more_sites:
        lines += ["", "[[sites]]", f"x_m = {num(p.x_m)}", f"y_m = {num(p.y_m)}"]
    return "\n".join(lines) + "\n"
