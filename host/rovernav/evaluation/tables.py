"""What a benchmark writes: trials.csv, trials.json, trials.md (the Markdown tables) and the
gallery of failed runs."""

from __future__ import annotations

import contextlib
import csv
import io
import json
import platform
import shutil
import subprocess
from collections.abc import Callable, Iterable
from pathlib import Path

from .. import __version__
from ..files import strict_json_value, write_atomic
from .scoring import GATED_STRATEGY, ROW_FIELDS, _row_order, gate_violations, headline, headlines_by, strategies_of

# ---------------------------------------------------------------- outputs


def _frac(count: int, total: int) -> str:
    return f"{count}/{total} ({100 * count / total:.0f} %)" if total else "-"


def _num(value: float | None, digits: int) -> str:
    return "-" if value is None else f"{value:.{digits}f}"


TABLE_COLUMNS: tuple[tuple[str, Callable[[dict], str]], ...] = (
    ("runs", lambda h: str(h["runs"])),
    ("success (solvable)", lambda h: _frac(h["successes"], h["solvable_runs"])),
    ("crashes", lambda h: _frac(h["crashes"], h["runs"])),
    ("false 'unreachable'", lambda h: _frac(h["false_unreachable"], h["solvable_runs"])),
    ("correct 'unreachable'", lambda h: _frac(h["correct_unreachable"], h["unsolvable_runs"])),
    ("timeouts", lambda h: str(h["timeouts"])),
    ("hung", lambda h: str(h["hung"])),
    ("errors", lambda h: str(h["errors"])),
    ("median time / optimum", lambda h: _num(h["median_time_ratio"], 2)),
    ("BARN score", lambda h: _num(h["mean_barn_score"], 3)),
    ("time score", lambda h: _num(h["mean_time_score"], 3)),
    ("SPL", lambda h: _num(h["mean_spl"], 2)),
)


def markdown_table(first_column: str, groups: dict[str, dict]) -> str:
    """A Markdown table: one line per group (name -> headline), the columns of TABLE_COLUMNS."""
    lines = [
        "| " + " | ".join([first_column] + [name for name, _ in TABLE_COLUMNS]) + " |",
        "|" + "---|" * (len(TABLE_COLUMNS) + 1),
    ]
    for group, h in groups.items():
        lines.append("| " + " | ".join([group] + [cell(h) for _, cell in TABLE_COLUMNS]) + " |")
    return "\n".join(lines)


DEFINITIONS = """\
- *success*: every leg reached with no contact at all; rates over solvable runs (an arena is
  solvable by its [generated] label, else if the clairvoyant planner finds a path).
- *crashes*: runs with any contact (the simulator stops a run at the first); rate over all runs.
- *false / correct 'unreachable'*: the host's verdict that the target cannot be reached, on a
  solvable / unsolvable arena.
- *timeouts*: stopped by the simulated --max-time; *hung*: past the wall-clock --run-timeout.
- *time / optimum*: mission time AT over the optimal time OT (the clairvoyant optimum's length
  at the rover's cruise speed), median over successes.
- *BARN score* (Xiao et al., 2022): mean over solvable runs of success x OT / clip(AT, 4 OT, 8 OT),
  at most 0.25. *time score*: mean of success x OT / max(AT, OT), 1 at the optimum.
- *SPL*: success weighted by path length (Anderson et al., 2018), mean over solvable runs."""


def render_markdown(summary: dict) -> str:
    """trials.md from the summary (trials.json without its rows)."""
    s = summary
    gate = s["gate"]
    verdict = "passed" if gate["passed"] else f"FAILED ({len(gate['violations'])} violations)"
    parts = [
        f"# Trials: {s['settings']['arenas']} arenas of {s['settings']['arenas_dir']}",
        "",
        f"`{s['command']}`",
        "",
        f"{s['started_utc']}, {s['wall_time_s']:.0f} s wall, {s['settings']['runner']}; "
        f"rovernav {s['versions']['rovernav']}.",
        "",
        f"Radio: {radio_text(s['settings'].get('radio'))}.",
        "",
        "## Headline",
        "",
        markdown_table("strategy", s["headline"]),
        "",
        f"Gate ({GATED_STRATEGY} runs; fails on {', '.join(gate['fail_on']) or 'nothing'}): {verdict}.",
    ]
    parts += [f"- {v['run']}: {v['category']} ({v['reason']})" for v in gate["violations"]]
    for strategy in s["headline"]:
        parts += [
            "",
            f"## {strategy} by family",
            "",
            markdown_table("family", s["by_family"][strategy]),
            "",
            f"## {strategy} by difficulty band",
            "",
            markdown_table("band", s["by_band"][strategy]),
        ]
    parts += ["", "## Definitions", "", DEFINITIONS, ""]
    return "\n".join(parts)


def write_gallery(out_dir: Path, rows: list[dict]) -> list[dict]:
    """Copy the summary.png of every failed run into out_dir/gallery/ (rebuilt) and write
    out_dir/gallery.md listing them with their reasons. Returns the failed rows, in order."""
    gallery = out_dir / "gallery"
    if gallery.exists():
        shutil.rmtree(gallery)
    gallery.mkdir(parents=True)
    failed = [r for r in sorted(rows, key=_row_order) if r["failed"]]
    lines = [f"# Failed runs: {len(failed)} of {len(rows)}", ""]
    if failed:
        lines += ["| run | reason | picture | report |", "|---|---|---|---|"]
    for r in failed:
        picture = report = "-"
        if r["report"]:
            source = out_dir / Path(r["report"]).with_name("summary.png")
            report = f"[report.json]({r['report']})"
            if source.is_file():
                name = f"{r['strategy']}-{r['arena']}-s{r['seed']}.png"
                shutil.copyfile(source, gallery / name)
                picture = f"[{name}](gallery/{name})"
        reason = (r["reason"] or "").replace("|", "/")
        lines.append(f"| {r['arena']} {r['strategy']} s{r['seed']} | {reason} | {picture} | {report} |")
    write_atomic(out_dir / "gallery.md", "\n".join(lines) + "\n")
    return failed


def write_outputs(out_dir: Path, rows: list[dict], context: dict, fail_on: Iterable[str]) -> dict:
    """trials.csv, trials.json, trials.md and the gallery in out_dir. `rows` have report paths
    relative to out_dir; `context` holds command, versions, settings, started_utc, wall_time_s.
    Returns the summary (trials.json's content without the rows)."""
    rows = [strict_json_value(r) for r in sorted(rows, key=_row_order)]
    fail_on = list(fail_on)
    violations = gate_violations(rows, fail_on)
    summary = dict(context)
    summary.update(
        gate={"strategy": GATED_STRATEGY, "fail_on": fail_on, "passed": not violations, "violations": violations},
        headline={st: headline([r for r in rows if r["strategy"] == st]) for st in strategies_of(rows)},
        by_family=headlines_by(rows, "family"),
        by_band=headlines_by(rows, "band"),
    )
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=ROW_FIELDS, lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    write_atomic(out_dir / "trials.csv", buffer.getvalue())
    write_atomic(out_dir / "trials.json", json.dumps(summary | {"rows": rows}, indent=1, allow_nan=False) + "\n")
    write_atomic(out_dir / "trials.md", render_markdown(summary))
    write_gallery(out_dir, rows)
    return summary


def versions() -> dict:
    """What produced the results: rovernav, its git commit when known, Python and the libraries."""
    import dask
    import distributed
    import numpy

    commit = None
    with contextlib.suppress(OSError, subprocess.SubprocessError):
        done = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=Path(__file__).parent, capture_output=True, text=True, timeout=5
        )
        if done.returncode == 0:
            commit = done.stdout.strip() or None
    return {
        "rovernav": __version__,
        "git_commit": commit,
        "python": platform.python_version(),
        "numpy": numpy.__version__,
        "dask": dask.__version__,
        "distributed": distributed.__version__,
        "platform": platform.platform(),
    }


def radio_text(st: dict | None) -> str:
    """The radio's settings in a few words (trials.md)."""
    if not st:
        return "the simulator's default"
    parts = [
        f"{st['baud']:,} baud",
        f"{st['delay_ms']:g} ms latency",
        f"byte loss {st['loss_pct']:g} %",
        f"bit errors {st['ber_pct']:g} % of bytes",
    ]
    burst = st["burst"]
    parts.append(
        f"in bursts of {burst['mean_s']:g} s mean, {100 * burst['share']:g} % of the time, one process both ways"
        if burst
        else "independent, no bursts"
    )
    parts.append(f"jitter {st['jitter_ms']:g} ms mean per frame" if st["jitter_ms"] else "no jitter")
    parts.append("half duplex (collisions)" if st["half_duplex"] else "full duplex")
    return ", ".join(parts)
