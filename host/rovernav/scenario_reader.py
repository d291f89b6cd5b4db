"""Reading a scenario file's tables (rovernav.scenario's parts): the error every problem raises,
the reader that checks each key and names it in its message, and the [generated] table of a
generated arena."""

from __future__ import annotations

import math
from typing import Any

from .errors import InputError

DIFFICULTY_BANDS = ("easy", "medium", "hard")


class ScenarioError(InputError):
    """A scenario file is missing, unreadable or invalid; the message names the file and the key."""


class _Reader:
    def __init__(self, source: str):
        self.source = source

    def fail(self, key: str, problem: str) -> ScenarioError:
        return ScenarioError(f"{self.source}: {key} {problem}")

    def table(self, doc: dict[str, Any], key: str, required: bool = True) -> dict[str, Any]:
        if key not in doc:
            if required:
                raise self.fail(key, "is missing (a [" + key + "] table)")
            return {}
        value = doc[key]
        if not isinstance(value, dict):
            raise self.fail(key, f"must be a table, got {value!r}")
        return value

    def only(self, table: dict[str, Any], prefix: str, allowed: tuple[str, ...]) -> None:
        for key in table:
            if key not in allowed:
                raise self.fail(f"{prefix}{key}", f"is not a known key (known here: {', '.join(allowed)})")

    def number(
        self, table: dict[str, Any], prefix: str, key: str, default: float | None = None, positive: bool = False
    ) -> float:
        name = f"{prefix}{key}"
        if key not in table:
            if default is None:
                raise self.fail(name, "is missing")
            return default
        value = table[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise self.fail(name, f"must be a number, got {value!r}")
        if positive and value <= 0:
            raise self.fail(name, f"must be a number > 0, got {value!r}")
        return float(value)

    def array(self, doc: dict[str, Any], key: str, allowed: tuple[str, ...]):
        """The tables of an optional array of tables ([[key]]): (prefix "key[i].", table, known),
        each checked for unknown keys and its `known` flag (default true)."""
        values = doc.get(key, [])
        if not isinstance(values, list):
            raise self.fail(key, f"must be an array of tables ([[{key}]])")
        for i, o in enumerate(values):
            if not isinstance(o, dict):
                raise self.fail(f"{key}[{i}]", f"must be a table, got {o!r}")
            prefix = f"{key}[{i}]."
            self.only(o, prefix, allowed)
            known = o.get("known", True)
            if not isinstance(known, bool):
                raise self.fail(f"{prefix}known", f"must be true or false, got {known!r}")
            yield prefix, o, known


def _generated(r: _Reader, doc: dict[str, Any]) -> dict[str, Any]:
    """The optional [generated] table (see the module's docstring), checked key by key."""
    g = r.table(doc, "generated")
    r.only(g, "generated.", ("family", "seed", "index", "solvable", "passage_width_m", "difficulty"))
    for key in ("family", "seed", "index", "solvable", "difficulty"):
        if key not in g:
            raise r.fail(f"generated.{key}", "is missing")
    out: dict[str, Any] = {}
    family = g.get("family")
    if not isinstance(family, str) or not family:
        raise r.fail("generated.family", f"must be a non-empty string, got {family!r}")
    out["family"] = family
    for key in ("seed", "index"):
        value = g.get(key)
        if isinstance(value, bool) or not isinstance(value, int) or value < 0:
            raise r.fail(f"generated.{key}", f"must be a whole number ≥ 0, got {value!r}")
        out[key] = value
    solvable = g.get("solvable")
    if not isinstance(solvable, bool):
        raise r.fail("generated.solvable", f"must be true or false, got {solvable!r}")
    out["solvable"] = solvable
    if "passage_width_m" in g:
        out["passage_width_m"] = r.number(g, "generated.", "passage_width_m", positive=True)

    prefix = "generated.difficulty."
    d = r.table(g, "difficulty")
    numbers = (
        "closest_obstacle_m",
        "mean_clearance_m",
        "dispersion",
        "characteristic_dimension_m",
        "narrowest_dimension_m",
    )
    optional = ("optimal_length_m", "detour_ratio")
    r.only(d, prefix, (*numbers, *optional, "known_path_blocked", "score", "band"))
    difficulty: dict[str, Any] = {}
    for key in (*numbers, *(k for k in optional if k in d)):
        value = r.number(d, prefix, key)
        if value < 0:
            raise r.fail(f"{prefix}{key}", f"must be a number ≥ 0, got {value!r}")
        difficulty[key] = value
    if "known_path_blocked" in d:
        blocked = d["known_path_blocked"]
        if not isinstance(blocked, bool):
            raise r.fail(f"{prefix}known_path_blocked", f"must be true or false, got {blocked!r}")
        difficulty["known_path_blocked"] = blocked
    score = r.number(d, prefix, "score")
    if not 0.0 <= score <= 1.0:
        raise r.fail(f"{prefix}score", f"must be a number from 0 to 1, got {score!r}")
    difficulty["score"] = score
    band = d.get("band")
    if band not in DIFFICULTY_BANDS:
        raise r.fail(f"{prefix}band", f"must be one of {', '.join(DIFFICULTY_BANDS)}, got {band!r}")
    difficulty["band"] = band
    out["difficulty"] = difficulty
    return out


# --- writing -------------------------------------------------------------------------------
