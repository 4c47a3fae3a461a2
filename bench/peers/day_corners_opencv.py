#!/usr/bin/env python3
"""Building corners by day: vgps's vertex detector vs OpenCV, in one run, on the same images.

Usage (from the repository root, after `cargo build --release`):
    vgps simulate --preset short --length-m 150 --images --time-of-day day --out D
    python3 bench/peers/day_corners_opencv.py D [FRAMES]

On the first FRAMES frames (default 10) of the day drive D:
  * vgps: `target/release/vgps detect` with `--detector vertex --threads 1` on a copy of
    the drive holding those frames (wall time of the process: PNG decoding + detection +
    writing the CSV);
  * OpenCV (`cv2.setNumThreads(1)`): `cv2.imread(..., IMREAD_GRAYSCALE)`, then
    `cv2.goodFeaturesToTrack` (Shi-Tomasi, at most 200 corners, quality 0.01, 3 px apart,
    5 x 5 block) and `cv2.cornerSubPix` (5 x 5 window, 40 iterations or 0.001 px).
Both are scored against `images_truth.csv` (visible corner landmarks at least 10 px from
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


def score(name, detections, truth, seconds, frames):
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
        f"{total / max(len(detections), 1):6.1f} per image  {1e3 * seconds / frames:7.1f} ms/frame"
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

    with tempfile.TemporaryDirectory() as tmp:
        for name in ["calibration.json", "landmarks.csv", "images"]:
            os.symlink(os.path.abspath(os.path.join(drive, name)), os.path.join(tmp, name))
        with open(os.path.join(drive, "frames.csv")) as f:
            lines = f.read().splitlines()[: frames + 1]
        with open(os.path.join(tmp, "frames.csv"), "w") as f:
            f.write("\n".join(lines) + "\n")
        with open(os.path.join(tmp, "drive.json"), "w") as f:
            f.write('{"version": 1, "calibration": "calibration.json", '
                    '"landmarks": "landmarks.csv", "frames": "frames.csv"}')
        out = os.path.join(tmp, "corners.csv")
        vgps = os.path.join(ROOT, "target", "release", "vgps")
        t = time.perf_counter()
        subprocess.run([vgps, "detect", tmp, "--detector", "vertex", "--threads", "1",
                        "--quiet", "--out", out], check=True)
        vgps_s = time.perf_counter() - t
        found = collections.defaultdict(list)
        with open(out) as f:
            for r in csv.DictReader(f):
                found[(r["frame"], r["camera"])].append((float(r["u"]), float(r["v"])))
        for key, _ in images:
            found.setdefault(key, [])
    score("vgps detect --detector vertex (1 thread)", found, truth, vgps_s, len(rows))

    cv2.setNumThreads(1)
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 40, 0.001)
    found = {}
    t = time.perf_counter()
    for key, path in images:
        gray = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
        pts = cv2.goodFeaturesToTrack(gray, 200, 0.01, 3, blockSize=5)
        if pts is None:
            found[key] = []
            continue
        pts = cv2.cornerSubPix(gray, pts.astype(np.float32), (5, 5), (-1, -1), criteria)
        found[key] = [(float(p[0][0]), float(p[0][1])) for p in pts]
    cv_s = time.perf_counter() - t
    score("OpenCV goodFeaturesToTrack + cornerSubPix", found, truth, cv_s, len(rows))


if __name__ == "__main__":
    main()
