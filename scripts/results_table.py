#!/usr/bin/env python3
"""Build the README's results table from run reports (``OUT/report.json``).

    python3 scripts/results_table.py --straight REPORT.json --curly REPORT.json            # print it
    python3 scripts/results_table.py --straight ... --curly ... --write README.md          # rewrite the block
    python3 scripts/results_table.py --straight ... --curly ... --check README.md          # exit 1 if stale

The table holds undirected F1 (percent) at 1 mm/10°, 2 mm/20° and 3 mm/30° on the paper preset's straight
and curly captures: the paper's two rows (Dr.Hair, supplement Table 1: "Ours (w/o DR)" and "Ours"), then
this project's strands before DR (``scores.init_strands``) and after DR (``scores.dr_strands``), and a
line naming the commit of each report and the command. ``--write`` replaces what lies between the
markers ``<!-- results:begin -->`` and ``<!-- results:end -->`` in the file; ``--check`` compares that
block with what the reports give and exits 1 (printing a diff) when they differ.

A report has this shape (extra fields are ignored; a score may be null when it was not recorded):

    {"hairrecon_version": "0.1.0", "git_commit": "abc1234", "capture": "path",
     "stages": [{"stage": "orient2d", "seconds": 1.2, "peak_rss_mb": 512.0}, ...],
     "scores": {"init_strands": M, "dr_strands": M, ...}}
    M = {"directed": [S, S, S], "undirected": [S, S, S]}
    S = {"dist_mm": 1.0, "angle_deg": 10.0, "precision": 71.2, "recall": 72.3, "f1": 71.7}

Standard library only.
"""

from __future__ import annotations

import argparse
import difflib
import json
import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
BEGIN = "<!-- results:begin -->"
END = "<!-- results:end -->"

# The three thresholds of the protocol, in the order reports list them.
THRESHOLDS = [(1.0, 10.0), (2.0, 20.0), (3.0, 30.0)]

# Dr.Hair (Takimoto et al., CVPR 2024), supplementary material, Table 1: undirected F1 (180° tolerant)
# on Cem Yuksel's wStraight and wCurly, 58 views, 512 px high; thresholds 1 mm/10°, 2 mm/20°, 3 mm/30°.
PAPER_ROWS = [
    ("Dr.Hair (paper), w/o DR", {"straight": [51.0, 83.4, 90.9], "curly": [18.6, 58.4, 80.1]}),
    ("Dr.Hair (paper), full", {"straight": [52.5, 86.2, 94.1], "curly": [29.2, 69.0, 85.4]}),
]

OUR_ROWS = [
    ("hairrecon, before DR (init_strands)", "init_strands"),
    ("hairrecon, after DR (dr_strands)", "dr_strands"),
]

STYLES = ["straight", "curly"]


class ReportError(Exception):
    """A report that cannot be read or does not have the expected shape."""


def load_report(path: Path) -> dict:
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as e:
        raise ReportError(f"{path}: cannot read it ({e.strerror})") from None
    try:
        report = json.loads(text)
    except json.JSONDecodeError as e:
        raise ReportError(f"{path}: not valid JSON ({e})") from None
    if not isinstance(report, dict):
        raise ReportError(f"{path}: the report must be a JSON object")
    scores = report.get("scores")
    if scores is not None and not isinstance(scores, dict):
        raise ReportError(f"{path}: 'scores' must be an object")
    for key, _ in [(k, None) for _, k in OUR_ROWS]:
        m = (scores or {}).get(key)
        if m is None:
            continue
        und = m.get("undirected") if isinstance(m, dict) else None
        if not isinstance(und, list) or len(und) != 3:
            raise ReportError(f"{path}: scores.{key}.undirected must be a list of three scores")
        for s, (d, a) in zip(und, THRESHOLDS):
            if not isinstance(s, dict):
                raise ReportError(f"{path}: scores.{key}.undirected holds a non-object")
            if s.get("dist_mm") != d or s.get("angle_deg") != a:
                raise ReportError(
                    f"{path}: scores.{key}.undirected must list 1 mm/10°, 2 mm/20°, 3 mm/30° in order, "
                    f"found {s.get('dist_mm')} mm/{s.get('angle_deg')}°"
                )
            f1 = s.get("f1")
            if f1 is not None and not isinstance(f1, (int, float)):
                raise ReportError(f"{path}: scores.{key}.undirected: f1 must be a number or null")
    return report


def undirected_f1(report: dict | None, key: str) -> list[float | None]:
    """The three undirected F1 of one strand set, None where the report has none."""
    if report is None:
        return [None, None, None]
    m = (report.get("scores") or {}).get(key)
    if not m:
        return [None, None, None]
    return [s.get("f1") for s in m["undirected"]]


def cell(v: float | None) -> str:
    return "–" if v is None else f"{v:.1f}"


def rel_link(target: Path, base_dir: Path | None) -> str:
    """``target`` as a path relative to ``base_dir`` (the file the table goes into), '/'-separated."""
    if base_dir is None:
        return target.as_posix()
    return Path(os.path.relpath(target.resolve(), base_dir.resolve())).as_posix()


def repo_path(p: Path) -> str:
    """``p`` relative to the repository root when it lies inside it, so the text does not depend on the cwd."""
    try:
        return p.resolve().relative_to(ROOT).as_posix()
    except ValueError:
        return p.as_posix()


def build_table(reports: dict[str, tuple[Path, dict] | None], target: Path | None) -> str:
    base_dir = target.parent if target is not None else None
    head = "| undirected F1 (%) | straight 1 mm/10° | 2 mm/20° | 3 mm/30° | curly 1 mm/10° | 2 mm/20° | 3 mm/30° |"
    lines = [head, "|---|---:|---:|---:|---:|---:|---:|"]
    for label, vals in PAPER_ROWS:
        cells = [cell(v) for style in STYLES for v in vals[style]]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    for label, key in OUR_ROWS:
        cells = []
        for style in STYLES:
            entry = reports.get(style)
            cells += [cell(v) for v in undirected_f1(entry[1] if entry else None, key)]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")

    parts = []
    args = []
    for style in STYLES:
        entry = reports.get(style)
        if entry is None:
            parts.append(f"{style}: no report")
            continue
        path, report = entry
        commit = report.get("git_commit") or "unknown commit"
        version = report.get("hairrecon_version")
        ver = f", hairrecon {version}" if version else ""
        link = rel_link(path, base_dir)
        parts.append(f"{style} at commit {commit}{ver} ([report]({link}))")
        args.append(f"--{style} {repo_path(path)}")
    note = (
        "\n*hairrecon rows: "
        + "; ".join(parts)
        + ". Each report says how it was measured. Paper rows: Dr.Hair's supplementary material, Table 1. "
        + "Made by `python3 scripts/results_table.py "
        + " ".join(args)
        + f" --write {repo_path(target) if target is not None else 'README.md'}`.*"
    )
    return "\n".join(lines) + "\n" + note + "\n"


def split_block(text: str, path: Path) -> tuple[str, str, str]:
    """(before and including BEGIN, the block, END and after) of a file holding the markers once."""
    if text.count(BEGIN) != 1 or text.count(END) != 1:
        raise ReportError(f"{path}: needs exactly one '{BEGIN}' and one '{END}'")
    i = text.index(BEGIN) + len(BEGIN)
    j = text.index(END)
    if j < i:
        raise ReportError(f"{path}: '{END}' comes before '{BEGIN}'")
    return text[:i], text[i:j], text[j:]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--straight", type=Path, help="report.json of a run on the paper preset's straight capture")
    ap.add_argument("--curly", type=Path, help="report.json of a run on the paper preset's curly capture")
    mode = ap.add_mutually_exclusive_group()
    mode.add_argument("--write", type=Path, metavar="FILE", help="replace the block between the markers in FILE")
    mode.add_argument("--check", type=Path, metavar="FILE", help="exit 1 if FILE's block differs from the reports")
    a = ap.parse_args(argv)
    if a.straight is None and a.curly is None:
        ap.error("give --straight and/or --curly")

    try:
        reports: dict[str, tuple[Path, dict] | None] = {}
        for style in STYLES:
            p = getattr(a, style)
            reports[style] = (p, load_report(p)) if p is not None else None
        target = a.write or a.check
        table = build_table(reports, target)
        if target is None:
            sys.stdout.write(table)
            return 0
        try:
            text = target.read_text(encoding="utf-8")
        except OSError as e:
            raise ReportError(f"{target}: cannot read it ({e.strerror})") from None
        before, block, after = split_block(text, target)
        want = "\n" + table
        if a.check:
            if block == want:
                print(f"{target}: the results table matches the reports")
                return 0
            print(f"{target}: the results table differs from the reports; run with --write {target}")
            sys.stdout.writelines(
                difflib.unified_diff(
                    block.splitlines(keepends=True),
                    want.splitlines(keepends=True),
                    f"{target} (now)",
                    "from the reports",
                )
            )
            return 1
        if block != want:
            target.write_text(before + want + after, encoding="utf-8")
            print(f"{target}: results table written")
        else:
            print(f"{target}: results table already up to date")
        return 0
    except ReportError as e:
        print(f"results_table: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
