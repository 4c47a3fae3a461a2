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
# by git). Prints one line per target: executions, seconds, executions per second,
# libFuzzer's final coverage (cov, ft), the grown corpus (inputs/size) and crashes.
# Needs nightly and cargo-fuzz (`cargo install cargo-fuzz`).
#
# Environment: RUNS (1000000), SANITIZER (address; `none` builds and runs faster: vgps has
# no unsafe code, and panics, timeouts and the RSS limit are caught without it), RSS_MB
# (2048), MAX_LEN (the largest input; default per target, see max_len below).
set -euo pipefail
cd "$(dirname "$0")"
seconds="${1:-600}"
shift || true
runs="${RUNS:-1000000}"
san="${SANITIZER:-address}"
rss="${RSS_MB:-2048}"
if [ "$#" -gt 0 ]; then
  targets=("$@")
else
  mapfile -t targets < <(ls fuzz_targets | sed 's/\.rs$//' | sort)
fi

# The largest input per target: a few kB for text, more for binary logs, images and
# MCAP (each larger than the biggest committed seed of its target, which would otherwise
# be cut to this length).
max_len() {
  case "$1" in
    ladybug_conf | mcap_read) echo 65536 ;;
    camera_mask | ros_cdr | raw_image) echo 32768 ;;
    nmea | ubx | sirf | png_decode | jpeg_decode | tiff_decode | bmp_decode | lut | nclt_table) echo 16384 ;;
    native_json | nclt_gps | ladybug_ini | drive_tables | landmarks_csv | observations_csv | gpx | truth_formats | gis_landmarks | building_footprints | imu_csv | drive_json | rays_csv | nclt_calibration | import_tables) echo 8192 ;;
    *) echo 4096 ;;
  esac
}

cargo +nightly fuzz build -O -s "$san"
mkdir -p logs
printf '%-18s %10s %7s %8s %7s %8s %14s %7s\n' target executions seconds exec/s cov ft corpus crashes
for t in "${targets[@]}"; do
  mkdir -p "work/$t" "artifacts/$t"
  len="${MAX_LEN:-$(max_len "$t")}"
  start=$(date +%s)
  set +e
  cargo +nightly fuzz run -O -s "$san" "$t" "work/$t" "corpus/$t" -- \
    -runs="$runs" -max_total_time="$seconds" -timeout=10 \
    -rss_limit_mb="$rss" -max_len="$len" -print_final_stats=1 \
    -artifact_prefix="artifacts/$t/" >"logs/$t.log" 2>&1
  status=$?
  set -e
  elapsed=$(( $(date +%s) - start ))
  execs=$(grep -E '^stat::number_of_executed_units' "logs/$t.log" | tail -1 | awk '{print $2}')
  rate=$(grep -E '^stat::average_exec_per_sec' "logs/$t.log" | tail -1 | awk '{print $2}')
  last=$(grep -aE '^#[0-9]+' "logs/$t.log" | tail -1)
  cov=$(sed -nE 's/.* cov: ([0-9]+).*/\1/p' <<<"$last")
  ft=$(sed -nE 's/.* ft: ([0-9]+).*/\1/p' <<<"$last")
  corp=$(sed -nE 's/.* corp: ([^ ]+).*/\1/p' <<<"$last")
  crashes=$(find "artifacts/$t" -type f | wc -l)
  printf '%-18s %10s %7s %8s %7s %8s %14s %7s%s\n' "$t" "${execs:-?}" "$elapsed" "${rate:-?}" \
    "${cov:-?}" "${ft:-?}" "${corp:-?}" "$crashes" \
    "$([ "$status" -ne 0 ] && echo "  (exit $status, see fuzz/logs/$t.log)")"
done
