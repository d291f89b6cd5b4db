"""One set of rules for what a user gives rovernav: command-line flags, scenario and configuration
values, output paths, port specs, and the sizes of the work they ask for.

Every entry point uses these, so `plan`, `sim` and `run` refuse the same things with the same
words. A refusal is one line naming the flag, file or key and the value, and the command exits
with status 2:

    exit 0   success
    exit 1   the run was made but did not reach its goal (a mission failed, a gate failed)
    exit 2   unusable input: a flag, a file or a value (nothing was run, or the run was refused)
    exit 3   an internal error (a bug: `rovernav -v ...` shows the traceback)
    exit 130 interrupted (Ctrl-C)

The argparse types below raise argparse.ArgumentTypeError (argparse names the flag); the
check_* functions raise InputError with the name they are given.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable
from pathlib import Path
from typing import NoReturn

from .errors import InputError

EXIT_CODES = """exit status: 0 success; 1 the run did not reach its goal; 2 unusable input (a flag, file or
value, named in a one-line error); 3 an internal error (rerun with -v for the traceback); 130 interrupted."""

# Limits on the work a request may ask for: checked before anything is allocated.
MAX_GRID_CELLS = 4_000_000  # an occupancy grid: 2,000 x 2,000 cells (60 x 60 m at 0.03 m), ~100 MB of planner arrays
MAX_ARENA_M = 100.0  # an arena's side
MAX_SIM_TIME_S = 24 * 3600.0  # a simulated mission
MAX_SIM_STEPS = 2_000_000  # steps of a fixed-step simulation (pose: duration / dt)
MAX_TRIPS = 1000  # round trips of one mission


class ArgParser(argparse.ArgumentParser):
    """argparse with one-line errors (`rovernav sim: error: argument --camera-fps: ...`, exit 2)
    and the exit statuses at the end of every command's --help (the common ones, unless the
    command's epilog states its own)."""

    def __init__(self, *args, **kwargs) -> None:
        epilog = kwargs.get("epilog")
        if not epilog:
            kwargs["epilog"] = EXIT_CODES
        elif "exit status" not in epilog.lower():  # a command that states its own says them once
            kwargs["epilog"] = f"{epilog}\n\n{EXIT_CODES}"
        super().__init__(*args, **kwargs)

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def show(text: object) -> str:
    """A name as the user typed it, or its repr if it holds anything unprintable (the error stays
    one line)."""
    t = str(text)
    t = t if t.isprintable() else repr(t)
    return t if len(t) <= 120 else t[:100] + f"... ({len(t):,} characters)"


def _kind(path: Path) -> str:
    """ "dir", "file" or "missing"; a name the system refuses (too long, a NUL) is refused here."""
    try:
        if path.is_dir():
            return "dir"
        return "file" if path.exists() else "missing"
    except (OSError, ValueError) as exc:
        raise argparse.ArgumentTypeError(f"{show(path)}: {getattr(exc, 'strerror', None) or exc}") from None


def _fmt(v: float) -> str:
    return f"{int(v):,}" if float(v).is_integer() and abs(v) >= 10_000 else f"{v:g}"


def _describe(lo: float | None, hi: float | None, lo_open: bool, integer: bool) -> str:
    kind = "an integer" if integer else "a number"
    if lo is not None and hi is not None:
        return f"{kind} {'>' if lo_open else '>='} {_fmt(lo)} and <= {_fmt(hi)}"
    if lo is not None:
        return f"{kind} {'>' if lo_open else '>='} {_fmt(lo)}"
    if hi is not None:
        return f"{kind} <= {_fmt(hi)}"
    return f"a finite {kind[2:] if integer else 'number'}"


def check_number(
    name: str,
    value: object,
    lo: float | None = None,
    hi: float | None = None,
    *,
    lo_open: bool = False,
    integer: bool = False,
) -> float | int:
    """`value` as a finite number within [lo, hi] (lo excluded when lo_open), or InputError naming it."""
    want = _describe(lo, hi, lo_open, integer)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise InputError(f"{name} must be {want}, got {value!r}")
    if integer and not isinstance(value, int):
        if not (isinstance(value, float) and math.isfinite(value) and value.is_integer()):
            raise InputError(f"{name} must be {want}, got {value!r}")
        value = int(value)
    if isinstance(value, float) and not math.isfinite(value):
        raise InputError(f"{name} must be {want}, got {value!r}")
    if lo is not None and (value <= lo if lo_open else value < lo):
        raise InputError(f"{name} must be {want}, got {value!r}")
    if hi is not None and value > hi:
        raise InputError(f"{name} must be {want}, got {value!r}")
    return value


def number(
    lo: float | None = None, hi: float | None = None, *, lo_open: bool = False, integer: bool = False
) -> Callable[[str], float | int]:
    """An argparse type: a finite number (or integer) within [lo, hi]; NaN and infinities refused."""

    def parse(text: str) -> float | int:
        try:
            value: float | int = int(text) if integer else float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not {_describe(lo, hi, lo_open, integer)}") from None
        try:
            return check_number("the value", value, lo, hi, lo_open=lo_open, integer=integer)
        except InputError as exc:
            raise argparse.ArgumentTypeError(f"{text!r}: {exc}".replace("the value ", "")) from None

    parse.__name__ = "integer" if integer else "number"  # argparse names the type in some messages
    return parse


def seconds(hi: float = MAX_SIM_TIME_S, *, positive: bool = False) -> Callable[[str], float]:
    """An argparse type: a time in seconds, >= 0 (or > 0), finite, at most `hi`."""
    return number(0.0, hi, lo_open=positive)


def time_window(text: str) -> tuple[float, float]:
    """An argparse type: START:DURATION in seconds, START >= 0, DURATION > 0, both finite."""
    parts = text.split(":")
    try:
        if len(parts) != 2:
            raise ValueError
        start, duration = float(parts[0]), float(parts[1])
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected START:DURATION in seconds, e.g. 20:10") from None
    if (
        not (math.isfinite(start) and math.isfinite(duration))
        or start < 0
        or duration <= 0
        or start > MAX_SIM_TIME_S
        or duration > MAX_SIM_TIME_S
    ):
        raise argparse.ArgumentTypeError(
            f"{text!r}: START must be >= 0 and DURATION > 0, both finite seconds up to {MAX_SIM_TIME_S:g}"
        )
    return start, duration


def out_dir(text: str) -> Path:
    """An argparse type: an output folder (made if missing), not an existing file."""
    if not text.strip():
        raise argparse.ArgumentTypeError("an empty folder name")
    path = Path(text)
    if _kind(path) == "file":
        raise argparse.ArgumentTypeError(f"{show(text)}: exists and is not a folder")
    return path


def output_file(*suffixes: str) -> Callable[[str], Path]:
    """An argparse type: a file to write, ending in one of `suffixes`, not a folder, in a folder
    that exists."""

    def parse(text: str) -> Path:
        path = Path(text)
        if not text.strip() or text.endswith(("/", "\\")) or _kind(path) == "dir":
            raise argparse.ArgumentTypeError(
                f"{text!r}: a file name is needed (e.g. out/name{suffixes[0]}), not a folder"
            )
        if suffixes and path.suffix.lower() not in suffixes:
            raise argparse.ArgumentTypeError(f"{text!r}: the file name must end in {' or '.join(suffixes)}")
        if _kind(path.parent) != "dir":
            raise argparse.ArgumentTypeError(f"{text!r}: no folder {str(path.parent)!r} to write it in")
        return path

    return parse


def input_file(text: str) -> Path:
    """An argparse type: a file that exists and is a file."""
    path = Path(text)
    if not text.strip():
        raise argparse.ArgumentTypeError("an empty file name")
    kind = _kind(path)
    if kind == "missing":
        raise argparse.ArgumentTypeError(f"{show(text)}: no such file")
    if kind == "dir":
        raise argparse.ArgumentTypeError(f"{show(text)}: is a folder, not a file")
    if not path.is_file():
        raise argparse.ArgumentTypeError(f"{show(text)}: not a regular file (a device or a pipe)")
    return path


def port_spec(text: str) -> str:
    """An argparse type: a serial port or transport spec (a name, loop://, pty://), not blank."""
    if not text.strip():
        raise argparse.ArgumentTypeError(
            "an empty port: give a serial port such as /dev/ttyUSB0 or COM4, or loop:// or pty://"
        )
    if any(ord(c) < 32 for c in text):
        raise argparse.ArgumentTypeError(f"{text!r}: control characters in a port name")
    return text


def read_text_file(path: Path, what: str, max_bytes: int = 10_000_000) -> str:
    """The text of a UTF-8 file, or InputError naming it (missing, a folder, a device or pipe,
    larger than `max_bytes`, unreadable, not UTF-8). Nothing is read before the checks."""
    import stat

    path = Path(path)
    try:
        st = path.stat()
        if stat.S_ISDIR(st.st_mode):
            raise IsADirectoryError
        if not stat.S_ISREG(st.st_mode):
            raise InputError(f"{show(path)}: not a regular file (a device or a pipe), so not a {what}")
        if st.st_size > max_bytes:
            raise InputError(f"{show(path)}: {st.st_size:,} bytes; a {what} is at most {max_bytes:,}")
        return path.read_text(encoding="utf-8")
    except InputError:
        raise
    except FileNotFoundError:
        raise InputError(f"{show(path)}: no such {what}") from None
    except IsADirectoryError:
        raise InputError(f"{show(path)}: is a folder, not a {what}") from None
    except UnicodeDecodeError as exc:
        raise InputError(f"{show(path)}: not a UTF-8 text file (byte {exc.start}): not a {what}") from None
    except (OSError, ValueError) as exc:  # ValueError: a NUL in the name
        raise InputError(f"{show(path)}: cannot read the {what}: {getattr(exc, 'strerror', None) or exc}") from None


def check_grid(width_m: float, height_m: float, resolution_m: float, what: str = "the arena") -> int:
    """The cell count of a width x height grid at `resolution_m`, or InputError with the figure
    when it passes MAX_GRID_CELLS (checked before anything is allocated)."""
    check_number(f"{what}'s width (m)", width_m, 0.0, None, lo_open=True)  # the side's own limit is the
    check_number(f"{what}'s height (m)", height_m, 0.0, None, lo_open=True)  # caller's (a crater map is 50 km)
    check_number("the grid resolution (m)", resolution_m, 0.0, None, lo_open=True)
    cells = math.ceil(width_m / resolution_m) * math.ceil(height_m / resolution_m)
    if cells > MAX_GRID_CELLS:
        raise InputError(
            f"{what}, {width_m:g} x {height_m:g} m at {resolution_m:g} m, is {cells:,} grid cells; "
            f"the limit is {MAX_GRID_CELLS:,} (a coarser resolution or a smaller arena)"
        )
    return cells


def internal_error(command: str, exc: BaseException, verbose: bool) -> int:
    """Report an unexpected exception in one line (the traceback with -v); exit status 3."""
    if verbose:
        import traceback

        traceback.print_exception(type(exc), exc, exc.__traceback__, file=sys.stderr)
    text = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
    print(
        f"rovernav {command}: internal error: {type(exc).__name__}{': ' + text if text else ''} "
        "(a bug; rerun with -v for the traceback)",
        file=sys.stderr,
    )
    return 3
