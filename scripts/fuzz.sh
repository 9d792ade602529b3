#!/usr/bin/env bash
# Coverage-guided fuzzing of every reader of hairrecon with libFuzzer, on the stable toolchain: the
# fuzz crate's targets (fuzz/, feature `libfuzzer`) are built with LLVM's SanitizerCoverage passes
# (stable -C flags; no sanitizer) and each target runs from its seeds (fuzz/seeds, the project's own
# writers' files) and its committed corpus (fuzz/corpus). A crash, a panic, a hang over 10 s or memory
# over 1 GB is a failure.
#
#   bash scripts/fuzz.sh                       # every target for 10 s each, one per core at a time
#                                              # (`cargo test` replays the seeds and corpus alone)
#   bash scripts/fuzz.sh --seconds 60 ply obj  # these targets, one minute each
#   bash scripts/fuzz.sh --runs 1000000 --keep # the long run: a million executions per target, new
#                                              # inputs merged into fuzz/corpus (commit them)
#   bash scripts/fuzz.sh --seeds               # rewrite fuzz/seeds with the current writers
set -euo pipefail
cd "$(dirname "$0")/.."
limit=(-max_total_time=10)
keep=0
seeds=0
targets=()
while [ $# -gt 0 ]; do
  case "$1" in
    --seconds) limit=(-max_total_time="$2"); shift 2 ;;
    --runs) limit=(-runs="$2"); shift 2 ;;
    --keep) keep=1; shift ;;
    --seeds) seeds=1; shift ;;
    -h|--help) sed -n '2,12p' "$0"; exit 0 ;;
    -*) echo "fuzz.sh: unknown option $1 (see --help)" >&2; exit 2 ;;
    *) targets+=("$1"); shift ;;
  esac
done
[ ${#targets[@]} -gt 0 ] || targets=(hair data ply obj image capture_json colmap_text colmap_binary metashape nerf photo)

host=$(rustc -vV | sed -n 's/^host: //p')
export CARGO_TARGET_DIR="${HAIRRECON_FUZZ_TARGET_DIR:-$(pwd)/fuzz/target}"
# The flags cargo-fuzz passes, minus the sanitizer (which needs nightly); the explicit --target keeps
# them off build scripts and proc macros.
export RUSTFLAGS="-Cpasses=sancov-module -Cllvm-args=-sanitizer-coverage-level=4 \
-Cllvm-args=-sanitizer-coverage-inline-8bit-counters -Cllvm-args=-sanitizer-coverage-pc-table \
-Cllvm-args=-sanitizer-coverage-trace-compares --cfg fuzzing -Cdebug-assertions -Coverflow-checks"
if [ $seeds = 1 ]; then
  env -u RUSTFLAGS -u CARGO_TARGET_DIR cargo run --quiet --release -p hairrecon-fuzz --example seeds
  exit 0
fi
echo "== building the fuzz targets ($host, coverage-instrumented)"
cargo build --quiet --release -p hairrecon-fuzz --features libfuzzer --target "$host" --bins
bin="$CARGO_TARGET_DIR/$host/release"

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
# One target per core at a time (libFuzzer's run is one thread); the table in the targets' order.
run_one() {
  local t=$1 start rc
  mkdir -p "fuzz/corpus/$t" "$work/$t" "$work/artifacts-$t"
  start=$(date +%s%N)
  set +e
  "$bin/$t" "$work/$t" "fuzz/seeds/$t" "fuzz/corpus/$t" "${limit[@]}" -rss_limit_mb=1024 -malloc_limit_mb=1024 \
    -timeout=10 -print_final_stats=1 -artifact_prefix="$work/artifacts-$t/" >"$work/$t.log" 2>&1
  rc=$?
  set -e
  echo "$rc" >"$work/$t.rc"
  awk -v a="$start" -v b="$(date +%s%N)" 'BEGIN { printf "%.1f", (b - a) / 1e9 }' >"$work/$t.secs"
}
jobs_max=$(nproc 2>/dev/null || echo 1)
for t in "${targets[@]}"; do
  while [ "$(jobs -rp | wc -l)" -ge "$jobs_max" ]; do wait -n || true; done
  run_one "$t" &
done
wait
failed=0
printf '%-14s %12s %9s %10s  %s\n' target executions seconds "exec/s" result
for t in "${targets[@]}"; do
  rc=$(cat "$work/$t.rc")
  secs=$(cat "$work/$t.secs")
  runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$work/$t.log" | tail -n 1)
  runs=${runs:-0}
  if [ "$rc" = 0 ]; then result=ok; else result="FAILED (exit $rc)"; failed=1; fi
  printf '%-14s %12s %9.0f %10.0f  %s\n' "$t" "$runs" "$secs" "$(awk -v r="$runs" -v s="$secs" 'BEGIN { print r / s }')" "$result"
  if [ "$rc" != 0 ]; then
    mkdir -p fuzz/artifacts
    cp "$work/artifacts-$t"/* fuzz/artifacts/ 2>/dev/null || true
    grep -v '^#\|^INFO\|^\s*$' "$work/$t.log" | tail -n 40 >&2
    echo "fuzz.sh: $t failed; the input that did it is in fuzz/artifacts/ (replay: $bin/$t FILE)" >&2
  elif [ $keep = 1 ]; then
    "$bin/$t" -merge=1 "fuzz/corpus/$t" "$work/$t" >/dev/null 2>&1
  fi
done
exit $failed
