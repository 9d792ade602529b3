"""The supplement's ablation table on one capture, in one command: runs every row and prints the table.

Rows (Dr.Hair's supplement, Table 3; ``docs/method.md``):

- ``full``: ``hairrecon reconstruct CAPTURE --out OUT/full`` (or ``--full DIR``, a finished whole run);
- ``no_dr`` (w/o DR): that run's strands before DR (``init_strands`` in its ``report.json``);
- ``no_guide_opt``, ``no_reparam``, ``no_n`` (w/o guide opt., w/o reparam., w/o N): DR alone, from the
  full run's saved stages, with one switch off: ``hairrecon reconstruct CAPTURE --out OUT/ROW --config
  FULL/config.json --from dr --no-guide-opt`` (the full run's orientation maps, partings and init linked
  into ``OUT/ROW``), so the row differs from ``full`` by its switch only;
- ``no_strand_init``, ``no_global_opt`` (w/o strand init., w/o global opt.): whole runs with
  ``--no-strand-init`` / ``--no-global-opt`` (they change the init).

Each row's output folder ``OUT/ROW`` is kept; a row that has finished (its ``strands.hair`` from DR, or
its ``report.json`` with scores after DR) is scored, not run again, so an interrupted table goes on
where it stopped (a row finished by an earlier call keeps its time only if ``OUT/ablations.json`` has it). The table (markdown) goes to stdout and to
``OUT/ablations.md``, the figures to ``OUT/ablations.json``: undirected P / R / F1 at 2 mm/20°, F1 at
1 mm/10° and 3 mm/30°, directed F1 at 2 mm/20°, and each row's wall time and peak memory (of the
process that ran it; ``full``'s covers the whole run, DR rows only DR and its targets).

    .venv/bin/python scripts/ablations.py bench_out/paper_curly_brown OUT
    .venv/bin/python scripts/ablations.py bench_out/paper_curly_brown OUT --full RUN --rows no_n no_reparam

The ground truth is ``CAPTURE/gt/strands.hair``. The paper preset takes 1–2 hours per style on 2 cores.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent

ROWS = ["full", "no_dr", "no_guide_opt", "no_reparam", "no_n", "no_strand_init", "no_global_opt"]
LABELS = {
    "full": "full",
    "no_dr": "w/o DR",
    "no_guide_opt": "w/o guide opt.",
    "no_reparam": "w/o reparam.",
    "no_n": "w/o N",
    "no_strand_init": "w/o strand init.",
    "no_global_opt": "w/o global opt.",
}
# DR-only rows: the reconstruct flag that switches their part of DR off.
DR_KEYS = {"no_guide_opt": "--no-guide-opt", "no_reparam": "--no-reparam", "no_n": "--no-neighbor-reparam"}
# What a DR-only row links from the full run: the stages before DR, as `--from dr` reloads them.
DR_INPUTS = ["config.json", "report.json", "orient2d", "partings.ply", "partings.json", "init_guides.hair",
             "init_strands.hair", "init.json"]
# Whole-run rows: the reconstruct flag.
WHOLE_FLAGS = {"full": [], "no_strand_init": ["--no-strand-init"], "no_global_opt": ["--no-global-opt"]}


class AblationError(RuntimeError):
    pass


def dr_row_args(name: str, full_dir: Path) -> list:
    """``hairrecon reconstruct``'s arguments (after the capture) for a DR-only row: the full run's
    configuration, DR alone, with the row's switch off."""
    return ["--config", full_dir / "config.json", "--from", "dr", DR_KEYS[name]]


def scores_row(report: dict) -> dict:
    """The table's figures from a metric report (``hairrecon eval --json`` or a score of
    ``report.json``): ``{"P2","R2","F2","F1mm","F3mm","D2"}`` in percent."""

    def at(mode: str, dist: float) -> dict:
        for s in report.get(mode, []):
            if abs(s["dist_mm"] - dist) < 1e-6:
                return s
        raise AblationError(f"the metric report has no {mode} score at {dist:g} mm: {sorted(report)}")

    u2 = at("undirected", 2.0)
    return {
        "P2": u2["precision"],
        "R2": u2["recall"],
        "F2": u2["f1"],
        "F1mm": at("undirected", 1.0)["f1"],
        "F3mm": at("undirected", 3.0)["f1"],
        "D2": at("directed", 2.0)["f1"],
    }


def format_table(rows: dict) -> str:
    """Markdown table of the rows present in ``rows`` (name -> {"scores", "seconds", "peak_mb"}), in
    the supplement's order."""
    out = [
        "| row | undirected P / R / F1, 2 mm/20° | F1 1 mm · 3 mm | directed F1 2 mm | wall, peak |",
        "|---|---|---|---|---|",
    ]
    for name in ROWS:
        r = rows.get(name)
        if r is None:
            continue
        s = r["scores"]
        cost = "(the full run)" if name == "no_dr" else _cost(r)
        before = f" (before DR {r['init_scores']['F2']:.1f})" if "init_scores" in r else ""
        out.append(
            f"| {LABELS[name]} | {s['P2']:.1f} / {s['R2']:.1f} / **{s['F2']:.1f}**{before} | "
            f"{s['F1mm']:.1f} · {s['F3mm']:.1f} | {s['D2']:.1f} | {cost} |"
        )
    return "\n".join(out)


def _cost(r: dict) -> str:
    secs = r.get("seconds")
    if secs is None:
        return ""
    m, s = divmod(int(round(secs)), 60)
    peak = r.get("peak_mb")
    return f"{m} min {s} s" + (f", {peak / 1024:.1f} GB" if peak else "")


def run_measured(cmd: list, log: Path) -> tuple[float, float]:
    """Runs ``cmd`` with its output in ``log``; returns (wall seconds, peak RSS in MB of the process)."""
    print("ablations: " + " ".join(map(str, cmd)), flush=True)
    t0 = time.monotonic()
    with open(log, "w") as f:
        p = subprocess.Popen([str(c) for c in cmd], stdout=f, stderr=subprocess.STDOUT)
        try:
            _, status, usage = os.wait4(p.pid, 0)
        except KeyboardInterrupt:
            p.kill()
            p.wait()
            raise
        p.returncode = os.waitstatus_to_exitcode(status)
    secs = time.monotonic() - t0
    if p.returncode != 0:
        raise AblationError(f"{cmd[0]} failed (exit {p.returncode}); its output is in {log}")
    return secs, usage.ru_maxrss / 1024.0


def _scores(run_dir: Path) -> dict:
    """The scores of a run's ``report.json`` (empty when it has none)."""
    try:
        return json.loads((run_dir / "report.json").read_text())["scores"]
    except (OSError, ValueError, KeyError):
        return {}


def find_binary(args) -> Path:
    exe = Path(args.hairrecon_bin) if args.hairrecon_bin else REPO / "target" / "release" / "hairrecon"
    if args.build:
        subprocess.run(["cargo", "build", "--release", "-p", "hairrecon-cli"], cwd=REPO, check=True)
    if not exe.is_file():
        raise AblationError(f"no {exe}; build it with: cargo build --release -p hairrecon-cli (or pass --build)")
    return exe


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("capture", type=Path, help="capture folder with gt/strands.hair")
    p.add_argument("out", type=Path, help="output folder (one sub-folder per row)")
    p.add_argument("--full", type=Path, help="a finished `hairrecon reconstruct CAPTURE --out DIR` to use as the full row")
    p.add_argument("--rows", nargs="+", default=ROWS, choices=ROWS)
    p.add_argument("--hairrecon-bin", help="the hairrecon binary (default: target/release/hairrecon)")
    p.add_argument("--build", action="store_true", help="cargo build the hairrecon binary first")
    a = p.parse_args(argv)
    try:
        return run(a)
    except AblationError as e:
        print(f"ablations: {e}", file=sys.stderr)
        return 1


def run(a) -> int:
    gt = a.capture / "gt" / "strands.hair"
    if not gt.is_file():
        raise AblationError(f"{a.capture} has no ground truth ({gt}); ablations need a synthetic capture")
    exe = find_binary(a)
    a.out.mkdir(parents=True, exist_ok=True)
    rows: dict = {}
    summary_path = a.out / "ablations.json"
    if summary_path.is_file():
        rows = json.loads(summary_path.read_text()).get("rows", {})

    def save():
        tmp = summary_path.with_suffix(".json.tmp")
        tmp.write_text(json.dumps({"capture": str(a.capture), "rows": rows}, indent=1))
        os.replace(tmp, summary_path)

    # The full run (needed by every DR row and by w/o DR).
    need_full = any(r in a.rows for r in ["full", "no_dr", *DR_KEYS])
    full_dir = a.full or a.out / "full"
    if need_full and "dr_strands" not in _scores(full_dir):
        if a.full:
            raise AblationError(f"--full {a.full} has no report.json with scores after DR: not a finished whole run "
                                "(run it without --no-dr on a capture with ground truth)")
        full_dir.mkdir(parents=True, exist_ok=True)
        secs, peak = run_measured([exe, "reconstruct", a.capture, "--out", full_dir], a.out / "full.log")
        rows["full"] = {"seconds": secs, "peak_mb": peak}
    if need_full:
        m = _scores(full_dir)
        if "dr_strands" not in m:
            raise AblationError(f"{full_dir}/report.json has no dr_strands: run the full method (without --no-dr)")
        rows.setdefault("full", {})["scores"] = scores_row(m["dr_strands"])
        rows["no_dr"] = {"scores": scores_row(m["init_strands"])}
        save()

    for name in a.rows:
        if name in ("full", "no_dr") or "scores" in rows.get(name, {}):
            continue
        row_dir = a.out / name
        row_dir.mkdir(parents=True, exist_ok=True)
        prev = rows.get(name, {})
        secs, peak = prev.get("seconds"), prev.get("peak_mb")
        init_scores = None
        if "dr_strands" not in _scores(row_dir):
            if name in DR_KEYS:
                for f in DR_INPUTS:
                    link = row_dir / f
                    if (full_dir / f).exists() and not link.exists():
                        link.symlink_to((full_dir / f).resolve())
                cmd = [exe, "reconstruct", a.capture, "--out", row_dir, *dr_row_args(name, full_dir)]
            else:
                cmd = [exe, "reconstruct", a.capture, "--out", row_dir, *WHOLE_FLAGS[name]]
            secs, peak = run_measured(cmd, a.out / f"{name}.log")
        m = _scores(row_dir)
        if name not in DR_KEYS:
            init_scores = scores_row(m["init_strands"])
        rows[name] = {"scores": scores_row(m["dr_strands"]), "seconds": secs, "peak_mb": peak}
        if init_scores is not None:
            rows[name]["init_scores"] = init_scores
        save()
    table = format_table(rows)
    (a.out / "ablations.md").write_text(table + "\n")
    print(table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
