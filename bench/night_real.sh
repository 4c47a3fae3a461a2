#!/usr/bin/env bash
# Lamp-head recall and precision of the night-street detector on the hand-labelled real
# night photos (issue #24): per image and in total. The photos live in the shared real-data
# folder beside the repository (../shared/realdata/night/, two of them GPL-2.0 and never
# committed); without it, the committed Unsplash photo alone is measured.
#
#   bench/night_real.sh            (from the repository root)
#   VGPS_DUMP=/tmp/marks bench/night_real.sh   (also writes marked PNGs)
set -euo pipefail
cd "$(dirname "$0")/.."
shared=../shared/realdata/night
if [ -f "$shared/labels.csv" ]; then
  dir="$shared"
else
  echo "note: $shared not found; measuring tests/data/night (Unsplash photo only)" >&2
  dir=$(mktemp -d)
  trap 'rm -rf "$dir"' EXIT
  cp tests/data/night/unsplash_street_lamps.jpg "$dir/"
  cp tests/data/night/unsplash_labels.csv "$dir/labels.csv"
fi
cargo run --release --quiet --example night_real -- "$dir"
