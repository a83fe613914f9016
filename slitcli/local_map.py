"""The planner's local view: frames, unicycle motion, range-table points, obstacle memory.

Shared by the closed loop and the offline planner.

Frames: the robot frame has its origin at the rotation centre, x forward, y left;
the world frame is fixed (in the offline planner, the robot frame at the first
frame). A pose is (x_m, y_m, yaw_rad). Points are arrays of shape (N, 2) in metres.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


def to_world(pose_xy_yaw: tuple[float, float, float], points_xy: np.ndarray) -> np.ndarray:
    """Robot-frame points (N, 2) to the world frame for a pose (x_m, y_m, yaw_rad)."""
    x, y, yaw = pose_xy_yaw
    c, s = math.cos(yaw), math.sin(yaw)
    p = np.asarray(points_xy, dtype=float).reshape(-1, 2)
    return np.column_stack([x + c * p[:, 0] - s * p[:, 1], y + s * p[:, 0] + c * p[:, 1]])


def to_robot(pose_xy_yaw: tuple[float, float, float], points_xy: np.ndarray) -> np.ndarray:
    """World-frame points (N, 2) to the robot frame of a pose (x_m, y_m, yaw_rad)."""
    x, y, yaw = pose_xy_yaw
    c, s = math.cos(yaw), math.sin(yaw)
    p = np.asarray(points_xy, dtype=float).reshape(-1, 2)
    dx, dy = p[:, 0] - x, p[:, 1] - y
    return np.column_stack([c * dx + s * dy, -s * dx + c * dy])


def scan_points(bearing_deg: np.ndarray, range_m: np.ndarray, forward_m: float) -> np.ndarray:
    """Obstacle points (N, 2), robot frame, from one range table frame (DESIGN §6).

    Each bearing bin with a return gives one point at the bin's bearing and range from
    the sensor origin, which lies ``forward_m`` ahead of the rotation centre. NaN
    ranges (no return) give no point.
    """
    b = np.radians(np.asarray(bearing_deg, dtype=float))
    r = np.asarray(range_m, dtype=float)
    ok = np.isfinite(r)
    return np.column_stack([forward_m + r[ok] * np.cos(b[ok]), r[ok] * np.sin(b[ok])])


def unicycle(pose_xy_yaw: tuple[float, float, float], v_mps: float, w_rps: float,
             t_s: np.ndarray) -> np.ndarray:
    """Poses (K, 3) = (x_m, y_m, yaw_rad) after holding (v, w) for the times ``t_s`` (K,).

    Exact integration of the unicycle x' = v cos yaw, y' = v sin yaw, yaw' = w.
    """
    x, y, yaw = pose_xy_yaw
    t = np.asarray(t_s, dtype=float)
    yaw_t = yaw + w_rps * t
    if abs(w_rps) < 1e-12:
        return np.column_stack([x + v_mps * t * math.cos(yaw), y + v_mps * t * math.sin(yaw),
                                yaw_t])
    r = v_mps / w_rps
    return np.column_stack([x + r * (np.sin(yaw_t) - math.sin(yaw)),
                            y - r * (np.cos(yaw_t) - math.cos(yaw)), yaw_t])


# ------------------------------------------------------------------ memory
@dataclass(frozen=True)
class PointMemory:
    """Short-term obstacle memory in the world frame (a minimal local costmap).

    The camera sees only +-32 deg: a robot turning away from an obstacle loses sight
    of it while still beside it. The memory keeps every point seen within the last
    ``keep_s`` seconds, one per ``cell_m`` grid cell (the newest), so that the planner
    still avoids what it saw. Static worlds only: nothing is cleared by free space.

    ``points_xy`` (N, 2) world frame, metres; ``seen_s`` (N,) time last seen, seconds.
    """

    points_xy: np.ndarray
    seen_s: np.ndarray

    @staticmethod
    def empty() -> PointMemory:
        """A memory holding nothing."""
        return PointMemory(np.zeros((0, 2)), np.zeros(0))

    def update(self, new_points_xy: np.ndarray, t_s: float, *, keep_s: float,
               cell_m: float) -> PointMemory:
        """Add points seen at ``t_s`` and forget those older than ``keep_s``.

        ``keep_s = 0`` keeps only the new points (no memory).
        """
        new = np.asarray(new_points_xy, dtype=float).reshape(-1, 2)
        pts = np.concatenate([self.points_xy, new])
        seen = np.concatenate([self.seen_s, np.full(len(new), float(t_s))])
        fresh = t_s - seen <= keep_s + 1e-9
        pts, seen = pts[fresh], seen[fresh]
        if len(pts) == 0:
            return PointMemory.empty()
        cells = np.floor(pts / cell_m).astype(np.int64)
        # Newest first, so np.unique's first occurrence per cell is the newest point.
        order = np.argsort(-seen, kind="stable")
        _, first = np.unique(cells[order], axis=0, return_index=True)
        keep = np.sort(order[first])
        return PointMemory(pts[keep], seen[keep])


# ------------------------------------------------------------------ ray clearing
FREE, SURFACE, OCCLUDED, UNSEEN = 0, 1, 2, 3


@dataclass(frozen=True)
class ScanRays:
    """The rays of one frame, for free-space tests (world frame).

    ``origin_xy`` (2,) sensor origin, ``heading_rad`` its bearing 0, ``bearing_deg`` (B,)
    uniformly spaced bin centres, ``range_m`` (B,) (NaN = no return), ``free_m``: up to
    this range a bin with no return is known free (the sensor would have seen anything
    there; 0 = a missed return is never taken as free space), ``cell_m`` the map cell.
    """

    origin_xy: np.ndarray
    heading_rad: float
    bearing_deg: np.ndarray
    range_m: np.ndarray
    free_m: float
    cell_m: float

    def state(self, points_xy: np.ndarray) -> np.ndarray:
        """What this frame says about each world point (N,): FREE, SURFACE, OCCLUDED, UNSEEN.

        A point inside the field of view lies in one bearing bin. It is FREE when it is
        nearer than that bin's return by more than the tolerance, or when the bin has no
        return and it is nearer than ``free_m``; SURFACE within the tolerance of the
        return; OCCLUDED behind it. The tolerance, cell_m + range x bin width (rad),
        covers a remembered point's placement error: one point per cell, at the bin
        centre's bearing, while the true nearest point may lie anywhere in the bin.
        UNSEEN: outside the field of view, or no return and beyond ``free_m``.
        """
        p = np.asarray(points_xy, dtype=float).reshape(-1, 2)
        out = np.full(len(p), UNSEEN, dtype=np.int8)
        b = np.asarray(self.bearing_deg, dtype=float)
        if len(p) == 0 or len(b) == 0:
            return out
        width = float(b[1] - b[0]) if len(b) > 1 else 1.0
        d = p - self.origin_xy
        rng = np.hypot(d[:, 0], d[:, 1])
        brg = np.degrees(np.arctan2(d[:, 1], d[:, 0]) - self.heading_rad)
        brg = (brg + 180.0) % 360.0 - 180.0
        k = np.floor((brg - b[0]) / width + 0.5).astype(np.int64)
        inside = (k >= 0) & (k < len(b))
        ret = np.where(inside, np.asarray(self.range_m, dtype=float)[np.clip(k, 0, len(b) - 1)],
                       np.nan)
        tol = self.cell_m + rng * np.radians(width)
        has = inside & np.isfinite(ret)
        out[has & (rng < ret - tol)] = FREE
        out[has & (np.abs(rng - ret) <= tol)] = SURFACE
        out[has & (rng > ret + tol)] = OCCLUDED
        out[inside & ~np.isfinite(ret) & (rng < self.free_m - tol)] = FREE
        return out


@dataclass(frozen=True)
class ObstacleMap:
    """Static obstacle memory, world frame, cleared by free space instead of by age.

    One point per ``cell`` (the newest), with the time it was last seen (``seen_s``,
    (N,)) and the track it came from (``track_id``, (N,), see :mod:`slitcli.tracking`).
    A remembered point is deleted only when a frame's rays show the space free
    (:meth:`ScanRays.state`); out of view it is kept for ever, so the robot does not
    forget a wall it is driving past. Points of moving tracks are not kept: the
    tracker's prediction stands for them, and dropping their track's points is what
    clears a walking person's trail.
    """

    points_xy: np.ndarray
    seen_s: np.ndarray
    track_id: np.ndarray

    @staticmethod
    def empty() -> ObstacleMap:
        """A map holding nothing."""
        return ObstacleMap(np.zeros((0, 2)), np.zeros(0), np.zeros(0, dtype=np.int64))

    def _keep(self, keep: np.ndarray) -> ObstacleMap:
        return ObstacleMap(self.points_xy[keep], self.seen_s[keep], self.track_id[keep])

    def clear(self, rays: ScanRays) -> ObstacleMap:
        """Delete the points this frame sees free."""
        return self._keep(rays.state(self.points_xy) != FREE)

    def drop_tracks(self, track_ids: np.ndarray) -> ObstacleMap:
        """Delete the points that came from the given tracks (moving obstacles)."""
        return self._keep(~np.isin(self.track_id, track_ids))

    def add(self, points_xy: np.ndarray, t_s: float, track_id: np.ndarray, *,
            cell_m: float) -> ObstacleMap:
        """Add points seen at ``t_s``; one point per ``cell_m`` cell, the newest."""
        new = np.asarray(points_xy, dtype=float).reshape(-1, 2)
        pts = np.concatenate([self.points_xy, new])
        if len(pts) == 0:
            return ObstacleMap.empty()
        seen = np.concatenate([self.seen_s, np.full(len(new), float(t_s))])
        tid = np.concatenate([self.track_id, np.asarray(track_id, dtype=np.int64)])
        cells = np.floor(pts / cell_m).astype(np.int64)
        order = np.argsort(-seen, kind="stable")
        _, first = np.unique(cells[order], axis=0, return_index=True)
        keep = np.sort(order[first])
        return ObstacleMap(pts[keep], seen[keep], tid[keep])
