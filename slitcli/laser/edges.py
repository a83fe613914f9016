"""Ends of the lit segments of a frame, to a fraction of a column (DESIGN §6).

A pixel integrates the light over its width, so a column at the end of a lit segment
shows the stripe at the share of its width that sees the surface
(:func:`covered_shift_px`), and a curved surface turning away from the emitter fades
towards its limb (:func:`edge_reach_px`); :func:`segment_edges` turns both into points
at the segments' edges.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from slitcli.laser._c.geometry import covered_shift
from slitcli.laser.geometry import triangulate_stripe
from slitcli.ranges import median_of_finite
from slitcli.rig import Rig

if TYPE_CHECKING:
    from slitcli.laser.frame import LaserFrame


@dataclass(frozen=True)
class EdgeParams:
    """How the ends of lit segments are located to a fraction of a column.

    Attributes
    ----------
    jump_m : float
        Neighbouring columns whose ranges differ by more than this belong to different
        surfaces (an occlusion boundary), metres.
    fade_ratio : float
        The stripe fades towards an end (a curved surface turning away from the
        emitter) when the strength of the column next to the end column is below this
        share of the strength three columns in from the end.
    max_reach_px : float
        A fading end is extrapolated at most this far past the end column's centre,
        pixels: beyond the next column's centre nothing was measured.
    min_inner_cols : int
        Columns of the segment needed inside the end column for an estimate.
    coverage_z : float
        An end column's coverage (:func:`covered_shift_px`) is taken this many standard
        errors below its measured value, so that the point stays on the surface.
    """

    jump_m: float = 0.05
    fade_ratio: float = 0.8
    max_reach_px: float = 1.0
    min_inner_cols: int = 3
    coverage_z: float = 2.0


@dataclass(frozen=True)
class LaserEdges:
    """Sub-pixel ends of the lit segments of one frame (shape (E,) each).

    ``u_px`` is the end column, ``direction`` +1 when the segment ends towards larger
    ``u`` (to the right in the image), -1 towards smaller; ``reach_px`` is how far past
    the end column's centre the lit surface is estimated to end (pixels, outward),
    ``fading`` whether the fading-stripe model gave it (else partial coverage);
    ``range_m`` and ``bearing_deg`` are the sensor-frame point at that edge.
    Only ends whose edge lies outward of the end column's centre are listed.
    """

    u_px: np.ndarray
    direction: np.ndarray
    reach_px: np.ndarray
    fading: np.ndarray
    range_m: np.ndarray
    bearing_deg: np.ndarray


def edge_reach_px(strength_dn: np.ndarray, saturated: np.ndarray,
                  params: EdgeParams | None = None) -> tuple[np.ndarray, np.ndarray]:
    """How far past the end column's centre a lit surface ends, from stripe strengths.

    Two models of the stripe's peak brightness ``s`` along a segment (the sheet light
    is Lambertian, ``s`` proportional to the cosine of incidence at the emitter and to
    the share of the pixel the surface covers; ``s`` is the extractor's red peak above
    the surface, Eqs. 1-4):

    * **partial coverage** (a face that ends inside the end column): the inner columns
      are fully covered, the end column by the share ``c = s_0 / median(s_1, s_2,
      s_3)``; the surface ends ``c - 1/2`` pixels past the end column's centre (0 = the
      centre, 1/2 = its outer border). Clipped to ``[-1/2, 1/2]``: a column as bright
      as the inner ones is covered, and an unseen next column says only that its share
      is below detection.
    * **fading** (a curved surface turning away, e.g. a cylinder's limb): near the
      limb the cosine of incidence goes as the square root of the distance to it, so
      ``s**2`` falls linearly; the straight-line fit of ``s**2`` over the last three
      columns reaches zero ``a / -b`` pixels past the end column (``a`` its value
      there, ``b`` its slope), at most ``max_reach_px``. Chosen when the inner columns
      fade (``s_1 < fade_ratio * s_3``), which a face with constant incidence does not.

    A clipped (saturated) end column carries no coverage information: reach 0. Clipped
    inner columns are left out of the coverage reference, and the fading model needs
    the end column and the two next to it unclipped (a clipped third column only takes
    part in the trend test, where an underestimate makes the test stricter).

    Parameters
    ----------
    strength_dn : ndarray, shape (E, K), K >= 4
        Per end, the strengths of the end column (``[:, 0]``) and of the columns 1, 2,
        3, ... inward (NaN where the segment is shorter).
    saturated : ndarray of bool, shape (E, K)
    params : EdgeParams, optional

    Returns
    -------
    reach_px : ndarray, shape (E,)
        Pixels past the end column's centre, outward (negative: inside it); NaN where
        no estimate is possible (fewer than ``min_inner_cols`` inner columns).
    fading : ndarray of bool, shape (E,)
        The fading model gave the estimate.
    """
    p = EdgeParams() if params is None else params
    s = np.asarray(strength_dn, dtype=float)
    sat = np.asarray(saturated, dtype=bool)
    s0, s1, s2, s3 = s[:, 0], s[:, 1], s[:, 2], s[:, 3]
    enough = np.isfinite(s[:, 1:p.min_inner_cols + 1]).all(axis=1)
    inner = np.where(sat[:, 1:4] | ~np.isfinite(s[:, 1:4]), np.nan, s[:, 1:4])
    ref = median_of_finite(inner, axis=1)
    has_ref = np.isfinite(ref)
    with np.errstate(invalid="ignore", divide="ignore"):
        cover = np.clip(s0 / ref, 0.0, 1.0) - 0.5
        # least-squares line through s**2 at t = -2, -1, 0 (t outward from the end)
        q0, q1, q2 = s0 * s0, s1 * s1, s2 * s2
        slope = (q0 - q2) / 2.0
        at_end = (q0 + q1 + q2) / 3.0 + slope
        fade_reach = np.minimum(at_end / -slope, p.max_reach_px)
        fading = ((s1 < p.fade_ratio * s3) & (slope < 0)
                  & ~sat[:, :3].any(axis=1) & np.isfinite(s3))
    reach = np.where(fading, fade_reach, cover)
    reach = np.where(sat[:, 0], 0.0, reach)
    ok = enough & (has_ref | fading)
    return np.where(ok, reach, np.nan), fading & ok


def segment_edges(frame: LaserFrame, rig: Rig, params: EdgeParams | None = None) -> LaserEdges:
    """Where the lit segments of a frame end, to a fraction of a column (DESIGN §6).

    A segment is a run of stripe columns whose ranges step by at most ``jump_m``. Its
    end is a column whose outward neighbour has no stripe, or a farther one (the near
    side of an occlusion boundary); the far side of a jump is not an edge of an
    obstacle in front of it. Only ends in the laser's band are used (beyond it the
    stripe has faded and its strength says little). The reach past the end column
    (:func:`edge_reach_px`) is turned into a point by moving along the segment's row
    (extrapolated from the neighbouring column) and intersecting that pixel's ray with
    the laser plane, so the point's bearing is the edge's and its range the surface's
    there.

    Parameters
    ----------
    frame : LaserFrame
    rig : Rig
    params : EdgeParams, optional

    Returns
    -------
    LaserEdges
    """
    p = EdgeParams() if params is None else params
    r, s = frame.range_m, frame.strength_dn
    w = r.size
    found = np.isfinite(r) & np.isfinite(s)
    with np.errstate(invalid="ignore"):
        link = found[:-1] & found[1:] & (np.abs(np.diff(r)) <= p.jump_m)
        farther_right = ~found[1:] | (r[1:] > r[:-1])
        farther_left = ~found[:-1] | (r[:-1] > r[1:])
    starts = np.r_[True, ~link]
    seg = np.cumsum(starts) - 1
    first = np.flatnonzero(starts)
    last = np.r_[first[1:] - 1, w - 1]
    band = found & frame.in_band
    right = np.flatnonzero(np.r_[band[:-1] & ~link & farther_right, False])
    left = np.flatnonzero(np.r_[False, band[1:] & ~link & farther_left])
    ends = np.r_[right, left]
    d = np.r_[np.ones(right.size, np.int64), -np.ones(left.size, np.int64)]
    inward = np.where(d > 0, ends - first[seg[ends]], last[seg[ends]] - ends)
    k = np.arange(max(4, p.min_inner_cols + 1))
    cols = ends[:, None] - d[:, None] * k[None, :]
    inside = k[None, :] <= inward[:, None]
    cols_c = np.clip(cols, 0, w - 1)
    strength = np.where(inside, s[cols_c], np.nan)
    sat = inside & frame.saturated[cols_c]
    reach, fading = edge_reach_px(strength, sat, p)
    keep = reach > 0
    ends, d, reach, fading = ends[keep], d[keep], reach[keep], fading[keep]
    v = frame.v_px
    # the row moves on along the segment as it did between the last two columns
    dv = v[ends] - v[np.clip(ends - d, 0, w - 1)]
    u_e = ends + d * reach
    v_e = v[ends] + dv * reach
    _, _, rng, bearing = triangulate_stripe(rig, u_e, v_e)
    return LaserEdges(u_px=ends.astype(np.float64), direction=d, reach_px=reach,
                      fading=fading, range_m=rng, bearing_deg=bearing)


def covered_shift_px(range_m: np.ndarray, strength_dn: np.ndarray, noise_sigma_dn: float,
                     params: EdgeParams) -> np.ndarray:
    """Shift of each stripe column's ray to the centre of the part of its pixel that sees
    the lit surface, pixels (positive: towards higher ``u``).

    A pixel integrates the light over its width, so a column that sees a surface over a
    share ``f`` of its width shows the stripe at ``f`` times the strength of the
    surface's full columns beside it; the seen part's centre lies ``(1 - f) / 2`` pixel
    inwards (away from the edge) of the pixel centre. That matters at the near end of a
    lit segment: its outward neighbour is unlit or farther (more than ``jump_m``), and
    the pixel centre may lie beyond the surface's edge, so the point would range a
    bearing where the surface is not. ``f`` is the end column's strength over the
    strongest of the three columns inward on the same surface (ranges within
    ``jump_m``), taken ``coverage_z`` standard errors low (noise ``noise_sigma_dn``),
    so the shifted ray stays on the surface; an end with no such column inward keeps
    its centre from that side.

    Parameters
    ----------
    range_m, strength_dn : ndarray, shape (W,)
        Triangulated range and fitted stripe strength of each column (NaN: no stripe).
    noise_sigma_dn : float
        Noise of the laser evidence, DN.
    params : EdgeParams

    Returns
    -------
    ndarray, shape (W,)
        Signed shift, pixels, in ``[-0.5, 0.5]``; 0 inside segments.
    """
    r = np.ascontiguousarray(range_m, dtype=np.float64)
    s = np.ascontiguousarray(strength_dn, dtype=np.float64)
    shift = np.zeros(r.size)
    if r.size < 2:
        return shift
    # (compiled, column by column: numpy's padded arrays and masks cost ~0.3 ms a frame)
    covered_shift(r, s, float(noise_sigma_dn), params.jump_m, params.coverage_z, shift)
    return shift
