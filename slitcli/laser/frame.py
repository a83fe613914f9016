"""Per-frame laser API: extraction plus triangulation (paper Eqs. 5-7 via DESIGN §4).

:func:`detect_laser` is what fusion (``detect``) and the closed-loop simulator
call for every frame; :func:`nearest_range_per_bin` reduces its points to the
per-bearing range table of DESIGN §6.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from slitcli.laser.diagnose import is_grey
from slitcli.laser.extract import extract_stripe
from slitcli.laser.params import LaserParams
from slitcli.ranges import BearingBins, absolute_bin, bin_count, bin_min, boundary_deg
from slitcli.rig import Rig


@dataclass(frozen=True)
class LaserGeometry:
    """What the extractor needs from a rig, computed once per rig and parameter set.

    Attributes
    ----------
    search_mask : ndarray, shape (H, W) bool
        Pixels whose ray meets the laser plane in front of the camera at a
        horizontal range (sensor frame) of at most ``max_search_range_m``; every pixel
        with ``search="full"``.
    px_per_m : ndarray, shape (H, W) float
        Image rows per metre of height on an upright surface at the point where each
        pixel's ray meets the laser plane (the scale of the sheet's thickness in the
        image); NaN where the ray misses the plane or lies beyond
        ``max_search_range_m``.
    ray_x : ndarray, shape (W,)
        ``(u - cx) / fx`` of every column: the x of its rays ``K^-1 (u, v, 1)``.
    ray_y_coeffs : ndarray, shape (2,)
        ``(1 / fy, -cy / fy)``: the ray's y is ``v / fy - cy / fy``.
    plane_cam : ndarray, shape (4,)
        The laser plane in the camera frame: unit normal and offset (m).
    sensor_from_cam : ndarray, shape (3, 4)
        Rotation and translation (m) from the camera to the sensor frame.

    The last four make :func:`triangulate_stripe`'s ray/plane intersection one
    compiled pass over the found columns (:func:`_triangulate`), the same arithmetic.
    """

    search_mask: np.ndarray
    px_per_m: np.ndarray
    ray_x: np.ndarray
    ray_y_coeffs: np.ndarray
    plane_cam: np.ndarray
    sensor_from_cam: np.ndarray

    @classmethod
    def from_rig(cls, rig: Rig, params: LaserParams) -> LaserGeometry:
        """Build the geometry of ``rig`` for ``params.max_search_range_m``."""
        h, w = rig.height_px, rig.width_px
        v, u = np.mgrid[0:h, 0:w]
        pts = rig.cam_to_sensor(rig.intersect_laser_plane(rig.pixel_rays_cam(u, v)))
        rng = np.hypot(pts[..., 0], pts[..., 1])
        with np.errstate(invalid="ignore"):
            in_range = np.isfinite(rng) & (rng <= params.max_search_range_m)
        mask = np.ones((h, w), bool) if params.search == "full" else in_range
        # rows of the points 1 mm above and below on the vertical through each point
        step = np.array([0.0, 0.0, 1e-3])
        _, v_up = rig.project_cam(rig.sensor_to_cam(pts + step))
        _, v_dn = rig.project_cam(rig.sensor_to_cam(pts - step))
        with np.errstate(invalid="ignore"):
            px_per_m = np.abs(v_dn - v_up) / 2e-3
        # Fortran order: the extractor walks image columns, and the transposes of
        # these are contiguous
        cam = rig.left
        return cls(search_mask=np.asfortranarray(mask),
                   px_per_m=np.asfortranarray(np.where(in_range, px_per_m, np.nan)),
                   ray_x=(np.arange(w, dtype=np.float64) - cam.cx_px) / cam.fx_px,
                   ray_y_coeffs=np.array([1.0 / cam.fy_px, -cam.cy_px / cam.fy_px]),
                   plane_cam=np.append(rig.laser.unit_normal, rig.laser.unit_offset_m),
                   sensor_from_cam=np.column_stack([rig.R_sensor_from_cam,
                                                    rig.cam_origin_sensor_xyz]))


@dataclass(frozen=True)
class LaserFrame:
    """The laser stripe of one frame, per image column, with its triangulated points.

    All arrays have shape (W,) (one entry per image column ``u_px = 0..W-1``);
    columns without a stripe hold NaN (``in_band`` and ``saturated`` False).
    Points are in the sensor frame (x forward, y left, metres; bearing positive
    to the left, degrees).

    Attributes
    ----------
    u_px, v_px : column and sub-pixel stripe row, pixels.
    strength_dn : the stripe's peak brightness in the red channel (light it adds above the
        surface, texture cancelled, pixel blur undone where the rig geometry is known), DN.
    saturated : the stripe core is clipped.
    x_m, y_m : sensor-frame position of the lit point, metres.
    range_m : horizontal distance ``hypot(x, y)`` from the point below the left camera.
    bearing_deg : ``atan2(y, x)`` in degrees.
    in_band : the range lies in the rig's trusted laser band
        ``[laser.min_range_m, laser.max_range_m]``.
    noise_sigma_dn, threshold_dn : noise of the laser evidence measured on the image and
        the seed level used, DN.
    grey_image : the image is grey (red, green and blue equal): it cannot carry a red
        stripe (:func:`slitcli.laser.diagnose.stripe_absence`).
    """

    u_px: np.ndarray
    v_px: np.ndarray
    strength_dn: np.ndarray
    saturated: np.ndarray
    x_m: np.ndarray
    y_m: np.ndarray
    range_m: np.ndarray
    bearing_deg: np.ndarray
    in_band: np.ndarray
    noise_sigma_dn: float
    threshold_dn: float
    grey_image: bool = False

    @property
    def found(self) -> np.ndarray:
        """Columns with a stripe (bool, shape (W,))."""
        return np.isfinite(self.v_px)


def triangulate_stripe(rig: Rig, u_px: np.ndarray, v_px: np.ndarray) -> tuple[np.ndarray, ...]:
    """Sensor-frame points of stripe pixels by exact ray/laser-plane intersection.

    Replaces the paper's Eqs. 5-7 (valid only for an untilted camera) with
    DESIGN §4: ``X = d / (n . r) r`` for the ray ``r = K^-1 (u, v, 1)``, then the
    camera-to-sensor transform of the rig.

    Parameters
    ----------
    rig : Rig
    u_px, v_px : array_like, same shape
        Pixel coordinates of stripe points (NaN allowed).

    Returns
    -------
    x_m, y_m, range_m, bearing_deg : ndarray, same shape as the inputs
        Sensor frame forward and left coordinates, horizontal range and bearing
        (positive left); NaN where the ray misses the plane or the input is NaN.
    """
    pts = rig.cam_to_sensor(rig.intersect_laser_plane(rig.pixel_rays_cam(u_px, v_px)))
    x, y = pts[..., 0], pts[..., 1]
    return x, y, np.hypot(x, y), np.degrees(np.arctan2(y, x))


@njit(cache=True, nogil=True)
def _triangulate(v_px: np.ndarray, ray_x: np.ndarray, ray_y: np.ndarray, plane: np.ndarray,
                 sensor_from_cam: np.ndarray, min_range_m: float, max_range_m: float,
                 out: np.ndarray, in_band: np.ndarray) -> None:  # pragma: no cover
    """:func:`triangulate_stripe` for one frame's rows ``v_px`` (W,), column by column:
    ``out`` (4, W) gets x_m, y_m, range_m, bearing_deg (NaN where the row is NaN or the
    ray misses the plane), ``in_band`` whether the range lies in ``[min_range_m,
    max_range_m]``. Geometry as :class:`LaserGeometry`."""
    for u in range(v_px.shape[0]):
        out[:, u] = np.nan
        in_band[u] = False
        v = v_px[u]
        if not np.isfinite(v):
            continue
        rx = ray_x[u]
        ry = v * ray_y[0] + ray_y[1]
        den = plane[0] * rx + plane[1] * ry + plane[2]
        if abs(den) <= 1e-12:
            continue
        s = plane[3] / den
        if not s > 0.0:
            continue
        cx, cy, cz = s * rx, s * ry, s
        m = sensor_from_cam
        x = m[0, 0] * cx + m[0, 1] * cy + m[0, 2] * cz + m[0, 3]
        y = m[1, 0] * cx + m[1, 1] * cy + m[1, 2] * cz + m[1, 3]
        r = math.hypot(x, y)
        out[0, u] = x
        out[1, u] = y
        out[2, u] = r
        out[3, u] = math.degrees(math.atan2(y, x))
        in_band[u] = min_range_m <= r <= max_range_m


def detect_laser(left_bgr: np.ndarray, rig: Rig, params: LaserParams | None = None, *,
                 previous: LaserFrame | np.ndarray | None = None,
                 geometry: LaserGeometry | None = None,
                 edges: EdgeParams | None = None) -> LaserFrame:
    """Find the laser stripe in one left image and triangulate it (Eqs. 1-7).

    A column at the near end of a lit segment (its outward neighbour unlit or farther)
    sees the surface over part of its width only; it is triangulated along the ray
    through the centre of that part (:func:`covered_shift_px`), so that its bearing
    lies on the surface, not beyond its edge.

    Parameters
    ----------
    left_bgr : ndarray, shape (H, W, 3), uint8, BGR
        Rectified left image of the rig's size.
    rig : Rig
    params : LaserParams, optional
        Default: the paper's defaults.
    previous : LaserFrame or ndarray (W,), optional
        The previous frame's result (or its ``v_px``), for the continuity term of Eq. 4.
    geometry : LaserGeometry, optional
        ``LaserGeometry.from_rig(rig, params)``; pass it when processing many
        frames so it is computed once.
    edges : EdgeParams, optional
        Surface jump and coverage confidence of the end columns.

    Returns
    -------
    LaserFrame
    """
    params = LaserParams() if params is None else params
    edges = EdgeParams() if edges is None else edges
    img = np.asarray(left_bgr)
    if img.shape[:2] != (rig.height_px, rig.width_px):
        raise ValueError(f"image is {img.shape[1]}x{img.shape[0]}, the rig's is "
                         f"{rig.width_px}x{rig.height_px}")
    geometry = LaserGeometry.from_rig(rig, params) if geometry is None else geometry
    prev = previous.v_px if isinstance(previous, LaserFrame) else previous
    stripe = extract_stripe(img, params, search_mask=geometry.search_mask, previous_v_px=prev,
                            px_per_m=geometry.px_per_m)
    u = np.arange(rig.width_px, dtype=np.float64)
    pts = np.empty((4, rig.width_px))
    in_band = np.empty(rig.width_px, bool)
    _triangulate(stripe.v_px, geometry.ray_x, geometry.ray_y_coeffs, geometry.plane_cam,
                 geometry.sensor_from_cam, rig.laser.min_range_m, rig.laser.max_range_m,
                 pts, in_band)
    shift = covered_shift_px(pts[2], stripe.strength_dn, stripe.noise_sigma_dn, edges)
    if np.any(shift != 0.0):
        px = geometry.ray_x[1] - geometry.ray_x[0] if rig.width_px > 1 else 0.0
        _triangulate(stripe.v_px, geometry.ray_x + shift * px, geometry.ray_y_coeffs,
                     geometry.plane_cam, geometry.sensor_from_cam, rig.laser.min_range_m,
                     rig.laser.max_range_m, pts, in_band)
    x, y, rng, bearing = pts
    return LaserFrame(u_px=u, v_px=stripe.v_px, strength_dn=stripe.strength_dn,
                      saturated=stripe.saturated, x_m=x, y_m=y, range_m=rng,
                      bearing_deg=bearing, in_band=in_band,
                      noise_sigma_dn=stripe.noise_sigma_dn, threshold_dn=stripe.threshold_dn,
                      grey_image=is_grey(img))


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
    r = np.asarray(range_m, dtype=np.float64)
    s = np.asarray(strength_dn, dtype=np.float64)
    w = r.size
    found = np.isfinite(r) & np.isfinite(s)
    shift = np.zeros(w)
    if w < 2:
        return shift
    pad_r = np.r_[np.full(3, np.nan), r, np.full(3, np.nan)]
    pad_s = np.r_[np.full(3, np.nan), s, np.full(3, np.nan)]
    idx = np.arange(w) + 3
    with np.errstate(invalid="ignore"):
        for d in (1, -1):  # inward direction: +1 for a left end, -1 for a right end
            out_r = pad_r[idx - d]
            end = found & ~(out_r <= r + params.jump_m)
            ref = np.full(w, np.nan)
            for k in (1, 2, 3):
                rk, sk = pad_r[idx + d * k], pad_s[idx + d * k]
                same = np.abs(rk - r) <= params.jump_m
                ref = np.fmax(ref, np.where(same, sk, np.nan))
            ok = end & (ref > 0)
            f = s / ref - params.coverage_z * noise_sigma_dn / ref
            f = np.clip(np.where(ok, f, 1.0), 0.0, 1.0)
            shift += d * 0.5 * (1.0 - f)
    return shift


def bearing_bin_centres_deg(rig: Rig, bin_deg: float = 1.0) -> np.ndarray:
    """Bearing bin centres of the range tables (:class:`slitcli.ranges.BearingBins`),
    ascending (right to left), degrees."""
    return BearingBins.for_rig(rig, bin_deg).centres_deg


def laser_sight_range_m(rig: Rig, bearing_deg: np.ndarray, *, margin_px: float = 2.0,
                        max_range_m: float = 10.0, step_m: float = 1e-3) -> np.ndarray:
    """Nearest horizontal range at which the laser can be seen, per bearing.

    The lit point at bearing ``b`` and range ``r`` lies on the laser plane; it is in
    sight when it projects inside the left image with ``margin_px`` to spare (the
    stripe's width needs a few rows). Nearer than this the stripe of an obstacle falls
    out of the image (below it, for the paper's rig: about 0.6 m straight ahead, more
    to the sides), so the laser's silence there says nothing (fusion, Eq. 11).

    Parameters
    ----------
    rig : Rig
    bearing_deg : ndarray, shape (B,)
        Bearings, sensor frame, positive left, degrees.

    Returns
    -------
    ndarray, shape (B,)
        Metres, sampled every ``step_m``; inf where the laser is never in sight up
        to ``max_range_m``.
    """
    b = np.radians(np.asarray(bearing_deg, dtype=float))[:, None]
    r = np.arange(step_m, max_range_m + step_m / 2, step_m)[None, :]
    n_s, d_s = rig.laser_plane_sensor()
    x, y = r * np.cos(b), r * np.sin(b)
    if abs(n_s[2]) < 1e-9:
        return np.full(b.shape[0], np.inf)
    z = (d_s - n_s[0] * x - n_s[1] * y) / n_s[2]
    u, v = rig.project_cam(rig.sensor_to_cam(np.stack([x, y, z], axis=-1)))
    w, h = rig.image_size_px
    with np.errstate(invalid="ignore"):
        inside = ((u >= margin_px) & (u <= w - 1 - margin_px)
                  & (v >= margin_px) & (v <= h - 1 - margin_px))
    first = np.argmax(inside, axis=1)
    return np.where(inside.any(axis=1), r[0, first], np.inf)


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


def _median_of_finite(a: np.ndarray) -> np.ndarray:
    """Row medians of the finite entries of ``a`` (E, 3), NaN where a row has none
    (``np.nanmedian`` without its per-call overhead: sorting puts NaN last)."""
    srt = np.sort(a, axis=1)
    n = np.isfinite(a).sum(axis=1)
    lo = np.take_along_axis(srt, np.clip((n - 1) // 2, 0, 2)[:, None], axis=1)[:, 0]
    hi = np.take_along_axis(srt, np.clip(n // 2, 0, 2)[:, None], axis=1)[:, 0]
    return np.where(n > 0, 0.5 * (lo + hi), np.nan)


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
    ref = _median_of_finite(inner)
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
