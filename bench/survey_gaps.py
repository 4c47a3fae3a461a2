#!/usr/bin/env python3
"""Survey gaps over many seeds: how often the localizer carries the fix, and how honestly.

    python3 bench/survey_gaps.py VGPS WORKDIR [--short-seeds 2-9] [--reference-seeds 2-4]
                                 [--corner-keep 40]

VGPS is the `vgps` binary to measure (e.g. target/release/vgps); WORKDIR receives the
drives (simulated once, kept) and one replay per drive and binary (named after the
binary's file name, so two binaries can be compared in one WORKDIR). The drives are the
simulator's presets cut the ways the localizer finds hardest, each with its survey gap:

- SL<seed>: the `short` preset's streetlight detections only (5 frames/s, lamps alone);
- SD<seed>: the `short` preset's building-corner detections only, 40 % of them kept at
  random (about the vertex detector's recall by day; replayed to 150 m); with
  `--corner-keep P`, P % of them, in drives named SD<P>_<seed> (how availability by day
  grows with the detector's recall);
- RL3_<seed>: the `reference` preset's streetlights, every third frame (5 frames/s);
- RL1_<seed>: the `reference` preset's streetlights at 15 frames/s.

Prints, per drive and per group, the frames fixed, the fixes more than 1 m and 5 m from
the truth, and the fixes outside their 95 % circle (error > 2.45 σ_h, σ_h the mean of the
east and north σ). One seed is one sample of a chaotic process (a survey gap is carried or
lost on a handful of associations), so compare groups, not single drives.
"""

import argparse
import csv
import math
import os
import random
import shutil
import subprocess
import sys


def seeds(text):
    lo, _, hi = text.partition("-")
    return list(range(int(lo), int(hi or lo) + 1))


def filtered_copy(src, dst, keep_detection, keep_frame=lambda f: True):
    """Copies drive `src` to `dst` keeping the frames and detections the predicates keep."""
    if os.path.exists(dst):
        return
    shutil.copytree(src, dst + ".tmp")
    for name, column in [("frames.csv", 0), ("truth.csv", 0), ("detections.csv", None)]:
        with open(os.path.join(src, name), newline="") as f:
            rows = list(csv.reader(f))
        out = [rows[0]]
        for r in rows[1:]:
            if not keep_frame(int(r[0])):
                continue
            if column is None and not keep_detection(r):
                continue
            out.append(r)
        with open(os.path.join(dst + ".tmp", name), "w", newline="") as f:
            csv.writer(f).writerows(out)
    os.rename(dst + ".tmp", dst)


def make_drives(vgps, work, short_seeds, reference_seeds, corner_keep=40):
    drives = []
    for s in short_seeds:
        base = os.path.join(work, f"short{s}")
        if not os.path.exists(base):
            subprocess.run([vgps, "simulate", "--preset", "short", "--seed", str(s), "--out", base],
                           check=True, stdout=subprocess.DEVNULL)
        filtered_copy(base, os.path.join(work, f"SL{s}"), lambda r: r[5] == "streetlight")
        rng = random.Random(s)
        sd = f"SD{s}" if corner_keep == 40 else f"SD{corner_keep}_{s}"
        filtered_copy(base, os.path.join(work, sd),
                      lambda r: r[5] == "corner" and rng.random() < corner_keep / 100)
        drives += [f"SL{s}", sd]
    for s in reference_seeds:
        base = os.path.join(work, f"reference{s}")
        if not os.path.exists(base):
            subprocess.run([vgps, "simulate", "--seed", str(s), "--out", base],
                           check=True, stdout=subprocess.DEVNULL)
        filtered_copy(base, os.path.join(work, f"RL3_{s}"), lambda r: r[5] == "streetlight",
                      lambda f: f % 3 == 0)
        filtered_copy(base, os.path.join(work, f"RL1_{s}"), lambda r: r[5] == "streetlight")
        drives += [f"RL3_{s}", f"RL1_{s}"]
    return drives


def tally(fixes):
    with open(fixes, newline="") as f:
        rows = list(csv.DictReader(f))
    ok = [r for r in rows if r["status"] == "ok" and r["err_h_m"]]
    err = [float(r["err_h_m"]) for r in ok]
    outside = sum(
        e > 2.45 * math.hypot(float(r["sigma_e_m"]), float(r["sigma_n_m"])) / math.sqrt(2)
        for e, r in zip(err, ok))
    return {"frames": len(rows), "ok": len(ok), "over1": sum(e > 1 for e in err),
            "over5": sum(e > 5 for e in err), "outside": outside, "max": max(err, default=0.0)}


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("vgps")
    p.add_argument("work")
    p.add_argument("--short-seeds", default="2-9", type=seeds)
    p.add_argument("--reference-seeds", default="2-4", type=seeds)
    p.add_argument("--corner-keep", default=40, type=int, metavar="PERCENT",
                   help="share of the corner detections the SD drives keep (default 40; "
                        "another value names them SD<PERCENT>_<seed>)")
    a = p.parse_args()
    if not 0 < a.corner_keep <= 100:
        p.error("--corner-keep must be within 1-100")
    os.makedirs(a.work, exist_ok=True)
    vgps = os.path.abspath(a.vgps)
    tag = os.path.basename(vgps)
    drives = make_drives(vgps, a.work, a.short_seeds, a.reference_seeds, a.corner_keep)
    groups = {}
    for d in drives:
        out = os.path.join(a.work, f"out_{tag}_{d}")
        if not os.path.exists(os.path.join(out, "fixes.csv")):
            extra = ["--visibility-range-m", "150"] if d.startswith("SD") else []
            subprocess.run([vgps, "replay", os.path.join(a.work, d), "--out", out, "--quiet"] + extra,
                           check=True, stdout=subprocess.DEVNULL)
        t = tally(os.path.join(out, "fixes.csv"))
        print(f"{d:7} {t['ok']:5}/{t['frames']:<5} >1 m {t['over1']:3}  >5 m {t['over5']:2}  "
              f"outside 95 % {t['outside']:3}  max {t['max']:.2f} m", flush=True)
        g = groups.setdefault(d.split("_")[0] if "_" in d else d.rstrip("0123456789"), {})
        for k, v in t.items():
            g[k] = max(g.get(k, 0), v) if k == "max" else g.get(k, 0) + v
    for name, g in groups.items():
        print(f"{name:7} {g['ok']:5}/{g['frames']:<5} ({100 * g['ok'] / max(g['frames'], 1):.1f} %) "
              f">1 m {g['over1']}  >5 m {g['over5']}  outside 95 % {g['outside']} "
              f"({100 * g['outside'] / max(g['ok'], 1):.1f} %)  max {g['max']:.2f} m")


if __name__ == "__main__":
    sys.exit(main())
