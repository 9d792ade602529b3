#!/usr/bin/env python3
"""What holds the memory at a hairrecon run's peak: heaptrack's peak, grouped by the code that allocated it.

    python3 scripts/heap_peak.py -- hairrecon reconstruct CAPTURE --out OUT [options ...]
    python3 scripts/heap_peak.py --data heaptrack.hairrecon.zst      (an earlier recording)

Runs the command under ``heaptrack`` (Debian/Ubuntu: ``apt install heaptrack``), then prints the heap
memory that was live at the process's peak, grouped by the innermost three frames of the project's
own code that allocated it (the standard library's and rayon's frames are skipped), largest first.
A developer's tool: the figures are heap bytes, which the resident set exceeds by the binary, the
stacks and the allocator's slack.
"""

from __future__ import annotations

import argparse
import collections
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

# Frames that say nothing of who holds the memory.
SKIP = set(
    "alloc alloc_impl alloc_impl_runtime allocate allocate_in allocate_zeroed alloc_zeroed realloc finish_grow "
    "grow grow_impl grow_impl_runtime grow_amortized grow_one shrink shrink_to shrink_to_fit into_boxed_slice "
    "do_reserve_and_handle reserve reserve_for_push "
    "with_capacity with_capacity_in with_capacity_zeroed_in try_allocate_in from_elem extend_with resize "
    "push clone clone_from from_iter extend spec_extend extend_trusted extend_from_slice to_vec collect "
    "new_uninitialized fallible_with_capacity call_once call_mut map next execute run main_loop "
    "wait_until wait_until_cold wait_until_out_of_work".split()
)


def frames(stack: str):
    """(function, file) of each frame, outermost first."""
    out = []
    for f in stack.split(";"):
        m = re.match(r"(.*?) \(([^()]*)\)$", f)
        if m:
            out.append((m.group(1), m.group(2)))
    return out


def ours(fn: str, file: str) -> bool:
    return (
        file.endswith(".rs")
        and not fn.endswith("<>")
        and not fn.startswith("_R")
        and not fn.startswith("{closure")
        and fn not in SKIP
        and "rayon" not in fn
    )


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    cmd = argv[argv.index("--") + 1 :] if "--" in argv else []
    ap = argparse.ArgumentParser(prog="heap_peak.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, help="a heaptrack recording (.zst) to read instead of running")
    ap.add_argument("--top", type=int, default=20, help="how many groups to print")
    a = ap.parse_args(argv[: argv.index("--")] if "--" in argv else argv)
    if (a.data is None) == (not cmd):
        ap.error("give a command after -- (to record it), or --data (to read a recording)")
    for tool in ["heaptrack", "heaptrack_print"]:
        if shutil.which(tool) is None:
            print(f"heap_peak.py: {tool} is not installed (apt install heaptrack)", file=sys.stderr)
            return 2
    with tempfile.TemporaryDirectory() as tmp:
        data = a.data
        if data is None:
            base = Path(tmp) / "heap"
            rc = subprocess.call(["heaptrack", "-o", str(base), *cmd])
            if rc != 0:
                print(f"heap_peak.py: the command exited with {rc}", file=sys.stderr)
                return rc
            data = base.with_suffix(".zst")
        stacks = Path(tmp) / "peak.stacks"
        subprocess.run(
            ["heaptrack_print", "-f", str(data), "--print-peaks", "0", "--print-allocators", "0",
             "--print-temporary", "0", "--print-leaks", "0", "-F", str(stacks), "--flamegraph-cost-type", "peak"],
            check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        )
        groups: collections.Counter[str] = collections.Counter()
        for line in stacks.read_text().splitlines():
            stack, _, cost = line.rpartition(" ")
            own = [f"{fn} ({file})" for fn, file in frames(stack) if ours(fn, file)]
            groups[" < ".join(reversed(own[-3:])) if own else "(elsewhere)"] += int(cost)
    total = sum(groups.values())
    print(f"heap at the peak: {total / 2**20:.0f} MiB")
    for key, cost in groups.most_common(a.top):
        print(f"{cost / 2**20:9.1f} MiB  {key}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
