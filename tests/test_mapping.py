"""The log-odds sonar map: the inverse sensor model against hand-worked cells, sharpening by
repeated readings, explained echoes, and what the planner then sees."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rovernav import vehicle_gen as vehicle
from rovernav.mapping import SensorModel, SonarMap, SonarReading
from rovernav.mapping.learned_map import LearnedMap, read_map_file
from rovernav.planning import OccupancyGrid, PlannerConfig, plan

RES = 0.03


def _cell(m: SonarMap, x_m: float, y_m: float) -> float:
    return float(m.logodds[int(y_m / RES), int(x_m / RES)])


def _map(**kw) -> SonarMap:
    # Sensor at the rover's centre (offset 0) to keep the hand-worked geometry plain.
    return SonarMap(3.0, 3.0, RES, sonar_offset_m=0.0, **kw)


def test_an_echo_raises_its_arc_lowers_the_cone_before_it_and_leaves_what_is_behind_unknown():
    m = _map()
    model = m.model
    # Rover at (1.5, 1.0) facing +y (0 deg), sonar ahead, echo at 0.30 m: the arc is at y = 1.30.
    m.update(SonarReading(1.5, 1.0, 0.0, 0.0, 0.30, 0.4))
    # Hand-worked cells (centres on the 0.03 m grid: x 1.515 is the column holding 1.5).
    assert _cell(m, 1.515, 1.305) == pytest.approx(model.occupied_logodds)  # on the axis, on the arc
    assert _cell(m, 1.515, 1.155) == pytest.approx(model.free_logodds)  # on the axis, half way
    assert _cell(m, 1.515, 1.395) == 0.0  # behind the arc: unknown
    # 7.5 deg off the axis at 0.30 m is 0.039 m to the side: still on the arc; 0.10 m to the side is not.
    assert _cell(m, 1.545, 1.305) == pytest.approx(model.occupied_logodds)
    assert _cell(m, 1.605, 1.305) == 0.0
    # Under the rover's body: free.
    assert _cell(m, 1.515, 1.005) == pytest.approx(model.free_logodds)


def test_no_echo_clears_the_cone_to_the_report_range_and_no_further():
    m = _map()
    m.update(SonarReading(1.5, 1.0, 90.0, 0.0, None, 0.4))  # facing +x, nothing within 0.4 m
    assert _cell(m, 1.875, 1.005) == pytest.approx(m.model.free_logodds)  # 0.36 m out
    assert _cell(m, 1.965, 1.005) == 0.0  # 0.45 m out: unknown
    assert not m.occupied.any()


def test_silence_clears_only_cells_whose_centre_is_in_the_cone_an_echo_takes_any_it_touches():
    # Facing +y from (1.5, 1.0). At 0.30 m the 15-degree cone's edge is 0.0395 m off the axis.
    # The cell centred 0.045 m off (x 1.545) is only cut by the cone: an echo there counts it
    # (the surface may be in its part inside the cone), silence does not clear it (a box's
    # corner may stand in the part the sound missed).
    m = _map()
    m.update(SonarReading(1.5, 1.0, 0.0, 0.0, None, 0.4))
    assert _cell(m, 1.545, 1.305) == 0.0
    assert _cell(m, 1.515, 1.305) == pytest.approx(m.model.free_logodds)
    m.update(SonarReading(1.5, 1.0, 0.0, 0.0, 0.30, 0.4))
    assert _cell(m, 1.545, 1.305) == pytest.approx(m.model.occupied_logodds)
    # The Figure 4.8 box's corner after a radio outage: a ping from beside it, aimed so that the
    # corner cell lies just outside the nominal cone, keeps the corner an obstacle.
    corner = _map()
    corner.update(SonarReading(1.5, 1.0, 0.0, 0.0, 0.30, 0.4))  # the face, seen once
    corner.update(SonarReading(1.5, 1.0, 0.0, -17.5, None, 0.4))  # silence, 9 degrees off it
    assert corner.occupied[int(1.305 / RES), int(1.455 / RES)]


def test_repeated_readings_sharpen_a_smeared_arc_instead_of_widening_it():
    m = _map()
    # An echo at 0.30 m straight ahead marks its whole arc: cells from x 1.455 to 1.545.
    m.update(SonarReading(1.5, 1.0, 0.0, 0.0, 0.30, 0.4))
    wide = int(m.occupied.sum())
    assert _cell(m, 1.545, 1.305) >= m.model.occupied_threshold
    # A second look from 8 cm to the right finds nothing within 0.4 m: its cone passes through
    # the arc's right end (x 1.545), which was never an obstacle, and clears it; the rest stays.
    m.update(SonarReading(1.58, 1.0, 0.0, 0.0, None, 0.4))
    assert _cell(m, 1.545, 1.305) < m.model.occupied_threshold
    assert _cell(m, 1.485, 1.305) >= m.model.occupied_threshold
    assert int(m.occupied.sum()) < wide
    # A second echo on the same face raises the cells it shares with the first.
    before = _cell(m, 1.485, 1.305)
    m.update(SonarReading(1.45, 1.0, 0.0, 0.0, 0.30, 0.4))
    assert _cell(m, 1.485, 1.305) > before


def test_an_echo_off_the_wall_or_a_known_obstacle_marks_nothing_new():
    known = np.zeros((100, 100), dtype=bool)
    known[40:45, 40:60] = True  # a known box, cells [iy, ix]: y 1.20 to 1.35, x 1.20 to 1.80
    m = _map(known=known)
    m.update(SonarReading(1.5, 0.9, 0.0, 0.0, 0.30, 0.4))  # its face at y = 1.20
    assert not m.occupied.any()
    m.update(SonarReading(0.3, 2.5, -90.0, 0.0, 0.30, 0.4))  # the left wall, at 0.30 m
    assert not m.occupied.any()


def test_the_planner_goes_round_what_the_sonar_found_and_unknown_space_is_planned_through():
    grid = OccupancyGrid(2.4, 1.8, PlannerConfig())
    lm = LearnedMap(grid)
    direct = plan(grid, (0.3, 0.9), (2.1, 0.9))
    assert direct.length_m == pytest.approx(1.8, abs=0.01)  # nothing known: straight through
    # A face 0.30 m ahead of the sensor (offset 0.10 m), across the straight line, seen by a fan.
    for bearing in (-15.0, -7.5, 0.0, 7.5, 15.0):
        lm.add(SonarReading(0.8, 0.9, 90.0, bearing, 0.30 / math.cos(math.radians(bearing)), 0.4))
    assert grid.path_blocked(direct.waypoints)
    around = plan(grid, (0.3, 0.9), (2.1, 0.9))
    assert around.length_m > 1.85 and not grid.path_blocked(around.waypoints)


def test_a_gap_one_cell_wider_than_the_rover_needs_stays_open_after_sweeping_both_sides():
    grid = OccupancyGrid(2.4, 1.8, PlannerConfig())
    inflation = grid.config.inflation_m
    gap = 2 * inflation + 2 * RES
    lm = LearnedMap(grid)
    # Two walls along x = 1.2 with a gap centred on y = 0.9; the rover at (0.8, 0.9) sweeps them.
    lower_top, upper_bottom = 0.9 - gap / 2, 0.9 + gap / 2
    sx, sy = 0.8 + 0.10, 0.9
    for bearing in range(-60, 61, 15):
        a = math.radians(90.0 + bearing)
        dx, dy = math.sin(a), math.cos(a)
        t = (1.2 - sx) / dx
        y = sy + t * dy
        hit = y <= lower_top or y >= upper_bottom
        lm.add(SonarReading(0.8, 0.9, 90.0, float(bearing), t if hit and t <= 0.4 else None, 0.4))
    result = plan(grid, (0.8, 0.9), (1.8, 0.9))
    assert result.length_m < 1.2


def test_the_open_map_clears_what_the_careful_map_keeps_and_is_planned_on_only_after_it():
    # A face seen once, then silence whose cone only cuts the face's end cell (9 degrees off):
    # the careful map keeps that cell (a corner may stand in the part the sound missed), the open
    # map clears it as the map always did.
    grid = OccupancyGrid(2.4, 1.8, PlannerConfig())
    lm = LearnedMap(grid)
    assert lm.open_grids() == []
    # The rover at (1.5, 0.9) facing +y: its sensor, 0.10 m ahead, at (1.5, 1.0).
    lm.add(SonarReading(1.5, 0.9, 0.0, 0.0, 0.30, 0.4))
    assert lm.open_grids() == []  # both believe the same
    lm.add(SonarReading(1.5, 0.9, 0.0, -17.5, None, 0.4))
    cell = (int(1.305 / RES), int(1.455 / RES))
    assert lm.sonar.occupied[cell] and not lm.open_sonar.occupied[cell]
    full, lenient = lm.open_grids()
    assert full.raw[cell] == False and grid.raw[cell] == True  # noqa: E712 - numpy booleans
    assert full.inflated.sum() < grid.inflated.sum() and lenient.inflated.sum() < full.inflated.sum()
    # Replaying a saved map rebuilds both.
    again = LearnedMap(OccupancyGrid(2.4, 1.8, PlannerConfig()))
    again.replay(list(lm.readings))
    assert (again.open_sonar.logodds == lm.open_sonar.logodds).all()
    assert (again.sonar.logodds == lm.sonar.logodds).all()


def test_an_echo_that_puts_back_only_on_the_open_map_what_its_silence_cleared_is_a_change():
    # The fleet on a lossy radio, seed 3: a path planned on the open map through a box's corner that
    # silence had cleared there; the corner's next echo changed the open map alone, and the add that
    # said "no change" left the rover on that path into the corner.
    grid = OccupancyGrid(2.4, 1.8, PlannerConfig())
    lm = LearnedMap(grid)
    lm.add(SonarReading(1.5, 0.9, 0.0, 0.0, 0.30, 0.4))
    lm.add(SonarReading(1.5, 0.9, 0.0, -17.5, None, 0.4))  # the open map clears the face's end cell
    cell = (int(1.305 / RES), int(1.455 / RES))
    assert lm.sonar.occupied[cell] and not lm.open_sonar.occupied[cell]
    careful, version = lm.sonar.occupied.copy(), grid.version
    # From the left, facing +x (sensor at x 1.15): an echo at 0.30 m, its arc on that end cell alone.
    assert lm.add(SonarReading(1.05, 1.30, 90.0, 0.0, 0.30, 0.4))
    assert lm.open_sonar.occupied[cell]
    assert (lm.sonar.occupied == careful).all() and grid.version == version  # the careful map: as it was
    # The same echo again changes neither map: no change said.
    assert not lm.add(SonarReading(1.05, 1.30, 90.0, 0.0, 0.30, 0.4))


def test_the_map_saves_and_reloads_to_the_same_grid(tmp_path):
    grid = OccupancyGrid(2.4, 1.8, PlannerConfig())
    lm = LearnedMap(grid)
    for b in (-30.0, 0.0, 30.0):
        lm.add(SonarReading(1.0, 0.9, 90.0, b, 0.25, 0.4, 0.003))
    lm.add(SonarReading(1.0, 0.9, 90.0, 60.0, None, 0.4, 0.003))
    lm.save(tmp_path / "map.json")
    again = LearnedMap(OccupancyGrid(2.4, 1.8, PlannerConfig()))
    assert again.load(tmp_path / "map.json") == 4
    assert (again.grid.inflated == grid.inflated).all() and (again.sonar.logodds == lm.sonar.logodds).all()
    assert len(read_map_file(tmp_path / "map.json")) == 4


@pytest.mark.parametrize(
    "text, what",
    [
        ("[]", "not a rovernav map"),
        ('{"format": "rovernav-map", "version": 2, "readings": {}}', "must be a list"),
        ('{"format": "rovernav-map", "version": 2, "readings": [{"x_m": 1}]}', "exactly the keys"),
        (
            '{"format": "rovernav-map", "version": 2, "readings": [{"x_m": NaN, "y_m": 0, "heading_deg": 0, '
            '"bearing_deg": 0, "range_m": 0.2, "max_range_m": 0.4, "sd_m": 0}]}',
            "finite number",
        ),
        (
            '{"format": "rovernav-map", "version": 2, "readings": [{"x_m": 1, "y_m": 0, "heading_deg": 0, '
            '"bearing_deg": 0, "range_m": -1, "max_range_m": 0.4, "sd_m": 0}]}',
            "range_m",
        ),
    ],
)
def test_a_bad_map_file_is_refused_naming_what_is_wrong(tmp_path, text, what):
    from rovernav.errors import MapFileError

    (tmp_path / "m.json").write_text(text)
    with pytest.raises(MapFileError, match=what):
        read_map_file(tmp_path / "m.json")


def test_the_sensor_model_numbers_make_one_echo_occupied_and_one_clear_look_undo_it():
    m = SensorModel()
    assert m.occupied_logodds >= m.occupied_threshold
    assert m.occupied_logodds + m.free_logodds < m.occupied_threshold


def test_the_sonar_geometry_is_defined_once_and_as_the_firmware_places_an_echo():
    # The ranger sits sonar_offset_mm (the protocol's default, 100 mm) ahead of the rover's
    # centre; an echo lies on the beam's axis (heading + servo bearing, clockwise from +y).
    from rovernav.link import messages_gen as mg
    from rovernav.mapping import echo_point, sonar_origin
    from rovernav.mapping.learned_map import Echo
    from rovernav.mission.legs import legs_per_trip

    off = mg.PARAMS[mg.Param.SONAR_OFFSET_MM].default / 1000
    assert sonar_origin(1.0, 0.5, 0.0, off) == pytest.approx((1.0, 0.6))
    assert sonar_origin(1.0, 0.5, 90.0, off) == pytest.approx((1.1, 0.5))
    assert echo_point(1.0, 0.5, 90.0, 90.0, 0.3, off) == pytest.approx((1.1, 0.2))  # facing +x, looking -y
    assert echo_point(1.0, 0.8, 0.0, -45.0, 0.3, off) == pytest.approx((1.0 - 0.3 * 0.5**0.5, 0.9 + 0.3 * 0.5**0.5))
    assert Echo(1.0, 0.5, 90.0, 90.0, 0.3).point(off) == echo_point(1.0, 0.5, 90.0, 90.0, 0.3, off)
    assert (legs_per_trip("out-and-back"), legs_per_trip("reach")) == (2, 1)


def test_silence_clears_nothing_past_the_sensor_s_range_whatever_the_reading_claims():
    # An old map file (or a rover told to report out to 4 m) says "no echo within 4 m"; the
    # HC-SR04's driver measures nothing past the sensor's range (protocol/vehicle.toml), 1 m.
    from rovernav.mapping.sonar_map import SonarMap, SonarReading

    m = SonarMap(3.0, 1.0, 0.03, 0.1)
    m.update(SonarReading(0.2, 0.5, 90.0, 0.0, None, 4.0))  # facing +x from x = 0.2 (sensor at 0.3)
    free = m.logodds < 0
    xs_free = m.xs[free.any(axis=0)]
    assert xs_free.max() <= 0.3 + vehicle.SONAR_MAX_RANGE_MM / 1000 + 0.03
    assert xs_free.max() > 1.2  # it does clear out to the sensor's range


def test_the_host_map_uses_the_cone_the_configuration_sends():
    from rovernav.config import config_from_dict
    from rovernav.mapping.learned_map import LearnedMap
    from rovernav.planning.grid import OccupancyGrid

    cfg = config_from_dict({"planner": {"sonar_cone_deg": 30}})
    lm = LearnedMap(OccupancyGrid(2.0, 2.0, cfg.planner))
    assert lm.sonar.model.cone_deg == lm.open_sonar.model.cone_deg == 30.0


def _sweep(lm: LearnedMap, x_m: float, y_m: float, heading_deg: float, echo_at: dict | None = None) -> None:
    """A sweep of 13 readings, -90 to +90 degrees by 15, reporting within 0.4 m: silent but for the
    bearings in `echo_at` (bearing -> range)."""
    for b in range(-90, 91, 15):
        lm.add(SonarReading(x_m, y_m, heading_deg, float(b), (echo_at or {}).get(b), 0.4))


def test_ground_is_seen_along_a_path_once_sweeps_have_heard_it_clear_or_found_a_box_beside_it():
    grid = OccupancyGrid(2.4, 1.8, PlannerConfig())
    lm = LearnedMap(grid)
    path = [(0.6, 0.9), (1.4, 0.9)]
    assert not lm.seen_along(path, 0.25)  # nothing looked at yet

    def there_and_back(m, echo_at=None):
        for i in range(9):  # sweeps every 0.2 m along the line, facing along it, and back
            _sweep(m, 0.2 + 0.2 * i, 0.9, 90.0, echo_at if i == 4 else None)
            _sweep(m, 1.8 - 0.2 * i, 0.9, 270.0)

    there_and_back(lm)
    assert lm.seen_along(path, 0.25)  # every cell within 0.25 m of the line heard clear
    assert not lm.seen_along([(0.6, 0.9), (1.4, 1.5)], 0.25)  # a way off what was looked at
    # A cell unheard just beyond the corridor (its centre 0.255 m from the line) does not count.
    cell = (int(0.63 / 0.03), int(1.0 / 0.03))
    lm.sonar.logodds[cell], kept = 0.0, lm.sonar.logodds[cell]
    assert lm.seen_along(path, 0.25)
    lm.sonar.logodds[cell] = kept
    assert lm.seen_along([(0.6, 1.0), (1.4, 1.0)], 0.25)
    # A box beside the line, found by the sonar: the cells behind its face, which no sonar hears,
    # lie within the planner's margin of what it found, where no path goes: still seen.
    for _ in range(3):
        lm.add(SonarReading(1.0, 0.9, 0.0, 0.0, 0.11, 0.4))  # a face 0.21 m off the line
    assert lm.sonar.occupied.any()
    # ... and a path through the margin round it (a squeeze the open map allows) is not seen.
    assert not lm.seen_along([(0.6, 1.0), (1.4, 1.0)], 0.25)
    lm.sonar.logodds[int(1.14 / 0.03), int(1.0 / 0.03)] = 0.0  # behind the face: never heard
    assert lm.seen_along(path, 0.25)
    # An unseen patch beside the path, away from any echo, is not seen.
    lm.sonar.logodds[int(0.7 / 0.03), int(1.0 / 0.03)] = 0.0
    assert not lm.seen_along(path, 0.25)
