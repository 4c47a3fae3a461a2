#!/usr/bin/env python3
"""Lamp recall and precision of `vgps detect` on a simulated drive, against the images'
truth (`images_truth.csv`), and what the false detections sit on (issue #24).

Usage: python3 bench/night_truth.py DRIVE/images_truth.csv DETECTIONS.csv [--radius 3]

- A lamp is found when a detection of its image lies within `--radius` px of its centre.
- A detection is true when it lies within `--radius` px of a lamp; a false one is charged to
  the nearest other truth spot within `--near` px (reflection, headlight, taillight,
  window: a window's row is its pane's centre, so a detection on the pane's corner may be
  farther than the radius), else to `other` (edges, bloom, noise, unlisted windows).
- Recall is also given for lamps of peak ≥ 20 DN (lamps far away are faint).
"""

import argparse
import csv
import math
from collections import Counter, defaultdict


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("truth")
    ap.add_argument("detections")
    ap.add_argument("--radius", type=float, default=3.0)
    ap.add_argument("--near", type=float, default=15.0)
    a = ap.parse_args()
    truth = defaultdict(list)
    with open(a.truth) as f:
        for r in csv.DictReader(f):
            peak = float(r["peak_dn"]) if r["peak_dn"] else 0.0
            truth[(r["frame"], r["camera"])].append(
                (r["kind"], float(r["u"]), float(r["v"]), peak)
            )
    dets = defaultdict(list)
    with open(a.detections) as f:
        for r in csv.DictReader(f):
            dets[(r["frame"], r["camera"])].append((float(r["u"]), float(r["v"])))
    lamps = found = bright = bright_found = 0
    true_dets = 0
    false_by = Counter()
    errors = []
    for key in set(truth) | set(dets):
        spots = truth.get(key, [])
        ds = dets.get(key, [])
        for kind, u, v, peak in spots:
            if kind != "lamp":
                continue
            lamps += 1
            bright += peak >= 20.0
            d = min((math.hypot(u - x, v - y) for x, y in ds), default=math.inf)
            if d <= a.radius:
                found += 1
                bright_found += peak >= 20.0
                errors.append(d)
        for x, y in ds:
            best = (math.inf, "other")
            for kind, u, v, _ in spots:
                d = math.hypot(u - x, v - y)
                if kind == "lamp" and d <= a.radius:
                    best = (0.0, "lamp")
                    break
                if kind != "lamp" and d <= a.near and d < best[0]:
                    best = (d, kind)
            if best[1] == "lamp":
                true_dets += 1
            else:
                false_by[best[1]] += 1
    n = sum(len(v) for v in dets.values())
    errors.sort()
    med = errors[len(errors) // 2] if errors else math.nan
    print(f"images with truth or detections: {len(set(truth) | set(dets))}")
    print(f"lamps found: {found} / {lamps} ({100.0 * found / max(lamps, 1):.1f} %); "
          f"peak >= 20 DN: {bright_found} / {bright} ({100.0 * bright_found / max(bright, 1):.1f} %)")
    print(f"detections: {n}, on lamps {true_dets} (precision {100.0 * true_dets / max(n, 1):.1f} %)")
    print("false detections by what they sit on: "
          + ", ".join(f"{k} {c}" for k, c in false_by.most_common()))
    print(f"found lamps' centre error: median {med:.2f} px")


if __name__ == "__main__":
    main()
