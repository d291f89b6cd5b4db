"""The arena generator: every family, deterministic files that load, labels that hold."""

from __future__ import annotations

import collections
import dataclasses
import json
import math

import numpy as np
import pytest

from rovernav.cli import main
from rovernav.evaluation.arenas import (
    ALL_FAMILY_NAMES,
    CELLULAR_CELL_M,
    FAMILIES,
    FAMILY_NAMES,
    NARROW_EXTRA_M,
    ArenaError,
    generate_arenas,
    measure_scenario,
    write_arenas,
)
from rovernav.planning import OccupancyGrid, PlannerConfig, Unreachable, plan
from rovernav.scenario import Arena, Mission, Obstacle, Pose, Scenario, Target, load_scenario, parse_scenario

INFLATION_M = PlannerConfig().inflation_m


@pytest.fixture(scope="module")
def arenas200():
    return generate_arenas(200, 1)


def of_family(arenas, family):
    chosen = [a for a in arenas if a.family == family]
    assert chosen, f"no {family} arena"
    return chosen


def test_200_arenas_of_seed_1_cover_every_family_evenly(arenas200):
    assert len(arenas200) == 200
    assert len(FAMILIES) == len(ALL_FAMILY_NAMES) > len(FAMILY_NAMES) >= 14
    counts = collections.Counter(a.family for a in arenas200)
    assert set(counts) == set(FAMILY_NAMES)  # by-name families (cellular) are not in the default cycle
    assert max(counts.values()) - min(counts.values()) <= 1
    assert [a.index for a in arenas200] == list(range(1, 201))
    assert {a.difficulty["band"] for a in arenas200} == {"easy", "medium", "hard"}


def test_the_same_seed_gives_the_same_text_and_another_seed_other_text(arenas200):
    again = generate_arenas(28, 1)
    assert [a.toml_text for a in again] == [a.toml_text for a in arenas200[:28]]
    other = generate_arenas(28, 2)
    assert all(a.toml_text != b.toml_text for a, b in zip(other, again))


def test_every_written_file_loads_and_keeps_its_labels(arenas200, tmp_path):
    paths = write_arenas(arenas200, tmp_path)
    assert [p.name for p in paths] == [f"arena-{i:04d}-{a.family}.toml" for i, a in enumerate(arenas200, 1)]
    for path, arena in zip(paths, arenas200):
        assert path.read_text(encoding="utf-8") == arena.toml_text
        loaded = load_scenario(path)
        assert loaded.name == path.stem
        assert loaded.generated == arena.scenario.generated
        g = loaded.generated
        assert (g["family"], g["seed"], g["index"], g["solvable"]) == (arena.family, 1, arena.index, arena.solvable)
        assert g["difficulty"] == arena.difficulty
        assert 0.0 <= g["difficulty"]["score"] <= 1.0
        assert loaded.obstacles == arena.scenario.obstacles
        assert loaded.start == arena.scenario.start and loaded.target == arena.scenario.target
        for o in loaded.obstacles:  # every box on the arena
            assert o.x_m - o.w_m / 2 >= -1e-9 and o.x_m + o.w_m / 2 <= loaded.arena.width_m + 1e-9
            assert o.y_m - o.h_m / 2 >= -1e-9 and o.y_m + o.h_m / 2 <= loaded.arena.height_m + 1e-9
        assert loaded.walls == arena.scenario.walls and loaded.posts == arena.scenario.posts
        for w in loaded.walls:  # every wall and post on the arena
            assert all(
                -1e-9 <= x <= loaded.arena.width_m + 1e-9 and -1e-9 <= y <= loaded.arena.height_m + 1e-9
                for x, y in w.corners()
            )
        for o in loaded.posts:
            assert o.radius_m - 1e-9 <= o.x_m <= loaded.arena.width_m - o.radius_m + 1e-9
            assert o.radius_m - 1e-9 <= o.y_m <= loaded.arena.height_m - o.radius_m + 1e-9
    rows = json.loads((tmp_path / "index.json").read_text())
    assert [r["file"] for r in rows] == [p.name for p in paths]
    assert [(r["family"], r["solvable"], r["band"], r["score"]) for r in rows] == [
        (a.family, a.solvable, a.difficulty["band"], a.difficulty["score"]) for a in arenas200
    ]
    csv_lines = (tmp_path / "index.csv").read_text().splitlines()
    assert len(csv_lines) == 201 and csv_lines[0].startswith("file,")
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")], "a temporary file was left behind"


def test_start_and_target_are_free_with_every_obstacle_known(arenas200):
    for a in arenas200:
        grid = OccupancyGrid.from_scenario(a.scenario, all_obstacles=True)
        assert grid.is_free(*a.scenario.start.xy), a.name
        assert grid.is_free(*a.scenario.target.xy), a.name


def test_solvable_is_what_an_independent_plan_says(arenas200):
    for a in arenas200:
        grid = OccupancyGrid.from_scenario(a.scenario, PlannerConfig(), all_obstacles=True)
        try:
            result = plan(grid, a.scenario.start.xy, a.scenario.target.xy)
        except Unreachable:
            result = None
        assert a.solvable == (result is not None), a.name
        assert ("optimal_length_m" in a.difficulty) == a.solvable, a.name
        if result is not None:
            assert a.difficulty["optimal_length_m"] == pytest.approx(result.length_m, abs=1e-4)


def test_the_unreachable_family_is_enclosed_and_start_at_target_is_within_5_cm(arenas200):
    for a in of_family(arenas200, "unreachable"):
        assert not a.solvable
        grid = OccupancyGrid.from_scenario(a.scenario, all_obstacles=True)
        with pytest.raises(Unreachable):  # not GoalBlocked: the target is free but walled in
            plan(grid, a.scenario.start.xy, a.scenario.target.xy)
    assert all(a.solvable for a in arenas200 if a.family not in ("unreachable", "narrow_passage"))
    for a in of_family(arenas200, "start_at_target"):
        assert 0.02 <= math.dist(a.scenario.start.xy, a.scenario.target.xy) <= 0.05, a.name


def _edges(scenario):
    """x0, x1, y0, y1 [m] of every box and of every wall along x or y (a wall's square ends are
    flush with its end points)."""
    edges = [(o.x_m - o.w_m / 2, o.x_m + o.w_m / 2, o.y_m - o.h_m / 2, o.y_m + o.h_m / 2) for o in scenario.obstacles]
    for w in scenario.walls:
        assert w.x0_m == w.x1_m or w.y0_m == w.y1_m, f"{scenario.name}: a wall at an angle"
        xs, ys = [x for x, _ in w.corners()], [y for _, y in w.corners()]
        edges.append((min(xs), max(xs), min(ys), max(ys)))
    return edges


def _gaps(scenario):
    """Every axis-aligned gap [m] between two facing boxes or walls, or one of them and the arena's wall."""
    edges = _edges(scenario)
    W, H = scenario.arena.width_m, scenario.arena.height_m
    gaps = []
    for x0, x1, y0, y1 in edges:
        gaps += [x0, W - x1, y0, H - y1]
        for u0, _u1, v0, _v1 in edges:
            gaps += [u0 - x1, v0 - y1]
    return [g for g in gaps if g > 0]


def test_narrow_passages_lie_between_the_rovers_limit_and_a_few_centimetres_wider(arenas200):
    narrow = of_family(arenas200, "narrow_passage")
    for a in narrow:
        width = a.scenario.generated["passage_width_m"]
        assert 2 * INFLATION_M - 1e-9 <= width <= 2 * INFLATION_M + NARROW_EXTRA_M + 1e-9, a.name
        assert any(abs(g - width) < 1e-6 for g in _gaps(a.scenario)), f"{a.name}: no {width} m gap in the file"
    # the grid decides: some of them are open and some closed
    assert {a.solvable for a in narrow} == {True, False}


def _crosses(box, waypoints, step_m=0.002):
    pts = np.asarray(waypoints)
    for p, q in zip(pts[:-1], pts[1:]):
        t = np.linspace(0.0, 1.0, max(2, int(np.hypot(*(q - p)) / step_m) + 1))[:, None]
        s = p + (q - p) * t
        if np.any((np.abs(s[:, 0] - box.x_m) <= box.w_m / 2) & (np.abs(s[:, 1] - box.y_m) <= box.h_m / 2)):
            return True
    return False


def test_unknown_boxes_on_the_path_cross_the_optimum_of_the_known_map(arenas200):
    for a in of_family(arenas200, "unknown_on_path"):
        known_only = plan(OccupancyGrid.from_scenario(a.scenario), a.scenario.start.xy, a.scenario.target.xy)
        unknown = a.scenario.unknown_obstacles
        assert unknown, a.name
        assert all(_crosses(o, known_only.waypoints) for o in unknown), a.name
        assert a.difficulty["known_path_blocked"] is True


def test_families_put_unknown_boxes_where_they_say(arenas200):
    for a in of_family(arenas200, "unknown_near_start") + of_family(arenas200, "unknown_near_target"):
        p = a.scenario.start if a.family == "unknown_near_start" else a.scenario.target
        near = [
            math.hypot(max(abs(p.x_m - o.x_m) - o.w_m / 2, 0), max(abs(p.y_m - o.y_m) - o.h_m / 2, 0))
            for o in a.scenario.unknown_obstacles
        ]
        assert near and min(near) < INFLATION_M + 0.16, a.name
    for a in of_family(arenas200, "unknown_against_wall"):
        s, W, H = a.scenario, a.scenario.arena.width_m, a.scenario.arena.height_m
        assert any(
            min(o.x_m - o.w_m / 2, W - o.x_m - o.w_m / 2, o.y_m - o.h_m / 2, H - o.y_m - o.h_m / 2) < 1e-9
            for o in s.unknown_obstacles
        ), a.name
    for a in of_family(arenas200, "out_and_back"):
        assert (a.scenario.mission.kind, a.scenario.mission.trips) == ("out-and-back", 1)
        assert a.scenario.unknown_obstacles, a.name
    for family in FAMILY_NAMES:  # every family tests the sonar somewhere (an unknown box, wall or post)
        assert any(a.scenario.unknown_shapes for a in of_family(arenas200, family)), family


def _scenario(obstacles, start=(1.0, 0.6), target=(1.0, 1.4)):
    return Scenario(
        name="t",
        arena=Arena(2.0, 2.0),
        start=Pose(*start),
        target=Target(*target),
        mission=Mission(),
        obstacles=tuple(obstacles),
    )


def test_the_metrics_on_arenas_worked_by_hand():
    empty = measure_scenario(_scenario([]))
    assert empty.solvable and empty.difficulty["dispersion"] == 0.0
    assert empty.difficulty["known_path_blocked"] is False
    assert empty.difficulty["optimal_length_m"] == pytest.approx(0.8)
    assert empty.difficulty["detour_ratio"] == pytest.approx(1.0)
    # A straight corridor 0.5 m wide between two walls 5 cm thick: the path runs 0.25 m from both.
    walls = [Obstacle(0.725, 1.0, 0.05, 1.6, True), Obstacle(1.275, 1.0, 0.05, 1.6, False)]
    corridor = measure_scenario(_scenario(walls))
    d = corridor.difficulty
    assert d["closest_obstacle_m"] == pytest.approx(0.25)
    assert d["mean_clearance_m"] == pytest.approx(0.25)
    assert d["characteristic_dimension_m"] == pytest.approx(0.5)
    assert d["narrowest_dimension_m"] == pytest.approx(0.5)
    assert d["dispersion"] > 4  # both horizontal rays cross a wall, in and out
    assert d["known_path_blocked"] is False
    assert d["score"] > empty.difficulty["score"]
    # The same walls closed across the way: unsolvable, measured along the straight segment.
    closed = measure_scenario(_scenario(walls + [Obstacle(1.0, 1.0, 1.0, 0.05, False)]))
    assert not closed.solvable and closed.optimal_path == ()
    assert closed.difficulty["closest_obstacle_m"] == 0.0
    assert closed.difficulty["narrowest_dimension_m"] == 0.0
    assert "optimal_length_m" not in closed.difficulty
    assert closed.difficulty["known_path_blocked"] is True


def test_rooms_are_drawn_with_walls_and_clutter_with_posts(arenas200):
    for family in ("wall_gap", "corridor", "trap_l", "trap_u", "unreachable"):
        assert all(a.scenario.walls for a in of_family(arenas200, family)), family
    assert any(a.scenario.walls for a in of_family(arenas200, "narrow_passage"))  # its thin dividers
    assert any(a.scenario.posts for a in of_family(arenas200, "clutter"))
    assert any(not w.known for a in arenas200 for w in a.scenario.walls)
    assert any(not p.known for a in arenas200 for p in a.scenario.posts)
    doors = [w for a in of_family(arenas200, "wall_gap") for w in a.scenario.walls if not w.axis_aligned]
    assert doors  # an open door leaf at an angle
    for family in ("scattered", "unknown_on_path", "out_and_back"):  # these stay boxes
        assert not any(a.scenario.walls or a.scenario.posts for a in of_family(arenas200, family)), family
    # the index counts every obstacle, whatever its shape
    a = next(a for a in arenas200 if a.scenario.walls and a.scenario.posts == () and a.scenario.obstacles == ())
    from rovernav.evaluation.arenas import index_row

    row = index_row(a)
    assert row["known_obstacles"] + row["unknown_obstacles"] == len(a.scenario.walls)


def test_the_metrics_count_walls_at_an_angle_and_posts():
    from rovernav.scenario import Post, Wall

    # A corridor 0.5 m wide at 45°, of walls 5 cm thick, along the straight way: as the axis-aligned one.
    off = 0.275 / math.sqrt(2)
    walls = (
        Wall(0.3 - off, 0.3 + off, 1.7 - off, 1.7 + off, 0.05),
        Wall(0.3 + off, 0.3 - off, 1.7 + off, 1.7 - off, 0.05, known=False),
    )
    s = Scenario(
        name="t",
        arena=Arena(2.0, 2.0),
        start=Pose(0.6, 0.6),
        target=Target(1.4, 1.4),
        mission=Mission(),
        obstacles=(),
        walls=walls,
    )
    d = measure_scenario(s).difficulty
    assert d["optimal_length_m"] == pytest.approx(0.8 * math.sqrt(2), abs=1e-6)
    assert d["closest_obstacle_m"] == pytest.approx(0.25) and d["mean_clearance_m"] == pytest.approx(0.25)
    assert d["characteristic_dimension_m"] == pytest.approx(0.5) and d["narrowest_dimension_m"] == pytest.approx(0.5)
    assert d["dispersion"] > 4 and d["known_path_blocked"] is False
    # A post 0.3 m beside the middle of a straight way.
    s = _scenario([])
    s = dataclasses.replace(s, posts=(Post(1.3, 1.0, 0.05, known=False),))
    d = measure_scenario(s).difficulty
    # (the path is sampled every 3 cm or less: its point nearest the post is within 1.5 cm of the middle)
    assert d["closest_obstacle_m"] == pytest.approx(0.25, abs=1e-3)
    assert d["narrowest_dimension_m"] == pytest.approx(1.0 + 0.25, abs=5e-3)  # from the left wall to the post
    assert d["dispersion"] > 0
    # Across the way, the post blocks the known path: the grid of every obstacle has it.
    s = dataclasses.replace(s, posts=(Post(1.0, 1.0, 0.05, known=False),))
    m = measure_scenario(s)
    assert m.solvable and m.difficulty["known_path_blocked"] is True and m.difficulty["detour_ratio"] > 1.0


def test_the_family_filter_keeps_only_those_families():
    arenas = generate_arenas(5, 3, families=["trap_u", "clutter"])
    assert [a.family for a in arenas] == ["trap_u", "clutter", "trap_u", "clutter", "trap_u"]  # FAMILY_NAMES order
    with pytest.raises(ArenaError, match="unknown family 'cave'"):
        generate_arenas(3, 1, families=["cave"])
    for count, seed in ((0, 1), (100_001, 1), (3, -1)):
        with pytest.raises(ArenaError):
            generate_arenas(count, seed)


def test_the_command_writes_arenas_indexes_and_a_contact_sheet(tmp_path, capsys):
    out = tmp_path / "arenas"
    assert main(["arenas", "--count", "4", "--seed", "5", "--out", str(out), "--family", "corridor,unreachable"]) == 0
    printed = capsys.readouterr().out
    assert "corridor" in printed and "unreachable" in printed and "all" in printed
    names = sorted(p.name for p in out.glob("*.toml"))
    assert names == [
        "arena-0001-corridor.toml",
        "arena-0002-unreachable.toml",
        "arena-0003-corridor.toml",
        "arena-0004-unreachable.toml",
    ]
    assert (out / "gallery.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert len(json.loads((out / "index.json").read_text())) == 4
    first = (out / names[0]).read_bytes()
    # Run again with fewer: the same bytes, and the files of the earlier run it did not write are gone.
    picture = tmp_path / "sheet.png"
    assert (
        main(
            [
                "arenas",
                "--count",
                "2",
                "--seed",
                "5",
                "--out",
                str(out),
                "--family",
                "unreachable,corridor",
                "--picture",
                str(picture),
            ]
        )
        == 0
    )
    assert sorted(p.name for p in out.glob("*.toml")) == names[:2]
    assert (out / names[0]).read_bytes() == first
    assert picture.is_file()
    parse_scenario((out / names[1]).read_text())


@pytest.mark.parametrize(
    "flags, says",
    [
        (["--count", "0"], "--count"),
        (["--count", "100001"], "--count"),
        (["--count", "ten"], "--count"),
        (["--seed", "-1"], "--seed"),
        (["--family", "scattered,cave"], "cave"),
        (["--out", "FILE"], "not a folder"),
    ],
    ids=["zero", "too many", "not a number", "negative seed", "unknown family", "out is a file"],
)
def test_bad_input_gives_one_line_and_exit_status_2(tmp_path, capsys, flags, says):
    existing = tmp_path / "existing.txt"
    existing.write_text("keep me")
    flags = [str(existing) if f == "FILE" else f for f in flags]
    if "--out" not in flags:
        flags += ["--out", str(tmp_path / "out")]
    assert main(["arenas", *flags]) == 2
    captured = capsys.readouterr()
    err = captured.err.strip()
    assert err.startswith("rovernav arenas: ") and says in err
    assert "\n" not in err and "Traceback" not in captured.err
    assert existing.read_text() == "keep me"
    assert not (tmp_path / "out").exists()


def test_the_help_explains_the_families_and_the_metrics(capsys):
    with pytest.raises(SystemExit):
        main(["arenas", "--help"])
    text = capsys.readouterr().out
    for name in FAMILY_NAMES:
        assert name in text
    for metric in ("closest_obstacle_m", "dispersion", "characteristic_dimension_m", "score", "band"):
        assert metric in text


@pytest.fixture(scope="module")
def cellular40():
    return generate_arenas(40, 7, families=["cellular"])


def test_cellular_worlds_are_barn_s_scaled_every_box_unknown_a_way_through(cellular40):
    # BARN's construction at this rover's scale: boxes on a grid of 8.4 cm cells, every one
    # unknown, start and target on the centre line, solvable with every box known.
    for a in cellular40:
        s = a.scenario
        assert 2.5 <= s.arena.width_m <= 4.0 and 1.8 <= s.arena.height_m <= 3.0
        assert a.solvable and not s.known_shapes and 8 <= len(s.obstacles) <= 120
        assert s.start.y_m == pytest.approx(s.arena.height_m / 2, abs=0.001)
        assert s.target.y_m == pytest.approx(s.arena.height_m / 2, abs=0.001)
        for o in s.obstacles:  # whole cells
            for side in (o.w_m, o.h_m):
                assert side / CELLULAR_CELL_M == pytest.approx(round(side / CELLULAR_CELL_M), abs=1e-3)
        # The independent check: A* with every box known finds a way.
        plan(
            OccupancyGrid.from_scenario(s, all_obstacles=True), (s.start.x_m, s.start.y_m), (s.target.x_m, s.target.y_m)
        )
    counts = [len(a.scenario.obstacles) for a in cellular40]
    assert max(counts) >= 40 and min(counts) <= 20  # the densities BARN's fill and smoothing give
    bands = collections.Counter(a.difficulty["band"] for a in cellular40)
    assert bands["medium"] + bands["hard"] >= 20
    carved = sum("carved for a way through" in a.scenario.description for a in cellular40)
    assert 0 < carved < 40


def test_cellular_worlds_are_drawn_only_by_name_and_the_same_each_time(cellular40):
    again = generate_arenas(5, 7, families=["cellular"])
    assert [a.toml_text for a in again] == [a.toml_text for a in cellular40[:5]]
    assert "cellular" not in FAMILY_NAMES and "cellular" in ALL_FAMILY_NAMES
    mixed = generate_arenas(3, 7, families=["cellular", "scattered"])
    assert [a.family for a in mixed] == ["scattered", "cellular", "scattered"]
    with pytest.raises(ArenaError, match="cellular"):  # the error lists every family
        generate_arenas(1, 1, families=["cave"])
