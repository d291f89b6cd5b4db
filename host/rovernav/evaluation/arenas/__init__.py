"""`rovernav arenas`: scenario files drawn from families of arenas that real rooms and the seed's
tests contain, each labelled with its family, a difficulty and whether it can be solved.

    arenas = generate_arenas(200, seed=1)              # list[GeneratedArena], the families cycled
    write_arenas(arenas, Path("out/arenas"))           # arena-0001-scattered.toml ... index.json, index.csv
    write_gallery(arenas[:12], Path("out/arenas/gallery.png"))

Every file is an ordinary scenario (rovernav.scenario, TOML version 1) with an extra
[generated] table: family, seed, index, solvable, the narrow_passage family's passage_width_m,
and [generated.difficulty] (the metrics below, a score and a band).

Families: FAMILIES holds (name, one-line description) pairs, defined with their draw functions in
`_FAMILY_LIST` (`rovernav arenas --help` prints them). Arena i, counted from 1, is of family
number (i − 1) mod F of the F families asked for, so any count ≥ F covers all of them.

Geometry
    Arenas are 2.0-3.0 m × 1.5-2.2 m (the seed's is 2.36 × 1.75 m), so that missions stay as
    short as the seed's. Obstacles: axis-aligned boxes (the seed's box sizes, blocks up to
    0.25 m), walls ([[walls]]: dividers, corridor walls, traps and enclosures, 0.04-0.06 m thick,
    the traps' also 0.1 or 0.2 m; along x or y, but for wall_gap's door leaf, open at 70-90°) and
    round posts ([[posts]], 0.05-0.10 m across, in the clutter family). Every length that depends on the rover
    comes from PlannerConfig: the planner keeps the rover's centre `inflation_m` (robot radius +
    sonar margin, 0.17 m) from obstacles and walls, so a passage up to 2 × inflation_m wide is
    closed, and one up to a cell (0.03 m) wider is open or closed depending on where the cell
    centres fall.
    Each family is drawn in one frame (start on the left, target on the right) and then mirrored
    left-right and/or top-bottom at random. Lengths are drawn on a millimetre grid.

Constraints, checked on the scenario as parsed back from its own text
    every box, wall and post lies on the arena; start and target are free on the grid of every obstacle
    (OccupancyGrid.from_scenario(..., all_obstacles=True).is_free); `solvable` is whether
    `plan` (A*, default PlannerConfig) finds a path with every obstacle known; the unreachable
    family must be unsolvable because obstacles enclose the target (plan raises Unreachable with
    both ends free), the narrow_passage family may be either, every other family must be
    solvable. A draw that breaks a constraint is drawn again from the same stream, up to
    MAX_TRIES times, then GenerationFailed.

Difficulty metrics ([generated.difficulty]), in the spirit of BARN (Perille et al., 2020)
    The path is the clairvoyant optimum: A*'s simplified waypoints with every obstacle known,
    sampled every grid cell (0.03 m) with both ends included; for an unsolvable arena, the
    straight segment from start to target. Distances are exact, to the boxes, walls, posts and the
    arena's wall.
    closest_obstacle_m          the smallest distance from a path point to an obstacle or the wall
    mean_clearance_m            the mean of that distance over the path points
    dispersion                  from each path point, 16 rays (every 22.5°) of RAY_LENGTH_M,
                                sampled every RAY_STEP_M: the number of switches between free and
                                occupied (inside an obstacle) along them, summed over the rays, averaged
                                over the path points; a ray ends at the arena's wall, which is not
                                counted (open floor: 0; a ray across a thin wall: 2)
    characteristic_dimension_m  from each path point, the free length of the 8 lines through it
                                (the two opposite rays to the first obstacle or wall, each capped at
                                RAY_LENGTH_M); the shortest of the 8 is the width of the space the
                                point stands in; averaged over the path points
    narrowest_dimension_m       the smallest of those widths along the path: the tightest place it
                                passes (about a passage's width; 0 when unsolvable)
    optimal_length_m            the optimum's length (absent when unsolvable)
    detour_ratio                optimal_length_m / straight distance start-target (absent when
                                unsolvable; 1 when they are under a millimetre apart)
    known_path_blocked          the path A* plans on the known obstacles alone enters a cell the
                                grid of every obstacle inflates: the rover must find an unknown
                                obstacle with its sonar and replan (false when the known obstacles
                                alone already leave no path)
    score = 0.15 narrow + 0.15 pinch + 0.10 tight + 0.15 clutter + 0.25 detour + 0.20 surprise
        (SCORE_WEIGHTS), each term in [0, 1], higher is harder:
        narrow  = clip((CD_OPEN_M − characteristic_dimension_m) / (CD_OPEN_M − 2 inflation), 0, 1)
        pinch   = clip((PINCH_OPEN_M − narrowest_dimension_m) / (PINCH_OPEN_M − 2 inflation), 0, 1)
        tight   = clip((CLEARANCE_OPEN_M − mean_clearance_m) / (CLEARANCE_OPEN_M − inflation), 0, 1)
        clutter = clip(dispersion / DISPERSION_DENSE, 0, 1)
        detour  = clip((detour_ratio − 1) / DETOUR_LONG, 0, 1), 1 when unsolvable
        surprise = 1 when known_path_blocked, else 0
    band: "easy" below BAND_MEDIUM (0.45), "hard" from BAND_HARD (0.65), "medium" between: over the
        600 arenas of seeds 1-3, about a third in each. A score compares arenas; it predicts no
        particular outcome (start_at_target is nearly always easy, trap_u and unreachable hard).

Determinism
    Arena i draws from numpy's PCG64 seeded with SeedSequence([seed, i]): the same seed, index
    and family give the same text byte for byte, whatever the count; another seed draws other
    arenas.

The package
    draw.py        what a family draws (boxes, walls, posts; the random choices of one draw), the errors
    families.py    the families and their table (FAMILIES, FAMILY_NAMES, ALL_FAMILY_NAMES)
    cellular.py    the cellular family (BARN's worlds)
    difficulty.py  the metrics, the score and the band (measure_scenario)
    generate.py    generate_arena(s), the scenario text, write_arenas, write_gallery
    cli.py         `rovernav arenas`
"""

from __future__ import annotations

from .cellular import (
    CELLULAR_BOXES,
    CELLULAR_CELL_M,
    CELLULAR_FIELDS,
    CELLULAR_FILL_RANGE,
    CELLULAR_HEIGHT_RANGE_M,
    CELLULAR_SMOOTHING,
    CELLULAR_WIDTH_RANGE_M,
)
from .cli import add_arenas_parser, cmd_arenas
from .difficulty import (
    BAND_HARD,
    BAND_MEDIUM,
    CD_OPEN_M,
    CLEARANCE_OPEN_M,
    DETOUR_LONG,
    DISPERSION_DENSE,
    PINCH_OPEN_M,
    RAY_COUNT,
    RAY_LENGTH_M,
    RAY_STEP_M,
    SCORE_WEIGHTS,
    ArenaMeasure,
    band_of,
    measure_scenario,
)
from .draw import (
    ARENA_HEIGHT_RANGE_M,
    ARENA_WIDTH_RANGE_M,
    END_MARGIN_M,
    KEEP_CLEAR_M,
    NARROW_EXTRA_M,
    POST_DIAMETERS_M,
    SEED_BOX_SIZES_M,
    START_AT_TARGET_RANGE_M,
    WALL_THICKNESS_RANGE_M,
    ArenaError,
    GenerationFailed,
)
from .families import ALL_FAMILY_NAMES, FAMILIES, FAMILY_NAMES
from .generate import (
    GALLERY_COUNT,
    INDEX_FIELDS,
    MAX_COUNT,
    MAX_TRIES,
    GeneratedArena,
    generate_arena,
    generate_arenas,
    index_row,
    write_arenas,
    write_gallery,
)

__all__ = [
    "ARENA_HEIGHT_RANGE_M",
    "ARENA_WIDTH_RANGE_M",
    "ArenaError",
    "END_MARGIN_M",
    "GenerationFailed",
    "KEEP_CLEAR_M",
    "NARROW_EXTRA_M",
    "POST_DIAMETERS_M",
    "SEED_BOX_SIZES_M",
    "START_AT_TARGET_RANGE_M",
    "WALL_THICKNESS_RANGE_M",
    "ALL_FAMILY_NAMES",
    "FAMILIES",
    "FAMILY_NAMES",
    "CELLULAR_BOXES",
    "CELLULAR_CELL_M",
    "CELLULAR_FIELDS",
    "CELLULAR_FILL_RANGE",
    "CELLULAR_HEIGHT_RANGE_M",
    "CELLULAR_SMOOTHING",
    "CELLULAR_WIDTH_RANGE_M",
    "ArenaMeasure",
    "BAND_HARD",
    "BAND_MEDIUM",
    "CD_OPEN_M",
    "CLEARANCE_OPEN_M",
    "DETOUR_LONG",
    "DISPERSION_DENSE",
    "PINCH_OPEN_M",
    "RAY_COUNT",
    "RAY_LENGTH_M",
    "RAY_STEP_M",
    "SCORE_WEIGHTS",
    "band_of",
    "measure_scenario",
    "GALLERY_COUNT",
    "GeneratedArena",
    "INDEX_FIELDS",
    "MAX_COUNT",
    "MAX_TRIES",
    "generate_arena",
    "generate_arenas",
    "index_row",
    "write_arenas",
    "write_gallery",
    "add_arenas_parser",
    "cmd_arenas",
]
