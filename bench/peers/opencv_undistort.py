#!/usr/bin/env python3
"""Reference undistortions from OpenCV for vgps's camera models.

Generates pixel sets for three cameras (the Ladybug2-like wide-angle pinhole, a pinhole with
asymmetric focal lengths and pincushion/tangential distortion, and an OpenCV fisheye), runs
OpenCV's ``cv2.undistortPoints`` / ``cv2.fisheye.undistortPoints`` with a tight termination
criterion (so OpenCV's answer is converged), and writes

* ``tests/data/opencv_undistort_cameras.json``: the cameras in vgps's native serde JSON
  (``{"name": {"model": ..., ...}}``), and
* ``tests/data/opencv_undistort_reference.csv``: ``camera,u,v,x,y,reprojection_px`` with
  ``(x, y)`` OpenCV's undistorted normalised coordinates (``X/Z, Y/Z``) and the distance in
  pixels between ``(u, v)`` and OpenCV's own ``projectPoints`` of the answer.

Pixel convention: OpenCV's camera matrix puts integer coordinates at pixel centres, as vgps
does, so ``(u, v)`` and ``(cx, cy)`` are passed unchanged.

Only points whose OpenCV answer reprojects within 1e-9 px are kept (OpenCV's radial-tangential
undistortion is a fixed-point iteration that may not converge at the corners of strongly
distorted images); the number dropped is printed. Fisheye points are kept below 80 degrees
from the axis (``cv2.fisheye`` returns ``X/Z``, undefined at 90 degrees).

Usage: ``pip install -r bench/peers/requirements.txt && python3 bench/peers/opencv_undistort.py``
"""
import json
import math
import os
import sys

import cv2
import numpy as np

ROOT = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
OUT_DIR = os.path.join(ROOT, "tests", "data")
MAX_REPROJECTION_PX = 1e-9
MAX_FISHEYE_ANGLE = math.radians(80.0)
GRID = (13, 10)  # grid points along u and v, image corners included
RANDOM_POINTS = 60
SEED = 20240611
CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 2000, 1e-15)

LADYBUG2_FOCAL = 1.0 / 0.00167557

CAMERAS = {
    # Must equal vgps::synthetic::calibration::ladybug2_pinhole().
    "ladybug2": {
        "model": "pinhole", "width": 1024, "height": 768,
        "fx": LADYBUG2_FOCAL, "fy": LADYBUG2_FOCAL, "cx": 511.5, "cy": 383.5,
        "distortion": {"k1": -0.25, "k2": 0.06, "p1": 2e-4, "p2": -1.5e-4, "k3": -0.003},
    },
    "pinhole_distorted": {
        "model": "pinhole", "width": 1280, "height": 960,
        "fx": 900.0, "fy": 905.0, "cx": 641.2, "cy": 478.9,
        "distortion": {"k1": 0.12, "k2": -0.25, "p1": -5e-4, "p2": 3e-4, "k3": 0.1},
    },
    # Must equal vgps::synthetic::calibration::opencv_fisheye().
    "fisheye_opencv": {
        "model": "kannala_brandt", "width": 1280, "height": 1024,
        "fx": 420.0, "fy": 421.5, "cx": 640.3, "cy": 511.7,
        "k1": -0.02, "k2": 0.004, "k3": -0.001, "k4": 0.0001,
    },
}


def pixels(cam, rng):
    w, h = cam["width"], cam["height"]
    us = np.linspace(-0.5, w - 0.5, GRID[0])
    vs = np.linspace(-0.5, h - 0.5, GRID[1])
    grid = np.array([(u, v) for v in vs for u in us])
    rand = np.column_stack([rng.uniform(-0.5, w - 0.5, RANDOM_POINTS),
                            rng.uniform(-0.5, h - 0.5, RANDOM_POINTS)])
    centre = np.array([[cam["cx"], cam["cy"]], [cam["cx"] + 0.25, cam["cy"] - 0.125]])
    return np.vstack([grid, rand, centre])


def matrix(cam):
    return np.array([[cam["fx"], 0.0, cam["cx"]], [0.0, cam["fy"], cam["cy"]], [0.0, 0.0, 1.0]])


def undistort(cam, px):
    k = matrix(cam)
    src = px.reshape(-1, 1, 2).astype(np.float64)
    if cam["model"] == "pinhole":
        d = cam["distortion"]
        dist = np.array([d["k1"], d["k2"], d["p1"], d["p2"], d["k3"]])
        xy = cv2.undistortPoints(src, k, dist, criteria=CRITERIA).reshape(-1, 2)
        obj = np.column_stack([xy, np.ones(len(xy))]).reshape(-1, 1, 3)
        back, _ = cv2.projectPoints(obj, np.zeros(3), np.zeros(3), k, dist)
    else:
        dist = np.array([cam["k1"], cam["k2"], cam["k3"], cam["k4"]])
        xy = cv2.fisheye.undistortPoints(src, k, dist, criteria=CRITERIA).reshape(-1, 2)
        obj = np.column_stack([xy, np.ones(len(xy))]).reshape(-1, 1, 3)
        back, _ = cv2.fisheye.projectPoints(obj, np.zeros(3), np.zeros(3), k, dist)
    return xy, np.linalg.norm(back.reshape(-1, 2) - px, axis=1)


def fisheye_keep(cam, px):
    t = MAX_FISHEYE_ANGLE
    t2 = t * t
    td = t * (1 + t2 * (cam["k1"] + t2 * (cam["k2"] + t2 * (cam["k3"] + t2 * cam["k4"]))))
    rho = np.hypot((px[:, 0] - cam["cx"]) / cam["fx"], (px[:, 1] - cam["cy"]) / cam["fy"])
    return rho < td


def main():
    rng = np.random.default_rng(SEED)
    os.makedirs(OUT_DIR, exist_ok=True)
    rows = []
    for name, cam in CAMERAS.items():
        px = pixels(cam, rng)
        if cam["model"] == "kannala_brandt":
            px = px[fisheye_keep(cam, px)]
        xy, err = undistort(cam, px)
        ok = np.isfinite(err) & (err <= MAX_REPROJECTION_PX)
        print(f"{name}: {ok.sum()} of {len(px)} points kept (max kept reprojection "
              f"{err[ok].max():.2e} px); dropped {np.count_nonzero(~ok)}", file=sys.stderr)
        for (u, v), (x, y), e in zip(px[ok], xy[ok], err[ok]):
            rows.append((name, u, v, x, y, e))
    with open(os.path.join(OUT_DIR, "opencv_undistort_cameras.json"), "w") as f:
        json.dump(CAMERAS, f, indent=2)
        f.write("\n")
    with open(os.path.join(OUT_DIR, "opencv_undistort_reference.csv"), "w") as f:
        f.write(f"# OpenCV {cv2.__version__} undistortPoints / fisheye.undistortPoints, "
                f"criteria COUNT+EPS {CRITERIA[1]} {CRITERIA[2]:g}; "
                "written by bench/peers/opencv_undistort.py\n")
        f.write("camera,u,v,x,y,reprojection_px\n")
        for r in rows:
            f.write("%s,%.17g,%.17g,%.17g,%.17g,%.3g\n" % r)
    print(f"wrote {len(rows)} rows to {OUT_DIR}", file=sys.stderr)


if __name__ == "__main__":
    main()
