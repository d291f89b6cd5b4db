"""Scenario files: the shared ones load, and every mistake names the file and the key."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import pytest

from rovernav.scenario import (
    ScenarioError,
    default_scenario,
    load_scenario,
    parse_scenario,
    resolve_scenario,
    scenario_dir,
    scenario_names,
)

SHARED = ("out-and-back", "seed-fig4-8-unknown-obstacle", "seed-large-obstacles", "seed-small-obstacles")

GOOD = """
name = "test-arena"
version = 1

[arena]
width_m = 2.0
height_m = 1.5

[start]
x_m = 0.3
y_m = 0.3
heading_deg = 90.0

[target]
x_m = 1.7
y_m = 1.2

[mission]
kind = "out-and-back"
trips = 3

[[obstacles]]
x_m = 1.0
y_m = 0.7
w_m = 0.2
h_m = 0.1

[[obstacles]]
x_m = 0.5
y_m = 1.0
w_m = 0.1
h_m = 0.1
known = false
"""


def test_the_shared_scenarios_are_found_by_name_and_load():
    assert set(SHARED) <= set(scenario_names())
    for name in SHARED:
        scenario = load_scenario(name)
        assert scenario.name == name
        assert scenario.version == 1
        assert scenario.arena.width_m == 2.36 and scenario.arena.height_m == 1.75
        assert scenario.path == scenario_dir() / f"{name}.toml"


def test_the_seed_scenarios_hold_what_their_files_say():
    large = load_scenario("seed-large-obstacles")
    assert large.start.xy == (0.30, 0.875) and large.start.heading_deg == 90.0
    assert large.target.xy == (2.05, 0.875)
    assert large.mission.kind == "reach" and large.mission.trips == 1
    assert len(large.obstacles) == 3 and all(o.known for o in large.obstacles)
    small = load_scenario("seed-small-obstacles")
    assert len(small.obstacles) == 6 and {(o.w_m, o.h_m) for o in small.obstacles} == {(0.08, 0.08)}
    fig48 = load_scenario("seed-fig4-8-unknown-obstacle")
    assert fig48.known_obstacles == () and len(fig48.unknown_obstacles) == 1


def test_the_default_scenario_is_the_out_and_back_mission():
    scenario = default_scenario()
    assert scenario.name == "out-and-back"
    assert scenario.mission.kind == "out-and-back" and scenario.mission.trips == 2
    assert len(scenario.known_obstacles) == 2 and len(scenario.unknown_obstacles) == 2


def test_a_scenario_loads_from_a_path_as_text_or_path(tmp_path):
    f = tmp_path / "mine.toml"
    f.write_text(GOOD)
    for ref in (f, str(f)):
        scenario = load_scenario(ref)
        assert scenario.name == "test-arena" and scenario.path == f
        assert scenario.start.heading_deg == 90.0
        assert scenario.mission.trips == 3
        assert scenario.obstacles[0].known is True and scenario.obstacles[1].known is False
    assert resolve_scenario("seed-large-obstacles") == scenario_dir() / "seed-large-obstacles.toml"


def test_the_scenario_directory_can_be_overridden(tmp_path, monkeypatch):
    (tmp_path / "only-one.toml").write_text(GOOD)
    monkeypatch.setenv("ROVERNAV_SCENARIO_DIR", str(tmp_path))
    assert scenario_names() == ["only-one"]
    assert load_scenario("only-one").name == "test-arena"


def test_an_unknown_name_lists_the_shared_scenarios():
    with pytest.raises(ScenarioError, match="no scenario named 'nowhere'.*seed-large-obstacles"):
        load_scenario("nowhere")
    with pytest.raises(ScenarioError, match="no such scenario file"):
        load_scenario("missing/dir/file.toml")


def _replace(text: str, old: str, new: str) -> str:
    assert old in text, old
    return text.replace(old, new, 1)


# (what is wrong, how to break GOOD, the key the message must name, and what it must say)
MISTAKES = [
    ("missing table", lambda t: _replace(t, "[arena]\nwidth_m = 2.0\nheight_m = 1.5\n", ""), "arena", "missing"),
    ("missing key", lambda t: _replace(t, "width_m = 2.0\n", ""), "arena.width_m", "missing"),
    ("zero arena", lambda t: _replace(t, "height_m = 1.5", "height_m = 0"), "arena.height_m", "> 0"),
    ("text for a number", lambda t: _replace(t, "x_m = 0.3", 'x_m = "0.3"'), "start.x_m", "number"),
    ("start off the arena", lambda t: _replace(t, "x_m = 0.3", "x_m = 2.5"), "start.x_m", "outside the arena"),
    ("target off the arena", lambda t: _replace(t, "y_m = 1.2", "y_m = -0.1"), "target.y_m", "outside the arena"),
    ("negative size", lambda t: _replace(t, "w_m = 0.1", "w_m = -0.1"), "obstacles[1].w_m", "> 0"),
    ("bad known", lambda t: _replace(t, "known = false", 'known = "no"'), "obstacles[1].known", "true or false"),
    (
        "unknown key",
        lambda t: _replace(t, "h_m = 0.1\n\n", 'h_m = 0.1\ncolour = "red"\n\n'),
        "obstacles[0].colour",
        "not a known key",
    ),
    ("unknown top key", lambda t: "speed = 3\n" + t, "speed", "not a known key"),
    ("bad mission", lambda t: _replace(t, '"out-and-back"', '"explore"'), "mission.kind", "reach, out-and-back"),
    ("zero trips", lambda t: _replace(t, "trips = 3", "trips = 0"), "mission.trips", "from 1 to 1000"),
    ("other version", lambda t: _replace(t, "version = 1", "version = 2"), "version", "understands version 1"),
    ("no version", lambda t: _replace(t, "version = 1\n", ""), "version", "missing"),
    # sizes that would exhaust memory or time, shapes off the arena, a start in a box
    ("a 1 km arena", lambda t: _replace(t, "width_m = 2.0", "width_m = 1000.0"), "arena.width_m", "at most 100 m"),
    ("a billion trips", lambda t: _replace(t, "trips = 3", "trips = 1000000000"), "mission.trips", "from 1 to 1000"),
    ("infinite size", lambda t: _replace(t, "width_m = 2.0", "width_m = inf"), "arena.width_m", "must be a number"),
    ("NaN position", lambda t: _replace(t, "x_m = 0.3", "x_m = nan"), "start.x_m", "must be a number"),
    (
        "obstacle off the arena",
        lambda t: _replace(t, "x_m = 1.0\ny_m = 0.7", "x_m = 9.0\ny_m = 0.7"),
        "obstacles[0]",
        "lies outside the arena",
    ),
    (
        "start in a box",
        lambda t: _replace(t, "x_m = 1.0\ny_m = 0.7", "x_m = 0.3\ny_m = 0.3"),
        "start",
        "is inside obstacles[0]",
    ),
    (
        "target in a box",
        lambda t: _replace(t, "x_m = 0.5\ny_m = 1.0", "x_m = 1.7\ny_m = 1.2"),
        "target",
        "is inside obstacles[1]",
    ),
]


@pytest.mark.parametrize("what, breaks, key, says", MISTAKES, ids=[m[0] for m in MISTAKES])
def test_a_bad_scenario_file_names_the_file_and_the_key(tmp_path, what, breaks, key, says):
    f = tmp_path / "broken.toml"
    f.write_text(breaks(GOOD))
    with pytest.raises(ValueError) as info:
        load_scenario(f)
    message = str(info.value)
    assert message.startswith(f"{f}: {key} "), message
    assert says in message


def test_invalid_toml_names_the_file(tmp_path):
    f = tmp_path / "garbled.toml"
    f.write_text("[arena\nwidth_m = 1")
    with pytest.raises(ScenarioError, match=r"garbled\.toml: not valid TOML"):
        load_scenario(f)


def test_parse_scenario_labels_errors_with_its_source():
    with pytest.raises(ScenarioError, match=r"^<memory>: arena\.width_m is missing"):
        parse_scenario(_replace(GOOD, "width_m = 2.0\n", ""), source="<memory>")
    assert parse_scenario(GOOD).path is None


def test_the_scenarios_come_with_the_repository(monkeypatch):
    import rovernav.scenario

    monkeypatch.delenv("ROVERNAV_SCENARIO_DIR", raising=False)
    repo = Path(rovernav.scenario.__file__).resolve().parents[2]
    assert scenario_dir() == repo / "scenarios"
    assert {"out-and-back", "seed-fig4-8-unknown-obstacle", "seed-large-obstacles", "seed-small-obstacles"} <= set(
        scenario_names()
    )


def test_the_repository_copies_of_the_shared_scenarios_have_not_drifted():
    from rovernav.scenario import REPO_SCENARIOS, SHARED_SCENARIOS

    if not SHARED_SCENARIOS.is_dir():
        pytest.skip(f"no shared scenarios at {SHARED_SCENARIOS} to compare with")
    shared = {p.name: p.read_bytes() for p in SHARED_SCENARIOS.glob("*.toml")}
    ours = {p.name: p.read_bytes() for p in REPO_SCENARIOS.glob("*.toml")}
    assert shared, "the shared scenario folder is empty"
    for name, data in shared.items():
        assert ours.get(name) == data, f"scenarios/{name} differs from {SHARED_SCENARIOS / name}: copy it again"


GENERATED = (
    GOOD
    + """
[generated]
family = "narrow_passage"
seed = 7
index = 12
solvable = false
passage_width_m = 0.355

[generated.difficulty]
closest_obstacle_m = 0.0
mean_clearance_m = 0.21
dispersion = 6.5
characteristic_dimension_m = 0.74
narrowest_dimension_m = 0.0
known_path_blocked = true
score = 0.62
band = "hard"
"""
)


def test_a_generated_arena_keeps_its_labels_and_others_have_none(tmp_path):
    assert parse_scenario(GOOD).generated is None
    f = tmp_path / "arena.toml"
    f.write_text(GENERATED)
    scenario = load_scenario(f)
    assert scenario.generated == {
        "family": "narrow_passage",
        "seed": 7,
        "index": 12,
        "solvable": False,
        "passage_width_m": 0.355,
        "difficulty": {
            "closest_obstacle_m": 0.0,
            "mean_clearance_m": 0.21,
            "dispersion": 6.5,
            "characteristic_dimension_m": 0.74,
            "narrowest_dimension_m": 0.0,
            "known_path_blocked": True,
            "score": 0.62,
            "band": "hard",
        },
    }
    solvable = _replace(
        _replace(GENERATED, "solvable = false", "solvable = true"),
        "score = 0.62",
        "score = 0.62\noptimal_length_m = 2.5\ndetour_ratio = 1.1",
    )
    difficulty = parse_scenario(solvable).generated["difficulty"]
    assert difficulty["optimal_length_m"] == 2.5 and difficulty["detour_ratio"] == 1.1
    # the rest of the scenario is as without the table
    assert dataclasses.replace(scenario, generated=None) == dataclasses.replace(load_scenario(f), generated=None)
    assert scenario.obstacles == parse_scenario(GOOD).obstacles


GENERATED_MISTAKES = [
    (
        "unknown key",
        lambda t: _replace(t, "index = 12", "index = 12\ncolour = 1"),
        "generated.colour",
        "not a known key",
    ),
    (
        "unknown metric",
        lambda t: _replace(t, "dispersion = 6.5", "dispersion = 6.5\nfun = 1.0"),
        "generated.difficulty.fun",
        "not a known key",
    ),
    ("missing family", lambda t: _replace(t, 'family = "narrow_passage"\n', ""), "generated.family", "missing"),
    ("negative seed", lambda t: _replace(t, "seed = 7", "seed = -7"), "generated.seed", "≥ 0"),
    ("text for an index", lambda t: _replace(t, "index = 12", 'index = "12"'), "generated.index", "whole number"),
    ("bad solvable", lambda t: _replace(t, "solvable = false", "solvable = 0"), "generated.solvable", "true or false"),
    (
        "not finite",
        lambda t: _replace(t, "dispersion = 6.5", "dispersion = nan"),
        "generated.difficulty.dispersion",
        "number",
    ),
    (
        "infinite",
        lambda t: _replace(t, "mean_clearance_m = 0.21", "mean_clearance_m = inf"),
        "generated.difficulty.mean_clearance_m",
        "number",
    ),
    (
        "negative metric",
        lambda t: _replace(t, "closest_obstacle_m = 0.0", "closest_obstacle_m = -0.1"),
        "generated.difficulty.closest_obstacle_m",
        "≥ 0",
    ),
    (
        "missing metric",
        lambda t: _replace(t, "characteristic_dimension_m = 0.74\n", ""),
        "generated.difficulty.characteristic_dimension_m",
        "missing",
    ),
    ("score above 1", lambda t: _replace(t, "score = 0.62", "score = 1.5"), "generated.difficulty.score", "0 to 1"),
    (
        "bad band",
        lambda t: _replace(t, 'band = "hard"', 'band = "brutal"'),
        "generated.difficulty.band",
        "easy, medium, hard",
    ),
    (
        "zero passage",
        lambda t: _replace(t, "passage_width_m = 0.355", "passage_width_m = 0"),
        "generated.passage_width_m",
        "> 0",
    ),
    ("no difficulty", lambda t: t[: t.index("[generated.difficulty]")], "generated.difficulty", "missing"),
]


@pytest.mark.parametrize("what, breaks, key, says", GENERATED_MISTAKES, ids=[m[0] for m in GENERATED_MISTAKES])
def test_a_bad_generated_table_names_the_file_and_the_key(tmp_path, what, breaks, key, says):
    f = tmp_path / "arena.toml"
    f.write_text(breaks(GENERATED))
    with pytest.raises(ScenarioError) as info:
        load_scenario(f)
    message = str(info.value)
    assert message.startswith(f"{f}: {key} "), message
    assert says in message


def test_a_generated_scenario_can_still_be_hashed():
    plain, generated = parse_scenario(GOOD), parse_scenario(GENERATED)
    assert hash(plain) == hash(generated) and plain != generated


# --- walls and posts -------------------------------------------------------------------------

WALLS = (
    GOOD
    + """
[[walls]]
x0_m = 0.9
y0_m = 0.0
x1_m = 0.9
y1_m = 0.6
thickness_m = 0.05

[[walls]]
x0_m = 1.2
y0_m = 0.9
x1_m = 1.6
y1_m = 1.3
thickness_m = 0.04
known = false

[[posts]]
x_m = 1.5
y_m = 0.4
radius_m = 0.05
known = false
"""
)


def test_walls_and_posts_load_and_list_with_the_boxes():
    from rovernav.scenario import Obstacle, Post, Wall

    scenario = parse_scenario(WALLS)
    assert scenario.walls == (Wall(0.9, 0.0, 0.9, 0.6, 0.05, True), Wall(1.2, 0.9, 1.6, 1.3, 0.04, False))
    assert scenario.posts == (Post(1.5, 0.4, 0.05, False),)
    assert scenario.obstacles == parse_scenario(GOOD).obstacles  # the boxes as before
    assert [o.kind for o in scenario.shapes] == ["box", "box", "wall", "wall", "post"]
    assert scenario.known_shapes == (scenario.obstacles[0], scenario.walls[0])
    assert scenario.unknown_shapes == (scenario.obstacles[1], scenario.walls[1], scenario.posts[0])
    assert isinstance(scenario.shapes[0], Obstacle)
    # geometry: square ends flush with the end points, exact distances
    wall = scenario.walls[0]
    assert sorted(wall.corners()) == sorted([(0.875, 0.0), (0.925, 0.0), (0.925, 0.6), (0.875, 0.6)])
    assert wall.distance_m(0.9, 0.7) == pytest.approx(0.1) and wall.distance_m(1.0, 0.3) == pytest.approx(0.075)
    assert wall.distance_m(0.9, 0.3) == 0.0 and wall.axis_aligned and not scenario.walls[1].axis_aligned
    assert scenario.walls[1].distance_m(1.4 - 0.1, 1.1 + 0.1) == pytest.approx(0.1 * math.sqrt(2) - 0.02)
    assert scenario.posts[0].distance_m(1.5, 0.6) == pytest.approx(0.15)
    # files without walls or posts have none; the scenario still hashes (walls and posts included)
    assert parse_scenario(GOOD).walls == () and parse_scenario(GOOD).posts == ()
    assert hash(scenario) != hash(parse_scenario(GOOD)) and hash(scenario) == hash(parse_scenario(WALLS))
    for name in SHARED:
        assert load_scenario(name).walls == () and load_scenario(name).posts == ()


WALL_MISTAKES = [
    ("zero thickness", lambda t: _replace(t, "thickness_m = 0.05", "thickness_m = 0"), "walls[0].thickness_m", "> 0"),
    ("text for an end", lambda t: _replace(t, "x1_m = 1.6", 'x1_m = "1.6"'), "walls[1].x1_m", "number"),
    ("infinite end", lambda t: _replace(t, "y1_m = 1.3", "y1_m = inf"), "walls[1].y1_m", "number"),
    ("missing end", lambda t: _replace(t, "y0_m = 0.9\n", ""), "walls[1].y0_m", "missing"),
    ("no length", lambda t: _replace(t, "y1_m = 0.6", "y1_m = 0.0"), "walls[0]", "has no length"),
    (
        "unknown wall key",
        lambda t: _replace(t, "thickness_m = 0.04", "thickness_m = 0.04\nheight_m = 1"),
        "walls[1].height_m",
        "not a known key",
    ),
    (
        "bad wall known",
        lambda t: _replace(t, "known = false\n\n[[posts]]", "known = 0\n\n[[posts]]"),
        "walls[1].known",
        "true or false",
    ),
    ("walls not an array", lambda t: "walls = 3\n" + t[: t.index("[[walls]]")], "walls", "array of tables"),
    ("negative radius", lambda t: _replace(t, "radius_m = 0.05", "radius_m = -0.05"), "posts[0].radius_m", "> 0"),
    ("nan post", lambda t: _replace(t, "x_m = 1.5", "x_m = nan"), "posts[0].x_m", "number"),
    (
        "unknown post key",
        lambda t: _replace(t, "radius_m = 0.05", "radius_m = 0.05\nw_m = 0.1"),
        "posts[0].w_m",
        "not a known key",
    ),
    ("missing radius", lambda t: _replace(t, "radius_m = 0.05\n", ""), "posts[0].radius_m", "missing"),
]


@pytest.mark.parametrize("what, breaks, key, says", WALL_MISTAKES, ids=[m[0] for m in WALL_MISTAKES])
def test_a_bad_wall_or_post_names_the_file_and_the_key(tmp_path, what, breaks, key, says):
    f = tmp_path / "walls.toml"
    f.write_text(breaks(WALLS))
    with pytest.raises(ScenarioError) as info:
        load_scenario(f)
    message = str(info.value)
    assert message.startswith(f"{f}: {key} "), message
    assert says in message


def test_a_scenario_written_by_scenario_toml_reads_back_the_same():
    # The run log keeps a scenario as this text; replay builds the host's grid from it.
    import dataclasses

    from rovernav.evaluation.arenas import generate_arenas
    from rovernav.scenario import parse_scenario, scenario_names, scenario_toml

    scenarios = [load_scenario(n) for n in scenario_names()] + [a.scenario for a in generate_arenas(70, seed=3)]
    assert any(s.walls for s in scenarios) and any(s.posts for s in scenarios)
    for s in scenarios:
        again = parse_scenario(scenario_toml(s), source="<test>")
        assert again == dataclasses.replace(s, path=None, generated=None), s.name
