"""A test helper: learned-map files, good and bad, for the hostile-input tests of the map
loader (test_hostile_map_files.py) and of `rovernav run --map` (test_hostile_cli.py)."""

from __future__ import annotations

import json
import math

from rovernav.planning import OccupancyGrid, PlannerConfig


def grid() -> OccupancyGrid:
    return OccupancyGrid(2.4, 1.8, PlannerConfig())


def reading(**kw) -> dict:
    r = {
        "x_m": 1.0,
        "y_m": 0.9,
        "heading_deg": 90.0,
        "bearing_deg": 0.0,
        "range_m": 0.25,
        "max_range_m": 0.4,
        "sd_m": 0.003,
    }
    r.update(kw)
    return r


def map_text(readings, **top) -> str:
    doc = {"format": "rovernav-map", "version": 2, "readings": readings}
    doc.update(top)
    return json.dumps(doc)


BAD_MAPS = [
    ("empty", b"", "is empty"),
    ("blank", b"  \n", "is empty"),
    ("truncated", map_text([reading()])[:30].encode(), "not valid JSON"),
    ("not json", b"hello, map", "not valid JSON"),
    ("not utf-8", b'{"format": "rovernav-map\xff\xfe"}', "not a UTF-8 text file"),
    ("utf-16", map_text([]).encode("utf-16"), "not a UTF-8 text file"),
    ("a list", b"[]", "not a rovernav map"),
    ("another format", json.dumps({"format": "geojson", "version": 2, "readings": []}).encode(), "not a rovernav map"),
    ("version 3", map_text([], version=3).encode(), "version 3"),
    ("version true", map_text([], version=True).encode(), "version True"),
    ("version nan", map_text([], version=math.nan).encode(), "version nan"),
    ("no readings", json.dumps({"format": "rovernav-map", "version": 2}).encode(), "no 'readings'"),
    ("a grid", map_text([], grid=[[0, 1], [1, 0]], width=2).encode(), "unknown keys 'grid', 'width'"),
    ("readings not a list", map_text({"0": reading()}).encode(), "must be a list"),
    ("a reading not an object", map_text([[1, 2, 3]]).encode(), "readings[0] must be an object"),
    ("a key missing", map_text([reading(), {"x_m": 1}]).encode(), "readings[1] must have exactly the keys"),
    ("a key too many", map_text([{**reading(), "z_m": 0}]).encode(), "exactly the keys"),
    ("NaN", map_text([reading(x_m=math.nan)]).encode(), "readings[0].x_m must be a finite number"),
    ("Infinity", map_text([reading(sd_m=math.inf)]).encode(), "sd_m must be a finite number"),
    ("1e999", map_text([reading()]).replace('"y_m": 0.9', '"y_m": 1e999').encode(), "y_m must be a finite"),
    ("a string", map_text([reading(heading_deg="90")]).encode(), "heading_deg must be a finite number"),
    ("a bool", map_text([reading(bearing_deg=True)]).encode(), "bearing_deg must be a finite number"),
    (
        "a 5000-digit integer",
        map_text([reading()]).replace('"x_m": 1.0', '"x_m": 1' + "0" * 5000).encode(),
        "thousands of digits",
    ),
    (
        "a 400-digit integer",
        map_text([reading()]).replace('"x_m": 1.0', '"x_m": 1' + "0" * 400).encode(),
        "x_m must be a finite number",
    ),
    ("far off the arena", map_text([reading(x_m=40.0)]).encode(), "readings[0].x_m must be within"),
    ("another arena", map_text([reading(x_m=9.0, y_m=7.0)]).encode(), "a map of another arena"),
    ("a crazy angle", map_text([reading(heading_deg=1e6)]).encode(), "heading_deg must be within"),
    ("range too long", map_text([reading(range_m=40.0)]).encode(), "range_m must be in (0, 4]"),
    ("range zero", map_text([reading(range_m=0)]).encode(), "range_m must be in"),
    ("max range zero", map_text([reading(max_range_m=0)]).encode(), "max_range_m must be in"),
    ("negative sd", map_text([reading(sd_m=-0.1)]).encode(), "sd_m must be in"),
    ("nested deep", b"[" * 100_000 + b"]" * 100_000, "nested too deeply"),
    (
        "v1 with a null range",
        json.dumps(
            {
                "format": "rovernav-map",
                "version": 1,
                "echoes": [{k: v for k, v in reading(range_m=None).items() if k not in ("max_range_m", "sd_m")}],
            }
        ).encode(),
        "echoes[0].range_m must be a finite number",
    ),
]
