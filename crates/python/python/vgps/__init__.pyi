from os import PathLike
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

import numpy.typing as npt

from . import fleet as fleet
from ._vgps import Calibration as Calibration
from ._vgps import Localizer as Localizer
from ._vgps import VgpsError as VgpsError
from ._vgps import p3p as p3p
from ._vgps import triangulate as triangulate

def locate(
    landmarks: Union[str, "PathLike[str]", Tuple[Sequence[str], npt.ArrayLike, Optional[npt.ArrayLike]]],
    bearings: Optional[npt.ArrayLike] = None,
    *,
    ids: Optional[Sequence[Optional[str]]] = None,
    pixels: Optional[npt.ArrayLike] = None,
    camera: Union[int, Sequence[int], None] = None,
    frames: Optional[Sequence[int]] = None,
    calibration: Optional[Calibration] = None,
    prior: Optional[Tuple[float, float, float, float]] = None,
    region: Optional[Tuple[float, float, float, float]] = None,
    sigma_deg: float = 0.1,
    up_tolerance_deg: Optional[float] = None,
) -> List[Dict[str, Any]]: ...
def replay(drive: Union[str, "PathLike[str]"], out: Union[str, "PathLike[str]", None] = None, **options: Any) -> Dict[str, Any]: ...
def simulate(out: Union[str, "PathLike[str]"], **options: Any) -> str: ...
