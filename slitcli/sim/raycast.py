"""Analytic ray casting against a scene: floor plane, upright boxes, cylinders and walls.

All functions take one ray origin and many directions (N, 3) in the world frame and are
vectorised over the rays. A ray point is ``origin + t * direction``; with directions
scaled so that their camera-frame z is 1, ``t`` is directly the depth along the optical
axis.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from slitcli.sim.scene import Box, Cylinder, Obstacle, Scene, Wall

EPS = 1e-9
FLOOR_ID = 0


@dataclass(frozen=True)
class Hits:
    """First hits of a bundle of rays.

    ``t`` (N,) ray parameter (inf on a miss), ``obj`` (N,) object id (-1 miss, 0 floor,
    k + 1 for the scene's object k), ``normal_xyz`` (N, 3) unit normal facing the ray,
    ``st_m`` (N, 2) surface coordinates in metres for texturing.
    """

    t: np.ndarray
    obj: np.ndarray
    normal_xyz: np.ndarray
    st_m: np.ndarray


def _empty(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return np.full(n, np.inf), np.zeros((n, 3)), np.zeros((n, 2))


def hit_floor(o: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rays against the floor z = 0 (seen from above)."""
    t, n, st = _empty(len(d))
    with np.errstate(divide="ignore", invalid="ignore"):
        tt = -o[2] / d[:, 2]
    ok = (d[:, 2] < 0) & (tt > EPS) if o[2] > 0 else np.zeros(len(d), bool)
    t[ok] = tt[ok]
    n[:, 2] = 1.0
    st[:, 0] = o[0] + t * d[:, 0]
    st[:, 1] = o[1] + t * d[:, 1]
    st[~ok] = 0.0
    return t, n, st


def hit_box(b: Box, o: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rays against an upright box (slab method in the box's own frame)."""
    t, n, st = _empty(len(d))
    c, s = math.cos(math.radians(b.yaw_deg)), math.sin(math.radians(b.yaw_deg))
    half = np.array([b.size_m[0] / 2, b.size_m[1] / 2, b.size_m[2] / 2])
    centre = np.array([b.centre_xy_m[0], b.centre_xy_m[1], b.z_min_m + half[2]])
    rot = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])  # world -> box
    ol = rot @ (o - centre)
    dl = d @ rot.T
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / dl
        t1 = (-half - ol) * inv
        t2 = (half - ol) * inv
    # a ray parallel to a slab and outside it gives NaN/inf products: it never enters
    t1 = np.where(np.isnan(t1), -np.inf, t1)
    t2 = np.where(np.isnan(t2), np.inf, t2)
    tmin = np.minimum(t1, t2)
    tmax = np.maximum(t1, t2)
    axis = np.argmax(tmin, axis=1)
    t_near = np.take_along_axis(tmin, axis[:, None], 1)[:, 0]
    t_far = tmax.min(axis=1)
    ok = (t_near <= t_far) & (t_near > EPS)
    t[ok] = t_near[ok]
    dsign = np.take_along_axis(dl, axis[:, None], 1)[:, 0]
    nl = np.zeros_like(dl)
    nl[np.arange(len(d)), axis] = -np.sign(dsign)
    n[:] = nl @ rot  # box -> world
    pl = ol + np.where(ok, t_near, 0.0)[:, None] * dl
    zw = pl[:, 2] + centre[2]
    # distinct faces take distinct regions of the noise field so they do not repeat
    face = axis * 2 + (dsign > 0)
    st[:, 0] = np.where(axis == 0, pl[:, 1], pl[:, 0]) + 37.0 * face
    st[:, 1] = np.where(axis == 2, pl[:, 1], zw)
    return t, n, st


def hit_cylinder(cy: Cylinder, o: np.ndarray, d: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rays against an upright capped cylinder."""
    t, n, st = _empty(len(d))
    ox, oy = o[0] - cy.centre_xy_m[0], o[1] - cy.centre_xy_m[1]
    a = d[:, 0] ** 2 + d[:, 1] ** 2
    b = 2 * (ox * d[:, 0] + oy * d[:, 1])
    cc = ox * ox + oy * oy - cy.radius_m**2
    disc = b * b - 4 * a * cc
    with np.errstate(divide="ignore", invalid="ignore"):
        ts = (-b - np.sqrt(np.maximum(disc, 0.0))) / (2 * a)
    zs = o[2] + ts * d[:, 2]
    side = (disc >= 0) & (a > 0) & (ts > EPS) & (zs >= cy.z_min_m) & (zs <= cy.z_max_m)
    t = np.where(side, ts, t)
    px = ox + t * d[:, 0]
    py = oy + t * d[:, 1]
    n[:, 0] = np.where(side, px / cy.radius_m, 0.0)
    n[:, 1] = np.where(side, py / cy.radius_m, 0.0)
    st[:, 0] = np.where(side, cy.radius_m * np.arctan2(py, px), 0.0)
    st[:, 1] = np.where(side, zs, 0.0)
    for zc, sign in ((cy.z_max_m, 1.0), (cy.z_min_m, -1.0)):
        if sign < 0 and cy.z_min_m <= 0:
            continue  # a cylinder standing on the floor shows no bottom cap
        with np.errstate(divide="ignore", invalid="ignore"):
            tc = (zc - o[2]) / d[:, 2]
        cx_, cy_ = ox + tc * d[:, 0], oy + tc * d[:, 1]
        cap = (tc > EPS) & (cx_ * cx_ + cy_ * cy_ <= cy.radius_m**2) & (tc < t)
        t = np.where(cap, tc, t)
        n[cap] = (0.0, 0.0, sign)
        st[cap, 0] = cx_[cap] + (60.0 if sign > 0 else 90.0)
        st[cap, 1] = cy_[cap]
    return t, n, st


def hit_wall(w: Wall, o: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rays against a vertical two-sided rectangle."""
    t, n, st = _empty(len(d))
    a = np.array([w.from_xy_m[0], w.from_xy_m[1], 0.0])
    ab = np.array([w.to_xy_m[0] - a[0], w.to_xy_m[1] - a[1], 0.0])
    length = float(np.hypot(ab[0], ab[1]))
    u = ab / length
    nrm = np.array([-u[1], u[0], 0.0])
    den = d @ nrm
    with np.errstate(divide="ignore", invalid="ignore"):
        tt = ((a - o) @ nrm) / den
    p = o + np.where(np.isfinite(tt), tt, 0.0)[:, None] * d
    s = (p - a) @ u
    ok = (np.abs(den) > 1e-15) & (tt > EPS) & (s >= 0) & (s <= length) & \
        (p[:, 2] >= w.z_min_m) & (p[:, 2] <= w.z_max_m)
    t[ok] = tt[ok]
    n[:] = np.where((den < 0)[:, None], nrm, -nrm)
    st[:, 0] = s
    st[:, 1] = p[:, 2]
    return t, n, st


def hit_object(ob: Obstacle, o: np.ndarray, d: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Dispatch on the obstacle type."""
    if isinstance(ob, Box):
        return hit_box(ob, o, d)
    if isinstance(ob, Cylinder):
        return hit_cylinder(ob, o, d)
    return hit_wall(ob, o, d)


def object_hull(ob: Obstacle) -> np.ndarray:
    """8 corners of a convex hull of the obstacle, world frame (8, 3): a ring of 4 at its
    bottom, then the same ring at its top (a wall is a flat, degenerate ring)."""
    if isinstance(ob, Box):
        from slitcli.sim.scene import box_corners_xy

        xy = box_corners_xy(ob)
    elif isinstance(ob, Cylinder):
        cx, cy, r = ob.centre_xy_m[0], ob.centre_xy_m[1], ob.radius_m
        xy = np.array([[cx - r, cy - r], [cx + r, cy - r], [cx + r, cy + r], [cx - r, cy + r]])
    else:
        xy = np.array([ob.from_xy_m, ob.to_xy_m, ob.to_xy_m, ob.from_xy_m], dtype=float)
    lo = np.column_stack([xy, np.full(4, ob.z_min_m)])
    hi = np.column_stack([xy, np.full(4, ob.z_max_m)])
    return np.vstack([lo, hi])


def cast(scene: Scene, o: np.ndarray, d: np.ndarray, *, floor: bool = True) -> Hits:
    """First hit of every ray against the whole scene."""
    t, n, st = hit_floor(o, d) if floor else _empty(len(d))
    obj = np.where(np.isfinite(t), FLOOR_ID, -1)
    for k, ob in enumerate(scene.objects):
        tk, nk, sk = hit_object(ob, o, d)
        closer = tk < t
        t = np.where(closer, tk, t)
        obj = np.where(closer, k + 1, obj)
        n[closer] = nk[closer]
        st[closer] = sk[closer]
    return Hits(t, obj, n, st)
