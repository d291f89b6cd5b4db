"""The link's 128-bit key: made by `rovernav keygen`, kept in a file only its owner can read.

A key file holds 32 hexadecimal digits and a newline. It is written with mode 0600 and never
over an existing file unless asked; a key file that others can read, or that is not 32 hex
digits, is refused with a message naming it (the way ssh refuses a private key others can read).
"""

from __future__ import annotations

import os
import secrets
import stat
from pathlib import Path

from ..errors import InputError
from ..validate import show
from .siphash import KEY_BYTES


class KeyFileError(InputError):
    """A key file that cannot be used; the message names it."""


def write_key_file(path: Path, force: bool = False) -> bytes:
    """Make a new random key and write it to `path` (mode 0600); returns it."""
    path = Path(path)
    if path.is_dir():
        raise KeyFileError(f"{show(path)}: is a folder; give the key file's name")
    if not path.parent.is_dir():
        raise KeyFileError(f"{show(path)}: no folder {show(path.parent)} to write it in")
    key = secrets.token_bytes(KEY_BYTES)
    flags = os.O_WRONLY | os.O_CREAT | (os.O_TRUNC if force else os.O_EXCL)
    try:
        fd = os.open(path, flags, 0o600)
    except FileExistsError:
        raise KeyFileError(
            f"{show(path)}: exists; a new key would lock out the rover that has the old one (--force to replace it)"
        ) from None
    with os.fdopen(fd, "w") as f:
        os.fchmod(f.fileno(), 0o600)  # also when --force replaced a file with other permissions
        f.write(key.hex() + "\n")
    return key


def load_key_file(path: Path) -> bytes:
    """The key in `path`, or KeyFileError: missing, not a regular file, readable by others, or not
    32 hexadecimal digits."""
    path = Path(path)
    try:
        st = path.stat()
    except FileNotFoundError:
        raise KeyFileError(f"{show(path)}: no such key file (`rovernav keygen --out {show(path)}` makes one)") from None
    except OSError as exc:
        raise KeyFileError(f"{show(path)}: {exc.strerror}") from None
    if not stat.S_ISREG(st.st_mode):
        raise KeyFileError(f"{show(path)}: not a regular file, so not a key file")
    if st.st_mode & 0o077:
        raise KeyFileError(
            f"{show(path)}: others can read it (mode {stat.S_IMODE(st.st_mode):04o}); chmod 600 {show(path)}"
        )
    if st.st_size > 256:
        raise KeyFileError(f"{show(path)}: {st.st_size} bytes is not a key file (32 hex digits)")
    text = path.read_bytes().decode("ascii", errors="replace").strip()
    try:
        key = bytes.fromhex(text)
    except ValueError:
        key = b""
    if len(key) != KEY_BYTES:
        raise KeyFileError(f"{show(path)}: not a key file: {2 * KEY_BYTES} hexadecimal digits expected")
    return key
