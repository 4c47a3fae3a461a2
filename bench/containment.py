#!/usr/bin/env python3
"""Containment of a replay's fixes in their own 95 % horizontal ellipse, by pass and by
the number of surveyed landmarks used.

Reads OUT/fixes.csv of `vgps replay` on a drive with truth (a simulated drive: the
truth_lat/truth_lon columns). A fix is inside when (dE/σE)² + (dN/σN)² ≤ 5.991 (χ², 2
degrees of freedom, 95 %), with the reported per-axis σ (fixes.csv has no E–N
correlation). Rows whose message begins "backward pass:" are counted as the backward pass
of `--direction combined`.

    python3 bench/containment.py OUT
"""
import csv
import math
import sys

EARTH_RADIUS_M = 6378137.0
CHI2_2DOF_95 = 5.991


def main(out):
    groups = {}
    with open(f"{out}/fixes.csv", newline="") as f:
        for r in csv.DictReader(f):
            if r["status"] != "ok" or not r.get("truth_lat"):
                continue
            lat = math.radians(float(r["truth_lat"]))
            de = math.radians(float(r["lon"]) - float(r["truth_lon"])) * EARTH_RADIUS_M * math.cos(lat)
            dn = math.radians(float(r["lat"]) - float(r["truth_lat"])) * EARTH_RADIUS_M
            se, sn = float(r["sigma_e_m"]), float(r["sigma_n_m"])
            chi2 = (de / se) ** 2 + (dn / sn) ** 2
            surveyed = int(r["n_landmarks"])
            key = ("backward" if r["message"].startswith("backward pass") else "forward",
                   ">= 3" if surveyed >= 3 else str(surveyed))
            groups.setdefault(key, []).append((chi2, math.hypot(de, dn), math.hypot(se, sn)))
    print("pass      surveyed  fixes  inside95  err_p50_m  err_p95_m  err_max_m  sigma_h_p50_m")
    for key in sorted(groups):
        rows = groups[key]
        n = len(rows)
        inside = sum(1 for c, _, _ in rows if c <= CHI2_2DOF_95)
        err = sorted(e for _, e, _ in rows)
        sig = sorted(s for _, _, s in rows)
        print(f"{key[0]:9} {key[1]:>8} {n:6} {100 * inside / n:8.1f}% {err[n // 2]:10.3f} "
              f"{err[int(0.95 * (n - 1))]:10.3f} {err[-1]:10.3f} {sig[n // 2]:14.3f}")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: containment.py OUT (a vgps replay output folder)")
    main(sys.argv[1])
