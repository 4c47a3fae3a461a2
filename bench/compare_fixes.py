#!/usr/bin/env python3
"""Compare two fixes.csv on their shared columns: rows that differ, statuses."""
import csv, sys, collections
a = list(csv.DictReader(open(sys.argv[1]))); b = list(csv.DictReader(open(sys.argv[2])))
shared = [c for c in a[0].keys() if c in b[0].keys()]
diff = sum(1 for x, y in zip(a, b) if any(x[c] != y[c] for c in shared))
print(f"rows {len(a)} vs {len(b)}; shared columns {len(shared)}; rows differing {diff}")
for name, rows in (("A", a), ("B", b)):
    print(name, dict(collections.Counter(r.get("status", "?") for r in rows)))
