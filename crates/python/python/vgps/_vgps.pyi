"""Type stubs of the native module ``vgps._vgps`` (see ``vgps/__init__.py`` for the docs)."""

from os import PathLike
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

_Path = Union[str, "PathLike[str]"]
_F64 = npt.NDArray[np.float64]
_Cameras = Union[int, Sequence[int], npt.NDArray[np.integer[Any]], None]
_Landmarks = Union[_Path, Tuple[Sequence[str], npt.ArrayLike, Optional[npt.ArrayLike]]]

class VgpsError(ValueError):
    """An error of the vgps library, with the library's (the command line's) message."""

def p3p(bearings: npt.ArrayLike, points: npt.ArrayLike) -> Union[_F64, List[_F64]]:
    """P3P: ``(3, 3)`` bearings and points -> ``(k, 3, 4)`` poses ``world_from_rig = [R | t]``,
    k <= 4; ``(N, 3, 3)`` -> a list of N such arrays."""

def triangulate(
    origins: npt.ArrayLike,
    directions: npt.ArrayLike,
    sigma_pos_m: Optional[npt.ArrayLike] = None,
    sigma_rad: Optional[npt.ArrayLike] = None,
) -> Dict[str, Any]:
    """Least-squares intersection of ``(N, 3)`` rays: ``point``, ``covariance``, ``n_obs``,
    ``max_parallax_rad``."""

class Calibration:
    """A rig calibration (N cameras)."""
    @staticmethod
    def load(path: _Path, image_size: Optional[Tuple[int, int]] = None) -> "Calibration": ...
    def __len__(self) -> int: ...
    @property
    def image_sizes(self) -> List[Tuple[int, int]]: ...
    def pixel_to_bearing(self, pixels: npt.ArrayLike, camera: _Cameras = None) -> _F64:
        """``(N, 2)`` pixels -> ``(N, 3)`` unit bearings in the rig frame."""
    def bearing_to_pixel(
        self, bearings: npt.ArrayLike, camera: _Cameras = None
    ) -> Union[
        Tuple[_F64, npt.NDArray[np.bool_]],
        Tuple[_F64, npt.NDArray[np.bool_], npt.NDArray[np.int64]],
    ]:
        """``(N, 3)`` bearings -> ``(N, 2)`` pixels and a visibility mask (and, with
        ``camera=None``, the camera of each row, -1 for none)."""

class Localizer:
    """The frame-by-frame localizer for a robot loop."""
    def __init__(
        self,
        calibration: Calibration,
        landmarks: _Landmarks,
        *,
        pixel_sigma_px: Optional[float] = None,
        cold_start: bool = True,
        surrogates: bool = True,
        level_tolerance_deg: Optional[float] = 5.0,
        gnss_prior_radius_m: Optional[float] = None,
        max_turn_rate_change_deg_s: Optional[float] = None,
    ) -> None: ...
    def process(
        self,
        time_s: float,
        *,
        pixels: Optional[npt.ArrayLike] = None,
        camera: _Cameras = None,
        bearings: Optional[npt.ArrayLike] = None,
        sigma_rad: Optional[float] = None,
        gnss: Optional[Tuple[float, float, float]] = None,
        classes: Optional[Sequence[Optional[str]]] = None,
        backward: bool = False,
    ) -> Dict[str, Any]:
        """One frame in; ``status``, ``lat_lon_alt``, ``position_enu``, ``enu_from_rig_wxyz``,
        ``heading_pitch_roll_deg``, ``covariance`` (6x6), ``landmarks``, … out.
        ``backward=True``: frames given in decreasing time (one localizer per direction)."""
    def reset(self) -> None: ...
    @property
    def origin(self) -> Tuple[float, float, float]: ...

def _locate(landmarks: _Landmarks, bearings: Optional[npt.ArrayLike] = None, **kwargs: Any) -> List[Dict[str, Any]]: ...
def _run_cli(args: List[str]) -> str: ...
