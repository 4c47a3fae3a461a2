#!/usr/bin/env python3
"""P3P peers: vgps (Lambda Twist, Rust) vs PoseLib `poselib.p3p` and OpenCV `solveP3P`.

All figures come from one run on this machine:
  * vgps: `cargo run --release --example p3p_timing -- N SEED` (native loop, std::time::Instant);
  * PoseLib: `poselib.p3p(x, X)` per call from Python (the binding exposes the minimal
    solver; the per-call figure is dominated by the pybind11 call and list/array conversion,
    so it is an upper bound on the native solver time, not a like-for-like figure);
  * OpenCV: `cv2.solveP3P` (SOLVEPNP_P3P and SOLVEPNP_AP3P) per call from Python.

Problems: random poses, three landmarks at ranges uniform in [0.1, 1] x 50 m. vgps and
PoseLib get omnidirectional bearings (the whole sphere); OpenCV needs image points, so it
gets front-hemisphere problems (bearing z > 0.2) projected with an identity camera matrix.
Non-finite rate: fraction of calls, on samples with 0.5 degree bearing noise, whose output
contains a NaN or infinity.  Recovery rate: fraction of noise-free problems where a returned
pose is within 1e-6 x scene of the truth.

Usage: python bench/peers/p3p_peers.py [N]   (from the repository root; default N = 20000)
"""

import math
import os
import subprocess
import sys
import time

import numpy as np

N = int(sys.argv[1]) if len(sys.argv) > 1 else 20000
SEED = 1
SCENE = 50.0
SIGMA = math.radians(0.5)
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def random_rotation(rng):
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    w, x, y, z = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def random_unit(rng):
    v = rng.normal(size=3)
    return v / np.linalg.norm(v)


def make_problem(rng, front):
    """world_from_rig (R, c), world points X (3x3 rows), unit bearings in rig x (3x3 rows)."""
    R = random_rotation(rng)
    c = rng.uniform(-SCENE, SCENE, size=3)
    xs = []
    for _ in range(3):
        while True:
            d = random_unit(rng)
            if not front or d[2] > 0.2:
                break
        xs.append(d)
    x = np.array(xs)
    ranges = rng.uniform(0.1 * SCENE, SCENE, size=3)
    X = c + (R @ (x * ranges[:, None]).T).T
    return R, c, X, x


def perturb(rng, b, sigma):
    # Rotate b by a small random tangent vector of std sigma per axis.
    t1 = np.cross(b, [1.0, 0.0, 0.0] if abs(b[0]) < 0.9 else [0.0, 1.0, 0.0])
    t1 /= np.linalg.norm(t1)
    t2 = np.cross(b, t1)
    v = b + sigma * (rng.normal() * t1 + rng.normal() * t2)
    return v / np.linalg.norm(v)


def poselib_center(pose):
    # PoseLib: x_cam = R X + t, so the camera centre is -R^T t.
    Rm = pose.R
    return -Rm.T @ pose.t


def time_calls(fn, args_list, repeats=3):
    """(wall ns, thread-CPU ns) per call, best of `repeats`; the CPU figure is the one that
    stays meaningful on a loaded machine."""
    best, best_cpu = float("inf"), float("inf")
    for _ in range(repeats):
        c0 = time.thread_time_ns()
        t0 = time.perf_counter()
        for a in args_list:
            fn(*a)
        best = min(best, (time.perf_counter() - t0) / len(args_list) * 1e9)
        best_cpu = min(best_cpu, (time.thread_time_ns() - c0) / len(args_list))
    return best, best_cpu


def nonfinite(values):
    return any(not np.all(np.isfinite(np.asarray(v, dtype=float))) for v in values)


def main():
    rng = np.random.default_rng(SEED)
    rows = []

    # --- vgps (Rust, native loop) -------------------------------------------------------
    out = subprocess.run(
        ["cargo", "run", "--quiet", "--release", "--example", "p3p_timing", "--", str(N), str(SEED)],
        cwd=ROOT,
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    vg = {}
    for line in out.splitlines():
        fields = line.split()
        vg[fields[0]] = {k: float(v) for k, v in (f.split("=") for f in fields[1:])}
    vgps_ns = (vg["vgps_p3p"]["ns_per_solve"], vg["vgps_p3p"]["cpu_ns_per_solve"])
    vgps_nf = vg["vgps_p3p_noisy_0.5deg"]["nonfinite"] / N
    rows.append(("vgps p3p (Lambda Twist, omni, native)", vgps_ns, vgps_nf, float("nan")))

    # --- PoseLib --------------------------------------------------------------------------
    try:
        import poselib

        probs = [make_problem(rng, front=False) for _ in range(N)]
        args = [([p[3][i] for i in range(3)], [p[2][i] for i in range(3)]) for p in probs]
        ns = time_calls(poselib.p3p, args)
        found = 0
        for (R, c, X, x), a in zip(probs, args):
            sols = poselib.p3p(*a)
            if any(np.linalg.norm(poselib_center(s) - c) < 1e-6 * SCENE for s in sols):
                found += 1
        bad = 0
        for R, c, X, x in probs:
            xn = [perturb(rng, x[i], SIGMA) for i in range(3)]
            sols = poselib.p3p(xn, [X[i] for i in range(3)])
            if nonfinite([s.R for s in sols] + [s.t for s in sols]):
                bad += 1
        rows.append(("PoseLib p3p (omni, Python call)", ns, bad / N, found / N))
    except ImportError:
        print("poselib not installed: pip install -r bench/peers/requirements.txt")

    # --- OpenCV -----------------------------------------------------------------------------
    try:
        import cv2

        K = np.eye(3)
        fprobs = [make_problem(rng, front=True) for _ in range(N)]

        def cv_args(X, x):
            img = (x[:, :2] / x[:, 2:3]).reshape(3, 1, 2).astype(np.float64)
            return X.reshape(3, 1, 3).astype(np.float64), img

        for name, flag in (("P3P", cv2.SOLVEPNP_P3P), ("AP3P", cv2.SOLVEPNP_AP3P)):
            args = [cv_args(X, x) + (K, None, flag) for (R, c, X, x) in fprobs]
            ns = time_calls(lambda o, i, k, d, f: cv2.solveP3P(o, i, k, d, f), args)
            found = 0
            for (R, c, X, x), a in zip(fprobs, args):
                n, rvecs, tvecs = cv2.solveP3P(*a)
                for rv, tv in zip(rvecs, tvecs):
                    Rc, _ = cv2.Rodrigues(rv)
                    if np.all(np.isfinite(Rc)) and np.linalg.norm(-Rc.T @ tv.ravel() - c) < 1e-6 * SCENE:
                        found += 1
                        break
            bad = 0
            for R, c, X, x in fprobs:
                xn = np.array([perturb(rng, x[i], SIGMA) for i in range(3)])
                if np.any(xn[:, 2] <= 0):
                    continue
                n, rvecs, tvecs = cv2.solveP3P(*cv_args(X, xn), K, None, flag)
                if nonfinite(list(rvecs) + list(tvecs)):
                    bad += 1
            rows.append((f"OpenCV solveP3P {name} (front, Python call)", ns, bad / N, found / N))
    except ImportError:
        print("opencv not installed: pip install -r bench/peers/requirements.txt")

    print(f"\nP3P peers, N = {N} problems, seed {SEED}, noise {math.degrees(SIGMA):.1f} deg for the non-finite rate")
    print(
        f"{'solver':<44} {'wall ns':>9} {'cpu ns':>9} {'cpu x vgps':>10} {'non-finite':>11} {'recovered':>10}"
    )
    for name, (wall, cpu), nf, rec in rows:
        ratio = cpu / vgps_ns[1]
        nf_s = "" if math.isnan(nf) else f"{100 * nf:.3f}%"
        rec_s = "" if math.isnan(rec) else f"{100 * rec:.3f}%"
        print(f"{name:<44} {wall:>9.1f} {cpu:>9.1f} {ratio:>10.2f} {nf_s:>11} {rec_s:>10}")
    print(
        f"(vgps recovery rate: see `cargo test --release --test p3p -- --nocapture`; "
        f"vgps mean solutions {vg['vgps_p3p']['mean_solutions']:.3f})"
    )


if __name__ == "__main__":
    main()
