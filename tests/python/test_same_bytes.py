"""The reconstruction's bytes are pinned: a change meant to move the strands says so.

``hairrecon reconstruct`` on a small capture committed with the tests (``data/same_bytes_capture``: the
test preset's 16 views of 256 px of straight hair, 2,000 strands, seed 0, rendered by
``scripts/render_synthetic.py``; its photos, hair masks and fusion depth maps, the raw mesh fused from
them here) must write the strands and guides whose SHA-256 digests are below: the initial strands and
guides (``init_*.hair``) and those after DR. A change that moves any stage by one float changes these
digests; a new digest is recorded only when the change in the strands is meant, and its commit says so.

The inputs are files, not a render made by the test, because a render's bytes depend on the machine:
on a CPU with AVX-512, numpy's vectorised ``power`` in the sRGB conversion rounds 4 of these 16 photos
differently in a few pixels, and everything downstream moves. The library's own bytes do not depend on
the machine's vector units (the same digests with glibc's AVX2 and FMA paths turned off through
``GLIBC_TUNABLES``).

History of the digests: the refactor into stages behind a runner kept the bytes of the code before it
(commit 5573f38); they were recorded again when the flow's outer surface became the raw mesh smoothed,
when DR's conjugate-gradient solve began to sum its dot products per run of strands (commit c6c059c),
when DR began to move every other point (``DrOptions::stride`` 2), when its guide stage began to run on
every fourth point at half the image size (``guide_stride`` 4, ``guide_downsample`` 2), and when the
child stage began to move every third point with solves stopped at a relative residual of 1e-2
(``stride`` 3, ``cg_tolerance`` 1e-2); each time the code of the change, with the old options in its
config, still wrote the old digests. Those digests were of a render made on another machine; the
committed capture is this machine's render of the same scene with the same cameras (the cameras of
commit 5573f38), and its digests were recorded at the commit that added it, with no change in the code.
They were recorded again when the raw mesh's inset began to stop at the head (``--inset-above-head``:
the ribbons widen the hair, not the skin); without that flag the code of the change wrote the old digests.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
from pathlib import Path

import pytest

from conftest import hairrecon_bin, head_files, straight_hair

CAPTURE = Path(__file__).parent / "data" / "same_bytes_capture"
# The renderer's fusion radius for this capture (render_info.json's fusion_radius_mm, 2.3456 mm), the
# raw mesh's inset in `hairrecon fuse-depth` as scripts/render_synthetic.py passes it.
FUSION_INSET_MM = "2.3456"
DR_ARGS = ["--guides", "300", "--children", "3000", "--dr-iters-guides", "8", "--dr-iters-children", "4"]
DIGESTS = {
    "init_strands.hair": "a873f69970b76d9b5697ba3b4d9d934880871aeeb8f053054822c9675bd60558",
    "init_guides.hair": "dfdccc1fa4c0009be856a6ee420537b15a168382e47f5a13ad5b44d9528f6acc",
    "strands.hair": "27d6fcb6cb46b8a86143cd0b6227c58b6271e9f36fef9321c6bdd4875979f629",
    "guides.hair": "5e381b9dda86960da7d9b52b2c4dc829a5cd0573916633f53e3f930af3656ef6",
}


def run(cmd: list, env: dict | None = None) -> None:
    r = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, env=env)
    assert r.returncode == 0, f"{' '.join(map(str, cmd))} failed:\n{r.stderr[-3000:]}"


@pytest.fixture(scope="module")
def pinned_capture(tmp_path_factory) -> Path:
    """The committed capture with the bundled head and scalp, its ground-truth strands (the generator's,
    which rendered it) and its raw mesh fused from its depth maps."""
    cap = tmp_path_factory.mktemp("same_bytes") / "capture"
    shutil.copytree(CAPTURE, cap)
    head, scalp = head_files()
    shutil.copy(head, cap / "head.ply")
    shutil.copy(scalp, cap / "scalp.ply")
    (cap / "gt").mkdir()
    straight_hair(hairrecon_bin(), cap / "gt", 2000, "strands.hair")
    spec = json.loads((cap / "capture.json").read_text())
    assert {"head_mesh": "head.ply", "scalp_mesh": "scalp.ply", "raw_mesh": "raw_mesh.ply"}.items() <= spec.items()
    spec["gt_strands"] = "gt/strands.hair"
    (cap / "capture.json").write_text(json.dumps(spec, indent=1))
    run([hairrecon_bin(), "fuse-depth", cap, "--depth-dir", "fusion/depth", "--voxel-mm", "2.0",
         "--inset-mm", FUSION_INSET_MM, "--inset-above-head"])
    return cap


def digests(out: Path) -> dict:
    return {f: hashlib.sha256((out / f).read_bytes()).hexdigest() for f in DIGESTS}


def test_reconstruct_writes_the_pinned_bytes(pinned_capture, tmp_path):
    out = tmp_path / "dr"
    run([hairrecon_bin(), "reconstruct", pinned_capture, "--out", out, *DR_ARGS])
    assert json.loads((out / "report.json").read_text())["scores"], "the ground truth was not scored"
    assert digests(out) == DIGESTS


def test_one_thread_and_no_ground_truth_write_the_same_bytes(pinned_capture, tmp_path):
    """Work split over threads (rayon over views, tiles and strands) never changes a result, and no stage
    reads the ground truth: the run on one thread, on a copy of the capture without its ground truth
    (``gt/`` and the key naming it; nothing is scored), writes the digests pinned above for the
    machine's two threads with the ground truth scored."""
    cap = tmp_path / "no_gt"
    shutil.copytree(pinned_capture, cap, ignore=shutil.ignore_patterns("gt"))
    spec = json.loads((cap / "capture.json").read_text())
    assert spec.pop("gt_strands")
    (cap / "capture.json").write_text(json.dumps(spec, indent=1))
    out = tmp_path / "one_thread"
    run([hairrecon_bin(), "reconstruct", cap, "--out", out, *DR_ARGS], env={**os.environ, "RAYON_NUM_THREADS": "1"})
    assert json.loads((out / "report.json").read_text())["scores"] in ({}, None)
    assert digests(out) == DIGESTS
