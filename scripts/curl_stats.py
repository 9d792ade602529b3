"""The curl of a strand set, measured from the strands alone: arc length per turn, pitch angle, radius and
period of the helices, from the mean autocorrelation of the unit tangents along the arc.

For a helix of radius r and period p (centreline length per turn), the tangent makes the pitch angle ψ
with the axis, tan ψ = 2πr / p, and one turn takes L = sqrt(p² + (2πr)²) of arc. The tangents'
autocorrelation at an arc lag Δ is

    C(Δ) = cos²ψ + sin²ψ · cos(2πΔ / L),

so its first maximum after the first minimum lies at L, and its minimum is cos 2ψ = 2cos²ψ − 1. Hence
cos ψ = sqrt((1 + C_min) / 2), p = L cos ψ and r = L sin ψ / 2π. Real strands bend and their curls vary,
which damps the oscillation: the minimum then reads a little high (ψ a little small).

    .venv/bin/python scripts/curl_stats.py STRANDS.hair [MORE.hair ...] [--strands 500] [--json]

prints one line per file (``no curl`` when the autocorrelation does not turn back up within
``--max-lag-mm``). The reconstruction's `--curl auto` chooses a curl; this measures what it chose and
what the ground truth has (docs/curly-study.md, session 28).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _hairio import read_hair, resample_by_arc, strand_offsets  # noqa: E402


def tangent_autocorrelation(points: np.ndarray, counts: np.ndarray, step: float, max_lag: float,
                            max_strands: int = 500) -> np.ndarray:
    """Mean of t(s) · t(s + k·step) over every strand (up to ``max_strands``, evenly spaced) resampled every
    ``step`` metres, for k = 0 … max_lag / step; a lag no strand reaches is NaN."""
    nlag = int(round(max_lag / step)) + 1
    acc = np.zeros(nlag)
    cnt = np.zeros(nlag)
    offs = strand_offsets(counts)
    every = max(1, len(counts) // max(1, max_strands))
    for i in range(0, len(counts), every):
        strand = points[offs[i]:offs[i] + counts[i]]
        if len(strand) < 2:
            continue
        r, _ = resample_by_arc(strand, step)
        if len(r) < 3:
            continue
        t = np.diff(r, axis=0)
        norm = np.linalg.norm(t, axis=1, keepdims=True)
        ok = norm[:, 0] > 0
        t = t[ok] / norm[ok]
        n = len(t)
        for k in range(min(nlag, n)):
            acc[k] += np.einsum("ij,ij->", t[:n - k], t[k:])
            cnt[k] += n - k
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(cnt > 0, acc / np.maximum(cnt, 1), np.nan)


def curl_from_autocorrelation(c: np.ndarray, step: float) -> dict | None:
    """The helix whose tangents' autocorrelation is ``c`` (lags every ``step`` metres): ``{"arc_per_turn",
    "pitch_deg", "radius", "period", "c_min"}`` (metres), or None when ``c`` has no minimum followed by a
    maximum (no curl within the lags given)."""
    c = np.asarray(c, dtype=float)
    n = len(c)
    k_min = next((k for k in range(1, n - 1) if c[k] <= c[k - 1] and c[k] < c[k + 1]), None)
    if k_min is None:
        return None
    k_max = next((k for k in range(k_min + 1, n - 1) if c[k] >= c[k - 1] and c[k] > c[k + 1]), None)
    if k_max is None:
        return None

    def vertex(k: int) -> tuple[float, float]:
        """The parabola through c[k-1], c[k], c[k+1]: its vertex (lag in steps, value)."""
        a, b, d = c[k - 1], c[k], c[k + 1]
        den = a - 2 * b + d
        if den == 0:
            return float(k), float(b)
        x = 0.5 * (a - d) / den
        return k + x, b - 0.25 * (a - d) * x

    lag_max, _ = vertex(k_max)
    _, c_min = vertex(k_min)
    arc = lag_max * step
    cos_psi = float(np.sqrt(np.clip((1.0 + c_min) / 2.0, 0.0, 1.0)))
    sin_psi = float(np.sqrt(max(0.0, 1.0 - cos_psi**2)))
    return {
        "arc_per_turn": arc,
        "pitch_deg": float(np.degrees(np.arctan2(sin_psi, cos_psi))),
        "radius": arc * sin_psi / (2 * np.pi),
        "period": arc * cos_psi,
        "c_min": float(c_min),
    }


def curl_stats(path, step: float = 0.0005, max_lag: float = 0.12, max_strands: int = 500) -> dict:
    points, counts = read_hair(path)
    c = tangent_autocorrelation(points, counts, step, max_lag, max_strands)
    return {"file": str(path), "curl": curl_from_autocorrelation(c, step)}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("files", nargs="+", type=Path)
    p.add_argument("--strands", type=int, default=500, help="strands read per file, evenly spaced (500)")
    p.add_argument("--step-mm", type=float, default=0.5, help="resampling step along the arc (0.5 mm)")
    p.add_argument("--max-lag-mm", type=float, default=120.0, help="longest arc lag (120 mm)")
    p.add_argument("--json", action="store_true", help="print the figures as JSON")
    a = p.parse_args(argv)
    out = []
    for f in a.files:
        if not f.is_file():
            print(f"curl_stats: no such file: {f}", file=sys.stderr)
            return 2
        try:
            out.append(curl_stats(f, a.step_mm / 1000, a.max_lag_mm / 1000, a.strands))
        except (OSError, ValueError) as e:
            print(f"curl_stats: {f}: {e}", file=sys.stderr)
            return 2
    if a.json:
        print(json.dumps(out, indent=1))
    else:
        for r in out:
            c = r["curl"]
            if c is None:
                print(f"{r['file']}: no curl (the tangents' autocorrelation does not turn back within "
                      f"{a.max_lag_mm:g} mm)")
            else:
                print(f"{r['file']}: arc per turn {1000 * c['arc_per_turn']:.1f} mm, pitch angle "
                      f"{c['pitch_deg']:.1f} deg, radius {1000 * c['radius']:.1f} mm, period "
                      f"{1000 * c['period']:.1f} mm (autocorrelation minimum {c['c_min']:.2f})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
