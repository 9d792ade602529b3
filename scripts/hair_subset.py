"""Writes every n-th strand of a .hair file, from a given first one, to a new .hair file.

    .venv/bin/python scripts/hair_subset.py IN.hair OUT.hair --every 5 [--first 1]

Used for the ceiling of the init proxy (README, "where curly loses, by oracle points"): 10,000 other
ground-truth strands scored like a reconstruction against the proxy's every-5th ground truth:
``hair_subset.py gt/strands.hair a.hair --every 5``, ``... b.hair --every 5 --first 1``, then
``hairrecon eval --pred b.hair --gt a.hair``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _hairio import read_hair, strand_offsets, write_hair  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("input", type=Path)
    ap.add_argument("output", type=Path)
    ap.add_argument("--every", type=int, default=5, help="keep every n-th strand (default 5)")
    ap.add_argument("--first", type=int, default=0, help="index of the first strand kept (default 0)")
    a = ap.parse_args()
    if a.every < 1 or a.first < 0:
        ap.error("--every must be at least 1 and --first at least 0")
    try:
        points, counts = read_hair(a.input)
    except (OSError, ValueError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    offsets = strand_offsets(counts)
    keep = np.arange(a.first, len(counts), a.every)
    if len(keep) == 0:
        print(f"error: {a.input} has {len(counts)} strands; --first {a.first} keeps none", file=sys.stderr)
        return 1
    parts = [points[offsets[i] : offsets[i + 1]] for i in keep]
    write_hair(a.output, np.concatenate(parts), counts[keep], info="hairrecon subset")
    print(f"{len(keep)} of {len(counts)} strands written to {a.output}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
