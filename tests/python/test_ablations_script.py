"""scripts/ablations.py: the table's figures come from the metric reports' right entries."""

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "scripts"))
import ablations  # noqa: E402


def report(shift: float) -> dict:
    """A metric report shaped like `hairrecon eval --json` (and report.json's scores), with figures
    that differ per threshold, mode and measure so that a wrong pick shows."""

    def scores(base):
        return [
            {"dist_mm": d, "angle_deg": 10.0 * d, "precision": base + 10 * d, "recall": base + 10 * d + 1,
             "f1": base + 10 * d + 2}
            for d in (1.0, 2.0, 3.0)
        ]

    return {"directed": scores(shift), "undirected": scores(shift + 0.5)}


def test_scores_row_picks_the_thresholds_and_modes():
    r = ablations.scores_row(report(40.0))
    assert r == {"P2": 60.5, "R2": 61.5, "F2": 62.5, "F1mm": 52.5, "F3mm": 72.5, "D2": 62.0}


def test_a_report_without_the_2mm_threshold_is_an_error():
    bad = report(40.0)
    bad["undirected"] = [s for s in bad["undirected"] if s["dist_mm"] != 2.0]
    with pytest.raises(ablations.AblationError, match="undirected score at 2 mm"):
        ablations.scores_row(bad)


def test_table_keeps_the_supplements_order_and_marks_the_init():
    rows = {
        "no_n": {"scores": ablations.scores_row(report(30.0)), "seconds": 455.0, "peak_mb": 5734.4},
        "full": {"scores": ablations.scores_row(report(40.0))},
        "no_dr": {"scores": ablations.scores_row(report(35.0))},
        "no_global_opt": {"scores": ablations.scores_row(report(20.0)), "seconds": 61.0, "peak_mb": None,
                          "init_scores": ablations.scores_row(report(10.0))},
    }
    lines = ablations.format_table(rows).splitlines()
    assert [ln.split("|")[1].strip() for ln in lines[2:]] == ["full", "w/o DR", "w/o N", "w/o global opt."]
    assert "| w/o N | 50.5 / 51.5 / **52.5** | 42.5 · 62.5 | 52.0 | 7 min 35 s, 5.6 GB |" in lines
    assert "**42.5** (before DR 32.5)" in lines[-1] and lines[-1].endswith("| 1 min 1 s |")


def test_dr_rows_replay_the_full_runs_config_from_dr_with_one_switch_off():
    full = Path("/runs/full")
    assert ablations.dr_row_args("no_n", full) == ["--config", full / "config.json", "--from", "dr",
                                                   "--no-neighbor-reparam"]
    assert ablations.dr_row_args("no_reparam", full)[-1] == "--no-reparam"
    assert ablations.dr_row_args("no_guide_opt", full)[-1] == "--no-guide-opt"
    # The row links what `--from dr` reloads: the config, the maps, the partings and the init.
    assert {"config.json", "orient2d", "partings.json", "init_strands.hair", "init.json"} <= set(ablations.DR_INPUTS)
