"""Oracle inputs for a run: put the capture's ground truth in place of one stage's output, then re-run the rest.

What do the later stages lose on their own? Replace a stage's output in a copy of a finished run by what the
renderer knows, run the stages after it again, and compare the scores with the run's own:

- `maps`: each view's 2D orientation θ becomes the ground truth's (`gt/orientation`, the front strand's
  projected tangent) wherever both the run's map and the ground truth have hair; the run's confidence is kept.
  Then `--from orient3d`.
- `points`: the directed 3D points become ground-truth strand points (every vertex of the ground-truth strands
  within `--surface-mm` of the raw mesh's vertices, a seeded sample of `--count`), directed root to tip, at
  confidence 1. Then `--from init`.

    cp -r RUN ORACLE
    python research/scripts/oracle_inputs.py maps ORACLE CAPTURE
    hairrecon reconstruct CAPTURE --out ORACLE --config ORACLE/config.json --from orient3d --stop-after init

Needs numpy, scipy (`points` only) and the hairrecon module. Used for docs/reconstruction.md ("Where wavy
hair's gap is").
"""

import argparse
import json
import struct
from pathlib import Path

import numpy as np

import hairrecon

MAGIC = b"HRMAPS01"


def oracle_maps(run: Path, capture: Path) -> None:
    path = run / "orient2d" / "maps.bin"
    data = path.read_bytes()
    if data[:8] != MAGIC:
        raise SystemExit(f"{path} is not a hairrecon orientation-map file")
    (n,) = struct.unpack("<I", data[8:12])
    views = json.loads((capture / "capture.json").read_text())["views"]
    if n != len(views):
        raise SystemExit(f"{path} holds {n} maps, {capture} has {len(views)} views")
    out, off, replaced, hair = [data[:12]], 12, 0, 0
    for v in views:
        w, h = struct.unpack("<2I", data[off : off + 8])
        off += 8
        theta = np.frombuffer(data, np.float32, w * h, off).copy()
        conf = np.frombuffer(data, np.float32, w * h, off + 4 * w * h)
        off += 8 * w * h
        gt = hairrecon.read_exr(str(capture / v["gt_orientation"]))
        c2, s2, weight = (gt[ch].reshape(-1) for ch in "RGB")
        use = (weight > 0) & (conf > 0)
        theta[use] = np.mod(0.5 * np.arctan2(s2[use], c2[use]), np.pi)
        replaced, hair = replaced + int(use.sum()), hair + int((conf > 0).sum())
        out.append(struct.pack("<2I", w, h) + theta.astype("<f4").tobytes() + conf.astype("<f4").tobytes())
    path.write_bytes(b"".join(out))
    print(f"{path}: θ of {replaced} of {hair} hair pixels from the ground truth")


def tangents(points: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """Unit root-to-tip tangents by central differences (one-sided at the ends)."""
    counts = counts.astype(np.int64)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    ends = starts + counts - 1
    prev = np.arange(len(points)) - 1
    nxt = np.arange(len(points)) + 1
    prev[starts] = starts
    nxt[ends] = ends
    t = points[nxt] - points[prev]
    return t / np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-12)


def oracle_points(run: Path, capture: Path, count: int, surface_mm: float, seed: int) -> None:
    from scipy.spatial import cKDTree

    spec = json.loads((capture / "capture.json").read_text())
    points, counts = hairrecon.read_strands(str(capture / spec["gt_strands"]), skip_short_strands=True)
    raw = hairrecon.read_mesh(str(capture / spec["raw_mesh"]))["vertices"]
    t = tangents(points, counts)
    dist, _ = cKDTree(raw).query(points)
    near = np.flatnonzero(dist < surface_mm * 1e-3)
    pick = np.random.default_rng(seed).choice(near, min(count, len(near)), replace=False)
    rows = np.concatenate([points[pick], t[pick], np.ones((len(pick), 1))], axis=1).astype("<f4")
    header = (
        "ply\nformat binary_little_endian 1.0\ncomment hairrecon oriented points\n"
        f"element vertex {len(pick)}\n"
        + "".join(f"property float {p}\n" for p in ("x", "y", "z", "nx", "ny", "nz", "confidence"))
        + "end_header\n"
    ).encode()
    for name in ("points3d.ply", "points_directed.ply"):
        (run / name).write_bytes(header + rows.tobytes())
    print(f"{run}: {len(pick)} ground-truth points of the {len(near)} within {surface_mm} mm of the raw mesh")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("what", choices=["maps", "points"])
    p.add_argument("run", type=Path, help="a copy of a finished run's output folder (it is changed)")
    p.add_argument("capture", type=Path)
    p.add_argument("--count", type=int, default=400_000, help="points: how many")
    p.add_argument("--surface-mm", type=float, default=3.0, help="points: how far from the raw mesh's vertices")
    p.add_argument("--seed", type=int, default=0)
    a = p.parse_args()
    if a.what == "maps":
        oracle_maps(a.run, a.capture)
    else:
        oracle_points(a.run, a.capture, a.count, a.surface_mm, a.seed)


if __name__ == "__main__":
    main()
