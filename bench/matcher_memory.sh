#!/usr/bin/env bash
# Peak memory of the matcher's cold starts (issue #25): simulates a short drive and replays
# it without the GNSS prior, so that most frames are cold starts over the whole map, at the
# default visibility range (80 m) and at 150 m, and prints each replay's peak resident set
# size and wall time (GNU time). Before the cells' cache budget the 150 m replay of this
# drive peaked at 3.9 GB; see docs/matcher.md, "Memory".
#
# usage: bench/matcher_memory.sh [VGPS_BINARY] [WORK_DIR]
#   VGPS_BINARY  default: target/release/vgps (built with `cargo build --release --bin vgps`)
#   WORK_DIR     default: a new temporary directory (removed at the end)
#   LENGTH_M     route length in metres (default 150)
set -euo pipefail
cd "$(dirname "$0")/.."
vgps=${1:-target/release/vgps}
length=${LENGTH_M:-150}
if [ ! -x "$vgps" ]; then
  echo "no vgps binary at $vgps: cargo build --release --bin vgps" >&2
  exit 1
fi
if [ ! -x /usr/bin/time ]; then
  echo "GNU time (/usr/bin/time) is needed: apt-get install time" >&2
  exit 1
fi
if [ -n "${2:-}" ]; then
  work=$2
  mkdir -p "$work"
else
  work=$(mktemp -d)
  trap 'rm -rf "$work"' EXIT
fi
"$vgps" simulate --preset short --length-m "$length" --quiet --out "$work/drive" >/dev/null
for range in 80 150; do
  /usr/bin/time -f "%e %M" -o "$work/time_$range" \
    "$vgps" replay "$work/drive" --no-gnss-prior --visibility-range-m "$range" --quiet \
    --out "$work/replay_$range" >/dev/null 2>"$work/replay_$range.log"
  read -r seconds kb <"$work/time_$range"
  fixes=$(grep -m1 "visual fixes" "$work/replay_$range/summary.txt" || true)
  awk -v r="$range" -v kb="$kb" -v s="$seconds" -v f="$fixes" \
    'BEGIN { printf "visibility %3s m: peak RSS %7.1f MB, %6.1f s wall; %s\n", r, kb / 1024, s, f }'
done
