"""``render_synthetic.py --background clutter`` (issue 52, item 3): a textured room and a clothed torso.

One tiny capture (300 strands, 3 views of 96 px, 4 samples) rendered twice with the same seed, once
with the clutter and once uniform (no raw mesh); both renders take about 3 s each. Checks:

- the background is not uniform: the grey values of the pixels that show neither hair nor head (no
  surface in the uniform render) vary with a standard deviation of at least 12 (of 255; measured 18.6
  to 42.1, uniform 2.2 to 3.4) in every view;
- the masks are still exactly the visible hair: every pixel of a clutter mask has hair in the uniform
  mask, with no more coverage (the same camera samples; the room and torso can only hide hair), and
  the torso hides some hair;
- the raw mesh holds the torso (vertices under the head and wider than the hair hangs) and none of the
  room (no vertex outside the fusion box that render_info.json records).
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import hairrecon
import numpy as np
import pytest

from conftest import REPO, SCRIPTS, hairrecon_bin, head_files, straight_hair

TINY = ["--preset", "test", "--views", "3", "--height", "96", "--samples", "4", "--seed", "3"]


@pytest.fixture(scope="module")
def captures(tmp_path_factory) -> tuple[Path, Path]:
    tmp = tmp_path_factory.mktemp("backdrop")
    exe = hairrecon_bin()
    head, scalp = head_files()
    hair = straight_hair(exe, tmp, 300, "h.hair")
    caps = []
    for bg, extra in (("clutter", []), ("uniform", ["--no-fuse"])):
        cap = tmp / bg
        cmd = [sys.executable, SCRIPTS / "render_synthetic.py", hair, head, cap, *TINY, "--no-blend"]
        cmd += ["--background", bg, "--hairrecon-bin", exe, *extra]
        r = subprocess.run([str(c) for c in cmd], capture_output=True, text=True)
        assert r.returncode == 0, r.stderr[-3000:]
        caps.append(cap)
    return caps[0], caps[1]


def _views(cap: Path):
    return [v["name"] for v in json.loads((cap / "capture.json").read_text())["views"]]


def test_clutter_background_is_not_uniform(captures):
    clutter, uniform = captures
    info = json.loads((clutter / "render_info.json").read_text())
    assert info["background"] == "clutter"
    assert "background" not in json.loads((uniform / "render_info.json").read_text())
    for name in _views(clutter):
        empty = hairrecon.read_exr(str(uniform / "gt" / "depth" / f"{name}.exr"))["R"] == 0
        grey = hairrecon.read_image(str(clutter / "images" / f"{name}.png")).astype(np.float64).mean(axis=2)
        grey_u = hairrecon.read_image(str(uniform / "images" / f"{name}.png")).astype(np.float64).mean(axis=2)
        std, std_u = grey[empty].std(), grey_u[empty].std()
        print(f"{name}: {int(empty.sum())} background pixels, grey std {std:.1f} (uniform: {std_u:.1f})")
        assert std >= 12.0


def test_masks_are_the_visible_hair(captures):
    clutter, uniform = captures
    hidden = 0
    for name in _views(clutter):
        mc = hairrecon.read_image(str(clutter / "masks" / f"{name}.png")).astype(np.int64)
        mu = hairrecon.read_image(str(uniform / "masks" / f"{name}.png")).astype(np.int64)
        print(f"{name}: mask pixels {int((mc > 0).sum())} with clutter, {int((mu > 0).sum())} uniform")
        assert not ((mc > 0) & (mu == 0)).any(), "a mask pixel where the uniform render has no hair"
        assert (mc <= mu).all(), "more hair coverage with the clutter than without"
        hidden += int(((mu > 0) & (mc == 0)).sum())
    assert hidden > 0, "the torso hides no hair"


def test_raw_mesh_has_the_torso_and_not_the_room(captures):
    clutter, _ = captures
    info = json.loads((clutter / "render_info.json").read_text())
    v = hairrecon.read_mesh(str(clutter / "raw_mesh.ply"))["vertices"].astype(np.float64)
    head = hairrecon.read_mesh(str(REPO / "blend_fixtures" / "head.ply"))["vertices"]
    hair, _ = hairrecon.read_strands(str(clutter / "gt" / "strands.hair"))
    zb = float(head[:, 2].min())
    half = float(np.abs(hair[:, 0]).max()) + 0.015  # beyond the hair and its fusion ribbons
    shoulders = (v[:, 2] < zb - 0.03) & (np.abs(v[:, 0]) > half)
    lo, hi = (np.array(b) for b in info["clutter"]["fusion_box_m"])
    print(f"raw mesh: {len(v)} vertices, {int(shoulders.sum())} on the torso beyond |x| = {half:.3f} m")
    assert shoulders.sum() > 200
    assert (v >= lo - 0.01).all() and (v <= hi + 0.01).all()
