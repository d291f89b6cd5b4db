"""Reading a configuration file to update some of its tables, and writing it back checked: one
copy for `calibrate camera --write` ([vision]) and `calibrate rover --write` ([rover])."""

from __future__ import annotations

from pathlib import Path

from ..errors import InputError


def load_for_update(path: Path, comment: str):
    """FILE as a tomlkit document (every other table, key and comment kept), or a new one headed
    by `comment` when it does not exist. InputError names a file that cannot be read or parsed."""
    import tomlkit

    if not path.exists():
        doc = tomlkit.document()
        doc.add(tomlkit.comment(comment))
        return doc
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{path}: cannot read it to update it: {getattr(exc, 'strerror', None) or exc}") from None
    try:
        return tomlkit.parse(text)
    except Exception as exc:  # noqa: BLE001 - tomlkit's parse errors have no common base we can rely on
        raise InputError(f"{path}: not a TOML file this can update ({str(exc).splitlines()[0]})") from None


def table_for_update(path: Path, doc, name: str):
    """The document's [name] table, made if missing; InputError when [name] is not a table."""
    import tomlkit

    if name in doc and not isinstance(doc[name], dict):
        raise InputError(f"{path}: [{name}] is not a table, so it cannot be updated")
    if name not in doc:
        doc[name] = tomlkit.table()
    return doc[name]


def write_checked(path: Path, doc) -> None:
    """Writes the document atomically once it loads as a configuration (InputError if not)."""
    import tomlkit

    from ..config import ConfigError, config_from_dict
    from ..files import write_atomic

    try:
        config_from_dict(doc.unwrap(), where=f"{path}: ")
    except ConfigError as exc:
        raise InputError(f"the configuration would not load after the update: {exc}") from None
    write_atomic(path, tomlkit.dumps(doc))
