"""hairrecon.make_masks on a capture as an import leaves it (tests/python/fit_fixture.py: the bundled head,
bald, moved by a similarity as the raw mesh, four cameras) after fit_head(write=True): a bald head has
no hair, so every mask is empty and no raw-mesh vertex is hair; write=True names the masks in
capture.json; a capture without a head says to fit one first. (Masks of real hair are tested through
the command line in rust/cli/tests/masks_cli.rs.)
"""

from __future__ import annotations

import json

import numpy as np
import pytest

hairrecon = pytest.importorskip("hairrecon")

from fit_fixture import write_capture  # noqa: E402


def test_a_bald_head_has_empty_masks_and_write_names_them(tmp_path):
    cap = tmp_path / "cap"
    write_capture(hairrecon, cap, photos=True)
    hairrecon.fit_head(str(cap), write=True)
    m = hairrecon.make_masks(str(cap), write=True)
    spec = json.loads((cap / "capture.json").read_text())
    assert len(m["alphas"]) == len(spec["views"]) == 4
    for v, a in zip(spec["views"], m["alphas"]):
        assert a.dtype == np.float32 and a.shape == (v["height"], v["width"])
        assert float(a.max()) < 0.5, (v["name"], float(a.max()))
        assert v["mask"] == f"masks/{v['name']}.png" and (cap / v["mask"]).is_file()
    raw = hairrecon.read_mesh(str(cap / "raw.ply"))
    assert m["region"].shape == (len(raw["vertices"]),) and float(m["region"].max()) < 0.5
    assert m["report"]["region"]["hair_vertices"] == 0 and m["report"]["views"] == 4
    names = sorted(p.rsplit("/", 1)[-1] for p in map(str, m["written"]))
    assert names == ["capture.json", "hair_region.ply", "masks.json"] + [f"v{i}.png" for i in range(4)], names


def test_make_masks_needs_a_head_and_one_destination(tmp_path):
    cap = tmp_path / "cap"
    write_capture(hairrecon, cap, photos=True)
    with pytest.raises(hairrecon.CaptureError, match="fit_head|fit-head"):
        hairrecon.make_masks(str(cap))
    with pytest.raises(hairrecon.InputError, match="not both"):
        hairrecon.make_masks(str(cap), write=True, out=str(tmp_path / "o"))
