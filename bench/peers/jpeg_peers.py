#!/usr/bin/env python3
"""JPEG night frames, decode + detect: vgps (Rust) vs OpenCV, in one run on the same files.

  * frames: `cargo run --release --example jpeg_timing -- DIR FRAMES REPEATS` renders FRAMES
    Ladybug2-rig night frames (6 x 1024x768 colour JPEGs, quality 90, 4:2:0) into DIR and
    times vgps on them, single-threaded: `vgps::imaging::decode_image` (zune-jpeg, luma
    output) + `StreetLampDetector::detect` (core level from the white level, run-length
    8-connected components, halo merging with bridge tests, local-background annulus per
    core, classes);
  * OpenCV (`cv2.setNumThreads(1)`): `cv2.imdecode(..., IMREAD_GRAYSCALE)` (libjpeg-turbo;
    like vgps it decodes the Y plane only), `cv2.threshold` at the same core-level rule
    (0.92 x the image's maximum, computed with `img.max()`, included in the time) and
    `cv2.connectedComponentsWithStats(connectivity=8)`: less work than vgps (no merging,
    no local background, no classes), so the ratio is conservative.
  * with ../shared/realdata/night present, the same two pipelines on the real photos too.

Times are per image: the best of REPEATS runs per image, median over the images.
Usage: python3 bench/peers/jpeg_peers.py [FRAMES] [REPEATS]  (from anywhere; defaults 5, 7).
Needs `pip install opencv-python-headless numpy`.
"""

import os
import subprocess
import sys
import tempfile
import time

import cv2
import numpy as np

FRAMES = int(sys.argv[1]) if len(sys.argv) > 1 else 5
REPEATS = int(sys.argv[2]) if len(sys.argv) > 2 else 7
CORE_FRACTION = 0.92  # vgps::imaging::street::CORE_FRACTION
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def opencv_times(paths):
    cv2.setNumThreads(1)
    decode, both = [], []
    for path in paths:
        buf = np.fromfile(path, dtype=np.uint8)
        best_dec = best_both = float("inf")
        for _ in range(REPEATS):
            t0 = time.perf_counter()
            img = cv2.imdecode(buf, cv2.IMREAD_GRAYSCALE)
            t1 = time.perf_counter()
            level = CORE_FRACTION * float(img.max())
            _, binary = cv2.threshold(img, level, 255, cv2.THRESH_BINARY)
            cv2.connectedComponentsWithStats(binary, connectivity=8)
            t2 = time.perf_counter()
            best_dec = min(best_dec, t1 - t0)
            best_both = min(best_both, t2 - t0)
        decode.append(best_dec * 1e3)
        both.append(best_both * 1e3)
    return float(np.median(decode)), float(np.median(both))


def main():
    subprocess.run(
        ["cargo", "build", "--quiet", "--release", "--example", "jpeg_timing"], cwd=ROOT, check=True
    )
    with tempfile.TemporaryDirectory() as tmp:
        out = subprocess.run(
            [os.path.join(ROOT, "target/release/examples/jpeg_timing"), tmp, str(FRAMES), str(REPEATS)],
            check=True,
            capture_output=True,
            text=True,
        ).stdout.strip()
        print(out)
        vgps = {k: float(v) for k, v in (f.split("=") for f in out.split()[1:])}
        paths = sorted(os.path.join(tmp, f) for f in os.listdir(tmp) if f.endswith(".jpg"))
        cv_dec, cv_both = opencv_times(paths)
    print(f"{len(paths)} JPEG images of 1024x768; OpenCV {cv2.__version__}")
    print(f"{'per image (ms, median)':<26}{'vgps':>10}{'OpenCV':>10}{'OpenCV/vgps':>13}")
    print(f"{'JPEG decode':<26}{vgps['zune_luma_ms']:>10.3f}{cv_dec:>10.3f}{cv_dec / vgps['zune_luma_ms']:>12.2f}x")
    print(f"{'decode + detect':<26}{vgps['decode_detect_ms']:>10.3f}{cv_both:>10.3f}{cv_both / vgps['decode_detect_ms']:>12.2f}x")
    for name, ms in [("vgps", vgps["decode_detect_ms"]), ("OpenCV", cv_both)]:
        print(f"{name} 6-image frame, decode + detect on one core: {6 * ms:.1f} ms = {1e3 / (6 * ms):.0f} frames/s")


if __name__ == "__main__":
    main()
