"""How fast strands rise off the head: the height above the head along the strands rooted on top.

Reads a run's `flow.bin` (the head's and the raw mesh's signed distances per voxel) and a strand file (a
run's `init_guides.hair`, or the ground truth); for the strands whose root lies above `--min-root-z`, prints
per arc length the median height above the head and depth below the raw mesh, the strands' median length,
and what the voxel after their last point is (0: not hair, the hole growth ends in).

    python research/scripts/height_by_arc.py OUT/flow.bin OUT/init_guides.hair [--min-root-z 0.14]
"""

import argparse

import numpy as np

import hairrecon


def load_flow(path):
    b = open(path, "rb").read()
    dims = np.frombuffer(b, "<u8", 3, 8).astype(int)
    org = np.frombuffer(b, "<f4", 4, 32)
    rec = np.dtype([("f", "<f4", 3), ("so", "<f4"), ("si", "<f4"), ("l", "u1")])
    grid = np.frombuffer(b[48:], rec).reshape(dims[2], dims[1], dims[0])
    return grid, org[:3], float(org[3]), dims


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("flow")
    p.add_argument("strands")
    p.add_argument("--min-root-z", type=float, default=0.14)
    a = p.parse_args()
    grid, org, vox, dims = load_flow(a.flow)

    def at(P, key):
        q = np.clip(np.round((P - org) / vox).astype(int), 0, dims - 1)
        return grid[key][q[:, 2], q[:, 1], q[:, 0]]

    pts, counts = hairrecon.read_strands(a.strands)
    off = np.concatenate([[0], np.cumsum(counts.astype(np.int64))])
    rows = []
    for s in range(len(counts)):
        P = pts[off[s]:off[s + 1]]
        if P[0, 2] >= a.min_root_z:
            arc = np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))])
            rows.append((arc, at(P, "si"), at(P, "so"), P))
    print(f"{len(rows)} strands rooted above z = {a.min_root_z} m")
    for cm in [1, 2, 3, 4, 6, 8, 10, 14]:
        live = [r for r in rows if r[0][-1] >= cm / 100]
        if not live:
            break
        h = np.median([np.interp(cm / 100, r[0], r[1]) for r in live]) * 1e3
        d = -np.median([np.interp(cm / 100, r[0], r[2]) for r in live]) * 1e3
        print(f"arc {cm:3d} cm: {len(live):5d} strands, height above the head {h:5.1f} mm, below the raw mesh {d:5.1f} mm")
    print(f"median length {np.median([r[0][-1] for r in rows]) * 100:.1f} cm")
    ends = np.array([r[3][-1] for r in rows])
    tang = np.array([r[3][-1] - r[3][-2] for r in rows])
    nxt = ends + tang / np.linalg.norm(tang, axis=1, keepdims=True) * 0.004
    print("label of the voxel after the last point (0 not hair, 1 hair, 2 constrained):", np.bincount(at(nxt, "l"), minlength=3))


if __name__ == "__main__":
    main()
