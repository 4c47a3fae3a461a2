"""Small exact problems for the docstrings, the README and the tests (no files needed)."""

from __future__ import annotations

from typing import List, Optional, Tuple

import numpy as np

_A = 6378137.0
_F = 1.0 / 298.257223563
_E2 = _F * (2.0 - _F)


def ecef(lat_deg: float, lon_deg: float, alt_m: float) -> np.ndarray:
    """WGS84 geodetic (degrees, metres) to ECEF (metres)."""
    lat, lon = np.radians(lat_deg), np.radians(lon_deg)
    n = _A / np.sqrt(1.0 - _E2 * np.sin(lat) ** 2)
    return np.array([
        (n + alt_m) * np.cos(lat) * np.cos(lon),
        (n + alt_m) * np.cos(lat) * np.sin(lon),
        (n * (1.0 - _E2) + alt_m) * np.sin(lat),
    ])


def enu_from_ecef(lat_deg: float, lon_deg: float) -> np.ndarray:
    """The rotation from ECEF to the ENU axes at a place."""
    lat, lon = np.radians(lat_deg), np.radians(lon_deg)
    return np.array([
        [-np.sin(lon), np.cos(lon), 0.0],
        [-np.sin(lat) * np.cos(lon), -np.sin(lat) * np.sin(lon), np.cos(lat)],
        [np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)],
    ])


RIG = (37.7793, -122.4193, 10.0)


def square_of_landmarks(
    rig: Tuple[float, float, float] = RIG, heading_deg: float = 0.0
) -> Tuple[Tuple[List[str], np.ndarray, Optional[np.ndarray]], np.ndarray, List[str]]:
    """Six landmarks around a rig and the exact bearings the rig sees them along.

    The rig's attitude is level, its +x axis ``heading_deg`` clockwise from north (0: the
    rig's x points north). Returns ``(landmarks, bearings (6, 3), ids)`` where
    ``landmarks = (ids, lat_lon_alt (6, 3), None)``.
    """
    lat0, lon0, alt0 = rig
    offsets = np.array([
        [0.0004, 0.0003, 6.0], [-0.0003, 0.0004, 2.0], [-0.0002, -0.0005, 9.0],
        [0.0005, -0.0002, 4.0], [0.0001, 0.0006, 12.0], [-0.0006, -0.0001, 3.0],
    ])
    lla = np.array([[lat0 + a, lon0 + b, h] for a, b, h in offsets])
    ids = [f"L{k}" for k in range(len(lla))]
    r = enu_from_ecef(lat0, lon0)
    here = ecef(*rig)
    enu = np.array([r @ (ecef(*p) - here) for p in lla])
    # rig x = heading direction, y = left of it, z = up.
    h = np.radians(heading_deg)
    x = np.array([np.sin(h), np.cos(h), 0.0])
    z = np.array([0.0, 0.0, 1.0])
    y = np.cross(z, x)
    enu_from_rig = np.column_stack([x, y, z])
    bearings = enu @ enu_from_rig
    bearings /= np.linalg.norm(bearings, axis=1, keepdims=True)
    return (ids, lla, None), bearings, ids
