#!/usr/bin/env python3
"""Building corners by day: vgps's vertex detector vs OpenCV, in one run, on the same images.

Usage (from the repository root, after
`cargo build --release --bin vgps --example vertex_timing`):
    vgps simulate --preset short --length-m 150 --images --time-of-day day \
        --jpeg-quality 90 --out D
    python3 bench/peers/day_corners_opencv.py D [FRAMES] [REPEATS]

On the first FRAMES frames (default 10) of the day drive D, each 6-camera frame decoded and
detected REPEATS times (default 3) on one thread, the best of the repeats per frame (the
least disturbed by other processes), the median over frames reported:
  * vgps: `target/release/examples/vertex_timing` (the images read into memory first, then
    decode + `--detector vertex` detection with the camera models and masks, timed inside
    the process: no start-up in the figure); its detections are scored below;
  * OpenCV (`cv2.setNumThreads(1)`): `cv2.imread(..., IMREAD_GRAYSCALE)`, then
    `cv2.goodFeaturesToTrack` (Shi-Tomasi, at most 200 corners, quality 0.01, 3 px apart,
    5 x 5 block) and `cv2.cornerSubPix` (5 x 5 window, 40 iterations or 0.001 px).
The last line is the ratio of the medians of decode + detection per frame (OpenCV / vgps)
and vgps's frames per second on one core. Both are scored against `images_truth.csv` (visible corner landmarks at least 10 px from
the border): a truth corner is found when a detection lies within 3 px; the error is that
distance. Precision is the share of detections within 3 px of a truth corner.
"""

import collections
import csv
import math
import os
import subprocess
import sys
import tempfile
import time

import cv2
import numpy as np

MATCH_PX = 3.0
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def score(name, detections, truth, ms_per_frame):
    errors, hits, total = [], 0, 0
    for key, corners in truth.items():
        found = detections.get(key, [])
        for u, v in corners:
            best = min((math.hypot(u - a, v - b) for a, b in found), default=math.inf)
            if best <= MATCH_PX:
                errors.append(best)
    for key, found in detections.items():
        for a, b in found:
            total += 1
            hits += any(math.hypot(u - a, v - b) <= MATCH_PX for u, v in truth.get(key, []))
    n = sum(len(c) for c in truth.values())
    errors.sort()
    q = lambda p: errors[round((len(errors) - 1) * p)] if errors else float("nan")
    print(
        f"{name:<44} found {len(errors):>4}/{n:<4} ({100 * len(errors) / max(n, 1):5.1f} %)  "
        f"median {q(0.5):.3f} px  p95 {q(0.95):.3f} px  precision {100 * hits / max(total, 1):5.1f} %  "
        f"{total / max(len(detections), 1):6.1f} per image  {ms_per_frame:7.2f} ms/frame (median)"
    )


def main():
    drive = sys.argv[1]
    frames = int(sys.argv[2]) if len(sys.argv) > 2 else 10
    with open(os.path.join(drive, "frames.csv")) as f:
        rows = list(csv.DictReader(f))[:frames]
    keep = {r["frame"] for r in rows}
    truth = collections.defaultdict(list)
    with open(os.path.join(drive, "images_truth.csv")) as f:
        for r in csv.DictReader(f):
            if r["frame"] in keep and r["kind"] == "corner" and r["clipped"] == "false":
                truth[(r["frame"], r["camera"])].append((float(r["u"]), float(r["v"])))
    images = [
        ((r["frame"], k[len("image_"):]), os.path.join(drive, r[k]))
        for r in rows
        for k in r
        if k.startswith("image_") and r[k]
    ]

    repeats = int(sys.argv[3]) if len(sys.argv) > 3 else 3
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "corners.csv")
        timing = os.path.join(ROOT, "target", "release", "examples", "vertex_timing")
        run = subprocess.run([timing, drive, str(frames), str(repeats), out], check=True,
                             capture_output=True, text=True)
        summary = run.stdout.strip().splitlines()[-1]
        vgps_ms = float(summary.split("decode_detect_ms=")[1].split()[0])
        found = collections.defaultdict(list)
        with open(out) as f:
            for r in csv.DictReader(f):
                found[(r["frame"], r["camera"])].append((float(r["u"]), float(r["v"])))
        for key, _ in images:
            found.setdefault(key, [])
    print(f"vgps timing: {summary}")
    score("vgps vertex_timing (decode + vertex, 1 thread)", found, truth, vgps_ms)

    cv2.setNumThreads(1)
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 40, 0.001)
    files = {key: open(path, "rb").read() for key, path in images}
    by_frame = collections.defaultdict(list)
    for key, _ in images:
        by_frame[key[0]].append(key)
    found, per_frame = {}, []
    for frame, keys in by_frame.items():
        best = math.inf
        for _ in range(max(repeats, 1)):
            t = time.perf_counter()
            for key in keys:
                buf = np.frombuffer(files[key], dtype=np.uint8)
                gray = cv2.imdecode(buf, cv2.IMREAD_GRAYSCALE)
                pts = cv2.goodFeaturesToTrack(gray, 200, 0.01, 3, blockSize=5)
                if pts is None:
                    found[key] = []
                    continue
                pts = cv2.cornerSubPix(gray, pts.astype(np.float32), (5, 5), (-1, -1), criteria)
                found[key] = [(float(p[0][0]), float(p[0][1])) for p in pts]
            best = min(best, time.perf_counter() - t)
        per_frame.append(1e3 * best)
    per_frame.sort()
    cv_ms = per_frame[len(per_frame) // 2] if per_frame else float("nan")
    score("OpenCV goodFeaturesToTrack + cornerSubPix", found, truth, cv_ms)
    print(f"ratio OpenCV / vgps (decode + detection per frame, medians): {cv_ms / vgps_ms:.2f}; "
          f"vgps {1e3 / vgps_ms:.1f} frames/s, OpenCV {1e3 / cv_ms:.1f} frames/s on one core")


if __name__ == "__main__":
    main()
