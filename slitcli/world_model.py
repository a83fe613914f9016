"""The planner's model of the world around it: a static obstacle map plus moving tracks.

Each frame (one range table, DESIGN §6) goes through the same three steps, in the
closed loop (:mod:`slitcli.sim.loop`) and in the offline planner
(:mod:`slitcli.dwa_table`):

1. **clear**: remembered static points that this frame's rays see free are deleted
   (:class:`slitcli.local_map.ScanRays`); nothing expires with age;
2. **track**: the frame's points are clustered and matched to tracks
   (:class:`slitcli.tracking.Tracker`); a track whose old places are now empty and
   whose centroid moves is a moving obstacle;
3. **remember**: the points of tracks that never moved join the static map; the points
   of tracks that have moved are dropped from it (their trail goes with them) and the
   tracks are handed to the planner as predicted discs (:class:`slitcli.dwa.MovingDiscs`).

``memory`` selects the static map: ``clearing`` (the above), ``expiry`` (the former
rule: keep every point for ``memory_s`` seconds, no tracking; for comparison) or
``off`` (the current frame only).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from slitcli.local_map import ObstacleMap, PointMemory, ScanRays, scan_points, to_world
from slitcli.prediction import MovingDiscs
from slitcli.tracking import Tracker, TrackParams

MEMORY_MODES = ("clearing", "expiry", "off")


@dataclass(frozen=True, kw_only=True)
class WorldModelParams:
    """Settings of the planner's world model.

    ``memory`` (``clearing``, ``expiry`` or ``off``; module docstring), ``memory_s``
    (expiry only), ``cell_m`` (one remembered point per cell), ``predict`` (track moving
    obstacles and hand them to the planner; ``clearing`` only), ``track`` the tracker's
    settings.
    """

    memory: str = "clearing"
    memory_s: float = 10.0
    cell_m: float = 0.05
    predict: bool = True
    track: TrackParams = field(default_factory=TrackParams)


class WorldModel:
    """Static map and moving tracks of one run; :meth:`update` once per frame."""

    def __init__(self, params: WorldModelParams) -> None:
        self.params = params
        self.static_map = ObstacleMap.empty()
        self.expiry = PointMemory.empty()
        self.tracker = Tracker(params.track)
        self.moving_world = MovingDiscs.none()

    def update(self, pose: tuple[float, float, float], bearing_deg: np.ndarray,
               range_m: np.ndarray, forward_m: float, free_m: float, t_s: float
               ) -> tuple[np.ndarray, MovingDiscs]:
        """One frame seen from ``pose`` at ``t_s``.

        Parameters
        ----------
        pose : (x_m, y_m, yaw_rad)
            Robot pose, world frame.
        bearing_deg, range_m : ndarray, shape (B,)
            The frame's range table (sensor frame; NaN = no return).
        forward_m : float
            Sensor origin ahead of the rotation centre.
        free_m : float
            Range up to which a bin with no return is free (the sensor's reliable
            "nothing there"; 0 = never).

        Returns
        -------
        static_xy : ndarray, shape (N, 2)
            Static obstacle points, world frame.
        moving : MovingDiscs
            Moving obstacles, world frame (positions now, velocities in world axes).
        """
        p = self.params
        seen = to_world(pose, scan_points(bearing_deg, range_m, forward_m))
        if p.memory != "clearing":
            keep = p.memory_s if p.memory == "expiry" else 0.0
            self.expiry = self.expiry.update(seen, t_s, keep_s=keep, cell_m=p.cell_m)
            return self.expiry.points_xy, MovingDiscs.none()
        x, y, yaw = pose
        origin = np.array([x + forward_m * math.cos(yaw), y + forward_m * math.sin(yaw)])
        rays = ScanRays(origin, yaw, np.asarray(bearing_deg, dtype=float),
                        np.asarray(range_m, dtype=float), float(free_m), p.cell_m)
        self.static_map = self.static_map.clear(rays)
        if not p.predict:
            self.static_map = self.static_map.add(seen, t_s, np.full(len(seen), -1),
                                                  cell_m=p.cell_m)
            return self.static_map.points_xy, MovingDiscs.none()
        ok = np.isfinite(np.asarray(range_m, dtype=float))
        bins = np.flatnonzero(ok)
        at_edge = (bins == 0) | (bins == len(ok) - 1)
        snap = self.tracker.update(seen, t_s, rays.state, at_edge, origin)
        gone = snap.track_id[snap.ever_moving]
        static = ~np.isin(snap.point_track, gone)
        self.static_map = self.static_map.drop_tracks(gone).add(
            seen[static], t_s, snap.point_track[static], cell_m=p.cell_m)
        # moving tracks go to the planner as their outline points, each a small disc
        sel = snap.ever_moving[snap.shape_track]
        k = snap.shape_track[sel]
        vel = snap.velocity_xy[k]
        self.moving_world = MovingDiscs(snap.shape_xy[sel], vel, np.zeros(int(sel.sum())))
        return self.static_map.points_xy, self.moving_world


def moving_to_robot(pose: tuple[float, float, float], moving: MovingDiscs) -> MovingDiscs:
    """World-frame discs into the robot frame of ``pose`` (velocities rotated only)."""
    from slitcli.local_map import to_robot

    c, s = math.cos(pose[2]), math.sin(pose[2])
    u = moving.velocity_xy
    return MovingDiscs(to_robot(pose, moving.centre_xy),
                       np.column_stack([c * u[:, 0] + s * u[:, 1], -s * u[:, 0] + c * u[:, 1]]),
                       moving.radius_m)
