"""Where the laser sheet really lights the scene, per bearing bin, from geometry alone.

The laser's truth for a bin is the nearest point, inside the bin's wedge, of the lit
outline: the curve where the sheet (a plane) meets the scene's surfaces, kept where the
renderer's light model says the point is lit bright enough to be seen
(:func:`slitcli.sim.render` ``_laser_peak``: not shadowed from the emitter, inside the
fan, at least ``laser.visible_min_dn``) and where the left camera sees it inside the
image. No image and no estimator is involved, so the evaluator does not score the laser
against its own reduction.

Every object is a vertical prism (box, wall, cylinder) standing on the floor plane or
hovering above it. The sheet meets

- a vertical face along a segment of its footprint, at a height that is linear along
  it; the part whose height lies between the object's bottom and top is lit;
- a horizontal face (a box's or cylinder's top or bottom, the floor) along the straight
  line where the sheet crosses that height, clipped to the face.

A cylinder's side is its footprint polygon with :data:`CIRCLE_SIDES` sides (the chord
lies at most ``r (1 - cos(pi / N))`` = 5.6 um inside a 0.3 m radius for N = 512).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from slitcli.rig import Rig
from slitcli.sim.raycast import FLOOR_ID, cast
from slitcli.sim.render import _laser_peak, camera_poses, laser_plane_world
from slitcli.sim.scene import Box, Cylinder, Pose2D, Scene, Wall, box_corners_xy
from slitcli.sim.truth import nearest_on_segments, segment_wedge_interval, sensor_origin_xy

CIRCLE_SIDES = 512
SAMPLES_PER_PIECE = 65  # points tried along a lit piece when its nearest point is hidden


@dataclass(frozen=True)
class LitPieces:
    """Straight pieces of the lit outline (world frame, metres).

    ``segments_xy`` (M, 2, 2) start and end on the floor plane, ``obj`` (M,) the object
    id (0 = floor, k = scene object k - 1), ``normal_xyz`` (M, 3) the surface normal,
    ``circle_xyr`` (M, 3) the cylinder a side piece is a chord of (centre, radius; NaN
    for flat faces): points on such a chord are moved out onto the circle.
    """

    segments_xy: np.ndarray
    obj: np.ndarray
    normal_xyz: np.ndarray
    circle_xyr: np.ndarray


def _sheet_z(n: np.ndarray, d: float, xy: np.ndarray) -> np.ndarray:
    """Height of the sheet above floor points ``xy`` (..., 2)."""
    return (d - xy[..., 0] * n[0] - xy[..., 1] * n[1]) / n[2]


def _clip_vertical(p0: np.ndarray, p1: np.ndarray, n: np.ndarray, d: float, z_lo: float,
                   z_hi: float) -> tuple[np.ndarray, np.ndarray] | None:
    """The part of the vertical face over segment p0-p1 (z_lo..z_hi) the sheet meets."""
    z0, z1 = _sheet_z(n, d, p0), _sheet_z(n, d, p1)
    if abs(z1 - z0) < 1e-15:
        return (p0, p1) if z_lo <= z0 <= z_hi else None
    t_a, t_b = sorted(((z_lo - z0) / (z1 - z0), (z_hi - z0) / (z1 - z0)))
    t0, t1 = max(t_a, 0.0), min(t_b, 1.0)
    if t1 < t0:
        return None
    return p0 + t0 * (p1 - p0), p0 + t1 * (p1 - p0)


def _line_at_height(n: np.ndarray, d: float, z: float) -> tuple[np.ndarray, np.ndarray]:
    """The sheet at height z: a point on the floor-plane line and its unit direction."""
    a = np.array([n[0], n[1]])
    c = d - n[2] * z
    norm2 = float(a @ a)
    point = a * c / norm2
    direction = np.array([-a[1], a[0]]) / math.sqrt(norm2)
    return point, direction


def _clip_line_convex(point: np.ndarray, direction: np.ndarray, poly: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray] | None:
    """The line point + t direction inside a convex polygon (V, 2), or None."""
    t0, t1 = -np.inf, np.inf
    centre = poly.mean(axis=0)
    for a, b in zip(poly, np.roll(poly, -1, axis=0), strict=True):
        edge = b - a
        normal = np.array([edge[1], -edge[0]])
        if normal @ (centre - a) > 0:
            normal = -normal  # outward
        den = normal @ direction
        num = normal @ (a - point)
        if abs(den) < 1e-15:
            if num < 0:
                return None
            continue
        t = num / den
        if den > 0:
            t1 = min(t1, t)
        else:
            t0 = max(t0, t)
    if not t1 > t0:
        return None
    return point + t0 * direction, point + t1 * direction


def _clip_line_disc(point: np.ndarray, direction: np.ndarray, centre: np.ndarray,
                    radius: float) -> tuple[np.ndarray, np.ndarray] | None:
    """The chord of the line point + t direction through a disc, or None."""
    rel = point - centre
    b = float(rel @ direction)
    disc = b * b - (float(rel @ rel) - radius * radius)
    if disc <= 0:
        return None
    root = math.sqrt(disc)
    return point + (-b - root) * direction, point + (-b + root) * direction


def lit_pieces(scene: Scene, n_w: np.ndarray, d_w: float, origin_xy: np.ndarray,
               reach_m: float) -> LitPieces:
    """The straight pieces of the scene the sheet ``n . p = d`` meets (:class:`LitPieces`),
    the floor's within ``reach_m`` of ``origin_xy``."""
    segs: list[tuple[np.ndarray, np.ndarray]] = []
    objs: list[int] = []
    normals: list[np.ndarray] = []
    circles: list[tuple[float, float, float]] = []
    up = np.array([0.0, 0.0, 1.0])
    flat = (math.nan, math.nan, math.nan)
    empty = LitPieces(np.zeros((0, 2, 2)), np.zeros(0, np.int64), np.zeros((0, 3)),
                      np.zeros((0, 3)))
    if abs(n_w[2]) < 1e-12:  # a vertical sheet: not a slit laser over a floor
        return empty

    def add(piece: tuple[np.ndarray, np.ndarray] | None, obj: int, normal: np.ndarray,
            circle: tuple[float, float, float] = flat) -> None:
        if piece is not None and float(np.hypot(*(piece[1] - piece[0]))) > 1e-9:
            segs.append(piece)
            objs.append(obj)
            normals.append(normal)
            circles.append(circle)

    for k, ob in enumerate(scene.objects, start=1):
        if isinstance(ob, Box):
            outline = box_corners_xy(ob)
        elif isinstance(ob, Wall):
            outline = np.array([ob.from_xy_m, ob.to_xy_m], dtype=float)
        else:
            assert isinstance(ob, Cylinder)
            ang = np.linspace(0.0, 2 * math.pi, CIRCLE_SIDES, endpoint=False)
            outline = np.column_stack([ob.centre_xy_m[0] + ob.radius_m * np.cos(ang),
                                       ob.centre_xy_m[1] + ob.radius_m * np.sin(ang)])
        ends = zip(outline, np.roll(outline, -1, axis=0), strict=True) \
            if len(outline) > 2 else [(outline[0], outline[1])]
        circle = (*ob.centre_xy_m, ob.radius_m) if isinstance(ob, Cylinder) else flat
        for a, b in ends:
            e = b - a
            add(_clip_vertical(a, b, n_w, d_w, ob.z_min_m, ob.z_max_m), k,
                np.array([e[1], -e[0], 0.0]) / max(float(np.hypot(*e)), 1e-300), circle)
        if isinstance(ob, Wall):
            continue
        for z in (ob.z_max_m, ob.z_min_m) if ob.z_min_m > 0 else (ob.z_max_m,):
            point, direction = _line_at_height(n_w, d_w, z)
            chord = (_clip_line_convex(point, direction, outline) if isinstance(ob, Box)
                     else _clip_line_disc(point, direction, np.asarray(ob.centre_xy_m, float),
                                          ob.radius_m))
            add(chord, k, up)
    point, direction = _line_at_height(n_w, d_w, 0.0)
    add(_clip_line_disc(point, direction, np.asarray(origin_xy, float), reach_m), FLOOR_ID, up)
    if not segs:
        return empty
    return LitPieces(np.array([[p, q] for p, q in segs], dtype=float),
                     np.array(objs, dtype=np.int64), np.array(normals, dtype=float),
                     np.array(circles, dtype=float))


def lit_wedge_ranges(scene: Scene, rig: Rig, pose: Pose2D, bin_lo_deg: np.ndarray,
                     bin_hi_deg: np.ndarray) -> np.ndarray:
    """Nearest visible lit point per bearing wedge, horizontal range from the sensor origin.

    Parameters
    ----------
    scene, rig, pose
        The world, the rig and the robot pose.
    bin_lo_deg, bin_hi_deg : ndarray, shape (B,)
        Wedge limits, sensor frame, degrees, positive left.

    Returns
    -------
    ndarray, shape (B,)
        Metres; NaN where the sheet lights nothing the camera sees in the wedge.

    A piece's nearest point in the wedge is exact; when it is hidden (shadowed, too dim,
    out of the image or behind another object), :data:`SAMPLES_PER_PIECE` points evenly
    along the piece's part in the wedge are tried instead.
    """
    lo = np.radians(np.asarray(bin_lo_deg, dtype=float)) + pose.yaw_rad
    hi = np.radians(np.asarray(bin_hi_deg, dtype=float)) + pose.yaw_rad
    out = np.full(lo.shape, np.nan)
    if not scene.laser.enabled:
        return out
    origin = sensor_origin_xy(pose, rig.mount.forward_m)
    n_w, d_w, _ = laser_plane_world(rig, pose)
    pieces = lit_pieces(scene, n_w, d_w, origin, scene.max_range_m + 1.0)
    if not len(pieces.obj):
        return out
    rel = pieces.segments_xy - origin
    s_min, s_max, hit = segment_wedge_interval(rel, lo, hi)
    s_star = nearest_on_segments(rel, s_min, s_max)
    b_idx, m_idx = np.nonzero(hit)
    best = np.full(lo.shape, np.inf)
    # first the exact nearest point of every piece in every wedge; only where that is
    # hidden, points along the piece's part in the wedge
    seen, rng = _try_points(scene, rig, pose, pieces, origin, m_idx,
                            s_star[b_idx, m_idx][:, None])
    np.minimum.at(best, b_idx, np.where(seen[:, 0], rng[:, 0], np.inf))
    # a hidden nearest point is tried along its piece only if the piece could still be
    # the nearest: every point of it in the wedge is at least as far as that point
    again = ~seen[:, 0] & (rng[:, 0] < best[b_idx])
    if again.any():
        b2, m2 = b_idx[again], m_idx[again]
        frac = np.linspace(0.0, 1.0, SAMPLES_PER_PIECE)[None, :]
        s = s_min[b2, m2][:, None] + frac * (s_max - s_min)[b2, m2][:, None]
        seen, rng = _try_points(scene, rig, pose, pieces, origin, m2, s)
        np.minimum.at(best, b2, np.where(seen, rng, np.inf).min(axis=1))
    return np.where(np.isfinite(best), best, np.nan)


def _try_points(scene: Scene, rig: Rig, pose: Pose2D, pieces: LitPieces, origin: np.ndarray,
                m_idx: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points at parameters ``s`` (C, K) of pieces ``m_idx`` (C,): whether each is seen lit
    and its horizontal range from ``origin`` (both (C, K))."""
    seg = pieces.segments_xy[m_idx]
    xy = seg[:, None, 0, :] + s[..., None] * (seg[:, None, 1, :] - seg[:, None, 0, :])
    normal = np.broadcast_to(pieces.normal_xyz[m_idx][:, None, :], (*s.shape, 3)).copy()
    circ = pieces.circle_xyr[m_idx][:, None, :]
    on_circle = np.broadcast_to(np.isfinite(circ[..., 2]), s.shape)
    radial = xy - circ[..., :2]
    radial /= np.maximum(np.hypot(radial[..., 0], radial[..., 1]), 1e-300)[..., None]
    xy = np.where(on_circle[..., None], circ[..., :2] + circ[..., 2:] * radial, xy)
    normal[..., :2] = np.where(on_circle[..., None], radial, normal[..., :2])
    n_w, d_w, _ = laser_plane_world(rig, pose)
    pts = np.concatenate([xy, _sheet_z(n_w, d_w, xy)[..., None]], axis=-1).reshape(-1, 3)
    obj = np.repeat(pieces.obj[m_idx], s.shape[1])
    normal = normal.reshape(-1, 3)
    with np.errstate(invalid="ignore"):  # rays parallel to an axis: inf * 0 in misses
        seen = _visible(scene, rig, pose, pts) & \
            (_laser_peak(scene, rig, pose, pts, obj, normal) >= scene.laser.visible_min_dn)
    rng = np.hypot(pts[:, 0] - origin[0], pts[:, 1] - origin[1])
    return seen.reshape(s.shape), rng.reshape(s.shape)


def _visible(scene: Scene, rig: Rig, pose: Pose2D, pts: np.ndarray) -> np.ndarray:
    """World points the left camera sees (nothing in front) inside the image."""
    left, _ = camera_poses(rig, pose)
    vec = pts - left.origin_xyz
    dist = np.linalg.norm(vec, axis=1)
    first = cast(scene, left.origin_xyz, vec / np.maximum(dist, 1e-12)[:, None])
    cam = vec @ left.R_world_from_cam  # world -> camera frame
    u, v = rig.project_cam(cam)
    w, h = rig.image_size_px
    with np.errstate(invalid="ignore"):
        inside = (u >= -0.5) & (u <= w - 0.5) & (v >= -0.5) & (v <= h - 0.5)
    return (first.t >= dist - 1e-6) & inside


__all__ = ["CIRCLE_SIDES", "LitPieces", "lit_pieces", "lit_wedge_ranges"]
