"""Two child populations in one strand set, for the curly study (docs/curly-study.md, session 18).

Strand i of OUT is strand i of B with probability SHARE and strand i of A otherwise (a seeded draw,
so the same inputs give the same bytes); A and B are two `init_stage` outputs made from the same
child roots, so that every root keeps one strand. Score OUT with `hairrecon eval`.

    .venv/bin/python scripts/mix_strands.py A.hair B.hair OUT.hair SHARE [seed=0]
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _hairio  # noqa: E402


def main(argv):
    if len(argv) not in (4, 5):
        raise SystemExit(__doc__)
    a_path, b_path, out, share = argv[0], argv[1], argv[2], float(argv[3])
    seed = int(argv[4].partition("=")[2]) if len(argv) == 5 else 0
    if not 0.0 <= share <= 1.0:
        raise SystemExit(f"SHARE must lie in [0, 1], got {share}")
    a, ac = _hairio.read_hair(a_path)
    b, bc = _hairio.read_hair(b_path)
    if len(ac) != len(bc):
        raise SystemExit(f"{a_path} has {len(ac)} strands and {b_path} {len(bc)}: they must come from the same roots")
    ao = _hairio.strand_offsets(ac)
    bo = _hairio.strand_offsets(bc)
    pick = np.random.default_rng(seed).random(len(ac)) < share
    parts = [b[bo[i] : bo[i + 1]] if pick[i] else a[ao[i] : ao[i + 1]] for i in range(len(ac))]
    counts = np.where(pick, bc, ac)
    _hairio.write_hair(out, np.concatenate(parts), counts)
    print(f"{int(pick.sum())} of {len(ac)} strands from {b_path} -> {out}")


if __name__ == "__main__":
    main(sys.argv[1:])
