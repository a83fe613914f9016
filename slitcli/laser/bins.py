"""Nearest laser range per bearing bin (DESIGN §6): a frame's points reduced to the
per-bearing range table that fusion uses."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from slitcli.ranges import BearingBins, absolute_bin, bin_count, bin_min, boundary_deg
from slitcli.rig import Rig

if TYPE_CHECKING:
    from slitcli.laser.edges import LaserEdges
    from slitcli.laser.frame import LaserFrame


def bearing_bin_centres_deg(rig: Rig, bin_deg: float = 1.0) -> np.ndarray:
    """Bearing bin centres of the range tables (:class:`slitcli.ranges.BearingBins`),
    ascending (right to left), degrees."""
    return BearingBins.for_rig(rig, bin_deg).centres_deg


@dataclass(frozen=True)
class LaserBins:
    """Nearest laser range per bearing bin (shape (B,) each).

    ``bearing_deg`` are the bin centres, ``range_m`` the nearest laser point in
    the bin (NaN: no return), ``in_band`` whether that range lies in the rig's
    laser band, ``count`` the number of stripe columns in the bin.
    """

    bearing_deg: np.ndarray
    range_m: np.ndarray
    in_band: np.ndarray
    count: np.ndarray


def nearest_range_per_bin(frame: LaserFrame, rig: Rig, *, bin_deg: float = 1.0,
                          in_band_only: bool = False,
                          edges: LaserEdges | None = None,
                          boundary_jump_m: float | None = 0.05) -> LaserBins:
    """Reduce a frame's laser points to the nearest range per bearing bin.

    A bin's truth is the nearest point of the lit outline anywhere in its wedge, and on
    a surface seen obliquely that lies on the wedge's boundary, up to half a column
    from the nearest column's centre. So where two neighbouring stripe columns of one
    surface (ranges within ``boundary_jump_m``) straddle bin boundaries, the range is
    interpolated linearly in bearing at each boundary, and that point counts in the
    bins on both sides. On a convex surface the interpolated chord lies behind the
    surface, so the point is never nearer than the outline.

    Parameters
    ----------
    frame : LaserFrame
    rig : Rig
    bin_deg : float
        Bin width, degrees; bin ``c`` holds bearings in ``[c - bin/2, c + bin/2)``.
    in_band_only : bool
        Ignore points outside the rig's laser band.
    edges : LaserEdges, optional
        Sub-pixel segment edges (:func:`segment_edges`); each counts as one more point
        in the bin its bearing falls in, so a lit surface whose edge crosses a bin
        boundary between two columns ranges that bin too. ``count`` stays the number
        of stripe columns.
    boundary_jump_m : float or None
        Largest range step between neighbouring columns of one surface, metres; None
        turns the boundary interpolation off.

    Returns
    -------
    LaserBins
    """
    bins = BearingBins.for_rig(rig, bin_deg)
    use = np.isfinite(frame.range_m) & np.isfinite(frame.bearing_deg)
    if in_band_only:
        use &= frame.in_band
    idx = bins.index(frame.bearing_deg[use])
    rng_parts, idx_parts = [frame.range_m[use]], [idx]
    count = bin_count(idx, len(bins))
    if boundary_jump_m is not None:
        b_rng, b_lo, _ = bin_boundary_points(frame.range_m, frame.bearing_deg, use, bin_deg,
                                             boundary_jump_m)
        # a boundary point counts in the bins on both of its sides
        rng_parts += [b_rng, b_rng]
        idx_parts += [bins.table_bin(b_lo), bins.table_bin(b_lo + 1)]
    if edges is not None and edges.range_m.size:
        rng_parts.append(edges.range_m)
        idx_parts.append(bins.index(edges.bearing_deg))
    rng = bin_min(np.concatenate(idx_parts), np.concatenate(rng_parts), len(bins))
    centres = bins.centres_deg
    with np.errstate(invalid="ignore"):
        band = (rng >= rig.laser.min_range_m) & (rng <= rig.laser.max_range_m)
    return LaserBins(bearing_deg=centres, range_m=rng, in_band=band, count=count)


def bin_boundary_points(range_m: np.ndarray, bearing_deg: np.ndarray, use: np.ndarray,
                        bin_deg: float, jump_m: float, *,
                        adjacent: np.ndarray | None = None
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Ranges interpolated at the bin boundaries crossed between neighbouring columns.

    Parameters
    ----------
    range_m, bearing_deg : ndarray, shape (N,)
        Lit points in column order (metres, degrees).
    use : ndarray of bool, shape (N,)
        Points that may be used.
    bin_deg, jump_m : float
        Bin width (degrees) and the largest range step between two columns of one
        surface (metres).
    adjacent : ndarray of bool, shape (N - 1,), optional
        Whether points i and i + 1 are neighbouring columns of one image (default: all).

    Returns
    -------
    range_m : ndarray, shape (K,)
        Interpolated ranges, metres.
    lower_bin : ndarray of int, shape (K,)
        Absolute index ``k`` of the bin below each boundary (the boundary lies at
        bearing ``(k + 0.5) * bin_deg``); the point belongs to bins ``k`` and ``k + 1``.
    first_point : ndarray of int, shape (K,)
        Index of the point before each boundary (the pair is ``i``, ``i + 1``).
    """
    r, b = range_m, bearing_deg
    with np.errstate(invalid="ignore"):
        pair = use[:-1] & use[1:] & (np.abs(np.diff(r)) <= jump_m)
    if adjacent is not None:
        pair &= adjacent
    i = np.flatnonzero(pair)
    k_a = absolute_bin(b[i], bin_deg)
    k_b = absolute_bin(b[i + 1], bin_deg)
    lo = np.minimum(k_a, k_b)
    n = np.abs(k_b - k_a)  # boundaries crossed: more than one when bins are narrower
    pair_of = np.repeat(np.arange(i.size), n)
    k = lo[pair_of] + (np.arange(pair_of.size) - np.repeat(np.cumsum(n) - n, n))
    j = i[pair_of]
    t = (boundary_deg(k, bin_deg) - b[j]) / (b[j + 1] - b[j])
    return r[j] + t * (r[j + 1] - r[j]), k, j
