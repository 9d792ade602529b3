#!/usr/bin/env python3
"""Check that every relative link and image in the project's Markdown resolves.

    python3 scripts/check_links.py                 # README.md, docs/**/*.md, research/**/*.md
    python3 scripts/check_links.py FILE.md ...     # only these files

For each Markdown link or image (``[text](target)``, ``![alt](target)``, reference definitions
``[id]: target``, HTML ``<a href>`` and ``<img src>``) whose target is not a URL (``http:``, ``https:``,
``mailto:``, ...), the target must be an existing file or folder, relative to the file that links to it.
A ``#fragment`` must name a heading of the target Markdown file (GitHub's anchors: lower case,
punctuation dropped, spaces to hyphens, ``-1``, ``-2`` ... for repeats) or an ``<a id>``/``<a name>`` in
it; fragments of files other than Markdown are not checked. Links inside code spans and fenced code
blocks are ignored. Prints each broken link as ``file:line: target: why`` and exits 1 if there is any.

Standard library only.
"""

from __future__ import annotations

import re
import sys
import unicodedata
from pathlib import Path
from urllib.parse import unquote

ROOT = Path(__file__).resolve().parent.parent

FENCE = re.compile(r"^\s{0,3}(```|~~~)")
CODE_SPAN = re.compile(r"(`+)(.+?)\1")
# [text](target "title") and ![alt](target); the text may hold one level of brackets (images in links).
INLINE = re.compile(r"!?\[(?:[^\[\]]|\[[^\[\]]*\])*\]\(\s*(<[^>]*>|[^)\s]+)(?:\s+(?:\"[^\"]*\"|'[^']*'|\([^)]*\)))?\s*\)")
REFDEF = re.compile(r"^\s{0,3}\[[^\]]+\]:\s*(<[^>]*>|\S+)")
HTML = re.compile(r"<(?:a|img)\b[^>]*?\b(?:href|src)\s*=\s*[\"']([^\"']*)[\"']", re.IGNORECASE)
HTML_ID = re.compile(r"<a\b[^>]*?\b(?:id|name)\s*=\s*[\"']([^\"']*)[\"']", re.IGNORECASE)
HEADING = re.compile(r"^\s{0,3}(#{1,6})\s+(.*?)\s*#*\s*$")
SETEXT = re.compile(r"^\s{0,3}(=+|-+)\s*$")
SCHEME = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]*:")


def slug(text: str) -> str:
    """GitHub's anchor for a heading's text (as github-slugger makes it)."""
    text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", text)  # links and images: their text
    text = re.sub(r"<[^>]+>", "", text)  # inline HTML
    out = []
    for ch in text.lower():
        cat = unicodedata.category(ch)
        if ch in " -_" or cat[0] in "LNM" or cat == "Pc":
            out.append(ch)
    return "".join(out).replace(" ", "-")


def strip_code(lines: list[str]) -> list[str]:
    """The lines with fenced blocks blanked and code spans replaced by spaces (line numbers kept)."""
    out = []
    fence = None
    for line in lines:
        m = FENCE.match(line)
        if fence is not None:
            if m and m.group(1) == fence:
                fence = None
            out.append("")
            continue
        if m:
            fence = m.group(1)
            out.append("")
            continue
        out.append(CODE_SPAN.sub(lambda mm: " " * len(mm.group(0)), line))
    return out


_anchor_cache: dict[Path, set[str]] = {}


def anchors(path: Path) -> set[str]:
    """Every fragment a link may use for the Markdown file ``path``."""
    if path in _anchor_cache:
        return _anchor_cache[path]
    raw = path.read_text(encoding="utf-8").splitlines()
    lines = strip_code(raw)
    found: set[str] = set()
    seen: dict[str, int] = {}

    def add(text: str) -> None:
        base = slug(text)
        n = seen.get(base, 0)
        found.add(base if n == 0 else f"{base}-{n}")
        seen[base] = n + 1

    for i, line in enumerate(lines):
        m = HEADING.match(line)
        if m:
            # Code spans keep their text in a heading's anchor: take the heading from the raw line.
            add(HEADING.match(raw[i]).group(2))
        elif SETEXT.match(line) and i > 0 and lines[i - 1].strip():
            prev = lines[i - 1].lstrip()
            if not HEADING.match(prev) and not prev.startswith(("|", "- ", "* ", "+ ", ">")):
                add(raw[i - 1].strip())
        for mm in HTML_ID.finditer(raw[i]):
            found.add(mm.group(1))
    _anchor_cache[path] = found
    return found


def targets(line: str) -> list[str]:
    out = [m.group(1) for m in INLINE.finditer(line)]
    m = REFDEF.match(line)
    if m:
        out.append(m.group(1))
    out += [m.group(1) for m in HTML.finditer(line)]
    return [t[1:-1] if t.startswith("<") and t.endswith(">") else t for t in out]


def check_file(md: Path) -> list[str]:
    problems = []
    lines = strip_code(md.read_text(encoding="utf-8").splitlines())
    for n, line in enumerate(lines, 1):
        for target in targets(line):
            if not target or SCHEME.match(target) or target.startswith("//"):
                continue
            path_part, _, frag = target.partition("#")
            path_part = unquote(path_part)
            if path_part.startswith("/"):
                dest = ROOT / path_part.lstrip("/")
            elif path_part:
                dest = (md.parent / path_part).resolve()
            else:
                dest = md
            where = f"{display(md)}:{n}: {target}"
            if not dest.exists():
                problems.append(f"{where}: no such file or folder ({display(dest)})")
                continue
            if frag and dest.is_file() and dest.suffix.lower() == ".md":
                frag = unquote(frag)
                if frag not in anchors(dest) and frag.lower() not in anchors(dest):
                    problems.append(f"{where}: no heading or anchor '#{frag}' in {display(dest)}")
    return problems


def display(p: Path) -> str:
    try:
        return p.resolve().relative_to(ROOT).as_posix()
    except ValueError:
        return str(p)


def default_files() -> list[Path]:
    files = [ROOT / "README.md"]
    for folder in ("docs", "research"):
        files += sorted((ROOT / folder).rglob("*.md"))
    return [f for f in files if f.is_file()]


def main(argv: list[str]) -> int:
    files = [Path(a) for a in argv] if argv else default_files()
    problems = []
    for f in files:
        if not f.is_file():
            problems.append(f"{f}: no such file")
            continue
        problems += check_file(f)
    for p in problems:
        print(p)
    if problems:
        print(f"check_links: {len(problems)} broken link(s) in {len(files)} file(s)", file=sys.stderr)
        return 1
    print(f"check_links: all relative links resolve in {len(files)} file(s)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
