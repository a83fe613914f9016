"""Laser slit: stripe extraction (paper Eqs. 1-4) and triangulation (Eqs. 5-7, DESIGN §4)."""

from slitcli.laser.extract import StripeColumns, chromaticity, extract_stripe
from slitcli.laser.params import LaserParams

__all__ = ["LaserParams", "StripeColumns", "chromaticity", "extract_stripe"]
