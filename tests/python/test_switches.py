"""The Python module's switches reach the stages they switch: ``hull_trim`` (the visual-hull trim in the
init) and ``parting`` (the partings stage), each run on and off from one run's earlier stages on the
test-preset capture. The add-on's side (the panel's setting becomes the keyword) is in test_addon.py,
which runs under Blender 5.0 and 4.2; this side needs no Blender and runs once.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

hairrecon = pytest.importorskip("hairrecon")

SMALL = dict(guides=64, children=400)


@pytest.fixture(scope="module")
def base(test_capture, tmp_path_factory) -> Path:
    """A run of the test capture stopped after the direction stage."""
    out = tmp_path_factory.mktemp("switches") / "base"
    hairrecon.reconstruct(str(test_capture), str(out), stop_after="direction", **SMALL)
    return out


def stage_stats(test_capture, base: Path, tmp: Path, stage: str, **switch) -> dict:
    """The report's stats by stage after `stage` runs again from `base` with the keyword given."""
    folder = tmp / "run"
    shutil.copytree(base, folder)
    r = hairrecon.reconstruct(str(test_capture), str(folder), from_stage=stage, stop_after=stage, **SMALL, **switch)
    return {st["stage"]: st.get("stats") for st in r["report"]["stages"]}


def test_hull_switch_reaches_the_init(test_capture, base, tmp_path):
    on = stage_stats(test_capture, base, tmp_path / "on", "init", hull_trim=True)
    off = stage_stats(test_capture, base, tmp_path / "off", "init", hull_trim=False)
    hull = lambda stats: {k: v for k, v in stats["init"].items() if k.startswith("hull")}  # noqa: E731
    # on: the hull is built (its views counted: none here, the sparse capture's masks being see-through)
    assert hull(on) == {"hull_views": 0}, on["init"]
    # off: no hull at all
    assert hull(off) == {}, off["init"]


def test_parting_switch_reaches_the_partings_stage(test_capture, base, tmp_path):
    on = stage_stats(test_capture, base, tmp_path / "on", "partings", parting=True)["partings"]
    off = stage_stats(test_capture, base, tmp_path / "off", "partings", parting=False)["partings"]
    # on: the views are searched (none counts, the sparse capture's masks being see-through: no skin)
    assert on is not None and on["views"] == 0 and on["skin"] == 0 and on["samples"] == 20000, on
    # off: not searched at all
    assert off is None
