#!/usr/bin/env python3
"""The per-style table: how the reconstruction scores on each hairstyle of the synthetic benchmark.

    python3 scripts/style_table.py RUN [RUN ...] [--baseline straight] [--crown] [--json]

Each RUN is the output folder of ``hairrecon reconstruct`` on a benchmark capture with ground truth (one made
by ``scripts/make_benchmark.py``, which names it ``<preset>_<style>_<colour>``). The table has one row per
run: undirected F1 (percent) of the strands before DR (``scores.init_strands``) and after it
(``scores.dr_strands``) at 1 mm/10°, 2 mm/20° and 3 mm/30°, directed F1 after DR at 2 mm/20°, and the gap
to the baseline style's run at 2 mm/20° after DR (negative: below it). With ``--crown`` it also runs
``hairrecon eval --scalp`` on the final strands and gives how far the hair stands off the crown: the
median over 1 cm cells of the points' median height, reconstructed and true, and the median absolute error
per cell (millimetres). The footer names the commits of the runs.

    # a whole benchmark run: render the held-out styles, reconstruct each, print the table
    .venv/bin/python scripts/make_benchmark.py --presets colors --styles straight spiky coils --seed 11 --out B
    for s in straight spiky coils; do target/release/hairrecon reconstruct B/colors_${s}_brown --out R/$s; done
    python3 scripts/style_table.py R/* --crown

``--write FILE`` puts the table between the markers ``<!-- styles:begin -->`` and ``<!-- styles:end -->`` of FILE
(docs/reconstruction.md holds the held-out styles' table that way).

Standard library only (``--crown`` needs the hairrecon binary: target/release/hairrecon, then PATH).
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
THRESHOLDS = [(1.0, 10.0), (2.0, 20.0), (3.0, 30.0)]
BEGIN = "<!-- styles:begin -->"
END = "<!-- styles:end -->"


class RunError(Exception):
    """A run folder that cannot be read."""


def style_of(capture: Path) -> str:
    """The style of a benchmark capture: from make_benchmark.py's log beside it, else from its name
    (``<preset>_<style>_<colour>[_clutter|_wild]``), else the folder's name."""
    log = capture.parent / "benchmark.json"
    try:
        entry = json.loads(log.read_text(encoding="utf-8")).get(capture.name)
        if isinstance(entry, dict) and isinstance(entry.get("style"), str):
            return entry["style"]
    except (OSError, ValueError):
        pass
    parts = capture.name.split("_")
    for tail in ("clutter", "wild"):
        if parts and parts[-1] == tail:
            parts = parts[:-1]
    return "_".join(parts[1:-1]) if len(parts) >= 3 else capture.name


def f1s(scores: dict, key: str, kind: str) -> list[float | None]:
    """F1 at the three thresholds of one strand set, None where the report has none."""
    m = scores.get(key)
    if not isinstance(m, dict) or not isinstance(m.get(kind), list):
        return [None, None, None]
    by = {(s.get("dist_mm"), s.get("angle_deg")): s.get("f1") for s in m[kind] if isinstance(s, dict)}
    return [by.get(t) for t in THRESHOLDS]


def read_run(run: Path) -> dict:
    path = run / "report.json"
    try:
        report = json.loads(path.read_text(encoding="utf-8"))
    except OSError as e:
        raise RunError(f"{path}: cannot read it ({e.strerror}); is {run} a finished `hairrecon reconstruct` run?")
    except json.JSONDecodeError as e:
        raise RunError(f"{path}: not valid JSON ({e})")
    scores = report.get("scores") or {}
    if "init_strands" not in scores:
        raise RunError(f"{path}: no scores (the capture has no ground truth under gt/, or the run stopped early)")
    capture = Path(report.get("capture") or run)
    return {
        "run": str(run),
        "capture": str(capture),
        "style": style_of(capture),
        "commit": report.get("git_commit") or "unknown",
        "init": f1s(scores, "init_strands", "undirected"),
        "final": f1s(scores, "dr_strands", "undirected"),
        "final_directed_2mm": f1s(scores, "dr_strands", "directed")[1],
    }


def crown(row: dict, exe: str) -> dict | None:
    """`hairrecon eval --scalp` on the run's final strands: the crown heights, or None."""
    run, cap = Path(row["run"]), Path(row["capture"])
    pred = next((run / f for f in ("strands.hair", "dr_strands.hair", "init_strands.hair") if (run / f).is_file()), None)
    gt, scalp = cap / "gt" / "strands.hair", cap / "scalp.ply"
    if pred is None or not gt.is_file() or not scalp.is_file():
        return None
    cmd = [exe, "eval", "--pred", str(pred), "--gt", str(gt), "--scalp", str(scalp), "--json"]
    out = subprocess.run(cmd, capture_output=True, text=True)
    if out.returncode != 0:
        raise RunError(f"{' '.join(cmd)} failed: {out.stderr.strip()[-400:]}")
    return json.loads(out.stdout).get("crown_height")


def cell(v: float | None) -> str:
    return "–" if v is None else f"{v:.1f}"


def table(rows: list[dict], baseline: str) -> str:
    base = next((r for r in rows if r["style"] == baseline), None)
    base_f1 = base["final"][1] if base else None
    with_crown = any("crown" in r for r in rows)
    head = "| style | before DR 1 · 2 · 3 mm | after DR 1 · 2 · 3 mm | directed 2 mm | vs " + baseline + " |"
    rule = "|---|---|---|---:|---:|"
    if with_crown:
        head += " crown height mm: ours · true · error |"
        rule += "---|"
    lines = [head, rule]
    for r in rows:
        gap = None if base_f1 is None or r["final"][1] is None else r["final"][1] - base_f1
        line = (
            f"| {r['style']} | {' · '.join(map(cell, r['init']))} | {' · '.join(map(cell, r['final']))} | "
            f"{cell(r['final_directed_2mm'])} | {'–' if gap is None else f'{gap:+.1f}'} |"
        )
        if with_crown:
            c = r.get("crown")
            line += (
                " – |"
                if not c
                else f" {c['pred_median_mm']:.1f} · {c['gt_median_mm']:.1f} · {c['median_abs_error_mm']:.1f} |"
            )
        lines.append(line)
    commits = sorted({r["commit"] for r in rows})
    lines.append("")
    lines.append(
        "*Undirected F1 (%) unless named; runs at commit "
        + ", ".join(commits)
        + "; made by `python3 scripts/style_table.py"
        + (" --crown" if with_crown else "")
        + " RUN ...`.*"
    )
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", type=Path, help="output folders of `hairrecon reconstruct`")
    ap.add_argument("--baseline", default="straight", help="the style the gap column compares with")
    ap.add_argument("--crown", action="store_true", help="also the hair's height over the crown (hairrecon eval)")
    ap.add_argument("--hairrecon-bin", help="the hairrecon binary for --crown")
    ap.add_argument("--json", action="store_true", help="print the rows as JSON instead of the table")
    ap.add_argument("--write", type=Path, metavar="FILE", help=f"put the table between {BEGIN} and {END} in FILE")
    a = ap.parse_args(argv)
    try:
        rows = [read_run(r) for r in a.runs]
        if a.crown:
            exe = a.hairrecon_bin or (
                str(ROOT / "target/release/hairrecon")
                if (ROOT / "target/release/hairrecon").is_file()
                else shutil.which("hairrecon")
            )
            if exe is None:
                raise RunError("--crown needs the hairrecon binary: cargo build --release -p hairrecon-cli")
            for r in rows:
                c = crown(r, exe)
                if c:
                    r["crown"] = c
        if a.write is not None:
            write_block(a.write, table(rows, a.baseline))
            return 0
    except RunError as e:
        print(f"style_table: {e}", file=sys.stderr)
        return 1
    sys.stdout.write(json.dumps(rows, indent=1) + "\n" if a.json else table(rows, a.baseline))
    return 0


def write_block(path: Path, block: str) -> None:
    """Replaces what lies between the markers in `path` (each there once) with `block`."""
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as e:
        raise RunError(f"{path}: cannot read it ({e.strerror})")
    if text.count(BEGIN) != 1 or text.count(END) != 1 or text.index(END) < text.index(BEGIN):
        raise RunError(f"{path}: needs one '{BEGIN}' followed by one '{END}'")
    i, j = text.index(BEGIN) + len(BEGIN), text.index(END)
    path.write_text(text[:i] + "\n" + block + text[j:], encoding="utf-8")


if __name__ == "__main__":
    sys.exit(main())
