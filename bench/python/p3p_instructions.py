"""Instructions per vgps.p3p call under callgrind (independent of the machine's load). Usage:
    MODE=p3p valgrind --tool=callgrind python3.11 bench/python/p3p_instructions.py 5000
    callgrind_annotate --inclusive=yes callgrind.out.PID | grep trampoline::cfunction
(inclusive cost of the PyO3 trampoline / 5001 calls); MODE=loop runs the loop alone."""
import os, sys
import numpy as np
import vgps
n = int(sys.argv[1])
rng = np.random.default_rng(0)
t = np.array([10.0, -5.0, 2.0])
points = t + rng.normal(0, 30, (n, 3, 3))
bearings = points - t[None, None, :]
bearings /= np.linalg.norm(bearings, axis=2, keepdims=True)
vgps.p3p(bearings[0], points[0])  # warm: NumPy's C API looked up
if os.environ["MODE"] == "p3p":
    for k in range(n):
        vgps.p3p(bearings[k], points[k])
else:
    for k in range(n):
        (bearings[k], points[k])
