"""Hostile learned-map files: every bad map file is one MapFileError naming the file, in one
line, and nothing of it is replayed; a file too large, with too many readings or too much replay
work is refused before it is read or checked; any content loads or raises only a MapFileError.
(Split from test_hostile_link.py.)"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from tests.hostile_maps import BAD_MAPS, grid, map_text, reading

from rovernav.errors import MapFileError
from rovernav.mapping import SonarReading
from rovernav.mapping.learned_map import (
    MAX_MAP_BYTES,
    MAX_MAP_READINGS,
    LearnedMap,
    check_map_path,
    read_map_file,
)

# ------------------------------------------------------------------ case 1: learned-map files


@pytest.mark.parametrize("content, words", [(c, w) for _, c, w in BAD_MAPS], ids=[i for i, _, _ in BAD_MAPS])
def test_a_bad_map_file_is_one_map_file_error_naming_the_file_and_nothing_is_replayed(tmp_path, content, words):
    path = tmp_path / "learned.json"
    path.write_bytes(content)
    lm = LearnedMap(grid())
    with pytest.raises(MapFileError) as info:
        lm.load(path)
    message = str(info.value)
    assert words in message and str(path) in message and "\n" not in message
    assert lm.readings == []


def test_a_map_file_larger_than_its_limit_is_refused_before_it_is_read(tmp_path):
    path = tmp_path / "huge.json"
    with open(path, "wb") as f:
        f.truncate(MAX_MAP_BYTES + 1)  # sparse: costs no disk
    with pytest.raises(MapFileError, match="a map file is at most"):
        read_map_file(path)


def test_more_readings_than_the_limit_are_refused_before_any_is_checked(tmp_path):
    path = tmp_path / "many.json"
    path.write_text(map_text([0] * (MAX_MAP_READINGS + 1)))
    with pytest.raises(MapFileError, match="at most 200,000 are read"):
        read_map_file(path)


def test_more_replay_work_than_allowed_on_a_huge_arena_is_refused(tmp_path, monkeypatch):
    from rovernav.mapping import learned_map

    monkeypatch.setattr(learned_map, "MAX_REPLAY_CELLS", 10 * grid().raw.size)
    path = tmp_path / "m.json"
    path.write_text(map_text([reading()] * 11))
    with pytest.raises(MapFileError, match="more replay work than allowed; at most 10 on this arena"):
        read_map_file(path, grid())


@pytest.mark.parametrize("make", ["folder", "device", "fifo", "missing"])
def test_a_map_path_that_is_not_a_regular_file_is_refused(tmp_path, make):
    if make == "folder":
        path = tmp_path / "dir.json"
        path.mkdir()
        words = "is a folder"
    elif make == "device":
        if not os.path.exists("/dev/zero"):
            pytest.skip("needs /dev/zero")
        path, words = Path("/dev/zero"), "not a regular file"
    elif make == "fifo":
        if not hasattr(os, "mkfifo"):
            pytest.skip("needs mkfifo")
        path = tmp_path / "pipe.json"
        os.mkfifo(path)
        words = "not a regular file"
    else:
        path, words = tmp_path / "nope.json", "no such map file"
    with pytest.raises(MapFileError, match=words):
        read_map_file(path)


@pytest.mark.parametrize(
    "where, words", [("nodir/map.json", "no folder"), ("", "empty map file name"), (".", "is a folder")]
)
def test_a_map_file_that_could_not_be_saved_is_refused_before_the_run(tmp_path, monkeypatch, where, words):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(MapFileError, match=words):
        check_map_path(where)


def test_a_good_map_still_loads_and_version_1_too(tmp_path):
    lm = LearnedMap(grid())
    lm.add(SonarReading(1.0, 0.9, 90.0, 0.0, 0.25, 0.4, 0.003))
    lm.add(SonarReading(1.0, 0.9, 90.0, 30.0, None, 0.4, 0.003))
    lm.save(tmp_path / "m.json")
    assert LearnedMap(grid()).load(tmp_path / "m.json") == 2
    (tmp_path / "v1.json").write_text(
        json.dumps(
            {
                "format": "rovernav-map",
                "version": 1,
                "echoes": [{"x_m": 1, "y_m": 0.9, "heading_deg": 90, "bearing_deg": 0, "range_m": 0.25}],
            }
        )
    )
    assert LearnedMap(grid()).load(tmp_path / "v1.json") == 1


_json_values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=10),
    lambda children: st.lists(children, max_size=4) | st.dictionaries(st.text(max_size=8), children, max_size=4),
    max_leaves=20,
)
_number = st.one_of(st.floats(), st.integers(), st.none(), st.booleans(), st.text(max_size=3))
_near_readings = st.fixed_dictionaries({k: _number for k in reading()})
_near_maps = st.fixed_dictionaries(
    {
        "format": st.sampled_from(["rovernav-map", "x"]),
        "version": st.sampled_from([1, 2, 2.0, 3, "2", None]),
        "readings": st.lists(st.one_of(_near_readings, _json_values), max_size=5),
    }
)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    st.one_of(
        st.binary(max_size=200),
        _json_values.map(lambda v: json.dumps(v).encode()),
        _near_maps.map(lambda v: json.dumps(v).encode()),
    )
)
def test_any_map_file_content_loads_or_raises_only_a_map_file_error(tmp_path, content):
    path = tmp_path / "fuzz.json"
    path.write_bytes(content)
    lm = LearnedMap(grid())
    try:
        n = lm.load(path)
    except MapFileError as exc:
        assert "\n" not in str(exc) and str(path) in str(exc)
        assert lm.readings == []
        return
    assert n == len(lm.readings)
    assert all(math.isfinite(v) for r in lm.readings for v in (r.x_m, r.y_m, r.heading_deg, r.sd_m))
