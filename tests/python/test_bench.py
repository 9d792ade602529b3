"""scripts/bench.py: one real run of the CLI under /usr/bin/time -v, its table and its JSON."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import REPO, hairrecon_bin


@pytest.mark.skipif(not Path("/usr/bin/time").exists(), reason="/usr/bin/time is not installed")
def test_bench_prints_each_stage_and_the_whole_process(test_capture, tmp_path):
    out, figures = tmp_path / "out", tmp_path / "bench.json"
    r = subprocess.run(
        [sys.executable, str(REPO / "scripts" / "bench.py"), str(test_capture), "--out", str(out),
         "--json", str(figures), "--", "--stop-after", "orient3d"],
        capture_output=True, text=True, env={**os.environ, "HAIRRECON_BIN": str(hairrecon_bin())},
    )
    assert r.returncode == 0, r.stderr[-2000:]
    report = json.loads((out / "report.json").read_text())
    got = json.loads(figures.read_text())
    assert [s["stage"] for s in got["stages"]] == [s["stage"] for s in report["stages"]] == ["orient2d", "orient3d"]
    for s in got["stages"]:
        # The stages compute (their CPU time is real, and no more than two cores' worth of their wall time).
        assert 0 < s["cpu_seconds"] <= 2.2 * s["wall_seconds"] + 0.05, s
    whole = got["process"]
    assert whole["wall_seconds"] >= sum(s["wall_seconds"] for s in got["stages"]) - 0.05
    assert whole["peak_rss_mb"] >= max(s["peak_rss_mb_so_far"] for s in got["stages"]) - 1
    lines = r.stdout.splitlines()
    head = next(i for i, line in enumerate(lines) if line.split()[:2] == ["stage", "wall"])
    assert lines[head + 1].startswith("orient2d") and lines[head + 2].startswith("orient3d")
    assert lines[head + 3].startswith("process") and lines[head + 3].endswith("/usr/bin/time -v")


@pytest.mark.skipif(shutil.which("heaptrack") is None, reason="heaptrack is not installed")
def test_heap_peak_names_the_code_that_holds_the_memory(test_capture, tmp_path):
    r = subprocess.run(
        [sys.executable, str(REPO / "scripts" / "heap_peak.py"), "--top", "5", "--",
         str(hairrecon_bin()), "reconstruct", str(test_capture), "--out", str(tmp_path / "out"),
         "--stop-after", "orient2d"],
        capture_output=True, text=True,
    )
    assert r.returncode == 0, r.stderr[-2000:]
    lines = r.stdout[r.stdout.index("heap at the peak:"):].splitlines()
    total = float(lines[0].split(":")[1].split()[0])
    groups = [(float(l.split()[0]), l.split("MiB", 1)[1].strip()) for l in lines[1:]]
    assert total > 1 and 1 <= len(groups) <= 5, r.stdout[-2000:]
    # Largest first, each no more than the total, and the largest named by the project's own frames.
    assert [g for g, _ in groups] == sorted((g for g, _ in groups), reverse=True)
    assert groups[0][0] <= total + 0.1
    assert ".rs)" in groups[0][1] and "alloc.rs" not in groups[0][1], groups[0]
