"""Replaces each strand by a helix about its own centreline, for the curly study (docs/curly-study.md, session 21).

    .venv/bin/python scripts/curl_resynth.py IN.hair OUT.hair WINDOW_MM RADIUS_MM PERIOD_MM
        [hand=1] [ramp_mm=15] [seed=0] [phase=random|own]

Each strand is resampled every 1 mm of arc; its centreline is the mean of its points over WINDOW_MM of arc
(a window of one turn cancels a round helix exactly; the window shrinks at the ends, the root is kept). The
centreline is resampled every 1 mm of its own arc and a helix of RADIUS_MM and PERIOD_MM of centreline per
turn is swept about it in a frame carried along it (as `hairrecon synth-hair` makes curls), growing to full
radius over `ramp_mm` from the root, at a random phase per strand (seeded), or with phase=own at the phase that
follows the strand itself best (the phase ceiling of session 24's study). hand=1 turns right-handed about
the root-to-tip tangent (the curly preset's curls), -1 left-handed, 0 writes the centrelines alone.
The output has about 100 points per strand. Score it with `hairrecon eval`. Needs only numpy.

The curly preset's curls: radius 6.5 mm, period 22 mm, so one turn is 46 mm of arc.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _hairio  # noqa: E402

STEP = 0.001


def box_mean(pts: np.ndarray, window: int) -> np.ndarray:
    """Mean of each point's neighbours within window // 2 samples on both sides (fewer at the ends)."""
    n = len(pts)
    cs = np.concatenate([np.zeros((1, 3)), np.cumsum(pts, axis=0)])
    i = np.arange(n)
    half = np.minimum(window // 2, np.minimum(i, n - 1 - i))
    lo, hi = i - half, i + half + 1
    return (cs[hi] - cs[lo]) / (hi - lo)[:, None]


def frames(c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The frame (e1, e2) carried along the centreline `c` (e1 kept across the tangent, e2 = t x e1)."""
    t = np.gradient(c, axis=0)
    t /= np.linalg.norm(t, axis=1, keepdims=True) + 1e-12
    e1 = np.cross(t[0], [0.0, 0.0, 1.0])
    if np.linalg.norm(e1) < 1e-6:
        e1 = np.cross(t[0], [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    E1, E2 = np.empty_like(c), np.empty_like(c)
    for k in range(len(c)):
        e1 = e1 - t[k] * (t[k] @ e1)
        e1 /= np.linalg.norm(e1) + 1e-12
        E1[k], E2[k] = e1, np.cross(t[k], e1)
    return E1, E2


def helix_about(
    c: np.ndarray, radius: float, period: float, hand: float, ramp: float, phi0: float, frame=None
) -> np.ndarray:
    """A helix about the centreline `c` (points every STEP of arc); `frame`: `frames(c)` if known."""
    E1, E2 = frames(c) if frame is None else frame
    s = np.arange(len(c)) * STEP
    x = np.minimum(s / ramp, 1.0) if ramp > 0 else np.ones(len(c))
    r = radius * x * x * (3.0 - 2.0 * x)
    phi = phi0 + hand * 2.0 * np.pi * s / period
    return c + r[:, None] * (np.cos(phi)[:, None] * E1 + np.sin(phi)[:, None] * E2)


def own_phase(s: np.ndarray, c_raw: np.ndarray, c: np.ndarray, frame, period: float, hand: float, ramp: float):
    """The phase at which `helix_about(c, ...)` follows the strand `s` best (`c_raw`: its box mean, one
    sample per sample of `s`; `c`: that resampled; `frame`: `frames(c)`): the circular mean, past the
    ramp, of each sample's angle about the centreline in the helix's frame less the helix's turning.
    None when nothing is past the ramp."""
    E1, E2 = frame
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(c_raw, axis=0), axis=1))])
    k = np.clip(np.round(arc / STEP).astype(int), 0, len(c) - 1)
    off = s - c_raw
    ang = np.arctan2(np.einsum("ij,ij->i", off, E2[k]), np.einsum("ij,ij->i", off, E1[k]))
    keep = arc > ramp
    if not keep.any():
        return None
    return float(np.angle(np.exp(1j * (ang[keep] - hand * 2.0 * np.pi * arc[keep] / period)).mean()))


def main(argv: list[str]) -> None:
    if len(argv) < 5:
        raise SystemExit(__doc__)
    kw = {}
    for a in argv[5:]:
        k, sep, v = a.partition("=")
        if not sep or k not in ("hand", "ramp_mm", "seed", "phase"):
            raise SystemExit(f"unknown option {a!r}; use hand=, ramp_mm=, seed=, phase=")
        if k == "phase":
            if v not in ("random", "own"):
                raise SystemExit(f"phase={v!r}: give phase=random or phase=own")
            kw[k] = v
        else:
            kw[k] = float(v)
    window = int(round(float(argv[2])))
    radius, period = float(argv[3]) / 1000, float(argv[4]) / 1000
    if window < 1 or radius < 0 or period <= 0:
        raise SystemExit("WINDOW_MM must be >= 1, RADIUS_MM >= 0 and PERIOD_MM > 0")
    hand, ramp = kw.get("hand", 1.0), kw.get("ramp_mm", 15.0) / 1000
    rng = np.random.default_rng(int(kw.get("seed", 0)))
    try:
        pts, counts = _hairio.read_hair(argv[0])
    except (OSError, ValueError) as e:
        raise SystemExit(f"{argv[0]}: cannot read the strands: {e}") from None
    offsets = _hairio.strand_offsets(counts)
    out, out_counts = [], []
    for i in range(len(counts)):
        phi0 = rng.uniform(0.0, 2.0 * np.pi)
        s, _ = _hairio.resample_by_arc(pts[offsets[i] : offsets[i + 1]].astype(np.float64), STEP)
        if len(s) < 3:
            continue
        c_raw = box_mean(s, window)
        c_raw[0] = s[0]
        c, _ = _hairio.resample_by_arc(c_raw, STEP)
        if len(c) < 3:
            continue
        frame = frames(c) if hand != 0 else None
        if kw.get("phase") == "own" and hand != 0:
            fitted = own_phase(s, c_raw, c, frame, period, hand, ramp)
            phi0 = phi0 if fitted is None else fitted
        res = c if hand == 0 else helix_about(c, radius, period, hand, ramp, phi0, frame)
        every = max(1, len(res) // 99)
        keep = res[::every]
        if (len(res) - 1) % every:
            keep = np.concatenate([keep, res[-1:]])
        out.append(keep.astype(np.float32))
        out_counts.append(len(keep))
    if not out:
        raise SystemExit(f"{argv[0]}: no strand long enough")
    _hairio.write_hair(argv[1], np.concatenate(out), np.array(out_counts))
    print(f"{len(out_counts)} of {len(counts)} strands -> {argv[1]}")


if __name__ == "__main__":
    main(sys.argv[1:])
