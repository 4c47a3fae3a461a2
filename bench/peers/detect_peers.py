#!/usr/bin/env python3
"""Lamp detection peers: vgps (Rust) vs OpenCV on the same rendered night frames.

All figures come from one run on this machine:
  * frames: `cargo run --release --example render_frames -- DIR FRAMES` renders FRAMES
    Ladybug2-like rig frames (6 x 1024x768 8-bit PNGs each, street lamps + 6 clutter
    lights per image) into a temporary directory;
  * vgps: `cargo run --release --example detect_timing -- DIR REPEATS` (native loop,
    std::time::Instant): `vgps::imaging::decode_png` and `LampDetector::detect` (robust
    background/noise estimate, adaptive threshold, run-length 8-connected components,
    background-subtracted intensity-weighted centroids, area/elongation limits);
  * OpenCV (single thread, `cv2.setNumThreads(1)`): `cv2.imdecode(..., IMREAD_GRAYSCALE)`,
    then `cv2.threshold` (fixed threshold, the value vgps's adaptive rule gives on these
    frames) + `cv2.connectedComponentsWithStats(connectivity=8)`, whose centroids are
    *binary* (unweighted). This is less work than vgps does (no background estimate, no
    intensity weighting, no shape limits), so the ratio is conservative.

Times are per image: the best of REPEATS runs per image, median over the images.
Usage: python bench/peers/detect_peers.py [FRAMES] [REPEATS]  (from the repository root;
defaults 5 frames = 30 images, 7 repeats).
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
THRESHOLD = 14  # background 6 DN + max(6 x 1.48 DN noise, 6 DN), floored: vgps's rule here
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def cargo_example(name, *args):
    cmd = ["cargo", "run", "--quiet", "--release", "--example", name, "--", *map(str, args)]
    return subprocess.run(cmd, cwd=ROOT, check=True, capture_output=True, text=True).stdout


def parse(line):
    return {k: float(v) for k, v in (f.split("=") for f in line.split()[1:])}


def opencv_times(paths):
    cv2.setNumThreads(1)
    decode, detect, both, counts = [], [], [], []
    for path in paths:
        buf = np.fromfile(path, dtype=np.uint8)
        best_dec = best_det = best_both = float("inf")
        for _ in range(REPEATS):
            t0 = time.perf_counter()
            img = cv2.imdecode(buf, cv2.IMREAD_GRAYSCALE)
            t1 = time.perf_counter()
            _, binary = cv2.threshold(img, THRESHOLD, 255, cv2.THRESH_BINARY)
            n, _labels, stats, centroids = cv2.connectedComponentsWithStats(binary, connectivity=8)
            t2 = time.perf_counter()
            best_dec = min(best_dec, t1 - t0)
            best_det = min(best_det, t2 - t1)
            best_both = min(best_both, t2 - t0)
        counts.append(int(np.sum(stats[1:, cv2.CC_STAT_AREA] >= 2)))
        decode.append(best_dec * 1e3)
        detect.append(best_det * 1e3)
        both.append(best_both * 1e3)
    return {
        "decode_ms": float(np.median(decode)),
        "detect_ms": float(np.median(detect)),
        "decode_detect_ms": float(np.median(both)),
        "detections_per_image": float(np.mean(counts)),
    }


def main():
    subprocess.run(
        ["cargo", "build", "--quiet", "--release", "--example", "render_frames", "--example", "detect_timing"],
        cwd=ROOT,
        check=True,
    )
    with tempfile.TemporaryDirectory() as tmp:
        print(cargo_example("render_frames", tmp, FRAMES).strip())
        paths = sorted(os.path.join(tmp, f) for f in os.listdir(tmp) if f.endswith(".png"))
        sizes = [os.path.getsize(p) for p in paths]
        vgps = parse(cargo_example("detect_timing", tmp, REPEATS).strip())
        cv = opencv_times(paths)
    print(f"{len(paths)} images of 1024x768, mean PNG size {np.mean(sizes) / 1024:.0f} KiB; OpenCV {cv2.__version__}")
    print(f"{'per image (ms, median)':<26}{'vgps':>10}{'OpenCV':>10}{'OpenCV/vgps':>13}")
    for key, label in [
        ("detect_ms", "detect only"),
        ("decode_ms", "PNG decode"),
        ("decode_detect_ms", "decode + detect"),
    ]:
        print(f"{label:<26}{vgps[key]:>10.3f}{cv[key]:>10.3f}{cv[key] / vgps[key]:>12.1f}x")
    print(
        f"{'spots per image':<26}{vgps['detections_per_image']:>10.1f}{cv['detections_per_image']:>10.1f}"
        "   (OpenCV: components of >= 2 px)"
    )
    frame = 6 * vgps["decode_detect_ms"]
    print(f"vgps 6-image frame, decode + detect on one core: {frame:.1f} ms = {1e3 / frame:.0f} frames/s")


if __name__ == "__main__":
    main()
