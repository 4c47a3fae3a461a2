#!/usr/bin/env python3
"""Robust absolute pose with known correspondences: vgps vs PoseLib and OpenCV.

One run generates the problems, runs every estimator on the SAME problems, and prints the
median time per frame and the median position error, with ratios against vgps:

  * the problems come from vgps's shared generator (`vgps::synthetic::robust`), written by
    `cargo run --release --example ransac_problems -- generate N SEED FILE`: 100 bearings,
    50 % outliers, 0.1 degree noise per tangent axis, ranges 5-50 m, in two scenes:
      - all_around: a Ladybug-like rig (5 side cameras + 1 top, centres 4 cm out), points
        all around the sphere, every ray starting at the centre of its camera;
      - front_hemisphere: a central camera looking along rig +z, points and outliers within
        80 degrees of the axis (what a pinhole camera can image);
  * vgps: `ransac_problems solve FILE` (native loop, std::time::Instant per solve, after one
    warm-up pass): `estimate_absolute_pose` (robust estimator + Gauss-Newton) and
    `compute_fix` (the same plus the covariance refinement and the ambiguity check);
  * PoseLib `estimate_generalized_absolute_pose` on the all-around rig: one pinhole camera
    (f = 1000 px) per rig camera with its true extrinsics; a ray more than ~78 degrees off
    its camera's axis gets its own virtual camera at the ray origin looking along the ray
    (the same ray, exactly; a generalized camera is a set of rays). Default RANSAC options
    (min 1000 iterations, as PoseLib ships) except the threshold, 5 sigma x f pixels;
  * PoseLib `estimate_absolute_pose` (default options, threshold 5 sigma x f pixels) and
    OpenCV `solvePnPRansac` (default options: SOLVEPNP_ITERATIVE, 100 iterations, 0.99;
    threshold 5 sigma x f pixels) on the front hemisphere (pinhole only). With 1000
    iterations at 0.9999 OpenCV takes ~10x longer for a worse median with P3P/AP3P/EPnP
    samples and 2.7 cm with SQPnP at ~125 ms.
  * the maximum-likelihood pose on the true inliers (angular least squares started at the
    truth, `ransac_problems solve`): the reference no estimator beats on average; stderr
    also says how many observations compute_fix's inlier sets differ from the truth by.
Python timings include the binding overhead (array conversion, a few microseconds).

Usage (repository root): python bench/peers/ransac_peers.py [N] [SEED]   (default 200 1)
Needs: pip install -r bench/peers/requirements.txt (numpy, poselib, opencv-python-headless).
"""

import json
import math
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

N = int(sys.argv[1]) if len(sys.argv) > 1 else 200
SEED = int(sys.argv[2]) if len(sys.argv) > 2 else 1
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
FOCAL = 1000.0
THRESHOLD_SIGMAS = 5.0
MIN_AXIS_COSINE = 0.2  # rays farther off their camera axis get a virtual camera


def cargo_example(*args):
    cmd = ["cargo", "run", "--quiet", "--release", "--example", "ransac_problems", "--"]
    return subprocess.run(cmd + list(args), cwd=ROOT, check=True, capture_output=True, text=True).stdout


def camera_from_rig(axis):
    """Right-handed camera frame (x right, y down, z = axis) as rows, in the rig frame."""
    z = np.asarray(axis, float)
    z = z / np.linalg.norm(z)
    up = np.array([0.0, 0.0, 1.0]) if abs(z[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    x = np.cross(z, up)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return np.vstack([x, y, z])


def project(r_cam, d):
    c = r_cam @ d
    return np.array([FOCAL * c[0] / c[2], FOCAL * c[1] / c[2]])


def camera_pose(poselib, rot, t):
    pose = poselib.CameraPose()
    pose.R = rot
    pose.t = t
    return pose


def pinhole_dict():
    return {"model": "PINHOLE", "width": 4000, "height": 4000, "params": [FOCAL, FOCAL, 0.0, 0.0]}


def run_poselib_generalized(poselib, scene, sigma):
    cams = scene["cameras"]
    rots = [camera_from_rig(c["axis"]) for c in cams]
    times, errors = [], []
    opt = {"max_reproj_error": THRESHOLD_SIGMAS * sigma * FOCAL}
    for p in scene["problems"]:
        x2d, x3d, ext = [[] for _ in cams], [[] for _ in cams], []
        for k, c in enumerate(cams):
            ext.append(camera_pose(poselib, rots[k], -rots[k] @ np.asarray(c["centre"])))
        virtual = []
        for o, d, X, k in zip(p["origins"], p["directions"], p["points"], p["camera"]):
            d = np.asarray(d)
            if (rots[k] @ d)[2] > MIN_AXIS_COSINE and np.allclose(o, cams[k]["centre"]):
                x2d[k].append(project(rots[k], d))
                x3d[k].append(X)
            else:
                virtual.append((np.asarray(o), d, X))
        for o, d, X in virtual:
            r = camera_from_rig(d)
            ext.append(camera_pose(poselib, r, -r @ o))
            x2d.append([np.zeros(2)])
            x3d.append([X])
        x2d = [np.asarray(a, float).reshape(-1, 2) for a in x2d]
        x3d = [np.asarray(a, float).reshape(-1, 3) for a in x3d]
        cam_list = [pinhole_dict() for _ in x2d]
        t0 = time.perf_counter()
        pose, _info = poselib.estimate_generalized_absolute_pose(x2d, x3d, ext, cam_list, opt, {})
        times.append((time.perf_counter() - t0) * 1e3)
        errors.append(np.linalg.norm(pose.center() - np.asarray(p["translation"])))
    return times, errors


def pinhole_inputs(scene):
    r = camera_from_rig(scene["cameras"][0]["axis"])
    for p in scene["problems"]:
        x2d = np.array([project(r, np.asarray(d)) for d in p["directions"]])
        x3d = np.asarray(p["points"], float)
        yield r, x2d, x3d, np.asarray(p["translation"])


def run_poselib_pinhole(poselib, scene, sigma):
    times, errors = [], []
    opt = {"max_reproj_error": THRESHOLD_SIGMAS * sigma * FOCAL}
    cam = pinhole_dict()
    for _r, x2d, x3d, truth in pinhole_inputs(scene):
        t0 = time.perf_counter()
        pose, _info = poselib.estimate_absolute_pose(x2d, x3d, cam, opt, {})
        times.append((time.perf_counter() - t0) * 1e3)
        errors.append(np.linalg.norm(pose.center() - truth))
    return times, errors


def run_opencv(cv2, scene, sigma):
    times, errors = [], []
    k = np.array([[FOCAL, 0, 0], [0, FOCAL, 0], [0, 0, 1.0]])
    for _r, x2d, x3d, truth in pinhole_inputs(scene):
        t0 = time.perf_counter()
        ok, rvec, tvec, _inliers = cv2.solvePnPRansac(
            x3d, x2d, k, None, reprojectionError=THRESHOLD_SIGMAS * sigma * FOCAL)
        times.append((time.perf_counter() - t0) * 1e3)
        if ok:
            rot, _ = cv2.Rodrigues(rvec)
            errors.append(np.linalg.norm(-rot.T @ tvec.ravel() - truth))
        else:
            errors.append(math.inf)
    return times, errors


def median(v):
    return float(np.median(np.asarray(v, float)))


def main():
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "problems.json")
        cargo_example("generate", str(N), str(SEED), path)
        with open(path) as f:
            problems = json.load(f)
        vgps = json.loads(cargo_example("solve", path))
    sigma = problems["sigma_rad"]
    rows = []  # (scene, name, times, errors, reference)

    def nan_inf(v):
        return [math.inf if x is None else x for x in v]

    for scene in ("all_around", "front_hemisphere"):
        v = vgps[scene]
        rows.append((scene, "vgps estimate_absolute_pose", v["ransac_ms"], nan_inf(v["ransac_err_m"])))
        rows.append((scene, "vgps compute_fix", v["fix_ms"], nan_inf(v["fix_err_m"])))
        rows.append((scene, "ML on true inliers (ref.)", [math.nan] * len(v["ml_err_m"]),
                     nan_inf(v["ml_err_m"])))
        diff = v["fix_inliers_differing"]
        print(f"{scene}: compute_fix inlier sets differ from the truth by {sum(diff)} "
              f"observations over {len(diff)} problems", file=sys.stderr)
    try:
        import poselib

        rows.append(("all_around", "PoseLib generalized", *run_poselib_generalized(
            poselib, problems["all_around"], sigma)))
        rows.append(("front_hemisphere", "PoseLib pinhole", *run_poselib_pinhole(
            poselib, problems["front_hemisphere"], sigma)))
    except ImportError:
        print("poselib not installed: skipped", file=sys.stderr)
    try:
        import cv2

        rows.append(("front_hemisphere", "OpenCV solvePnPRansac", *run_opencv(
            cv2, problems["front_hemisphere"], sigma)))
    except ImportError:
        print("opencv not installed: skipped", file=sys.stderr)

    print(f"{N} problems per scene, seed {SEED}: 100 bearings, 50 % outliers, "
          f"{math.degrees(sigma):.2f} deg noise, ranges {problems['min_range_m']}-{problems['max_range_m']} m")
    print(f"{'scene':<17} {'estimator':<28} {'median ms':>10} {'x vgps':>7} {'median err cm':>14} "
          f"{'x vgps':>7} {'>1 m':>5}")
    for scene in ("all_around", "front_hemisphere"):
        ref = next(r for r in rows if r[0] == scene)
        t_ref, e_ref = median(ref[2]), median(ref[3])
        for s, name, times, errors in rows:
            if s != scene:
                continue
            t, e = median(times), median(errors)
            bad = sum(1 for x in errors if not x < 1.0)
            print(f"{scene:<17} {name:<28} {t:>10.3f} {t / t_ref:>7.2f} {e * 100:>14.2f} "
                  f"{e / e_ref:>7.2f} {bad:>5}")


if __name__ == "__main__":
    main()
