"""slitcli: obstacle detection with a stereo camera and a red laser slit, and a modified DWA.

The library in a few names (docs/api.md), imported on first use so that ``import
slitcli`` stays cheap:

>>> import slitcli
>>> rig = slitcli.load_rig("sample_data/sequences/corridor/rig.yaml")   # or paper_rig()
>>> detector = slitcli.Detector(rig)
>>> for frame in slitcli.open_frames("sample_data/sequences/corridor").frames(rig):
...     ranges = detector(frame.left_bgr, frame.right_bgr).ranges
...     print(frame.index, ranges.fused_range_m[ranges.bearing_deg == 0])  # doctest: +SKIP

``Detector`` (one stereo pair -> :class:`RangeTable`), ``DetectParams``,
``load_rig`` / ``paper_rig`` / ``Rig``, ``open_frames`` (a sequence folder or a ROS
bag), ``RangeTable`` and ``BearingBins`` (the range table and its bins),
``run_detect`` (a whole sequence to ``ranges.csv``) and ``SlitcliError`` (bad input).

Coordinate conventions (stated once, used everywhere)
-----------------------------------------------------
Camera frame
    x right, y down, z along the optical axis (OpenCV). Metres.
Sensor frame
    x forward, y left, z up; the floor is z = 0 and the origin lies on the floor
    directly below the left camera's optical centre. Ranges, bearings and range
    tables are in this frame. Bearing is positive to the left (counter-clockwise
    seen from above). The robot's rotation centre is ``mount.forward_m`` behind
    the origin.
Pixels
    (u, v): u to the right, v down, pixel centres at integer coordinates;
    (cx, cy) is the principal point.
World frame (simulation only)
    x, y on the floor, z up. A robot pose (x, y, yaw) locates the rotation centre.
"""

__version__ = "0.2.0"

import importlib as _importlib
from typing import Any as _Any

_API = {
    "BearingBins": "slitcli.ranges", "RangeTable": "slitcli.ranges",
    "Detector": "slitcli.detect", "DetectParams": "slitcli.detect",
    "FrameDetection": "slitcli.detect", "run_detect": "slitcli.detect",
    "FrameSource": "slitcli.io.frames", "open_frames": "slitcli.io.frames",
    "Rig": "slitcli.rig", "load_rig": "slitcli.rig", "paper_rig": "slitcli.rig",
    "SlitcliError": "slitcli.errors",
}


def __getattr__(name: str) -> _Any:
    where = _API.get(name)
    if where is None:
        raise AttributeError(f"module 'slitcli' has no attribute {name!r}")
    value = getattr(_importlib.import_module(where), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted([*_API, "__version__"])


__all__ = sorted(_API)
