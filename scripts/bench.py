#!/usr/bin/env python3
"""Time and memory of one ``hairrecon reconstruct``, stage by stage, as one table.

    .venv/bin/python scripts/bench.py CAPTURE --out OUT [-- reconstruct options ...]
    .venv/bin/python scripts/bench.py --report OUT/report.json      (the table of an earlier run)

Runs the release CLI (``target/release/hairrecon``, or ``$HAIRRECON_BIN``) under ``/usr/bin/time -v``
and prints, from the run's ``report.json``: each stage's wall and CPU seconds, how many cores it kept
busy, the process's peak resident memory at the stage's end (a running maximum: the stage where it
jumps is the one that needed the memory), and DR's steps per second; then the whole process as
``time -v`` measured it (wall, user + system, maximum resident set). With ``--json FILE`` it also
writes those figures. A benchmark, not a test: nothing here asserts a time.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def parse_args(argv):
    ap = argparse.ArgumentParser(prog="bench.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("capture", nargs="?", type=Path, help="capture folder to reconstruct")
    ap.add_argument("--out", type=Path, help="output folder of the run")
    ap.add_argument("--report", type=Path, help="print the table of this report.json instead of running")
    ap.add_argument("--json", type=Path, help="also write the figures to this JSON file")
    rest = argv[argv.index("--") + 1 :] if "--" in argv else []
    a = ap.parse_args(argv[: argv.index("--")] if "--" in argv else argv)
    if a.report is None and (a.capture is None or a.out is None):
        ap.error("give CAPTURE and --out (to run), or --report (to read an earlier run)")
    a.rest = rest  # options after -- go to hairrecon reconstruct
    return a


def time_v(stderr: str) -> dict:
    """The figures of ``/usr/bin/time -v`` from its output."""

    def field(name):
        m = re.search(rf"^\s*{re.escape(name)}: (.+)$", stderr, re.M)
        return m.group(1).strip() if m else None

    wall = field("Elapsed (wall clock) time (h:mm:ss or m:ss)")
    secs = 0.0
    for part in (wall or "0").split(":"):
        secs = secs * 60 + float(part)
    return {
        "wall_seconds": secs,
        "cpu_seconds": float(field("User time (seconds)") or 0) + float(field("System time (seconds)") or 0),
        "peak_rss_mb": round(int(field("Maximum resident set size (kbytes)") or 0) / 1024),
    }


def rows(report: dict) -> list[dict]:
    out = []
    for s in report["stages"]:
        wall, cpu = s["seconds"], s.get("cpu_seconds")
        row = {
            "stage": s["stage"],
            "wall_seconds": round(wall, 2),
            "cpu_seconds": cpu,
            "cores_busy": round(cpu / wall, 2) if cpu is not None and wall > 0 else None,
            "peak_rss_mb_so_far": s.get("peak_rss_mb"),
        }
        stats = s.get("stats") or {}
        if s["stage"] == "dr" and stats.get("optimize_seconds"):
            row["dr_steps_per_second"] = round(stats["steps"] / stats["optimize_seconds"], 2)
        out.append(row)
    return out


def table(stage_rows: list[dict], whole: dict | None) -> str:
    def f(v, fmt):
        width = int(fmt.split(".")[0])
        return "-".rjust(width) if v is None else format(v, fmt)

    lines = [f"{'stage':<10} {'wall s':>8} {'CPU s':>8} {'cores':>6} {'peak RSS MiB':>13}  note"]
    for r in stage_rows:
        note = f"DR {r['dr_steps_per_second']} steps/s" if "dr_steps_per_second" in r else ""
        lines.append(
            f"{r['stage']:<10} {f(r['wall_seconds'], '8.1f')} {f(r['cpu_seconds'], '8.1f')} "
            f"{f(r['cores_busy'], '6.2f')} {f(r['peak_rss_mb_so_far'], '13.0f')}  {note}"
        )
    if whole:
        cores = whole["cpu_seconds"] / whole["wall_seconds"] if whole["wall_seconds"] else 0
        lines.append(
            f"{'process':<10} {whole['wall_seconds']:8.1f} {whole['cpu_seconds']:8.1f} {cores:6.2f} "
            f"{whole['peak_rss_mb']:13.0f}  /usr/bin/time -v"
        )
    return "\n".join(lines)


def main(argv=None) -> int:
    a = parse_args(sys.argv[1:] if argv is None else argv)
    whole = None
    if a.report is not None:
        report_path = a.report
    else:
        binary = os.environ.get("HAIRRECON_BIN", str(ROOT / "target" / "release" / "hairrecon"))
        if not Path("/usr/bin/time").exists():
            print("error: /usr/bin/time is missing (Debian: apt install time)", file=sys.stderr)
            return 1
        cmd = ["/usr/bin/time", "-v", binary, "reconstruct", str(a.capture), "--out", str(a.out), *a.rest]
        r = subprocess.run(cmd, stderr=subprocess.PIPE, text=True)
        if r.returncode != 0:
            print(r.stderr[-3000:], file=sys.stderr)
            print(f"error: hairrecon reconstruct failed (exit {r.returncode})", file=sys.stderr)
            return 1
        whole = time_v(r.stderr)
        report_path = a.out / "report.json"
    report = json.loads(report_path.read_text())
    stage_rows = rows(report)
    print(f"{report_path}  (hairrecon {report.get('hairrecon_version', '?')}, commit {report.get('git_commit', '?')})")
    print(table(stage_rows, whole))
    if a.json:
        a.json.write_text(json.dumps({"stages": stage_rows, "process": whole}, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
