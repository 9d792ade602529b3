"""What a hair simulation says about strands being simulation-ready (numpy only, no bpy).

Test Hair Physics (``physics.py``) runs Blender's own hair dynamics on a sample of the strands while the
head turns and nods, and hands each frame's strand points here, in the head's own frame (so that a
strand that moves only with the head does not move at all). This module picks and resamples the
strands that are simulated, keys the head's motion, and turns the frames into measures:

- roots: how far each root strays from where it is bound on the scalp (they are pinned to it);
- stretch: each segment's length against its rest length (the strands are inextensible hair): the
  median over the segments in the worst frame, and over the strands the 95th percentile of each
  strand's largest stretch (a few strands caught in a collision stretch for a frame or two; the
  largest of all is reported, not bounded);
- penetration: the share of points more than ``INSIDE_M`` inside the head, and the deepest;
- explosion: a point that is not a finite number, or farther from its root than 1.5 times the
  strand's length along it (no hair can be), in any frame;
- motion: the median distance the tips moved from their rest pose (a simulation that moves nothing
  measures nothing).

``BOUNDS`` are the limits the check holds strands to; the ground truth's strands of the synthetic
captures meet them (docs/blender.md, "Test Hair Physics").
"""

from __future__ import annotations

import numpy as np

# a point deeper than this inside the head counts as inside (the collision shell is 1 mm)
INSIDE_M = 0.002
# the limits of a simulation-ready result, over all frames
BOUNDS = {
    "root_max_mm": 0.1,
    "stretch_median_pct": 1.0,
    "stretch_p95_pct": 30.0,
    "inside_max_pct": 2.0,
}


class PhysicsInputError(ValueError):
    """Strands that cannot be simulated (the message says which and why)."""


def pick(counts: np.ndarray, k: int, seed: int) -> np.ndarray:
    """Indices (sorted) of ``min(k, S)`` strands drawn without replacement with ``seed``, among the
    strands with at least 2 points."""
    counts = np.asarray(counts, np.int64)
    ok = np.flatnonzero(counts >= 2)
    if len(ok) == 0:
        raise PhysicsInputError("no strand has two points or more")
    if k >= len(ok):
        return ok
    rng = np.random.default_rng(seed)
    return np.sort(rng.choice(ok, size=int(k), replace=False))


def resample(points: np.ndarray, counts: np.ndarray, which: np.ndarray, n: int) -> np.ndarray:
    """Strands ``which`` resampled to ``n`` points evenly spaced along their length: (len(which), n, 3).
    The first and last points are kept exactly."""
    if n < 3:
        raise PhysicsInputError(f"a simulated strand needs at least 3 points, not {n}")
    points = np.asarray(points, np.float64).reshape(-1, 3)
    offsets = np.concatenate([[0], np.cumsum(np.asarray(counts, np.int64))])
    out = np.empty((len(which), n, 3))
    for row, s in enumerate(which):
        p = points[offsets[s] : offsets[s + 1]]
        arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])
        if not np.isfinite(arc[-1]) or arc[-1] <= 0.0:
            raise PhysicsInputError(f"strand {int(s)} has no length (its points coincide or are not finite)")
        t = np.linspace(0.0, arc[-1], n)
        for c in range(3):
            out[row, :, c] = np.interp(t, arc, p[:, c])
        out[row, -1] = p[-1]
    return out


def head_keys(frames: int, turn_deg: float, nod_deg: float) -> list[tuple[int, float, float]]:
    """The head's motion as keyframes ``(frame, yaw_deg, pitch_deg)`` over frames 1..frames: still for
    the first sixth (the hair settles under gravity), a turn to +turn and to -turn about the vertical
    axis (yaw, about +Z), back to the front, then a nod by ``nod_deg`` about +X (positive tips the face,
    which looks toward -Y, down) and back up. Yaw and pitch are never both non-zero."""
    if frames < 12:
        raise PhysicsInputError(f"the head's motion needs at least 12 frames, not {frames}")

    def at(x: float) -> int:
        return 1 + int(round(x * (frames - 1)))

    return [
        (1, 0.0, 0.0),
        (at(1 / 6), 0.0, 0.0),
        (at(2 / 6), turn_deg, 0.0),
        (at(3.5 / 6), -turn_deg, 0.0),
        (at(4.25 / 6), 0.0, 0.0),
        (at(5.1 / 6), 0.0, nod_deg),
        (frames, 0.0, 0.0),
    ]


class Measures:
    """Accumulates the frames of one simulation. The rest pose (S, P, 3, in the head's frame) is
    ``rest`` or, when None, the first frame added (the pose the simulation starts from, read back the
    same way as every later frame)."""

    def __init__(self, rest: np.ndarray | None = None):
        self.rows: list[dict] = []
        self.rest = None
        if rest is not None:
            self._set_rest(rest)

    def _set_rest(self, rest: np.ndarray):
        self.rest = np.asarray(rest, np.float64)
        if not np.isfinite(self.rest).all():
            raise PhysicsInputError("the strands' rest pose holds points that are not finite numbers")
        seg = np.linalg.norm(np.diff(self.rest, axis=1), axis=2)
        self.rest_len = np.maximum(seg, 1e-9)
        self.reach = np.concatenate([np.zeros((len(seg), 1)), np.cumsum(seg, axis=1)], axis=1)
        self.strand_stretch = np.zeros(len(seg))  # each strand's largest stretch so far

    def add(self, frame: int, pos: np.ndarray, depth: np.ndarray) -> dict:
        """One frame: ``pos`` (S, P, 3) in the head's frame, ``depth`` (S, P) how far each point lies
        inside the head (m, negative outside). Returns the frame's row."""
        pos = np.asarray(pos, np.float64)
        if self.rest is None:
            self._set_rest(pos)
        finite = bool(np.isfinite(pos).all())
        row = {"frame": int(frame), "finite": finite}
        if not finite:
            row["exploded"] = True
            self.rows.append(row)
            return row
        far = np.linalg.norm(pos - pos[:, :1], axis=2) > 1.5 * self.reach + 1e-3
        stretch = np.abs(np.linalg.norm(np.diff(pos, axis=1), axis=2) / self.rest_len - 1.0)
        inside = np.asarray(depth, np.float64)[:, 1:]
        self.strand_stretch = np.maximum(self.strand_stretch, stretch.max(axis=1))
        if len(self.rows) == 0:
            self.rest_inside = (inside > INSIDE_M).any(axis=1)  # strands that start inside the head
        row.update(
            exploded=bool(far.any()),
            root_max_mm=1e3 * float(np.linalg.norm(pos[:, 0] - self.rest[:, 0], axis=1).max()),
            stretch_max_pct=100.0 * float(stretch.max()),
            stretch_median_pct=100.0 * float(np.median(stretch)),
            inside_pct=100.0 * float((inside > INSIDE_M).mean()),
            inside_depth_max_mm=1e3 * float(max(inside.max(), 0.0)),
            tip_motion_median_mm=1e3 * float(np.median(np.linalg.norm(pos[:, -1] - self.rest[:, -1], axis=1))),
        )
        self.rows.append(row)
        return row

    def summary(self) -> dict:
        """The worst of every measure over the frames, and whether ``BOUNDS`` hold."""
        if not self.rows:
            raise PhysicsInputError("no frame was simulated")
        rows = [r for r in self.rows if r["finite"]]
        out = {
            "strands": int(self.rest.shape[0]),
            "points_per_strand": int(self.rest.shape[1]),
            "frames": len(self.rows),
            "exploded": any(r.get("exploded", False) for r in self.rows),
            "finite": all(r["finite"] for r in self.rows),
        }
        if rows:
            out.update(
                root_max_mm=max(r["root_max_mm"] for r in rows),
                stretch_max_pct=max(r["stretch_max_pct"] for r in rows),
                stretch_p95_pct=100.0 * float(np.quantile(self.strand_stretch, 0.95)),
                stretch_median_pct=max(r["stretch_median_pct"] for r in rows),
                inside_max_pct=max(r["inside_pct"] for r in rows),
                inside_depth_max_mm=max(r["inside_depth_max_mm"] for r in rows),
                tip_motion_median_mm=max(r["tip_motion_median_mm"] for r in rows),
            )
        failed = [] if out["finite"] and not out["exploded"] else ["exploded"]
        failed += [k for k, bound in BOUNDS.items() if k in out and not out[k] <= bound]
        out["failed"] = failed
        out["ok"] = not failed
        return out


def describe(summary: dict) -> str:
    """One line for a report."""
    if not summary.get("finite", False) or summary.get("exploded", False):
        return f"the simulation exploded ({summary['strands']} strands, {summary['frames']} frames)"
    text = (
        f"{summary['strands']} strands, {summary['frames']} frames: roots within {summary['root_max_mm']:.3f} mm, "
        f"stretch {summary['stretch_median_pct']:.2f}% median / {summary['stretch_p95_pct']:.1f}% p95, "
        f"{summary['inside_max_pct']:.2f}% of points inside the head at worst, "
        f"tips moved {summary['tip_motion_median_mm']:.0f} mm (median)"
    )
    if summary["failed"]:
        text += f"; outside the bounds: {', '.join(summary['failed'])}"
    return text
