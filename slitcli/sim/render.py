"""The ground-truth renderer (DESIGN §10): stereo images of a scene with the laser stripe.

Both cameras of any rig are rendered by analytic ray casting (:mod:`slitcli.sim.raycast`),
``supersample`` x ``supersample`` rays per pixel averaged (a box filter, so a symmetric
stripe keeps its centre), Lambertian shading with ambient light, seeded value-noise
textures, white highlights, the laser sheet as a Gaussian across the plane whose peak
falls with range, then sensor noise and 8-bit quantisation with saturation, or, if the
scene asks for one, a physical camera model (:mod:`slitcli.sim.camera`).

Ground truth is computed from the geometry, never from the images: depth and disparity
at pixel centres, the obstacle mask, the subpixel stripe row per column (bisection on
the exact surface) and the nearest obstacle range per bearing bin.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from slitcli.rig import Rig
from slitcli.sim.camera import apply_camera
from slitcli.sim.raycast import (
    FLOOR_ID,
    Hits,
    cast,
    hit_floor,
    hit_object,
    object_hull,
)
from slitcli.sim.scene import Pose2D, Scene, Surface
from slitcli.sim.texture import TextureTables, value_noise
from slitcli.sim.truth import true_ranges

SKY_DN = 0.7 * 255.0
FLOOR_MARGIN_M = 0.02


@dataclass(frozen=True)
class CameraPose:
    """A camera in the world: optical centre (3,) and rotation camera -> world (3, 3)."""

    origin_xyz: np.ndarray
    R_world_from_cam: np.ndarray


@dataclass(frozen=True)
class FrameTruth:
    """Ground truth of one frame, all for the left camera / the sensor frame.

    Attributes
    ----------
    depth_m : (H, W) float
        Depth along the optical axis at pixel centres, metres; NaN where a ray meets nothing.
    disparity_px : (H, W) float
        ``f B / depth`` (Eq. 8); NaN where there is no depth.
    obstacle_mask : (H, W) bool
        The pixel sees an obstacle point above the floor margin and below the robot height.
    textured : (H, W) bool
        The image carries texture at the pixel, so stereo can match it: the pixel sees a
        surface with a noise texture, or the laser stripe lights it by at least
        :data:`LIT_MIN_SIGMAS` noise sigmas (a plain surface is plain only off the stripe).
    object_id : (H, W) int
        -1 nothing, 0 floor, k + 1 for scene object k.
    stripe_v_px : (W,) float
        Subpixel row of the laser stripe centre per column; NaN where no stripe is visible.
    stripe_peak_dn : (W,) float
        Expected stripe peak brightness (digital numbers) per column; NaN where none.
    stripe_sensor_xyz : (W, 3) float
        The lit point of each column in the sensor frame, metres; NaN where none.
    bearing_deg, range_m : (B,) float
        Bin centres and the nearest obstacle range per bin (NaN: none within max range).
    pose : Pose2D
    """

    depth_m: np.ndarray
    disparity_px: np.ndarray
    obstacle_mask: np.ndarray
    textured: np.ndarray
    object_id: np.ndarray
    stripe_v_px: np.ndarray
    stripe_peak_dn: np.ndarray
    stripe_sensor_xyz: np.ndarray
    bearing_deg: np.ndarray
    range_m: np.ndarray
    pose: Pose2D


@dataclass(frozen=True)
class RenderedFrame:
    """A rendered stereo pair (BGR uint8, (H, W, 3)) with its ground truth."""

    left_bgr: np.ndarray
    right_bgr: np.ndarray
    truth: FrameTruth


@dataclass(frozen=True)
class RenderedView:
    """The left image of a rendered pair (BGR uint8, (H, W, 3)) with the pair's ground
    truth (:func:`render_left`)."""

    left_bgr: np.ndarray
    truth: FrameTruth


# ------------------------------------------------------------------ placement
def _rot_z(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def camera_poses(rig: Rig, pose: Pose2D) -> tuple[CameraPose, CameraPose]:
    """World placement of the left and right cameras for a robot pose."""
    rz = _rot_z(pose.yaw_rad)
    sensor = np.array([pose.x_m + rig.mount.forward_m * math.cos(pose.yaw_rad),
                       pose.y_m + rig.mount.forward_m * math.sin(pose.yaw_rad), 0.0])
    r_wc = rz @ rig.R_sensor_from_cam
    left = sensor + rz @ rig.cam_origin_sensor_xyz
    right = left + r_wc @ rig.right_origin_cam_xyz
    return CameraPose(left, r_wc), CameraPose(right, r_wc)


def laser_plane_world(rig: Rig, pose: Pose2D) -> tuple[np.ndarray, float, np.ndarray]:
    """The laser plane in the world (unit normal, offset) and the emitter position.

    The emitter is taken at the foot of the perpendicular from the left camera to the
    sheet: for the paper rig, on the robot front directly below the camera.
    """
    left, _ = camera_poses(rig, pose)
    n_w = left.R_world_from_cam @ rig.laser.unit_normal
    d_w = rig.laser.unit_offset_m + float(n_w @ left.origin_xyz)
    emitter = left.origin_xyz - (float(n_w @ left.origin_xyz) - d_w) * n_w
    return n_w, d_w, emitter


def pixel_dirs_world(rig: Rig, cam: CameraPose, u_px: np.ndarray, v_px: np.ndarray
                     ) -> np.ndarray:
    """World directions of pixel rays, scaled so their camera-frame z is 1 (..., 3)."""
    return rig.pixel_rays_cam(u_px, v_px) @ cam.R_world_from_cam.T


# ------------------------------------------------------------------ ray casting
def _cast_grid(scene: Scene, rig: Rig, cam: CameraPose, ss: int) -> tuple[Hits, np.ndarray]:
    """Cast a supersampled grid of rays; each object is tested only inside its image box."""
    w, h = rig.image_size_px
    offs = (np.arange(ss) + 0.5) / ss - 0.5
    u = (np.arange(w)[:, None] + offs[None, :]).ravel()
    v = (np.arange(h)[:, None] + offs[None, :]).ravel()
    hs, ws = len(v), len(u)
    dirs = pixel_dirs_world(rig, cam, u[None, :], v[:, None])          # (hs, ws, 3)
    flat = dirs.reshape(-1, 3)
    t, n, st = hit_floor(cam.origin_xyz, flat)
    obj = np.where(np.isfinite(t), FLOOR_ID, -1)
    t, obj, n, st = (a.reshape(hs, ws, *a.shape[1:]) for a in (t, obj, n, st))
    for k, ob in enumerate(scene.objects):
        win = _image_window(rig, cam, object_hull(ob), ss)
        if win is None:
            continue
        r0, r1, c0, c1 = win
        sub = dirs[r0:r1, c0:c1].reshape(-1, 3)
        tk, nk, sk = hit_object(ob, cam.origin_xyz, sub)
        shape = (r1 - r0, c1 - c0)
        tk = tk.reshape(shape)
        closer = tk < t[r0:r1, c0:c1]
        t[r0:r1, c0:c1] = np.where(closer, tk, t[r0:r1, c0:c1])
        obj[r0:r1, c0:c1] = np.where(closer, k + 1, obj[r0:r1, c0:c1])
        n[r0:r1, c0:c1][closer] = nk.reshape(*shape, 3)[closer]
        st[r0:r1, c0:c1][closer] = sk.reshape(*shape, 2)[closer]
    return Hits(t.ravel(), obj.ravel(), n.reshape(-1, 3), st.reshape(-1, 2)), flat


_HULL_EDGES = np.array([[0, 1], [1, 2], [2, 3], [3, 0], [4, 5], [5, 6], [6, 7], [7, 4],
                        [0, 4], [1, 5], [2, 6], [3, 7]])


def _image_window(rig: Rig, cam: CameraPose, corners_xyz: np.ndarray, ss: int
                  ) -> tuple[int, int, int, int] | None:
    """Supersampled-grid rows/cols that can see a convex hull (8 corners, two rings of 4);
    None if it is out of view.

    The hull is clipped against a near plane in front of the camera first, so an object
    that reaches behind the camera (a corridor wall beside the robot) is bounded by the
    part in front of it instead of falling back to the whole image.
    """
    w, h = rig.image_size_px
    near = 1e-3
    pc = (corners_xyz - cam.origin_xyz) @ cam.R_world_from_cam
    front = pc[pc[:, 2] > near]
    a, b = pc[_HULL_EDGES[:, 0]], pc[_HULL_EDGES[:, 1]]
    cross = (a[:, 2] - near) * (b[:, 2] - near) < 0
    if np.any(cross):
        s = (near - a[cross, 2]) / (b[cross, 2] - a[cross, 2])
        front = np.vstack([front, a[cross] + s[:, None] * (b[cross] - a[cross])])
    if len(front) == 0:
        return None
    u, v = rig.project_cam(front)
    c0 = int(np.floor(max((u.min() + 0.5) * ss, -1.0))) - 2
    c1 = int(np.ceil(min((u.max() + 0.5) * ss, w * ss + 1.0))) + 2
    r0 = int(np.floor(max((v.min() + 0.5) * ss, -1.0))) - 2
    r1 = int(np.ceil(min((v.max() + 0.5) * ss, h * ss + 1.0))) + 2
    c0, c1 = max(c0, 0), min(c1, w * ss)
    r0, r1 = max(r0, 0), min(r1, h * ss)
    if c0 >= c1 or r0 >= r1:
        return None
    return r0, r1, c0, c1


def _surfaces(scene: Scene) -> list[Surface]:
    return [scene.floor, *(ob.surface for ob in scene.objects)]


def _surface_seed(scene: Scene, obj_id: int) -> int:
    s = _surfaces(scene)[obj_id]
    return s.seed if s.seed is not None else scene.seed * 1009 + obj_id


# ------------------------------------------------------------------ shading
def _shade(scene: Scene, hits: Hits, points: np.ndarray,
           textures: TextureTables | None = None) -> np.ndarray:
    """Radiance of every hit in digital numbers before noise, (N, 3) RGB."""
    surfaces = _surfaces(scene)
    albedo = np.array([s.colour_rgb for s in surfaces])
    rgb = np.full((len(hits.t), 3), SKY_DN)
    hit = hits.obj >= 0
    light = np.asarray(scene.image.light_dir_xyz, dtype=float)
    light = light / np.linalg.norm(light)
    amb = scene.image.ambient
    shade = amb + (1.0 - amb) * np.abs(hits.normal_xyz @ light)
    tex = np.ones(len(hits.t))
    for oid, s in enumerate(surfaces):
        if s.texture != "noise" or s.contrast <= 0:
            continue
        sel = hits.obj == oid
        if not np.any(sel):
            continue
        noise = value_noise(hits.st_m[sel, 0], hits.st_m[sel, 1],
                            seed=_surface_seed(scene, oid), scale_m=s.scale_m,
                            textures=textures)
        # value noise concentrates near 0.5: stretch it so `contrast` is the usual swing
        tex[sel] = np.clip(1.0 + 2.5 * s.contrast * (noise - 0.5), 0.05, 2.0)
    ids = np.where(hit, hits.obj, 0)
    rgb[hit] = (255.0 * scene.image.exposure * albedo[ids[hit]]
                * (tex[hit] * shade[hit])[:, None])
    for hl in scene.highlights:
        d2 = ((points[hit] - np.asarray(hl.position_xyz_m)) ** 2).sum(axis=1)
        rgb[hit] += (255.0 * hl.brightness * np.exp(-d2 / (2 * hl.radius_m**2)))[:, None]
    return rgb


def _laser_peak(scene: Scene, rig: Rig, pose: Pose2D, points: np.ndarray, obj: np.ndarray,
                normals: np.ndarray) -> np.ndarray:
    """Peak stripe brightness (DN) the laser would give at each point if it lies on the
    sheet; 0 where the point is shadowed from the emitter or outside the fan."""
    _, _, emitter = laser_plane_world(rig, pose)
    vec = points - emitter
    r = np.linalg.norm(vec, axis=1)
    dirs = vec / np.maximum(r, 1e-12)[:, None]
    first = cast(scene, emitter, dirs)
    lit = (first.t >= r - 1e-6) & (obj >= 0)
    fwd = np.array([math.cos(pose.yaw_rad), math.sin(pose.yaw_rad), 0.0])
    off_axis = np.degrees(np.arccos(np.clip(dirs @ fwd, -1, 1)))
    lit &= off_axis <= scene.laser.fan_deg
    red = np.array([s.colour_rgb[0] for s in _surfaces(scene)])[np.where(obj >= 0, obj, 0)]
    cos_inc = np.abs((normals * dirs).sum(axis=1))
    lk = scene.laser
    peak = lk.power_dn * (lk.ref_range_m / np.maximum(r, 1e-6)) ** lk.falloff_exponent
    return np.where(lit, peak * red * cos_inc, 0.0)


def _add_laser(scene: Scene, rig: Rig, pose: Pose2D, hits: Hits, points: np.ndarray,
               rgb: np.ndarray) -> np.ndarray:
    """``rgb`` (N, 3) plus the laser's light at each hit (a new array; DN)."""
    if not scene.laser.enabled:
        return rgb
    n_w, d_w, _ = laser_plane_world(rig, pose)
    w = scene.laser.width_m
    dist = points @ n_w - d_w
    near = np.nonzero((hits.obj >= 0) & (np.abs(dist) < 6 * w))[0]
    if len(near) == 0:
        return rgb
    peak = _laser_peak(scene, rig, pose, points[near], hits.obj[near], hits.normal_xyz[near])
    light = peak * np.exp(-0.5 * (dist[near] / w) ** 2)
    out = rgb.copy()
    out[near, 0] += light
    out[near, 1:] += scene.laser.crosstalk * light[:, None]
    return out


def _cast_and_shade(scene: Scene, rig: Rig, cam: CameraPose,
                    textures: TextureTables | None = None
                    ) -> tuple[Hits, np.ndarray, np.ndarray]:
    hits, dirs = _cast_grid(scene, rig, cam, scene.image.supersample)
    t = np.where(np.isfinite(hits.t), hits.t, 0.0)
    points = cam.origin_xyz + t[:, None] * dirs
    return hits, points, _shade(scene, hits, points, textures)


def linear_radiance(scene: Scene, rig: Rig, pose: Pose2D, cam: CameraPose, *,
                    textures: TextureTables | None = None
                    ) -> tuple[np.ndarray, np.ndarray]:
    """The light reaching one camera, before any camera model: the scene's and the laser's.

    ``textures``: texture tables kept by the caller
    (:class:`~slitcli.sim.texture.TextureTables`), as for :func:`render_frame`.

    Returns
    -------
    scene_rgb_dn, laser_rgb_dn : (H, W, 3) float
        Linear radiance per pixel (box filter of the supersampled rays), RGB, DN (255 =
        white level), without and of the laser sheet. ``apply_camera`` turns the pair
        into an image (:mod:`slitcli.sim.camera`).
    """
    ss = scene.image.supersample
    w, h = rig.image_size_px
    hits, points, rgb = _cast_and_shade(scene, rig, cam, textures)
    laser = _add_laser(scene, rig, pose, hits, points, np.zeros_like(rgb))
    return (rgb.reshape(h, ss, w, ss, 3).mean(axis=(1, 3)),
            laser.reshape(h, ss, w, ss, 3).mean(axis=(1, 3)))


def _render_camera(scene: Scene, rig: Rig, pose: Pose2D, cam: CameraPose,
                   rng: np.random.Generator, textures: TextureTables | None) -> np.ndarray:
    if scene.image.camera is not None:
        # the camera model needs the laser's light apart (speckle is on it alone)
        scene_rgb, laser_rgb = linear_radiance(scene, rig, pose, cam, textures=textures)
        # speckle is fixed by the geometry: the same view gives the same pattern
        view = np.r_[cam.origin_xyz, cam.R_world_from_cam.ravel()].round(9) + 0.0
        speckle_rng = np.random.default_rng([scene.seed, *np.frombuffer(view.tobytes(),
                                                                         np.uint32)])
        return apply_camera(scene_rgb, scene.image.camera, rng, laser_rgb_dn=laser_rgb,
                            speckle_rng=speckle_rng)
    ss = scene.image.supersample
    w, h = rig.image_size_px
    hits, points, rgb = _cast_and_shade(scene, rig, cam, textures)
    rgb = _add_laser(scene, rig, pose, hits, points, rgb)
    img = rgb.reshape(h, ss, w, ss, 3).mean(axis=(1, 3))
    if scene.image.noise_sigma_dn > 0:
        img = img + rng.normal(0.0, scene.image.noise_sigma_dn, img.shape)
    img = np.clip(np.rint(img), 0, 255).astype(np.uint8)
    return np.ascontiguousarray(img[..., ::-1])  # RGB -> BGR (OpenCV order)


# ------------------------------------------------------------------ truth
LIT_MIN_SIGMAS = 3.0  # laser light (DN) above this many noise sigmas is image texture
def _stripe_truth(scene: Scene, rig: Rig, pose: Pose2D, cam: CameraPose, hits: Hits,
                  depth: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact stripe row per column: sign changes of the hit point's signed distance to
    the laser sheet between pixel rows, refined by bisection on the object's own surface,
    then checked for visibility from the camera and for light from the emitter."""
    w, h = rig.image_size_px
    v_out = np.full(w, np.nan)
    peak_out = np.full(w, np.nan)
    xyz_out = np.full((w, 3), np.nan)
    if not scene.laser.enabled:
        return v_out, peak_out, xyz_out
    n_w, d_w, _ = laser_plane_world(rig, pose)
    obj = hits.obj.reshape(h, w)
    dirs = pixel_dirs_world(rig, cam, np.arange(w)[None, :], np.arange(h)[:, None])
    pts = cam.origin_xyz + np.where(np.isfinite(depth), depth, 0.0)[..., None] * dirs
    f = np.where(obj >= 0, pts @ n_w - d_w, np.nan)
    change = np.sign(f[:-1]) * np.sign(f[1:]) <= 0
    rows, cols = np.nonzero(change & np.isfinite(f[:-1]) & np.isfinite(f[1:]))
    cand_v, cand_u, cand_obj = [], [], []
    for which in (obj[rows, cols], obj[rows + 1, cols]):
        cand_v.append(rows)
        cand_u.append(cols)
        cand_obj.append(which)
    v0 = np.concatenate(cand_v).astype(float)
    u = np.concatenate(cand_u).astype(float)
    oid = np.concatenate(cand_obj)
    best_v = np.full(len(u), np.nan)
    for k in np.unique(oid):
        sel = np.nonzero(oid == k)[0]
        best_v[sel] = _bisect_on_object(scene, rig, cam, int(k), u[sel], v0[sel], n_w, d_w)
    ok = np.isfinite(best_v)
    u, best_v, oid = u[ok], best_v[ok], oid[ok]
    d = pixel_dirs_world(rig, cam, u, best_v)
    first = cast(scene, cam.origin_xyz, d)
    own_t = np.full(len(oid), np.nan)
    for k in np.unique(oid):
        sel = oid == k
        own_t[sel] = _t_on(scene, int(k), cam.origin_xyz, d[sel])
    visible = (first.obj == oid) & (np.abs(first.t - own_t) < 1e-7)
    p = cam.origin_xyz + own_t[:, None] * d
    peak = _laser_peak(scene, rig, pose, p, oid, first.normal_xyz)
    keep = visible & (peak >= scene.laser.visible_min_dn) & (best_v >= -0.5) & \
        (best_v <= h - 0.5)
    u, best_v, peak, p = u[keep], best_v[keep], peak[keep], p[keep]
    sensor = _world_to_sensor(rig, pose, p)
    rng_h = np.hypot(sensor[:, 0], sensor[:, 1])
    # with two lit points in a column (rare occlusion geometry) keep the nearest
    order = np.lexsort((rng_h, u))
    u, best_v, peak, sensor = u[order], best_v[order], peak[order], sensor[order]
    first_in_col = np.r_[True, u[1:] != u[:-1]][: len(u)]
    ui = u[first_in_col].astype(int)
    v_out[ui] = best_v[first_in_col]
    peak_out[ui] = peak[first_in_col]
    xyz_out[ui] = sensor[first_in_col]
    return v_out, peak_out, xyz_out


def _t_on(scene: Scene, oid: int, o: np.ndarray, d: np.ndarray) -> np.ndarray:
    if oid == FLOOR_ID:
        return hit_floor(o, d)[0]
    return hit_object(scene.objects[oid - 1], o, d)[0]


def _bisect_on_object(scene: Scene, rig: Rig, cam: CameraPose, oid: int, u: np.ndarray,
                      v0: np.ndarray, n_w: np.ndarray, d_w: float) -> np.ndarray:
    """Row in [v0, v0 + 1] where the ray meets object ``oid`` exactly on the sheet."""
    def f(v: np.ndarray) -> np.ndarray:
        d = pixel_dirs_world(rig, cam, u, v)
        t = _t_on(scene, oid, cam.origin_xyz, d)
        hit = np.isfinite(t)
        p = cam.origin_xyz + np.where(hit, t, 0.0)[:, None] * d
        return np.where(hit, p @ n_w - d_w, np.nan)

    lo, hi = v0.copy(), v0 + 1.0
    f_lo, f_hi = f(lo), f(hi)
    ok = np.isfinite(f_lo) & np.isfinite(f_hi) & (np.sign(f_lo) != np.sign(f_hi))
    for _ in range(48):
        mid = 0.5 * (lo + hi)
        f_mid = f(mid)
        go_hi = np.sign(f_mid) == np.sign(f_lo)
        ok &= np.isfinite(f_mid)
        lo = np.where(go_hi, mid, lo)
        f_lo = np.where(go_hi, f_mid, f_lo)
        hi = np.where(go_hi, hi, mid)
    return np.where(ok, 0.5 * (lo + hi), np.nan)


def _world_to_sensor(rig: Rig, pose: Pose2D, p: np.ndarray) -> np.ndarray:
    origin = np.array([pose.x_m + rig.mount.forward_m * math.cos(pose.yaw_rad),
                       pose.y_m + rig.mount.forward_m * math.sin(pose.yaw_rad), 0.0])
    return (p - origin) @ _rot_z(pose.yaw_rad)


def frame_truth(scene: Scene, rig: Rig, pose: Pose2D, *, bin_deg: float = 1.0) -> FrameTruth:
    """Ground truth of the left view from the geometry alone (no image is rendered)."""
    w, h = rig.image_size_px
    left, _ = camera_poses(rig, pose)
    dirs = pixel_dirs_world(rig, left, np.arange(w)[None, :], np.arange(h)[:, None])
    hits = cast(scene, left.origin_xyz, dirs.reshape(-1, 3))
    depth = np.where(np.isfinite(hits.t), hits.t, np.nan).reshape(h, w)
    disparity = rig.disparity_from_depth(depth)
    obj = hits.obj.reshape(h, w)
    z = (left.origin_xyz[2] + np.where(np.isfinite(depth), depth, 0.0)
         * dirs[..., 2])
    mask = (obj >= 1) & (z > FLOOR_MARGIN_M) & (z < scene.robot.height_m)
    textured_ids = np.array([s.texture == "noise" and s.contrast >= 0.05
                             for s in _surfaces(scene)])
    textured = (obj >= 0) & textured_ids[np.where(obj >= 0, obj, 0)]
    if scene.laser.enabled:
        centres_xyz = left.origin_xyz + np.where(np.isfinite(hits.t), hits.t, 0.0)[:, None] \
            * dirs.reshape(-1, 3)
        light = _add_laser(scene, rig, pose, hits, centres_xyz,
                           np.zeros((h * w, 3)))[:, 0].reshape(h, w)
        textured |= light >= LIT_MIN_SIGMAS * max(scene.image.noise_sigma_dn, 1.0)
    stripe_v, stripe_peak, stripe_xyz = _stripe_truth(scene, rig, pose, left, hits, depth)
    centres, lo, hi = rig.bearing_bins(bin_deg)
    ranges = true_ranges(scene, pose, lo, hi, forward_m=rig.mount.forward_m,
                         floor_margin_m=FLOOR_MARGIN_M)
    return FrameTruth(depth, disparity, mask, textured, obj, stripe_v, stripe_peak, stripe_xyz,
                      centres, ranges, pose)


def _frame_rng(scene: Scene, frame_index: int) -> np.random.Generator:
    """The sensor noise of frame ``frame_index``: the left image takes its first draws,
    the right image the next (:func:`render_pair`, :func:`render_left`)."""
    return np.random.default_rng([scene.seed, frame_index])


def render_pair(scene: Scene, rig: Rig, pose: Pose2D, *, frame_index: int = 0,
                textures: TextureTables | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The two images of :func:`render_frame` (BGR uint8, (H, W, 3)), without the ground
    truth: for the closed loop's vision sensing, which needs none (the truth is about a
    fifth of such a step). Parameters are :func:`render_frame`'s."""
    left_cam, right_cam = camera_poses(rig, pose)
    rng = _frame_rng(scene, frame_index)
    left = _render_camera(scene, rig, pose, left_cam, rng, textures)
    return left, _render_camera(scene, rig, pose, right_cam, rng, textures)


def render_frame(scene: Scene, rig: Rig, pose: Pose2D, *, frame_index: int = 0,
                 textures: TextureTables | None = None) -> RenderedFrame:
    """Render one stereo pair and its ground truth.

    Parameters
    ----------
    scene : Scene
    rig : Rig
        Any rectified rig; both of its cameras are rendered.
    pose : Pose2D
        Robot pose in the world.
    frame_index : int
        Seeds the sensor noise together with ``scene.seed`` (textures depend on the
        scene seed only, so they stay fixed in the world across frames).
    textures : TextureTables, optional
        Texture tables kept from earlier frames of the scene
        (:class:`~slitcli.sim.texture.TextureTables`): the same images, without drawing
        the textures' random tables again for each frame.
    """
    left, right = render_pair(scene, rig, pose, frame_index=frame_index, textures=textures)
    return RenderedFrame(left, right, frame_truth(scene, rig, pose))


def render_left(scene: Scene, rig: Rig, pose: Pose2D, *, frame_index: int = 0,
                textures: TextureTables | None = None) -> RenderedView:
    """The left image of :func:`render_frame` and its ground truth, without the right
    image: bit for bit the left image and truth of that call, in a little more than half
    its time. For work that looks through the left camera alone (the laser stripe).

    Parameters are :func:`render_frame`'s.
    """
    left_cam, _ = camera_poses(rig, pose)
    left = _render_camera(scene, rig, pose, left_cam, _frame_rng(scene, frame_index), textures)
    return RenderedView(left, frame_truth(scene, rig, pose))
