"""scripts/style_table.py: one row per run, its style from the benchmark's log, the right scores."""

import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "scripts"))
import style_table  # noqa: E402


def scores(base: float) -> dict:
    """Scores shaped like report.json's, different per threshold and mode so that a wrong pick shows."""

    def at(b):
        return [{"dist_mm": d, "angle_deg": 10.0 * d, "f1": b + 10 * d} for d in (1.0, 2.0, 3.0)]

    return {"directed": at(base - 1.0), "undirected": at(base)}


def make_run(tmp: Path, name: str, style: str, init: float, final: float | None) -> Path:
    bench = tmp / "bench"
    cap = bench / f"colors_{style}_brown"
    cap.mkdir(parents=True)
    log = bench / "benchmark.json"
    entries = json.loads(log.read_text()) if log.is_file() else {}
    entries[cap.name] = {"style": style, "preset": "colors"}
    log.write_text(json.dumps(entries))
    run = tmp / name
    run.mkdir()
    s = {"init_strands": scores(init)}
    if final is not None:
        s["dr_strands"] = scores(final)
    run.joinpath("report.json").write_text(json.dumps({"git_commit": "abc1234", "capture": str(cap), "scores": s}))
    return run


def test_rows_gaps_and_styles(tmp_path, capsys):
    a = make_run(tmp_path, "r1", "straight", 60.0, 62.0)
    b = make_run(tmp_path, "r2", "loose_curls", 40.0, 45.5)
    c = make_run(tmp_path, "r3", "side_part", 50.0, None)
    assert style_table.main([str(a), str(b), str(c)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[2] == "| straight | 70.0 · 80.0 · 90.0 | 72.0 · 82.0 · 92.0 | 81.0 | +0.0 |"
    # directed after DR at 2 mm is the undirected minus one; the gap is 65.5 - 82.0
    assert out[3] == "| loose_curls | 50.0 · 60.0 · 70.0 | 55.5 · 65.5 · 75.5 | 64.5 | -16.5 |"
    assert out[4] == "| side_part | 60.0 · 70.0 · 80.0 | – · – · – | – | – |"
    assert "abc1234" in out[-1]


def test_the_style_comes_from_the_name_without_a_log(tmp_path):
    assert style_table.style_of(tmp_path / "paper_loose_curls_gold_wild") == "loose_curls"
    assert style_table.style_of(tmp_path / "colors_spiky_black") == "spiky"
    assert style_table.style_of(tmp_path / "mine") == "mine"


def test_a_run_without_scores_is_a_clear_error(tmp_path, capsys):
    run = tmp_path / "run"
    run.mkdir()
    run.joinpath("report.json").write_text(json.dumps({"capture": str(tmp_path), "scores": {}}))
    assert style_table.main([str(run)]) == 1
    assert "no scores" in capsys.readouterr().err
    assert style_table.main([str(tmp_path / "missing")]) == 1
    assert "cannot read it" in capsys.readouterr().err


def test_write_replaces_the_block_between_the_markers(tmp_path):
    a = make_run(tmp_path, "r1", "straight", 60.0, 62.0)
    doc = tmp_path / "doc.md"
    doc.write_text("# T\n\n<!-- styles:begin -->\nold table\n<!-- styles:end -->\n\nafter\n")
    assert style_table.main([str(a), "--write", str(doc)]) == 0
    text = doc.read_text()
    assert "old table" not in text
    assert "| straight | 70.0 · 80.0 · 90.0 | 72.0 · 82.0 · 92.0 | 81.0 | +0.0 |" in text
    assert text.startswith("# T\n\n<!-- styles:begin -->\n| style |") and text.endswith("<!-- styles:end -->\n\nafter\n")
    doc.write_text("no markers\n")
    assert style_table.main([str(a), "--write", str(doc)]) == 1
