"""The supplement's ablation table on one capture, in one command: runs every row and prints the table.

Rows (Dr.Hair's supplement, Table 3; ``docs/method.md``):

- ``full``: ``hairrecon reconstruct CAPTURE --out OUT/full`` (or ``--full DIR``, a finished whole run);
- ``no_dr`` (w/o DR): that run's strands before DR (``init_strands`` in its ``metrics.json``);
- ``no_guide_opt``, ``no_reparam``, ``no_n`` (w/o guide opt., w/o reparam., w/o N): DR alone, from the
  full run's init, with one switch off: ``dr_on_capture CAPTURE INIT OUT/ROW eval=0 KEY=0`` (the example
  binary of ``hairrecon-recon``; the init is deterministic, so these rows start from the same strands as
  ``full``), scored with ``hairrecon eval --json``; with ``keep_curls=1`` too when the full run's DR kept
  curls (``dr_keeps_curls`` in its ``metrics.json``) and ``quiet=1`` (its ``partings.ply`` linked into the
  init) when it quieted the orientation around the partings (``parting_pixels_quieted``), so the row
  differs from ``full`` by its switch only;
- ``no_strand_init``, ``no_global_opt`` (w/o strand init., w/o global opt.): whole runs with
  ``--no-strand-init`` / ``--no-global-opt`` (they change the init).

Each row's output folder ``OUT/ROW`` is kept; a row that has finished (its ``strands.hair`` from DR, or
its ``metrics.json`` with scores after DR) is scored, not run again, so an interrupted table goes on
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
# DR-only rows: the dr_on_capture key switched off.
DR_KEYS = {"no_guide_opt": "guide_opt", "no_reparam": "reparam", "no_n": "n"}
# Whole-run rows: the reconstruct flag.
WHOLE_FLAGS = {"full": [], "no_strand_init": ["--no-strand-init"], "no_global_opt": ["--no-global-opt"]}


class AblationError(RuntimeError):
    pass


def dr_row_keys(name: str, keep_curls: bool, quiet: bool = False) -> list:
    """``dr_on_capture``'s keys for a DR-only row: its switch off, the full run's curl options when its
    DR kept curls, and the orientation quiet around the partings when the full run's DR quieted it
    (the row then differs from ``full`` by the switch only)."""
    return (["eval=0", f"{DR_KEYS[name]}=0"] + (["keep_curls=1"] if keep_curls else [])
            + (["quiet=1"] if quiet else []))


def scores_row(report: dict) -> dict:
    """The table's figures from a metric report (``hairrecon eval --json`` or an entry of
    ``metrics.json``): ``{"P2","R2","F2","F1mm","F3mm","D2"}`` in percent."""

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


def _finished(run_dir: Path) -> bool:
    """A whole run that got through DR: its metrics.json has the scores after DR."""
    try:
        return "dr_strands" in json.loads((run_dir / "metrics.json").read_text())
    except (OSError, ValueError):
        return False


def evaluate(exe: Path, pred: Path, gt: Path) -> dict:
    """``hairrecon eval --json`` of ``pred`` against ``gt``."""
    print(f"ablations: scoring {pred}", flush=True)
    ev = subprocess.run([str(exe), "eval", "--pred", str(pred), "--gt", str(gt), "--json"],
                        capture_output=True, text=True)
    if ev.returncode != 0:
        raise AblationError(f"hairrecon eval failed on {pred}: {ev.stderr.strip()}")
    return json.loads(ev.stdout)


def find_binaries(args) -> tuple[Path, Path]:
    exe = Path(args.hairrecon_bin) if args.hairrecon_bin else REPO / "target" / "release" / "hairrecon"
    dr = REPO / "target" / "release" / "examples" / "dr_on_capture"
    if args.build:
        subprocess.run(
            ["cargo", "build", "--release", "-p", "hairrecon-cli", "-p", "hairrecon-recon", "--example", "dr_on_capture"],
            cwd=REPO,
            check=True,
        )
    for b in (exe, dr):
        if not b.is_file():
            raise AblationError(f"no {b}; build it with: cargo build --release -p hairrecon-cli -p hairrecon-recon "
                                "--example dr_on_capture (or pass --build)")
    return exe, dr


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("capture", type=Path, help="capture folder with gt/strands.hair")
    p.add_argument("out", type=Path, help="output folder (one sub-folder per row)")
    p.add_argument("--full", type=Path, help="a finished `hairrecon reconstruct CAPTURE --out DIR` to use as the full row")
    p.add_argument("--rows", nargs="+", default=ROWS, choices=ROWS)
    p.add_argument("--hairrecon-bin", help="the hairrecon binary (default: target/release/hairrecon)")
    p.add_argument("--build", action="store_true", help="cargo build the two binaries first")
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
    exe, dr_bin = find_binaries(a)
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
    if need_full and not (full_dir / "metrics.json").is_file():
        if a.full:
            raise AblationError(f"--full {a.full} has no metrics.json: not a finished reconstruct run")
        full_dir.mkdir(parents=True, exist_ok=True)
        secs, peak = run_measured([exe, "reconstruct", a.capture, "--out", full_dir], a.out / "full.log")
        rows["full"] = {"seconds": secs, "peak_mb": peak}
    keep_curls = quiet = False
    if need_full:
        m = json.loads((full_dir / "metrics.json").read_text())
        keep_curls = bool(m.get("dr_keeps_curls", False))
        # The pipeline's DR quiets the orientation loss around the partings it found.
        quiet = "parting_pixels_quieted" in m and (full_dir / "partings.ply").is_file()
        if "dr_strands" not in m:
            raise AblationError(f"{full_dir}/metrics.json has no dr_strands: run the full method (without --no-dr)")
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
        if name in DR_KEYS:
            if not (row_dir / "strands.hair").is_file():
                init = a.out / "init"
                init.mkdir(exist_ok=True)
                for src, dst in [("init_guides.hair", "guides.hair"), ("init_strands.hair", "strands.hair"),
                                 ("orient2d", "orient2d"), ("partings.ply", "partings.ply")]:
                    link = init / dst
                    if not (full_dir / src).exists():
                        continue
                    if not link.exists():
                        link.symlink_to((full_dir / src).resolve())
                secs, peak = run_measured([dr_bin, a.capture, init, row_dir, *dr_row_keys(name, keep_curls, quiet)],
                                          a.out / f"{name}.log")
            report = evaluate(exe, row_dir / "strands.hair", gt)
        else:
            if not _finished(row_dir):
                secs, peak = run_measured([exe, "reconstruct", a.capture, "--out", row_dir, *WHOLE_FLAGS[name]],
                                          a.out / f"{name}.log")
            m = json.loads((row_dir / "metrics.json").read_text())
            report, init_scores = m["dr_strands"], scores_row(m["init_strands"])
        rows[name] = {"scores": scores_row(report), "seconds": secs, "peak_mb": peak}
        if init_scores is not None:
            rows[name]["init_scores"] = init_scores
        save()
    table = format_table(rows)
    (a.out / "ablations.md").write_text(table + "\n")
    print(table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
