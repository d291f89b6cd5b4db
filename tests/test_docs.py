"""The README is a page to start from, and docs/ holds the rest: the README stays short, its first
code block is the two commands (CI runs `scripts/test`, the README's test command), and every
relative link and image in the README and in docs/ points at a file in the repository."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
PAGES = [README, *sorted((ROOT / "docs").glob("*.md"))]
MAX_README_LINES = 150

#: [text](target) and ![alt](target), the target up to the first space or ")" (a title may follow).
LINK = re.compile(r"!?\[(?:[^\]\\]|\\.)*\]\(\s*<?([^)\s>]*)>?(?:\s+\"[^\"]*\")?\s*\)")
#: [text]: target (reference definitions).
REFERENCE = re.compile(r"^\s{0,3}\[[^\]]+\]:\s*<?(\S+?)>?(?:\s+.*)?$", re.MULTILINE)
FENCE = re.compile(r"^(```|~~~).*?^\1[ \t]*$", re.MULTILINE | re.DOTALL)
CODE_SPAN = re.compile(r"(`+)(?:(?!\1).)+?\1", re.DOTALL)


def links(text: str) -> list[str]:
    """Every link and image target of a Markdown text, outside code blocks and code spans."""
    text = CODE_SPAN.sub("", FENCE.sub("", text))
    return LINK.findall(text) + REFERENCE.findall(text)


def broken_links(text: str, folder: Path) -> list[str]:
    """The relative links of a page in `folder` that name no file or folder of the repository."""
    broken = []
    for target in links(text):
        if re.match(r"[a-z][a-z0-9+.-]*:", target, re.IGNORECASE):  # http:, https:, mailto:, ...
            continue
        path = target.split("#", 1)[0].split("?", 1)[0]
        if not path:  # an anchor on the same page
            continue
        resolved = (folder / path).resolve()
        if not resolved.exists() or ROOT.resolve() not in (resolved, *resolved.parents):
            broken.append(target)
    return broken


def test_the_readme_is_a_page_to_start_from():
    lines = README.read_text().splitlines()
    assert len(lines) <= MAX_README_LINES, f"README.md has {len(lines)} lines; docs/ is for the rest"


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_relative_link_resolves_inside_the_repository(page):
    assert page.is_file()
    assert broken_links(page.read_text(), page.parent) == []


def test_the_readmes_first_code_block_is_the_two_commands():
    first = FENCE.search(README.read_text())
    assert first, "README.md has no fenced code block"
    block = first.group(0)
    assert re.search(r"^scripts/run\b", block, re.MULTILINE), block
    assert re.search(r"^scripts/test\b", block, re.MULTILINE), block


def test_the_link_check_finds_a_broken_link_and_passes_the_rest():
    # The check itself: a missing file, a path out of the repository, and links in code told apart.
    text = (
        "[ok](../README.md) [ok](#anchor) [ok](https://example.org/x) ![ok](arenas.png)\n"
        "[missing](no-such-page.md#part) ![missing](no-such.png) [outside](../../../etc/passwd)\n"
        "`[in code](nowhere.md)`\n```\n[in a block](nowhere.md)\n```\n[ref]: also-missing.md\n"
    )
    assert "nowhere.md" not in links(text)
    assert broken_links(text, ROOT / "docs") == [
        "no-such-page.md#part",
        "no-such.png",
        "../../../etc/passwd",
        "also-missing.md",
    ]
