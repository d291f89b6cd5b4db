"""Writing results so that a reader never sees half a file or a stale one mixed with a new one."""

from __future__ import annotations

import json
import math
import os
import tempfile
from pathlib import Path
from typing import Any


def write_atomic(path: Path, data: str | bytes) -> None:
    """Write `data` to a temporary file beside `path`, then rename it into place."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data.encode("utf-8") if isinstance(data, str) else data)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # as an ordinary new file (mkstemp makes it 0600)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def strict_json_value(value: Any) -> Any:
    """`value` with every NaN or infinity replaced by None (and numpy scalars and arrays by Python
    values), so that json.dumps(..., allow_nan=False) accepts it: JSON has no NaN, and other
    languages' parsers refuse it."""
    if isinstance(value, dict):
        return {k: strict_json_value(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [strict_json_value(v) for v in value]
    if hasattr(value, "tolist") and callable(value.tolist):  # numpy scalar or array
        return strict_json_value(value.tolist())
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def strict_json(value: Any, indent: int | None = 2) -> str:
    """Strict JSON text of `value` (undefined numbers as null), with a final newline."""
    return json.dumps(strict_json_value(value), indent=indent, allow_nan=False) + "\n"


def write_json_atomic(path: Path, value: Any) -> None:
    """Strict JSON, written atomically."""
    write_atomic(path, strict_json(value))


def remove_stale(folder: Path, names: tuple[str, ...]) -> list[str]:
    """Delete the files `names` of a previous run from `folder` (before a new run writes there), so
    that an interrupted or failed run never leaves the old results beside the new. Returns what
    was removed."""
    removed = []
    for name in names:
        path = Path(folder) / name
        if path.is_file() or path.is_symlink():
            path.unlink()
            removed.append(name)
    return removed


class build_lock:
    """`with build_lock(folder):` one process at a time builds into `folder` (an flock on
    folder/.build.lock): two simulations, or two test workers, that find the firmware core or the
    simavr harness out of date do not both run the compiler over the same outputs."""

    def __init__(self, folder: Path):
        self.path = Path(folder) / ".build.lock"
        self._fd: int | None = None

    def __enter__(self) -> build_lock:
        import fcntl

        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
        fcntl.flock(self._fd, fcntl.LOCK_EX)
        return self

    def __exit__(self, *exc) -> None:
        import fcntl

        if self._fd is not None:
            fcntl.flock(self._fd, fcntl.LOCK_UN)
            os.close(self._fd)
            self._fd = None
