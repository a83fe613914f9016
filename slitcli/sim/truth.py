"""Exact range truth of a generated scene per bearing bin (DESIGN §6, §10).

Obstacles are reduced to their outlines on the floor plane (segments and circles,
world frame, metres), and each bearing bin's truth is the distance from the sensor
origin to the nearest outline point inside the bin's wedge, computed in closed form.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from slitcli.sim.scene import Box, Pose2D, Scene, Wall, box_corners_xy


@dataclass(frozen=True)
class Footprints:
    """Obstacle outlines on the floor plane, for exact 2-D range truth.

    ``segments_xy`` has shape (M, 2, 2) (start and end points), ``circles_xyr`` shape
    (K, 3) (centre x, y and radius); world frame, metres.
    """

    segments_xy: np.ndarray
    circles_xyr: np.ndarray


def footprints(scene: Scene, *, z_low_m: float, z_high_m: float) -> Footprints:
    """Outlines of the obstacles that reach into the height band (z_low_m, z_high_m)."""
    segs: list[np.ndarray] = []
    circles: list[tuple[float, float, float]] = []
    for ob in scene.objects:
        if ob.z_max_m <= z_low_m or ob.z_min_m >= z_high_m:
            continue
        if isinstance(ob, Box):
            corners = box_corners_xy(ob)
            segs.extend(np.stack([corners, np.roll(corners, -1, axis=0)], axis=1))
        elif isinstance(ob, Wall):
            segs.append(np.array([ob.from_xy_m, ob.to_xy_m], dtype=float))
        else:
            circles.append((ob.centre_xy_m[0], ob.centre_xy_m[1], ob.radius_m))
    seg_arr = np.array(segs, dtype=float).reshape(-1, 2, 2)
    circ_arr = np.array(circles, dtype=float).reshape(-1, 3)
    return Footprints(seg_arr, circ_arr)


def sensor_origin_xy(pose: Pose2D, forward_m: float) -> np.ndarray:
    """World position of the sensor origin for a robot pose."""
    return np.array([pose.x_m + forward_m * math.cos(pose.yaw_rad),
                     pose.y_m + forward_m * math.sin(pose.yaw_rad)])


def wedge_min_range(fp: Footprints, origin_xy: np.ndarray, heading_rad: float,
                    bin_lo_deg: np.ndarray, bin_hi_deg: np.ndarray) -> np.ndarray:
    """Exact distance from ``origin_xy`` to the nearest outline point in each bearing wedge.

    Parameters
    ----------
    fp : Footprints
    origin_xy : ndarray, shape (2,)
        The sensor origin in the world, metres.
    heading_rad : float
        World direction of bearing 0.
    bin_lo_deg, bin_hi_deg : ndarray, shape (B,)
        Wedge limits relative to the heading, degrees, positive to the left.

    Returns
    -------
    range_m : ndarray, shape (B,)
        Horizontal distance to the nearest point of any outline inside the wedge; inf
        where the wedge meets nothing.
    """
    lo = np.radians(np.asarray(bin_lo_deg, dtype=float)) + heading_rad
    hi = np.radians(np.asarray(bin_hi_deg, dtype=float)) + heading_rad
    best = np.full(lo.shape, np.inf)
    o = np.asarray(origin_xy, dtype=float)
    if len(fp.segments_xy):
        best = np.minimum(best, _segments_in_wedges(fp.segments_xy - o, lo, hi).min(axis=1))
    if len(fp.circles_xyr):
        c = fp.circles_xyr.copy()
        c[:, :2] -= o
        best = np.minimum(best, _circles_in_wedges(c, lo, hi).min(axis=1))
    return best


def _ray_segment_t(angle: np.ndarray, p0: np.ndarray, p1: np.ndarray) -> tuple[np.ndarray, ...]:
    """Where the ray from the origin at ``angle`` (B, 1) meets segments (1, M): the segment
    parameter s in [0, 1] and the ray distance; NaN when they miss."""
    d = np.stack([np.cos(angle), np.sin(angle)], axis=-1)          # (B, 1, 2)
    e = p1 - p0                                                     # (1, M, 2)
    den = d[..., 0] * e[..., 1] - d[..., 1] * e[..., 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        s = (p0[..., 0] * d[..., 1] - p0[..., 1] * d[..., 0]) / den
        t = (p0[..., 0] * e[..., 1] - p0[..., 1] * e[..., 0]) / den
    ok = (np.abs(den) > 1e-15) & (s >= 0) & (s <= 1) & (t >= 0)
    return np.where(ok, s, np.nan), np.where(ok, t, np.nan)


def segment_wedge_interval(seg: np.ndarray, lo: np.ndarray, hi: np.ndarray
                           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The part of each segment inside each wedge, as an interval of its parameter.

    Parameters
    ----------
    seg : ndarray, shape (M, 2, 2)
        Segments (start, end), relative to the wedges' apex, metres.
    lo, hi : ndarray, shape (B,)
        Wedge limits, radians (world directions).

    Returns
    -------
    s_min, s_max : ndarray, shape (B, M)
        The interval ``[s_min, s_max]`` of ``p0 + s (p1 - p0)`` inside the wedge.
    hit : ndarray of bool, shape (B, M)
        The segment enters the wedge.
    """
    p0 = seg[None, :, 0, :]
    p1 = seg[None, :, 1, :]
    lo_c, hi_c = lo[:, None], hi[:, None]
    mid = 0.5 * (lo_c + hi_c)
    half = 0.5 * (hi_c - lo_c)

    def inside(p: np.ndarray) -> np.ndarray:
        ang = np.arctan2(p[..., 1], p[..., 0])
        return np.abs(_wrap(ang - mid)) <= half + 1e-12

    # The bearing along a segment that does not pass through the origin is monotonic,
    # so the part inside a wedge is one interval of the segment parameter, bounded by
    # the endpoints that are inside and the crossings of the two boundary rays.
    s_lo, _ = _ray_segment_t(lo_c, p0, p1)
    s_hi, _ = _ray_segment_t(hi_c, p0, p1)
    in0 = inside(p0)
    in1 = inside(p1)
    cands = np.stack([np.where(in0, 0.0, np.nan), np.where(in1, 1.0, np.nan), s_lo, s_hi])
    s_min = np.nanmin(np.where(np.isnan(cands), np.inf, cands), axis=0)
    s_max = np.nanmax(np.where(np.isnan(cands), -np.inf, cands), axis=0)
    hit = np.isfinite(s_min) & (s_max >= s_min)
    return np.where(hit, s_min, 0.0), np.where(hit, s_max, 0.0), hit


def nearest_on_segments(seg: np.ndarray, s_min: np.ndarray, s_max: np.ndarray) -> np.ndarray:
    """Parameter of the point nearest the origin within ``[s_min, s_max]`` of each
    segment (``seg`` (M, 2, 2) relative to the origin; intervals (B, M))."""
    p0 = seg[None, :, 0, :]
    e = seg[None, :, 1, :] - p0
    ee = np.maximum((e * e).sum(-1), 1e-300)
    return np.clip(-(p0 * e).sum(-1) / ee, s_min, s_max)


def _segments_in_wedges(seg: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(B, M) nearest distance of each segment portion inside each wedge (inf if none)."""
    s_min, s_max, hit = segment_wedge_interval(seg, lo, hi)
    s_star = nearest_on_segments(seg, s_min, s_max)
    pt = seg[None, :, 0, :] + s_star[..., None] * (seg[None, :, 1, :] - seg[None, :, 0, :])
    dist = np.hypot(pt[..., 0], pt[..., 1])
    return np.where(hit, dist, np.inf)


def _circles_in_wedges(circ: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(B, K) nearest distance of each disc's part inside each wedge (inf if none)."""
    cx, cy, r = circ[None, :, 0], circ[None, :, 1], circ[None, :, 2]
    lo_c, hi_c = lo[:, None], hi[:, None]
    dist_c = np.hypot(cx, cy)
    mid = 0.5 * (lo_c + hi_c)
    half = 0.5 * (hi_c - lo_c)
    centre_in = np.abs(_wrap(np.arctan2(cy, cx) - mid)) <= half
    # Over disc ∩ wedge, the nearest point is on the disc boundary towards the origin
    # (if that direction lies in the wedge) or the first crossing of a boundary ray.
    best = np.where(centre_in, np.maximum(dist_c - r, 0.0), np.inf)
    for ang in (lo_c, hi_c):
        dx, dy = np.cos(ang), np.sin(ang)
        b = dx * cx + dy * cy
        disc = b * b - (dist_c * dist_c - r * r)
        root = np.sqrt(np.maximum(disc, 0.0))
        t0 = b - root
        t1 = b + root
        t = np.where(t0 >= 0, t0, np.where(t1 >= 0, 0.0, np.inf))
        best = np.minimum(best, np.where(disc >= 0, t, np.inf))
    return best


def _wrap(a: np.ndarray) -> np.ndarray:
    return (a + np.pi) % (2 * np.pi) - np.pi


def true_ranges(scene: Scene, pose: Pose2D, bin_lo_deg: np.ndarray, bin_hi_deg: np.ndarray, *,
                forward_m: float = 0.0, floor_margin_m: float = 0.02,
                max_range_m: float | None = None) -> np.ndarray:
    """Ground-truth nearest obstacle range per bearing bin, sensor frame (DESIGN §6).

    An obstacle counts when it reaches above ``floor_margin_m`` and starts below the
    robot's height. NaN where nothing lies within ``max_range_m`` (default: the scene's).
    """
    fp = footprints(scene, z_low_m=floor_margin_m, z_high_m=scene.robot.height_m)
    origin = sensor_origin_xy(pose, forward_m)
    r = wedge_min_range(fp, origin, pose.yaw_rad, bin_lo_deg, bin_hi_deg)
    limit = scene.max_range_m if max_range_m is None else max_range_m
    return np.where(r <= limit, r, np.nan)
