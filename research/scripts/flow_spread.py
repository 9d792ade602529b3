"""How well one direction per voxel can hold a capture's ground-truth strands near the hair surface.

- `flow RUN CAPTURE`: the run's flow field (`flow.bin`, read trilinearly) at a seeded sample of 300,000
  ground-truth strand points, against their tangents (undirected), by distance to the raw mesh's vertices.
- `spread CAPTURE`: the ground truth against itself: for a seeded sample of 20,000 strand points within 3 mm of
  the raw mesh, the angle of each tangent to the mean tangent of the strand points within `--radius-mm`, and the
  widest angle between the point's tangent and theirs.

    python research/scripts/flow_spread.py flow RUN CAPTURE
    python research/scripts/flow_spread.py spread CAPTURE --radius-mm 1.5

Needs numpy, scipy and the hairrecon module. Used for docs/reconstruction.md ("Where wavy hair's gap is").
"""

import argparse
import json
import sys
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

import hairrecon

sys.path.insert(0, str(Path(__file__).resolve().parent))
from oracle_inputs import tangents  # noqa: E402


def ground_truth(capture: Path):
    spec = json.loads((capture / "capture.json").read_text())
    points, counts = hairrecon.read_strands(str(capture / spec["gt_strands"]), skip_short_strands=True)
    raw = hairrecon.read_mesh(str(capture / spec["raw_mesh"]))["vertices"]
    return points, tangents(points, counts), raw


def read_flow(path: Path):
    b = path.read_bytes()
    if b[:8] != b"HRFLOW01":
        raise SystemExit(f"{path} is not a hairrecon flow file")
    dims = np.frombuffer(b, np.uint64, 3, 8).astype(int)
    origin = np.frombuffer(b, np.float32, 3, 32)
    voxel = float(np.frombuffer(b, np.float32, 1, 44)[0])
    n = int(dims.prod())
    rec = np.frombuffer(b, np.uint8, n * 21, 48).reshape(n, 21)
    field = rec[:, :12].copy().view(np.float32).reshape(dims[2], dims[1], dims[0], 3)
    return field, origin, voxel, dims


def flow(run: Path, capture: Path) -> None:
    points, tang, raw = ground_truth(capture)
    field, origin, voxel, dims = read_flow(run / "flow.bin")
    pick = np.random.default_rng(1).choice(len(points), 300_000, replace=False)
    p, t = points[pick], tang[pick]
    q = (p - origin) / voxel
    f = np.floor(q).astype(int)
    w = q - f
    inside = np.all((f >= 0) & (f + 1 < dims), axis=1)
    p, t, f, w = p[inside], t[inside], f[inside], w[inside]
    v = np.zeros((len(p), 3), np.float32)
    for c in range(8):
        dx, dy, dz = c & 1, (c >> 1) & 1, c >> 2
        wt = (w[:, 0] if dx else 1 - w[:, 0]) * (w[:, 1] if dy else 1 - w[:, 1]) * (w[:, 2] if dz else 1 - w[:, 2])
        v += wt[:, None] * field[f[:, 2] + dz, f[:, 1] + dy, f[:, 0] + dx]
    norm = np.linalg.norm(v, axis=1)
    has = norm > 1e-6
    cos = np.abs(np.sum(v[has] / norm[has, None] * t[has], axis=1))
    angle = np.degrees(np.arccos(np.clip(cos, 0, 1)))
    depth, _ = cKDTree(raw).query(p[has])
    print(f"{len(p)} ground-truth points in the grid, the field defined at {100 * has.mean():.1f} %")
    for lo, hi in [(0, 3), (3, 6), (6, 10), (10, 20), (20, 1000)]:
        m = (depth >= lo * 1e-3) & (depth < hi * 1e-3)
        if m.any():
            print(
                f"  {lo:>2}-{hi:<4} mm from the raw mesh: {100 * m.mean():5.1f} % of them, angle to the field median "
                f"{np.median(angle[m]):.1f}°, within 20° {100 * (angle[m] < 20).mean():.1f} %"
            )


def spread(capture: Path, radius_mm: float) -> None:
    points, tang, raw = ground_truth(capture)
    near, _ = cKDTree(raw).query(points)
    keep = near < 0.003
    p, t = points[keep], tang[keep]
    pick = np.random.default_rng(2).choice(len(p), 20_000, replace=False)
    tree = cKDTree(p)
    to_mean, widest = [], []
    for i, nb in zip(pick, tree.query_ball_point(p[pick], radius_mm * 1e-3)):
        mean = t[nb].sum(0)
        mean /= np.linalg.norm(mean)
        to_mean.append(np.degrees(np.arccos(min(1.0, abs(float(t[i] @ mean))))))
        widest.append(np.degrees(np.arccos(np.clip(np.abs(t[nb] @ t[i]), 0, 1))).max())
    to_mean, widest = np.array(to_mean), np.array(widest)
    print(
        f"within {radius_mm} mm: angle to the local mean median {np.median(to_mean):.1f}°, within 20° "
        f"{100 * (to_mean < 20).mean():.1f} %; widest pair median {np.median(widest):.1f}°, "
        f"90th percentile {np.percentile(widest, 90):.1f}°"
    )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("what", choices=["flow", "spread"])
    p.add_argument("paths", nargs="+", type=Path, help="flow: RUN CAPTURE; spread: CAPTURE")
    p.add_argument("--radius-mm", type=float, default=1.5)
    a = p.parse_args()
    if a.what == "flow":
        if len(a.paths) != 2:
            p.error("flow takes RUN CAPTURE")
        flow(*a.paths)
    else:
        if len(a.paths) != 1:
            p.error("spread takes CAPTURE")
        spread(a.paths[0], a.radius_mm)


if __name__ == "__main__":
    main()
