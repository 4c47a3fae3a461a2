"""Issue #29 fleet figure: every drive folder under DRIVES replayed by vgps.fleet.replay_many
on a local Ray instance with 2 CPUs, ray.init and replay_many timed apart. Usage:
    RAY_worker_niceness=0 python3 bench/python/fleet_ray.py DRIVES OUT
Compare with the CLI two at a time, on the same drives, right after:
    ls DRIVES | xargs -P 2 -I{} vgps replay DRIVES/{} --out OUT_CLI/{} --quiet --threads 1
"""
import glob
import sys
import time

t0 = time.perf_counter()
import ray  # noqa: E402

ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, configure_logging=False)
t1 = time.perf_counter()
import vgps.fleet  # noqa: E402

drives = sorted(glob.glob(sys.argv[1] + "/*"))
rows = vgps.fleet.replay_many(drives, sys.argv[2], progress=True)
t2 = time.perf_counter()
print(f"ray.init {t1 - t0:.1f} s; replay_many {t2 - t1:.1f} s; total {t2 - t0:.1f} s; "
      f"ok {sum(r['status'] == 'ok' for r in rows)}/{len(rows)}; "
      f"task wall sum {sum(r['wall_s'] for r in rows):.1f} s")
ray.shutdown()
