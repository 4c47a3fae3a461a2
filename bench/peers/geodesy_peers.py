#!/usr/bin/env python3
"""Time pyproj (PROJ) for the conversions benchmarked by `cargo bench --bench solvers -- geo/`.

Prints ns per point for scalar calls (one point per call, like vgps' API) and for vectorised
calls (numpy arrays of 100,000 points), on the same San Francisco points as
benches/solvers/geo.rs. Needs `pip install -r bench/peers/requirements.txt` (pyproj, numpy).
"""

import timeit

import numpy as np
from pyproj import Transformer

LAT0, LON0, H0 = 37.7749, -122.4194, 10.0
LAT, LON, H = 37.8024, -122.4058, 64.0

cart = Transformer.from_pipeline("+proj=cart +ellps=WGS84")
topo = Transformer.from_pipeline(
    "+proj=pipeline +step +proj=cart +ellps=WGS84 "
    f"+step +proj=topocentric +ellps=WGS84 +lat_0={LAT0} +lon_0={LON0} +h_0={H0}"
)
x, y, z = cart.transform(LON, LAT, H)
e, n, u = topo.transform(LON, LAT, H)

CASES = {
    "geodetic_to_ecef": (lambda a, b, c: cart.transform(a, b, c), (LON, LAT, H)),
    "ecef_to_geodetic": (lambda a, b, c: cart.transform(a, b, c, direction="INVERSE"), (x, y, z)),
    "geodetic_to_enu": (lambda a, b, c: topo.transform(a, b, c), (LON, LAT, H)),
    "enu_to_geodetic": (lambda a, b, c: topo.transform(a, b, c, direction="INVERSE"), (e, n, u)),
}


def best_ns(fn, args, number, repeat=5):
    return min(timeit.repeat(lambda: fn(*args), number=number, repeat=repeat)) / number * 1e9


def main():
    points = 100_000
    print(f"{'conversion':20s} {'scalar ns/pt':>14s} {'vector ns/pt':>14s}")
    for name, (fn, args) in CASES.items():
        scalar = best_ns(fn, args, number=20_000)
        arrays = tuple(np.full(points, v) for v in args)
        vector = best_ns(fn, arrays, number=5) / points
        print(f"{name:20s} {scalar:14.0f} {vector:14.1f}")


if __name__ == "__main__":
    main()
