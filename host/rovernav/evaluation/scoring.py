"""A run's row (ROW_FIELDS) from its report, the judgements on it (success, the verdicts, the
BARN and time scores, failed and why) and the headline figures of many rows, with the gate."""

from __future__ import annotations

import collections
import statistics
from collections.abc import Iterable

STRATEGIES = ("rovernav", "seed")
GATED_STRATEGY = "rovernav"
UNLABELLED = "unlabelled"
BARN_CLIP_LOW = 4.0  # BARN: actual time clipped to [4 OT, 8 OT]
BARN_CLIP_HIGH = 8.0

ROW_FIELDS = (
    "arena",
    "family",
    "band",
    "difficulty",
    "solvable",
    "strategy",
    "seed",
    "outcome",
    "reached",
    "success",
    "failed",
    "reason",
    "crashed",
    "crash_against",
    "crash_t_s",
    "collisions",
    "verdict_unreachable",
    "correct_unreachable",
    "false_unreachable",
    "timed_out",
    "mission_time_s",
    "optimal_time_s",
    "time_ratio",
    "barn_score",
    "time_score",
    "spl",
    "path_length_m",
    "optimal_length_m",
    "min_clearance_m",
    "replans",
    "max_dr_error_m",
    "wall_time_s",
    "error",
    "report",
)


def _blank_row(arena: str, strategy: str, seed: int, meta: dict | None) -> dict:
    meta = meta or {}
    difficulty = meta.get("difficulty") or {}
    row = dict.fromkeys(ROW_FIELDS)
    row.update(
        arena=arena,
        strategy=strategy,
        seed=seed,
        family=meta.get("family") or UNLABELLED,
        band=difficulty.get("band"),
        difficulty=difficulty.get("score"),
        solvable=meta.get("solvable"),
        reached=False,
        crashed=False,
        timed_out=False,
        collisions=0,
    )
    return row


def row_from_report(report: dict, arena: str) -> dict:
    """The row of a run from its report (build_report's dict, with the arena's [generated]
    table as its scenario_meta)."""
    row = _blank_row(arena, report["strategy"], report["seed"], report["scenario_meta"])
    crash = report["crash"] or {}
    if row["solvable"] is None:  # an unlabelled arena: the clairvoyant planner decides
        row["solvable"] = report["optimal_length_m"] is not None
    row.update(
        outcome=report["outcome"],
        reached=report["reached"],
        crashed=report["crashed"] or report["collisions"] > 0,
        crash_against=crash.get("against"),
        crash_t_s=crash.get("t_s"),
        collisions=report["collisions"],
        timed_out=report["timed_out"],
        mission_time_s=report["mission_time_s"],
        optimal_time_s=report["optimal_time_s"],
        spl=report["spl"],
        path_length_m=report["path_length_m"],
        optimal_length_m=report["optimal_length_m"],
        min_clearance_m=report["min_clearance_m"],
        replans=report["replans"],
        max_dr_error_m=report["faults"]["max_dr_error_m"],
        wall_time_s=report["wall_time_s"],
        error=report["error"],
    )
    return derive(row)


# ---------------------------------------------------------------- scores


def barn_score(success: bool, optimal_time_s: float | None, actual_time_s: float | None) -> float | None:
    """BARN Challenge score (Xiao et al., 2022): success x OT / clip(AT, 4 OT, 8 OT).
    0 for a failure; None for a success whose optimal time is unknown."""
    if not success:
        return 0.0
    if not optimal_time_s or optimal_time_s <= 0 or actual_time_s is None:
        return None
    clipped = min(max(actual_time_s, BARN_CLIP_LOW * optimal_time_s), BARN_CLIP_HIGH * optimal_time_s)
    return optimal_time_s / clipped


def time_score(success: bool, optimal_time_s: float | None, actual_time_s: float | None) -> float | None:
    """success x OT / max(AT, OT): 1 for a run as fast as the clairvoyant optimum, 0 for a failure;
    None for a success whose optimal time is unknown."""
    if not success:
        return 0.0
    if not optimal_time_s or optimal_time_s <= 0 or actual_time_s is None:
        return None
    return optimal_time_s / max(actual_time_s, optimal_time_s)


def derive(row: dict) -> dict:
    """Fill a row's judgements from its facts (outcome, reached, crashed, collisions, solvable,
    times): success, the verdicts, the scores, failed and its reason. Returns the same row."""
    success = row["reached"] and row["collisions"] == 0 and not row["crashed"]
    verdict = row["outcome"] == "no_path"
    ot, at = row["optimal_time_s"], row["mission_time_s"]
    row.update(
        success=success,
        verdict_unreachable=verdict,
        correct_unreachable=verdict and row["solvable"] is False,
        false_unreachable=verdict and row["solvable"] is True,
        time_ratio=round(at / ot, 3) if ot and at is not None else None,
    )
    if row["solvable"] is False:  # no time to beat: scores do not apply
        row.update(barn_score=None, time_score=None)
    else:
        row.update(barn_score=_round(barn_score(success, ot, at), 4), time_score=_round(time_score(success, ot, at), 4))
    row["reason"] = failure_reason(row)
    row["failed"] = row["reason"] is not None
    return row


def failure_reason(row: dict) -> str | None:
    """Why a run counts as failed (one line), or None when it did what it should."""
    if row["correct_unreachable"] or (row["success"] and row["solvable"] is not False):
        return None
    error = row["error"] or "no reason given"
    if row["crashed"]:
        where = f" at {row['crash_t_s']:.1f} s" if row["crash_t_s"] is not None else ""
        return (
            f"crashed into {row['crash_against']}{where}"
            if row["crash_against"]
            else f"touched an obstacle ({row['collisions']} contacts)"
        )
    outcome = row["outcome"]
    if outcome == "no_path":  # on a solvable arena: an unsolvable one returned above
        return f"false 'unreachable': {error}"
    if outcome == "reached":
        return "reached a target labelled unreachable"
    if outcome == "timeout":
        return f"timed out at {row['mission_time_s']:.0f} s simulated"
    if outcome == "hung":
        return f"hung: {error}"
    if outcome == "error":
        return f"raised {error}"
    if row["solvable"] is False:
        return f"no 'unreachable' verdict ({outcome}): {error}"
    return f"{outcome}: {error}"


def _round(value: float | None, digits: int) -> float | None:
    return None if value is None else round(value, digits)


# ---------------------------------------------------------------- figures


def _rate(count: int, total: int) -> float | None:
    return count / total if total else None


def _mean(values: list[float]) -> float | None:
    return statistics.fmean(values) if values else None


def headline(rows: list[dict]) -> dict:
    """The headline figures of a set of rows (usually one strategy's); rates are fractions
    (None when their denominator is 0)."""
    solvable = [r for r in rows if r["solvable"] is not False]
    unsolvable = [r for r in rows if r["solvable"] is False]
    successes = [r for r in solvable if r["success"]]
    crashes = sum(r["crashed"] for r in rows)
    false_unreachable = sum(r["false_unreachable"] for r in solvable)
    correct_unreachable = sum(r["correct_unreachable"] for r in unsolvable)
    ratios = [r["time_ratio"] for r in successes if r["time_ratio"] is not None]
    return {
        "runs": len(rows),
        "solvable_runs": len(solvable),
        "unsolvable_runs": len(unsolvable),
        "successes": len(successes),
        "success_rate": _rate(len(successes), len(solvable)),
        "crashes": crashes,
        "crash_rate": _rate(crashes, len(rows)),
        "false_unreachable": false_unreachable,
        "false_unreachable_rate": _rate(false_unreachable, len(solvable)),
        "correct_unreachable": correct_unreachable,
        "correct_unreachable_rate": _rate(correct_unreachable, len(unsolvable)),
        "timeouts": sum(r["outcome"] == "timeout" for r in rows),
        "hung": sum(r["outcome"] == "hung" for r in rows),
        "errors": sum(r["outcome"] == "error" for r in rows),
        "failed": sum(r["failed"] for r in rows),
        "median_time_ratio": statistics.median(ratios) if ratios else None,
        "mean_barn_score": _mean([r["barn_score"] for r in solvable if r["barn_score"] is not None]),
        "mean_time_score": _mean([r["time_score"] for r in solvable if r["time_score"] is not None]),
        "mean_spl": _mean([r["spl"] for r in solvable if r["spl"] is not None]),
    }


def strategies_of(rows: list[dict]) -> list[str]:
    """The strategies present, rovernav first."""
    present = {r["strategy"] for r in rows}
    return [s for s in STRATEGIES if s in present] + sorted(present - set(STRATEGIES))


def headlines_by(rows: list[dict], field: str) -> dict[str, dict[str, dict]]:
    """{strategy: {group: headline}} grouped by `field` ("family" or "band"). Families in name
    order; bands by their median difficulty score; unlabelled last."""
    out: dict[str, dict[str, dict]] = {}
    for strategy in strategies_of(rows):
        mine = [r for r in rows if r["strategy"] == strategy]
        groups: dict[str, list[dict]] = collections.defaultdict(list)
        for r in mine:
            groups[r[field] or UNLABELLED].append(r)

        def order(name: str) -> tuple:
            scores = [r["difficulty"] for r in groups[name] if r["difficulty"] is not None]
            return (name == UNLABELLED, statistics.median(scores) if field == "band" and scores else 0.0, name)

        out[strategy] = {name: headline(groups[name]) for name in sorted(groups, key=order)}
    return out


def gate_violations(rows: list[dict], fail_on: Iterable[str]) -> list[dict]:
    """The gated strategy's runs that fail the gate: one entry per run and category."""
    checks = {
        "crash": lambda r: r["crashed"],
        "false_unreachable": lambda r: r["false_unreachable"],
        "timeout": lambda r: r["outcome"] in ("timeout", "hung"),
        "error": lambda r: r["outcome"] == "error",
        "failure": lambda r: r["failed"],
    }
    return [
        {"run": f"{r['arena']} {r['strategy']} s{r['seed']}", "category": category, "reason": r["reason"]}
        for r in sorted(rows, key=_row_order)
        if r["strategy"] == GATED_STRATEGY
        for category in fail_on
        if checks[category](r)
    ]


def _row_order(row: dict) -> tuple:
    return (row["strategy"] != GATED_STRATEGY, row["strategy"], row["arena"], row["seed"])
