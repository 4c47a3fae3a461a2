"""Per-call time of vgps.p3p from Python, one problem per call and batched, beside PoseLib's
binding on the same frames (issue #29 target: <= 2 us per call). Usage:
    python3 bench/python/p3p_overhead.py [N]
"""
import sys
import timeit

import numpy as np

import vgps

n = int(sys.argv[1]) if len(sys.argv) > 1 else 20000
rng = np.random.default_rng(0)
t = np.array([10.0, -5.0, 2.0])
points = t + rng.normal(0, 30, (n, 3, 3))
bearings = points - t[None, None, :]
bearings /= np.linalg.norm(bearings, axis=2, keepdims=True)


def best(f, repeat=5):
    return min(timeit.repeat(f, number=1, repeat=repeat))


single = best(lambda: [vgps.p3p(bearings[k], points[k]) for k in range(n)]) / n
loop_only = best(lambda: [(bearings[k], points[k]) for k in range(n)]) / n
batched = best(lambda: vgps.p3p(bearings, points)) / n
print(f"vgps.p3p one per call: {single * 1e6:.2f} us/call "
      f"(of which Python loop + indexing {loop_only * 1e6:.2f} us)")
print(f"vgps.p3p batched (N={n}): {batched * 1e6:.2f} us/problem")
try:
    import poselib
except ImportError:
    print("poselib not installed")
else:
    xs = [list(b) for b in bearings]
    Xs = [list(p) for p in points]
    pl = best(lambda: [poselib.p3p(xs[k], Xs[k]) for k in range(n)]) / n
    print(f"poselib.p3p one per call: {pl * 1e6:.2f} us/call")
