"""Laser slit: stripe extraction (paper Eqs. 1-4) and triangulation (Eqs. 5-7, DESIGN §4).

Per-frame API for fusion and the simulator: :func:`detect_laser` (image -> per-column
stripe rows and sensor-frame points) and :func:`nearest_range_per_bin` (points ->
nearest range per bearing bin). The ``slitcli laser`` command is :func:`run_laser`.

Names are imported on first use (the compiled kernels and their modules), so importing
``slitcli.laser.params`` for the command line's defaults stays cheap.
"""

from __future__ import annotations

import importlib
from typing import Any

_WHERE = {
    "TABLE_COLUMNS": "batch", "laser_table": "batch", "run_laser": "batch",
    "StripeColumns": "extract", "chromaticity": "extract", "extract_stripe": "extract",
    "StripeAbsence": "diagnose", "absence_notes": "diagnose", "is_grey": "diagnose",
    "stripe_absence": "diagnose",
    "LaserBins": "bins", "LaserFrame": "frame", "LaserGeometry": "geometry",
    "bearing_bin_centres_deg": "bins", "bin_boundary_points": "bins",
    "detect_laser": "frame", "laser_sight_range_m": "geometry",
    "nearest_range_per_bin": "bins", "triangulate_stripe": "geometry",
    "draw_overlay": "overlay", "LaserParams": "params",
}
_SUBMODULES = ("candidates", "choose", "evidence", "judge", "paper", "profile")


def __getattr__(name: str) -> Any:
    if name in _SUBMODULES:
        return importlib.import_module(f"slitcli.laser.{name}")
    where = _WHERE.get(name)
    if where is None:
        raise AttributeError(f"module 'slitcli.laser' has no attribute {name!r}")
    value = getattr(importlib.import_module(f"slitcli.laser.{where}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted([*_WHERE, *_SUBMODULES])


__all__ = sorted([*_WHERE, *_SUBMODULES])
