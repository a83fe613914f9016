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
