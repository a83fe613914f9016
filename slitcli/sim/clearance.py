"""Exact 2-D distances from floor points to the obstacles of a scene (for the closed loop).

Used to detect collisions, to measure clearance along a trajectory and to refuse
impossible worlds (a start in collision, a goal inside an obstacle). World frame,
metres. An obstacle counts when it reaches into the robot's height band, as for
:func:`slitcli.sim.truth.true_ranges`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from slitcli.sim.scene import Box, Cylinder, Scene, Wall, box_corners_xy


@dataclass(frozen=True)
class ObstacleGeometry:
    """Obstacle outlines with the index of the scene object each belongs to.

    ``segments_xy`` (M, 2, 2) with ``segment_owner`` (M,); ``circles_xyr`` (K, 3) with
    ``circle_owner`` (K,); ``is_box`` (n_objects,) marks boxes, whose inside counts
    as obstacle (a cylinder's signed distance comes from its circle; walls have no
    inside; objects outside the height band own no outline).
    """

    segments_xy: np.ndarray
    segment_owner: np.ndarray
    circles_xyr: np.ndarray
    circle_owner: np.ndarray
    is_box: np.ndarray
    n_objects: int


def obstacle_geometry(scene: Scene, *, z_low_m: float = 0.02,
                      z_high_m: float | None = None) -> ObstacleGeometry:
    """Outlines of the objects reaching into (z_low_m, z_high_m) (default: robot height)."""
    top = scene.robot.height_m if z_high_m is None else z_high_m
    segs: list[np.ndarray] = []
    seg_owner: list[int] = []
    circles: list[tuple[float, float, float]] = []
    circ_owner: list[int] = []
    is_box = np.zeros(len(scene.objects), dtype=bool)
    for i, ob in enumerate(scene.objects):
        if ob.z_max_m <= z_low_m or ob.z_min_m >= top:
            continue
        if isinstance(ob, Box):
            c = box_corners_xy(ob)
            segs.extend(np.stack([c, np.roll(c, -1, axis=0)], axis=1))
            seg_owner.extend([i] * 4)
            is_box[i] = True
        elif isinstance(ob, Wall):
            segs.append(np.array([ob.from_xy_m, ob.to_xy_m], dtype=float))
            seg_owner.append(i)
        elif isinstance(ob, Cylinder):
            circles.append((ob.centre_xy_m[0], ob.centre_xy_m[1], ob.radius_m))
            circ_owner.append(i)
    return ObstacleGeometry(np.array(segs, dtype=float).reshape(-1, 2, 2),
                            np.array(seg_owner, dtype=np.int64),
                            np.array(circles, dtype=float).reshape(-1, 3),
                            np.array(circ_owner, dtype=np.int64), is_box, len(scene.objects))


def object_distances(geom: ObstacleGeometry, points_xy: np.ndarray) -> np.ndarray:
    """Signed distance from each point to each object's outline, shape (N, n_objects).

    Negative inside a box or cylinder; inf for objects outside the height band.
    """
    p = np.asarray(points_xy, dtype=float).reshape(-1, 2)
    out = np.full((len(p), geom.n_objects), np.inf)
    if len(geom.segments_xy):
        a = geom.segments_xy[None, :, 0, :]
        e = geom.segments_xy[None, :, 1, :] - a
        rel = p[:, None, :] - a
        ee = np.maximum((e * e).sum(-1), 1e-300)
        t = np.clip((rel * e).sum(-1) / ee, 0.0, 1.0)
        d = np.hypot(*np.moveaxis(rel - t[..., None] * e, -1, 0))            # (N, M)
        # Box edges run counter-clockwise: inside means left of every edge.
        left = e[..., 0] * rel[..., 1] - e[..., 1] * rel[..., 0] >= 0
        starts = np.flatnonzero(np.r_[True, np.diff(geom.segment_owner) != 0])
        owners = geom.segment_owner[starts]
        out[:, owners] = np.minimum.reduceat(d, starts, axis=1)
        inside = np.logical_and.reduceat(left, starts, axis=1) & geom.is_box[owners]
        out[:, owners] = np.where(inside, -out[:, owners], out[:, owners])
    if len(geom.circles_xyr):
        c = geom.circles_xyr
        d = np.hypot(p[:, None, 0] - c[None, :, 0], p[:, None, 1] - c[None, :, 1]) - c[None, :, 2]
        out[:, geom.circle_owner] = np.minimum(out[:, geom.circle_owner], d)
    return out


def clearance_m(geom: ObstacleGeometry, points_xy: np.ndarray) -> np.ndarray:
    """Signed distance from each point (N, 2) to the nearest obstacle, shape (N,); inf if none."""
    d = object_distances(geom, points_xy)
    return d.min(axis=1) if d.shape[1] else np.full(len(d), np.inf)
