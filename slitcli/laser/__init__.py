"""Laser slit: stripe extraction (paper Eqs. 1-4) and triangulation (Eqs. 5-7, DESIGN §4).

Per-frame API for fusion and the simulator: :func:`detect_laser` (image -> per-column
stripe rows and sensor-frame points) and :func:`nearest_range_per_bin` (points ->
nearest range per bearing bin). The ``slitcli laser`` command is :func:`run_laser`.
"""

from slitcli.laser import candidates, choose, evidence, paper, profile
from slitcli.laser.batch import TABLE_COLUMNS, laser_table, run_laser
from slitcli.laser.diagnose import StripeAbsence, is_grey, stripe_absence
from slitcli.laser.extract import StripeColumns, chromaticity, extract_stripe
from slitcli.laser.frame import (
    LaserBins,
    LaserFrame,
    LaserGeometry,
    bearing_bin_centres_deg,
    bin_boundary_points,
    detect_laser,
    laser_sight_range_m,
    nearest_range_per_bin,
    triangulate_stripe,
)
from slitcli.laser.overlay import draw_overlay
from slitcli.laser.params import LaserParams

__all__ = [
    "TABLE_COLUMNS",
    "LaserBins",
    "LaserFrame",
    "LaserGeometry",
    "LaserParams",
    "StripeAbsence",
    "StripeColumns",
    "bearing_bin_centres_deg",
    "bin_boundary_points",
    "candidates",
    "choose",
    "chromaticity",
    "detect_laser",
    "draw_overlay",
    "evidence",
    "extract_stripe",
    "is_grey",
    "laser_sight_range_m",
    "laser_table",
    "nearest_range_per_bin",
    "paper",
    "profile",
    "run_laser",
    "stripe_absence",
    "triangulate_stripe",
]
