#!/usr/bin/env bash
# How `vgps replay --from-images` scales from 1 to 2 threads (issue #24): the replay of a
# drive's images run alternately with `--threads 1` and `--threads 2`, ROUNDS times each;
# prints each run's wall time and the replay's own line of time per stage (images' thread
# time, the localizer's serial time), then the median wall times and their ratio. The fixes
# of every run are compared: they must be the same whatever the thread count.
#
#   bench/replay_threads.sh DRIVE [ROUNDS] [extra replay flags, e.g. --detector street]
#
# A drive to measure: `vgps simulate --preset short --length-m 150 --images --out D` (the
# README's example) or the `short` preset rendered with `--night-scene realistic
# --jpeg-quality 90`.
set -euo pipefail
cd "$(dirname "$0")/.."
drive=${1:?usage: bench/replay_threads.sh DRIVE [ROUNDS] [replay flags]}
rounds=${2:-3}
shift $(( $# >= 2 ? 2 : 1 ))
cargo build --release --quiet --bin vgps
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
declare -A walls
for round in $(seq 1 "$rounds"); do
  for threads in 1 2; do
    dir="$out/r${round}_t${threads}"
    start=$(date +%s.%N)
    target/release/vgps replay "$drive" --from-images --threads "$threads" --out "$dir" "$@" \
      > /dev/null 2> "$dir.err"
    end=$(date +%s.%N)
    wall=$(echo "$end - $start" | bc -l)
    walls[$threads]="${walls[$threads]:-} $wall"
    printf 'round %s, %s thread(s): %.2f s; %s\n' "$round" "$threads" "$wall" \
      "$(grep -o 'time: .*' "$dir.err" || echo 'no timing line')"
    if ! cmp -s "$dir/fixes.csv" "$out/r1_t1/fixes.csv"; then
      echo "fixes differ from round 1 with 1 thread: $dir/fixes.csv" >&2
      exit 1
    fi
  done
done
median() { tr ' ' '\n' | grep -v '^$' | sort -g | awk '{a[NR]=$1} END {print (NR % 2) ? a[(NR+1)/2] : (a[NR/2] + a[NR/2+1]) / 2}'; }
m1=$(echo "${walls[1]}" | median)
m2=$(echo "${walls[2]}" | median)
printf 'median wall: 1 thread %.2f s, 2 threads %.2f s, speed-up %.2f×\n' "$m1" "$m2" \
  "$(echo "$m1 / $m2" | bc -l)"
