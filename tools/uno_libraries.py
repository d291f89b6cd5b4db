"""The libraries of the Uno image, found as PlatformIO's dependency finder finds them (the #include
lines from firmware/src through firmware/lib and the core's own libraries), and the order
PlatformIO puts their archives on the link line.

Part of tools/build_uno.py.
"""

from __future__ import annotations

import fnmatch
import json
import re
from dataclasses import dataclass, field
from pathlib import Path

from uno_platformio import SetupError
from uno_toolchain import ARDUINO_AVR

SOURCE_SUFFIXES = {".c": "c", ".cpp": "cxx", ".cc": "cxx", ".S": "asm"}
HEADER_SUFFIXES = {".h", ".hpp", ".hh", ""}
# PlatformIO's default library source filter leaves these folders out.
SKIPPED_LIB_DIRS = {"example", "examples", "test", "tests", ".git", ".svn"}
INCLUDE_RE = re.compile(r'^\s*#\s*include\s*[<"]([^>"]+)[>"]', re.MULTILINE)


# ----------------------------------------------------------------------------- libraries


@dataclass
class Library:
    name: str
    root: Path  # the library folder
    include_dir: Path  # src/ when present, else the folder itself
    project: bool  # under firmware/lib (warnings shown) or part of the core
    src_filter: list[str] = field(default_factory=list)

    def headers(self) -> set[str]:
        found = set()
        for path in self.include_dir.rglob("*"):
            if path.suffix in HEADER_SUFFIXES and path.is_file() and not self._skipped(path):
                found.add(path.relative_to(self.include_dir).as_posix())
        return found

    def sources(self) -> list[Path]:
        files = [
            p
            for p in sorted(self.include_dir.rglob("*"))
            if p.suffix in SOURCE_SUFFIXES and p.is_file() and not self._skipped(p)
        ]
        return [p for p in files if self._selected(p.relative_to(self.include_dir).as_posix())]

    def _skipped(self, path: Path) -> bool:
        parts = path.relative_to(self.include_dir).parts[:-1]
        return any(part in SKIPPED_LIB_DIRS for part in parts)

    def _selected(self, rel: str) -> bool:
        """library.json build.srcFilter: `+<glob>` and `-<glob>`, the last match wins."""
        if not self.src_filter:
            return True
        selected = False
        for sign, pattern in re.findall(r"([+-])<([^>]*)>", " ".join(self.src_filter)):
            pattern = pattern.rstrip("/")
            if fnmatch.fnmatch(rel, pattern) or fnmatch.fnmatch(rel, pattern + "/*") or pattern in ("*", "**"):
                selected = sign == "+"
        return selected


def load_library(folder: Path, project: bool) -> Library | None:
    """None when library.json says the library is not for atmelavr/arduino."""
    src = folder / "src"
    lib = Library(folder.name, folder, src if src.is_dir() else folder, project)
    manifest = folder / "library.json"
    if manifest.is_file():
        try:
            data = json.loads(manifest.read_text(encoding="utf-8"))
        except json.JSONDecodeError as exc:
            raise SetupError(f"{manifest}: {exc}") from exc
        lib.name = data.get("name", lib.name)
        for key, wanted in (("platforms", "atmelavr"), ("frameworks", "arduino")):
            allowed = data.get(key, "*")
            allowed = [allowed] if isinstance(allowed, str) else allowed
            if "*" not in allowed and wanted not in allowed:
                return None
        build = data.get("build", {})
        src_filter = build.get("srcFilter", build.get("srcfilter", []))
        lib.src_filter = [src_filter] if isinstance(src_filter, str) else list(src_filter)
        if "includeDir" in build:
            lib.include_dir = folder / build["includeDir"]
    return lib


def includes_of(path: Path) -> list[str]:
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError:
        return []
    return INCLUDE_RE.findall(text)


def find_libraries(src_dir: Path, include_dir: Path, lib_dir: Path, ignored: set[str]) -> list[Library]:
    """Follows #include from the sources in src_dir; returns the libraries reached, in the
    order they were reached. Project libraries win over the core's of the same header."""
    candidates: list[Library] = []
    for base, project in ((lib_dir, True), (ARDUINO_AVR / "libraries", False)):
        if base.is_dir():
            for folder in sorted(p for p in base.iterdir() if p.is_dir()):
                lib = load_library(folder, project)
                if lib is not None and lib.name not in ignored and folder.name not in ignored:
                    candidates.append(lib)
    providers: dict[str, Library] = {}
    for lib in reversed(candidates):  # earlier (project) libraries overwrite later ones
        for header in lib.headers():
            providers[header] = lib

    used: list[Library] = []
    seen: set[Path] = set()
    todo = [p for p in sorted(src_dir.rglob("*")) if p.suffix in SOURCE_SUFFIXES]
    while todo:
        path = todo.pop()
        if path in seen:
            continue
        seen.add(path)
        for name in includes_of(path):
            local = [path.parent / name, src_dir / name, include_dir / name]
            hit = next((p for p in local if p.is_file()), None)
            if hit is not None:
                todo.append(hit.resolve())
                continue
            lib = providers.get(name)
            if lib is None or lib in used:
                continue
            used.append(lib)
            todo.extend(lib.sources())
            todo.extend(lib.include_dir / h for h in lib.headers())
    return used


def archive_order(libs: list[Library], project_sources: list[Path], local_dirs: list[Path]) -> list[Library]:
    """The libraries in the order PlatformIO puts their archives on the link line.

    platformio-core 6.1 (builder/tools/piolib.py): ConfigureProjectLibBuilder scans the
    project's sources (ProjectAsLibBuilder.search_deps_recursive); every library that holds a
    header they include, directly or through other headers (SCons' CConditionalScanner walks
    #include depth-first, in the order written), becomes a dependency, in the order first met
    (get_implicit_includes, lib_inc_map). depend_on() then scans each such library's own
    sources the same way (deep+ mode: all of them) and records its dependencies, skipping one
    that would close a cycle (_already_depends). LibBuilderBase.build() returns the archives
    depth-first: a library's dependencies before the library itself, each archive once
    (is_built). piobuild.py ProcessProjectDeps prepends that list to the framework's LIBS.

    `local_dirs` are searched after a file's own folder (the project's include and src dirs).
    Libraries in `libs` that the scan does not reach keep their place at the end.
    """
    providers: dict[str, Library] = {}
    for lib in reversed(libs):  # earlier (project) libraries win, as in find_libraries
        for header in lib.headers():
            providers[header] = lib

    def owner(path: Path) -> Library | None:
        return next((lib for lib in libs if lib.include_dir in path.parents or lib.root in path.parents), None)

    def resolve(name: str, including: Path) -> Path | None:
        own = owner(including)
        bases = [including.parent] + ([own.include_dir] if own else []) + local_dirs
        hit = next((b / name for b in bases if (b / name).is_file()), None)
        if hit is not None:
            return hit.resolve()
        lib = providers.get(name)
        return (lib.include_dir / name).resolve() if lib is not None else None

    def dependencies(files: list[Path], me: Library | None) -> list[Library]:
        found: list[Library] = []
        seen: set[Path] = set()

        def walk(path: Path) -> None:
            for name in includes_of(path):
                hit = resolve(name, path)
                if hit is None or hit in seen:
                    continue
                seen.add(hit)
                lib = owner(hit)
                if lib is not None and lib is not me and lib not in found:
                    found.append(lib)
                walk(hit)

        for path in files:
            seen.add(path.resolve())
            walk(path.resolve())
        return found

    graph: dict[str | None, list[Library]] = {}  # None: the project

    def reaches(lib: Library, target: str | None) -> bool:
        return any(dep.name == target or reaches(dep, target) for dep in graph.get(lib.name, []))

    def search(name: str | None, files: list[Path], me: Library | None) -> None:
        if name in graph:
            return
        graph[name] = []
        for lib in dependencies(files, me):
            if not reaches(lib, name):  # piolib.py: a circular dependency is left out
                graph[name].append(lib)
            search(lib.name, lib.sources(), lib)

    search(None, project_sources, None)
    order: list[Library] = []

    def build(lib: Library) -> None:
        for dep in graph.get(lib.name, []):
            build(dep)
        if lib not in order:
            order.append(lib)

    for lib in graph[None]:
        build(lib)
    return order + [lib for lib in libs if lib not in order]
