"""The refactor into stages behind a runner kept the reconstruction's bytes.

``hairrecon reconstruct`` on the session's rendered test-preset capture (``test_capture``: straight,
2,000 strands, seed 0, 16 views of 256 px) must write the same ``strands.hair`` and ``guides.hair`` as
the code before the refactor (commit 5573f38, whose binary wrote the SHA-256 digests below on this
capture). Two runs: the initial strands with the default options, and a small whole run with DR.
Cycles renders this capture bit for bit the same on every run (checked with ``cmp`` on two renders).
A change that moves any stage by one float changes these digests: then a new digest is recorded only
when the change in the strands is meant, and the commit message says so.
"""

from __future__ import annotations

import hashlib
import subprocess

import pytest

from conftest import hairrecon_bin

RUNS = {
    "init": (["--stop-after", "init"], {
        "strands.hair": "157a4ddb30303409b0fb4dd6da80e84c300120fd24735099f17e872b472c8be1",
        "guides.hair": "853686bae74e77df9129902705e124c8a8ce47dd2bd8b9420436051256e6dbb6",
    }),
    "dr": (["--guides", "300", "--children", "3000", "--dr-iters-guides", "8", "--dr-iters-children", "4"], {
        "strands.hair": "f56c55b32b3d0a19660e6d5c963b7b094458661a96e1e238b428f19127ff7a35",
        "guides.hair": "3e48d4cd0a82473104ac84f77b319c8f7cbc1bcc67171731af0a5faa4aacc043",
    }),
}


@pytest.mark.parametrize("name", sorted(RUNS))
def test_reconstruct_writes_the_bytes_of_the_code_before_the_refactor(name, test_capture, tmp_path):
    args, digests = RUNS[name]
    out = tmp_path / name
    cmd = [str(hairrecon_bin()), "reconstruct", str(test_capture), "--out", str(out), *args]
    r = subprocess.run(cmd, capture_output=True, text=True)
    assert r.returncode == 0, f"{' '.join(cmd)} failed:\n{r.stderr[-3000:]}"
    got = {f: hashlib.sha256((out / f).read_bytes()).hexdigest() for f in digests}
    assert got == digests
