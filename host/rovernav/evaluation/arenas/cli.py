"""`rovernav arenas`: the command's flags, its help and what it prints."""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from ...validate import output_file
from .difficulty import BAND_HARD, BAND_MEDIUM, RAY_LENGTH_M, SCORE_WEIGHTS
from .draw import ArenaError, GenerationFailed
from .families import ALL_FAMILY_NAMES, FAMILIES
from .generate import GALLERY_COUNT, MAX_COUNT, GeneratedArena, _families, generate_arenas, write_arenas, write_gallery

# --- the command ----------------------------------------------------------------------------------


def _help_epilog() -> str:
    width = max(len(n) for n in ALL_FAMILY_NAMES)
    families = "\n".join(f"  {name:<{width}}  {text}" for name, text in FAMILIES)
    return f"""families (arena i is of family (i - 1) mod F of those asked for; by default all but those
drawn by name only):
{families}

every file is a scenario (see scenarios/) with a [generated] table: family, seed, index,
solvable (A* finds a path with every obstacle known), passage_width_m (narrow_passage), and
[generated.difficulty], measured along that clairvoyant optimum sampled every 3 cm (the
straight start-target segment when unsolvable), in the spirit of BARN:
  closest_obstacle_m          smallest distance from the path to an obstacle or the wall
  mean_clearance_m            mean of that distance along the path
  dispersion                  free/occupied switches along 16 rays of {RAY_LENGTH_M:g} m from each path
                              point, summed over the rays, mean over the points (walls end rays)
  characteristic_dimension_m  narrowest of the 8 lines through a path point (to the first
                              obstacle or wall each way, {RAY_LENGTH_M:g} m at most), mean over the points
  narrowest_dimension_m       the same, smallest over the points: the tightest place passed
  optimal_length_m, detour_ratio   the optimum's length, and over the straight distance
  known_path_blocked          the path planned on the known obstacles crosses an unknown one
  score in [0, 1] = {" + ".join(f"{w:.2f} {k}" for k, w in SCORE_WEIGHTS.items())}
  band: easy below {BAND_MEDIUM}, medium, hard from {BAND_HARD}
(rovernav.evaluation.arenas explains each term.)

writes DIR/arena-0001-<family>.toml ..., DIR/index.json and DIR/index.csv (one row per arena),
and a contact sheet of the first {GALLERY_COUNT} arenas (DIR/gallery.png, or --picture FILE); arena
files of an earlier run in DIR that this run did not write are removed. The same --seed gives
the same files byte for byte."""


def add_arenas_parser(sub) -> None:
    """Register `rovernav arenas` on the command's subparsers."""
    p = sub.add_parser(
        "arenas",
        help="generate arenas (scenario files) from families of rooms and tests, with labels",
        description="Write COUNT scenario files drawn from families of arenas that real rooms and the seed's "
        "tests contain, each labelled with its family, a difficulty and whether it can be solved "
        "with every obstacle known; the families are cycled, so any count of at least the number "
        "of families covers them all.",
        epilog=_help_epilog(),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--count", default="200", metavar="N", help=f"how many arenas, 1 to {MAX_COUNT} (default 200)")
    p.add_argument("--seed", default="1", metavar="S", help="random seed, a whole number ≥ 0 (default 1)")
    p.add_argument("--out", default="out/arenas", metavar="DIR", help="output folder (default out/arenas)")
    p.add_argument(
        "--family", default=None, metavar="F[,F...]", help="only these families (comma-separated; default all)"
    )
    p.add_argument(
        "--picture",
        default=None,
        metavar="FILE",
        type=output_file(".png", ".jpg"),
        help=f"where to write the contact sheet of the first {GALLERY_COUNT} arenas (default DIR/gallery.png)",
    )
    p.set_defaults(func=cmd_arenas)


def _whole(text: str, flag: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise ArenaError(f"{flag} must be a whole number, got {text!r}") from None


def cmd_arenas(args: argparse.Namespace) -> int:
    """The `arenas` command: 0 when written, 2 for a bad request or an unwritable folder, 1 if a
    draw fails."""
    started = time.perf_counter()
    try:
        count, seed = _whole(args.count, "--count"), _whole(args.seed, "--seed")
        if not 1 <= count <= MAX_COUNT:
            raise ArenaError(f"--count must be from 1 to {MAX_COUNT}, got {count}")
        if seed < 0:
            raise ArenaError(f"--seed must be ≥ 0, got {seed}")
        families = _families(args.family.split(",") if args.family is not None else None)
        out = Path(args.out)
        if out.exists() and not out.is_dir():
            raise ArenaError(f"--out {out}: exists and is not a folder")
        picture = Path(args.picture) if args.picture else out / "gallery.png"
        if picture.is_dir():
            raise ArenaError(f"--picture {picture}: is a folder")

        every = 20

        def progress(done: int, total: int) -> None:
            if done % every == 0 or done == total:
                print(f"  {done}/{total} arenas, {time.perf_counter() - started:.1f} s", flush=True)

        print(f"rovernav arenas: {count} arenas, seed {seed}, families: {', '.join(families)}", flush=True)
        arenas = generate_arenas(count, seed, families, progress=progress)
        write_arenas(arenas, out)
        write_gallery(arenas, picture)
    except (ArenaError, OSError) as exc:
        print(f"rovernav arenas: {exc}", file=sys.stderr)
        return 2
    except GenerationFailed as exc:
        print(f"rovernav arenas: {exc}", file=sys.stderr)
        return 1
    print(_summary(arenas))
    print(
        f"wrote {len(arenas)} arenas, index.json and index.csv to {out}, the contact sheet to {picture}, "
        f"in {time.perf_counter() - started:.1f} s"
    )
    return 0


def _summary(arenas: Sequence[GeneratedArena]) -> str:
    """A table: per family, how many arenas, how many solvable, and how many in each band."""
    width = max(len(n) for n in ALL_FAMILY_NAMES)
    lines = [f"{'family':<{width}}  arenas  solvable  easy  medium  hard"]
    groups: dict[str, list[GeneratedArena]] = {}
    for a in arenas:
        groups.setdefault(a.family, []).append(a)

    def line(label: str, group: Sequence[GeneratedArena]) -> str:
        bands = [a.difficulty["band"] for a in group]
        return (
            f"{label:<{width}}  {len(group):>6}  {sum(a.solvable for a in group):>8}  "
            f"{bands.count('easy'):>4}  {bands.count('medium'):>6}  {bands.count('hard'):>4}"
        )

    lines += [line(name, groups[name]) for name in ALL_FAMILY_NAMES if name in groups]
    lines.append(line("all", arenas))
    return "\n".join(lines)
