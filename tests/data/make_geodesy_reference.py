#!/usr/bin/env python3
"""Generate tests/data/geodesy_reference.csv: WGS84 reference values computed by PROJ.

Every row holds an origin (lat0, lon0, h0), a point (lat, lon, h), the point's ECEF
coordinates from PROJ's `+proj=cart` and its ENU coordinates relative to the origin from
PROJ's own `+proj=topocentric` conversion, so the reference is independent of vgps' maths.

Groups (column `group`):
  local       points within 50 km of a set of origins, heights -100 m .. 9000 m
  polar       origins and points at latitudes up to +-89.9 deg (and the poles themselves)
  antimeridian origins at lon +-179.9 deg, points across the 180 deg meridian
  global      random points anywhere on Earth, ENU relative to a random origin

Usage (needs `pip install pyproj`, see bench/peers/requirements.txt):
    python3 tests/data/make_geodesy_reference.py > tests/data/geodesy_reference.csv
The output is deterministic for a given PROJ version (fixed seed).
"""

import csv
import math
import random
import sys

import pyproj
from pyproj import Transformer

SEED = 20240917
EARTH_RADIUS_M = 6_371_000.0
LOCAL_RADIUS_M = 50_000.0
H_MIN_M, H_MAX_M = -100.0, 9_000.0

CART = Transformer.from_pipeline("+proj=cart +ellps=WGS84")


def topocentric(lat0, lon0, h0):
    return Transformer.from_pipeline(
        "+proj=pipeline +step +proj=cart +ellps=WGS84 "
        f"+step +proj=topocentric +ellps=WGS84 +lat_0={lat0!r} +lon_0={lon0!r} +h_0={h0!r}"
    )


def wrap_lon(lon):
    w = math.fmod(lon, 360.0)
    if w > 180.0:
        w -= 360.0
    elif w <= -180.0:
        w += 360.0
    return w


def near(rng, lat0, lon0):
    """A random point within ~LOCAL_RADIUS_M of (lat0, lon0), height in [H_MIN_M, H_MAX_M]."""
    dist = LOCAL_RADIUS_M * math.sqrt(rng.random())
    az = rng.uniform(0.0, 2.0 * math.pi)
    dlat = math.degrees(dist * math.cos(az) / EARTH_RADIUS_M)
    lat = max(-90.0, min(90.0, lat0 + dlat))
    coslat = max(math.cos(math.radians(lat)), 1e-9)
    # Near the poles a fixed ground distance spans many degrees of longitude; cap the span.
    dlon = math.degrees(dist * math.sin(az) / (EARTH_RADIUS_M * coslat))
    dlon = max(-179.0, min(179.0, dlon))
    return lat, wrap_lon(lon0 + dlon), rng.uniform(H_MIN_M, H_MAX_M)


def main():
    rng = random.Random(SEED)
    rows = []  # (group, lat0, lon0, h0, lat, lon, h)

    local_origins = [
        (37.7749, -122.4194, 10.0),  # San Francisco
        (27.9881, 86.9250, 8_848.0),  # Everest
        (-33.8568, 151.2153, 5.0),  # Sydney
        (0.0, 0.0, 0.0),  # equator / prime meridian
        (78.2232, 15.6267, 50.0),  # Svalbard
        (-54.8019, -68.3030, -20.0),  # Ushuaia
        (51.4779, -0.0015, 45.0),  # Greenwich
        (-1.2921, 36.8219, 1_795.0),  # Nairobi
    ]
    for o in local_origins:
        rows.append(("local", *o, *o))
        for _ in range(150):
            rows.append(("local", *o, *near(rng, o[0], o[1])))

    polar_origins = [
        (89.9, 0.0, 0.0),
        (-89.9, 45.0, 2_800.0),
        (89.99, -120.0, 100.0),
        (-89.95, 170.0, 3_000.0),
        (90.0, 0.0, 0.0),
        (-90.0, 0.0, 2_835.0),
    ]
    for o in polar_origins:
        for _ in range(100):
            rows.append(("polar", *o, *near(rng, o[0], o[1])))
        for lat in (89.9, -89.9, 90.0, -90.0):
            if (lat > 0) == (o[0] > 0):
                rows.append(("polar", *o, lat, rng.uniform(-180.0, 180.0), rng.uniform(H_MIN_M, H_MAX_M)))

    antimeridian_origins = [
        (10.0, 179.9, 0.0),
        (-45.0, -179.9, 500.0),
        (65.0, 180.0, 100.0),
        (-16.5, 179.99, 20.0),
    ]
    for o in antimeridian_origins:
        for _ in range(100):
            rows.append(("antimeridian", *o, *near(rng, o[0], o[1])))
        # Explicit points on the other side of the meridian.
        for dlon in (-0.2, 0.2, 0.1, -0.1, 0.05):
            rows.append(("antimeridian", *o, o[0] + rng.uniform(-0.1, 0.1), wrap_lon(o[1] + dlon), rng.uniform(H_MIN_M, H_MAX_M)))

    for _ in range(600):
        lat0 = math.degrees(math.asin(rng.uniform(-1.0, 1.0)))
        lat = math.degrees(math.asin(rng.uniform(-1.0, 1.0)))
        rows.append(
            (
                "global",
                lat0,
                rng.uniform(-180.0, 180.0),
                rng.uniform(H_MIN_M, H_MAX_M),
                lat,
                rng.uniform(-180.0, 180.0),
                rng.uniform(H_MIN_M, H_MAX_M),
            )
        )

    w = csv.writer(sys.stdout, lineterminator="\n")
    w.writerow(["group", "lat0_deg", "lon0_deg", "h0_m", "lat_deg", "lon_deg", "h_m",
                "x_m", "y_m", "z_m", "e_m", "n_m", "u_m"])
    topo_cache = {}
    for group, lat0, lon0, h0, lat, lon, h in rows:
        x, y, z = CART.transform(lon, lat, h)
        key = (lat0, lon0, h0)
        if key not in topo_cache:
            topo_cache[key] = topocentric(lat0, lon0, h0)
        e, n, u = topo_cache[key].transform(lon, lat, h)
        w.writerow([group] + [repr(float(v)) for v in (lat0, lon0, h0, lat, lon, h, x, y, z, e, n, u)])
    print(f"# {len(rows)} rows, pyproj {pyproj.__version__}, PROJ {pyproj.proj_version_str}", file=sys.stderr)


if __name__ == "__main__":
    main()
