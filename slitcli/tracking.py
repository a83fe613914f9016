"""Moving-obstacle tracking: obstacle points clustered per frame and followed across frames.

The planner's prediction (:class:`slitcli.dwa.MovingDiscs`) comes from here. Each frame's
obstacle points (one per bearing bin with a return, in bearing order) are split into
clusters where consecutive points lie more than ``gap_m`` apart; every cluster is matched
to the nearest predicted track centroid within a gate, and each track keeps its last
``history_s`` seconds of centroids and points.

A track is **moving** when two independent signs agree over that history:

- its centroid velocity (least-squares slope of the centroid over the history) exceeds
  ``moving_speed_mps``, and
- the places its points occupied at the start of the history are now empty: of those
  old points the current frame's rays reach (in view), at least ``moving_vacated``
  are seen free or hidden behind a nearer return, not on a surface
  (:meth:`slitcli.local_map.ScanRays.state`).

The second test is what keeps static obstacles static while the robot moves: the
visible part of a wall slides through the field of view and its centroid drifts at up
to the robot's speed, but its old points still lie on the surface the rays return
from. A person's old places are free (walking across or away) or behind the person
(walking at the robot).

World frame, metres, seconds. Tracks are few (one per object in view), so the per-track
work below runs over tracks, never over points or bins.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from slitcli.local_map import FREE, OCCLUDED, UNSEEN


@dataclass(frozen=True, kw_only=True)
class TrackParams:
    """Tracking settings.

    Attributes
    ----------
    gap_m : float
        Consecutive points (by bearing) farther apart than this start a new cluster.
    gate_m : float
        A cluster matches a track whose predicted centroid lies within this distance.
    history_s : float
        Span of centroids and points a track keeps for its velocity and shift tests.
    moving_speed_mps, moving_vacated : float
        The two thresholds of the moving test (module docstring).
    coast_s : float
        A track not seen for this long is dropped; until then its prediction continues
        (out of view, e.g. a walker the robot has passed). A track whose predicted
        centre the current rays see free is dropped at once.
    min_history_s : float
        No track is called moving before it has been seen over this span.
    min_in_view : int
        The vacated test needs at least this many old points in view.
    shape_cell_m : float
        A moving track's outline is handed to the planner as one point per cell of
        this size (:meth:`_Track.shape`).
    """

    gap_m: float = 0.25
    gate_m: float = 0.6
    history_s: float = 1.5
    moving_speed_mps: float = 0.05
    moving_vacated: float = 0.5
    min_in_view: int = 3
    shape_cell_m: float = 0.05
    coast_s: float = 15.0
    min_history_s: float = 0.6


def segment(points_xy: np.ndarray, gap_m: float) -> np.ndarray:
    """Cluster label per point (N,), points in bearing order: a new label at each gap."""
    p = np.asarray(points_xy, dtype=float).reshape(-1, 2)
    if len(p) == 0:
        return np.zeros(0, dtype=np.int64)
    jump = np.hypot(*np.diff(p, axis=0).T) > gap_m
    return np.concatenate([[0], np.cumsum(jump)]).astype(np.int64)


def register(old_xy: np.ndarray, new_xy: np.ndarray, guess_xy: np.ndarray, *,
             iterations: int = 10, keep: float = 0.7) -> np.ndarray:
    """Translation (2,) that moves the points ``old_xy`` (M, 2) onto ``new_xy`` (N, 2).

    Translation-only ICP from ``guess_xy``: each iteration matches every new point to
    its nearest moved old point and adds the mean residual of the best ``keep`` share
    (the parts seen only in one of the two frames find no true partner). The visible
    part of a body changes as the line of sight turns, which biases a centroid; the
    points of the two frames still lie on the same outline, and the registration
    follows the outline, not the visible part's centre.
    """
    shift = np.asarray(guess_xy, dtype=float).copy()
    n_keep = max(1, int(keep * len(new_xy)))
    for _ in range(iterations):
        moved = old_xy + shift
        d = new_xy[:, None, :] - moved[None, :, :]                      # (N, M, 2)
        dist = np.hypot(d[..., 0], d[..., 1])
        nn = dist.argmin(axis=1)
        res = d[np.arange(len(new_xy)), nn]
        best = np.argsort(dist[np.arange(len(new_xy)), nn])[:n_keep]
        step = res[best].mean(axis=0)
        shift += step
        if np.hypot(*step) < 1e-4:
            break
    return shift


@dataclass
class _Track:
    track_id: int
    times_s: list[float] = field(default_factory=list)
    centroids: list[np.ndarray] = field(default_factory=list)
    points: list[np.ndarray] = field(default_factory=list)
    whole: list[bool] = field(default_factory=list)
    velocity_xy: np.ndarray = field(default_factory=lambda: np.zeros(2))
    moving: bool = False
    ever_moving: bool = False

    def shape(self, t_s: float, cell_m: float) -> np.ndarray:
        """Points of the history moved on by the velocity to ``t_s``, one per cell, (S, 2).

        A person at the edge of the view shows only part of itself; the history,
        motion-compensated, keeps the rest.
        """
        v = self.velocity_xy if self.ever_moving else np.zeros(2)
        pts = np.concatenate([p + v * (t_s - t) for p, t in zip(self.points, self.times_s,
                                                                strict=True)])
        cells = np.floor(pts / cell_m).astype(np.int64)
        _, inv = np.unique(cells, axis=0, return_inverse=True)
        inv = inv.ravel()
        n = int(inv.max()) + 1
        cnt = np.bincount(inv, minlength=n)
        return np.column_stack([np.bincount(inv, pts[:, 0], n), np.bincount(inv, pts[:, 1], n)]
                               ) / cnt[:, None]


@dataclass(frozen=True)
class TrackSnapshot:
    """The tracks after one update; arrays over tracks (T,).

    ``track_id`` (T,), ``velocity_xy`` (T, 2) m/s, ``moving`` and ``ever_moving`` (T,)
    bool; ``shape_xy`` (S, 2) each track's motion-compensated outline at the update
    time (:meth:`_Track.shape`) with ``shape_track`` (S,) the index of its track;
    ``point_track`` (N,) the track id of each input point.
    """

    track_id: np.ndarray
    velocity_xy: np.ndarray
    moving: np.ndarray
    ever_moving: np.ndarray
    shape_xy: np.ndarray
    shape_track: np.ndarray
    point_track: np.ndarray


class Tracker:
    """Follows clusters of obstacle points across frames (see the module docstring).

    Stateful by design (one per closed-loop run); :meth:`update` returns an immutable
    :class:`TrackSnapshot`.
    """

    def __init__(self, params: TrackParams | None = None) -> None:
        self.params = params or TrackParams()
        self._tracks: list[_Track] = []
        self._next_id = 0

    def update(self, points_xy: np.ndarray, t_s: float,
               state: Callable[[np.ndarray], np.ndarray],
               at_edge: np.ndarray | None = None,
               origin_xy: np.ndarray | None = None) -> TrackSnapshot:
        """Add one frame's points (N, 2), world frame, in bearing order, seen at ``t_s``.

        ``state`` maps world points (M, 2) to what this frame's rays say about them
        (:meth:`slitcli.local_map.ScanRays.state` codes). ``at_edge`` (N,) marks points
        in the outermost bearing bins: a cluster touching them may be cut by the field
        of view, and its centroid then does not enter the velocity fit.

        A cluster's position is its centroid pushed away from the sensor (``origin_xy``)
        by its width across the line of sight over pi: the visible half of a round
        body of width 2r has its centroid 2r/pi in front of the body's centre, and
        without the correction a person passing beside the robot, seen from a turning
        line of sight, appears to drift towards it.
        """
        p = self.params
        pts = np.asarray(points_xy, dtype=float).reshape(-1, 2)
        edge = np.zeros(len(pts), dtype=bool) if at_edge is None else np.asarray(at_edge)
        labels = segment(pts, p.gap_m)
        n_cl = int(labels.max()) + 1 if len(pts) else 0
        counts = np.bincount(labels, minlength=n_cl)
        cut = np.bincount(labels, edge, minlength=n_cl) > 0
        cent = np.column_stack([np.bincount(labels, pts[:, 0], n_cl),
                                np.bincount(labels, pts[:, 1], n_cl)]) / np.maximum(counts,
                                                                                  1)[:, None]
        if origin_xy is not None and n_cl:
            los = cent - np.asarray(origin_xy, dtype=float)
            los /= np.maximum(np.hypot(los[:, 0], los[:, 1]), 1e-9)[:, None]
            across = pts[:, 0] * -los[labels, 1] + pts[:, 1] * los[labels, 0]
            lo = np.full(n_cl, np.inf)
            hi = np.full(n_cl, -np.inf)
            np.minimum.at(lo, labels, across)
            np.maximum.at(hi, labels, across)
            cent = cent + ((hi - lo) / np.pi)[:, None] * los
        pred = np.array([tr.centroids[-1] + tr.velocity_xy * (t_s - tr.times_s[-1])
                         for tr in self._tracks]).reshape(-1, 2)
        dist = np.hypot(cent[:, None, 0] - pred[None, :, 0], cent[:, None, 1] - pred[None, :, 1])
        # greedy nearest-first matching, one cluster per track
        cluster_track = np.full(n_cl, -1)
        taken = np.zeros(len(self._tracks), dtype=bool)
        for flat in np.argsort(dist, axis=None):
            c, k = np.unravel_index(flat, dist.shape)
            if dist[c, k] > p.gate_m:
                break
            if cluster_track[c] < 0 and not taken[k]:
                cluster_track[c], taken[k] = k, True
        for c in range(n_cl):
            if cluster_track[c] < 0:
                self._tracks.append(_Track(self._next_id))
                self._next_id += 1
                cluster_track[c] = len(self._tracks) - 1
            self._observe(self._tracks[cluster_track[c]], t_s, cent[c], pts[labels == c],
                          not cut[c], state)
        ids = np.array([tr.track_id for tr in self._tracks], dtype=np.int64)
        point_track = ids[cluster_track[labels]] if len(pts) else np.zeros(0, dtype=np.int64)
        unseen = [tr for tr in self._tracks if tr.times_s[-1] < t_s]
        if unseen:
            at = np.array([tr.centroids[-1] + (tr.velocity_xy * (t_s - tr.times_s[-1])
                                               if tr.ever_moving else 0.0) for tr in unseen])
            gone = {id(tr) for tr, st in zip(unseen, state(at), strict=True) if st == FREE}
        else:
            gone = set()
        self._tracks = [tr for tr in self._tracks
                        if t_s - tr.times_s[-1] <= p.coast_s and id(tr) not in gone]
        return self._snapshot(t_s, point_track)

    def _observe(self, tr: _Track, t_s: float, centroid: np.ndarray, pts: np.ndarray,
                 whole: bool, state: Callable[[np.ndarray], np.ndarray]) -> None:
        p = self.params
        tr.times_s.append(t_s)
        tr.centroids.append(centroid)
        tr.points.append(pts)
        tr.whole.append(whole)
        while t_s - tr.times_s[0] > p.history_s + 1e-9:
            for hist in (tr.times_s, tr.centroids, tr.points, tr.whole):
                hist.pop(0)
        ok = np.array(tr.whole)
        t = np.array(tr.times_s)
        v0 = tr.velocity_xy
        if ok.sum() >= 2 and t[ok][-1] > t[ok][0]:
            # least-squares slope of the centroid over the frames seen whole
            c = np.array(tr.centroids)[ok]
            tc = t[ok] - t[ok].mean()
            v0 = (tc[:, None] * (c - c.mean(axis=0))).sum(axis=0) / (tc * tc).sum()
        span = t[-1] - t[0]
        if span >= p.min_history_s - 1e-9:
            # refined by registering the oldest view onto the newest: outlines, not the
            # visible parts' centroids, so it works on views cut by the field of view too
            v0 = register(tr.points[0], pts, v0 * span) / span
        tr.velocity_xy = v0
        if tr.times_s[-1] - tr.times_s[0] < p.min_history_s - 1e-9:
            return
        st = state(tr.points[0])
        seen = st != UNSEEN
        vacated = (st == FREE) | (st == OCCLUDED)
        tr.moving = bool(np.hypot(*tr.velocity_xy) > p.moving_speed_mps
                         and seen.sum() >= p.min_in_view
                         and vacated.sum() >= p.moving_vacated * seen.sum())
        tr.ever_moving = tr.ever_moving or tr.moving

    def _snapshot(self, t_s: float, point_track: np.ndarray) -> TrackSnapshot:
        shapes = [tr.shape(t_s, self.params.shape_cell_m) for tr in self._tracks]
        return TrackSnapshot(
            np.array([tr.track_id for tr in self._tracks], dtype=np.int64),
            np.array([tr.velocity_xy for tr in self._tracks]).reshape(-1, 2),
            np.array([tr.moving for tr in self._tracks], dtype=bool),
            np.array([tr.ever_moving for tr in self._tracks], dtype=bool),
            np.concatenate([np.zeros((0, 2)), *shapes]),
            np.repeat(np.arange(len(shapes)), [len(x) for x in shapes]).astype(np.int64),
            point_track)
