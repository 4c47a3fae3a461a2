#!/usr/bin/env bash
# The vertex (building-corner) detector on the real daytime photos of the shared real-data
# folder beside the repository (../shared/realdata/day/: OpenSfM's Berlin and Lund photos,
# BSD-2; two Boreas frames, CC BY 4.0; issue #26 part 5). Prints per image the corners
# found and the detection time, then what became of all candidates; writes the photos with
# the corners drawn to OUT (default /tmp/vgps_day_real).
#
#   bench/day_real.sh [OUT]          (from the repository root)
#   VERTEX_MIN_OPEN_SIDE_DN=90 VERTEX_MAX_CANDIDATES=100000 bench/day_real.sh
set -euo pipefail
cd "$(dirname "$0")/.."
shared=../shared/realdata/day
out="${1:-/tmp/vgps_day_real}"
if [ ! -d "$shared" ]; then
  echo "error: $shared not found (the photos are not part of the repository)" >&2
  exit 2
fi
cargo run --release --quiet -p vgps-camera --example day_real -- "$out" \
  "$shared"/opensfm_berlin/*.jpg "$shared"/opensfm_lund/*.jpg "$shared"/boreas/*.png
