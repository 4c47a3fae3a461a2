#!/usr/bin/env bash
# Builds and runs the vgps fuzz targets one at a time (one libFuzzer process each, no
# -jobs/-workers: the machine is shared).
#
#   fuzz/run.sh [SECONDS] [TARGET…]
#
# SECONDS (default 600): the time limit per target; a target also stops after RUNS
# executions (environment, default 1000000). With no TARGET, every target of
# fuzz_targets/ is run. Seeds are read from corpus/<target>/ (committed, never written);
# the grown corpus goes to work/<target>/ and crashes to artifacts/<target>/ (both ignored
# by git). Prints one line per target: executions, seconds, crashes. Needs nightly and
# cargo-fuzz (`cargo install cargo-fuzz`).
set -euo pipefail
cd "$(dirname "$0")"
seconds="${1:-600}"
shift || true
runs="${RUNS:-1000000}"
if [ "$#" -gt 0 ]; then
  targets=("$@")
else
  mapfile -t targets < <(ls fuzz_targets | sed 's/\.rs$//' | sort)
fi
cargo +nightly fuzz build -O
mkdir -p logs
printf '%-18s %12s %8s %8s\n' target executions seconds crashes
for t in "${targets[@]}"; do
  mkdir -p "work/$t" "artifacts/$t"
  start=$(date +%s)
  set +e
  cargo +nightly fuzz run -O "$t" "work/$t" "corpus/$t" -- \
    -runs="$runs" -max_total_time="$seconds" -timeout=10 \
    -rss_limit_mb=2048 -max_len=65536 -print_final_stats=1 \
    -artifact_prefix="artifacts/$t/" >"logs/$t.log" 2>&1
  status=$?
  set -e
  elapsed=$(( $(date +%s) - start ))
  execs=$(grep -E '^stat::number_of_executed_units' "logs/$t.log" | tail -1 | awk '{print $2}')
  crashes=$(find "artifacts/$t" -type f | wc -l)
  printf '%-18s %12s %8s %8s%s\n' "$t" "${execs:-?}" "$elapsed" "$crashes" \
    "$([ "$status" -ne 0 ] && echo "  (exit $status, see fuzz/logs/$t.log)")"
done
