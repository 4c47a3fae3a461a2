#!/bin/sh
# `import vgps` wall-clock (issue #29: <= 50 ms): fresh interpreters, `import vgps` against an
# empty program, N alternating runs; prints the medians. Usage: bench/python/import_time.sh [N]
N=${1:-20}
python3 - "$N" <<'PY'
import statistics, subprocess, sys, time
n = int(sys.argv[1])
t = {"pass": [], "import vgps": []}
for _ in range(n):
    for code in t:
        s = time.perf_counter(); subprocess.run([sys.executable, "-c", code], check=True)
        t[code].append(time.perf_counter() - s)
m = {k: statistics.median(v) * 1e3 for k, v in t.items()}
print(f"median of {n}: python -c pass {m['pass']:.1f} ms, python -c 'import vgps' "
      f"{m['import vgps']:.1f} ms, difference {m['import vgps'] - m['pass']:.1f} ms")
PY
