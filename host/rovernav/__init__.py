"""rovernav: guide a small rover through a partially unknown arena from an overhead camera."""


def _version() -> str:
    # One definition: pyproject.toml's [project] version (the installed package's metadata, or the
    # checkout's file when rovernav runs from the source tree without being installed).
    from importlib import metadata

    try:
        return metadata.version("rovernav")
    except metadata.PackageNotFoundError:
        import tomllib
        from pathlib import Path

        pyproject = Path(__file__).resolve().parents[2] / "pyproject.toml"
        return tomllib.loads(pyproject.read_text(encoding="utf-8"))["project"]["version"]


__version__ = _version()
