"""vgps — visual GPS from a spherical camera, from Python.

Position and attitude of a camera rig from bearings to surveyed landmarks, as the ``vgps``
command-line tool computes them (the same Rust library, the same numbers and the same error
messages). Arrays are NumPy ``float64``; batches go in one call. Conventions: WGS84
latitude/longitude in degrees and ellipsoidal height in metres at the edges, ENU inside; rig
frame x forward, y left, z up; pixels ``(u, v) = (column, row)``, an integer is a pixel
centre; attitude ``enu_from_rig`` as a quaternion ``(w, x, y, z)``.

Example::

    >>> import numpy as np, vgps
    >>> points = np.array([[30.0, 0, 5], [-20, 4, 1], [12, 25, -3]])
    >>> poses = vgps.p3p(points - [10.0, -5.0, 2.0], points)   # (k, 3, 4): [R | t]
    >>> bool(min(np.abs(p[:, 3] - [10, -5, 2]).max() for p in poses) < 1e-9)
    True
"""

from __future__ import annotations

import os
# The typing names are for annotations only (not evaluated: `from __future__ import
# annotations`); importing `typing` would be most of the cost of `import vgps`.
TYPE_CHECKING = False
if TYPE_CHECKING:
    from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

from ._vgps import Calibration, Localizer, VgpsError, p3p, triangulate
from ._vgps import _locate, _run_cli

__all__ = [
    "Calibration",
    "Localizer",
    "VgpsError",
    "fleet",
    "locate",
    "p3p",
    "replay",
    "simulate",
    "triangulate",
]


def __getattr__(name: str) -> Any:
    """``vgps.fleet`` is imported on first use: ``import vgps`` stays fast and never imports
    Ray (the optional ``vgps[fleet]`` extra)."""
    if name == "fleet":
        import importlib

        return importlib.import_module(".fleet", __name__)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def locate(
    landmarks: Any,
    bearings: Any = None,
    *,
    ids: Optional[Sequence[Optional[str]]] = None,
    pixels: Any = None,
    camera: Any = None,
    frames: Optional[Sequence[int]] = None,
    calibration: Optional[Calibration] = None,
    prior: Optional[Tuple[float, float, float, float]] = None,
    region: Optional[Tuple[float, float, float, float]] = None,
    sigma_deg: float = 0.1,
    up_tolerance_deg: Optional[float] = None,
) -> List[Dict[str, Any]]:
    """One fix per frame, as ``vgps locate`` computes it (one dict per frame, its JSON line).

    ``landmarks``: a landmarks CSV path (``id,lat,lon,alt[,sigma_m][,class]``) or a tuple
    ``(ids, lat_lon_alt (N, 3), sigma_m (N,) or None)``. Observations: ``bearings`` ``(M, 3)``
    in the rig frame, or ``pixels`` ``(M, 2)`` with ``camera`` (int or ``(M,)``) and a
    ``calibration``. ``ids`` names each row's landmark (``None``: unknown); rows without ids
    are identified by the landmark matcher around ``prior`` or within ``region``, each a
    ``(lat, lon, alt, radius_m)`` tuple. ``frames`` (``(M,)`` ints) splits the rows into
    frames (default: one frame, number 0). Each dict has ``status`` (``ok`` or why not),
    ``lat``, ``lon``, ``alt``, ``enu_from_rig_wxyz``, ``heading_deg``, ``cov_enu_m2``, …
    (``None`` without a fix).

    Raises ``VgpsError`` with the command line's message for bad input (an unknown landmark
    id, pixel rows without a calibration, …), ``ValueError`` for arrays of the wrong shape.

    Example::

        >>> import numpy as np, vgps
        >>> from vgps._examples import square_of_landmarks
        >>> landmarks, bearings, ids = square_of_landmarks()
        >>> fix = vgps.locate(landmarks, bearings, ids=ids)[0]
        >>> fix["status"], round(fix["lat"], 6), round(fix["lon"], 6)
        ('ok', 37.7793, -122.4193)
    """
    return _locate(
        landmarks,
        bearings,
        ids=ids,
        pixels=pixels,
        camera=camera,
        frames=frames,
        calibration=calibration,
        prior=prior,
        region=region,
        sigma_deg=sigma_deg,
        up_tolerance_deg=up_tolerance_deg,
    )


def _cli_options(options: Dict[str, Any]) -> List[str]:
    """``key=value`` keyword arguments as ``--key value`` (``True``: a bare flag)."""
    args: List[str] = []
    for key, value in options.items():
        flag = "--" + key.replace("_", "-")
        if value is None or value is False:
            continue
        if value is True:
            args.append(flag)
        elif isinstance(value, (tuple, list)):
            args += [flag, ",".join(str(v) for v in value)]
        else:
            args += [flag, os.fspath(value) if isinstance(value, os.PathLike) else str(value)]
    return args


def replay(
    drive: Union[str, "os.PathLike[str]"],
    out: Union[str, "os.PathLike[str]", None] = None,
    **options: Any,
) -> Dict[str, Any]:
    """Replays a logged drive as ``vgps replay DRIVE --out OUT`` does, with the GIL released.

    Writes every output of the command (``fixes.csv``, ``report.json``, ``report.html``,
    tracks, NMEA) under ``out`` (default ``DRIVE/replay``) and returns ``report.json`` as a
    dict. Other options are the command's, by name: ``replay(d, o, from_images=True,
    threads=2, no_gnss_prior=True)`` is ``--from-images --threads 2 --no-gnss-prior``.

    Raises ``VgpsError`` with the command's message (a missing or corrupt drive, …).

    Example::

        >>> import tempfile, os, vgps
        >>> d = tempfile.mkdtemp()
        >>> _ = vgps.simulate(os.path.join(d, "drive"), preset="short", length_m=60)
        >>> report = vgps.replay(os.path.join(d, "drive"), os.path.join(d, "out"))
        >>> report["frames"] > 0
        True
    """
    import json  # here, not at the top: `import vgps` stays fast (issue #29: <= 50 ms)

    out_dir = os.fspath(out) if out is not None else os.path.join(os.fspath(drive), "replay")
    _run_cli(["replay", os.fspath(drive), "--out", out_dir, "--quiet"]
             + _cli_options(options))
    with open(os.path.join(out_dir, "report.json"), encoding="utf-8") as f:
        return json.load(f)


def simulate(out: Union[str, "os.PathLike[str]"], **options: Any) -> str:
    """Simulates a drive into the folder ``out`` as ``vgps simulate --out OUT`` does, with the
    GIL released, and returns the command's one-line summary.

    Options are the command's, by name: ``seed=1``, ``preset="short"``, ``length_m=150``,
    ``images=True``, ``origin=(lat, lon)``, ``calibration=path``, ``threads=2``.

    Example::

        >>> import tempfile, os, vgps
        >>> d = os.path.join(tempfile.mkdtemp(), "drive")
        >>> summary = vgps.simulate(d, preset="short", length_m=60, seed=3)
        >>> os.path.exists(os.path.join(d, "drive.json"))
        True
    """
    options.setdefault("quiet", True)
    return _run_cli(["simulate", "--out", os.fspath(out)] + _cli_options(options))
