"""Calibration targets seen by a raw (distorted) stereo camera: chessboards and a floor.

Renders what ``slitcli calibrate`` consumes, with exact ground truth:

- a planar chessboard at a given pose, optionally crossed by the laser sheet (a red
  Gaussian stripe of physical thickness ``laser_width_m``), for ``calibrate stereo``
  and ``calibrate laser``;
- a textured floor plane, for ``calibrate mount``.

Rendering is analytic ray casting per raw pixel: each of ``supersample**2`` sample
points of a pixel is undistorted to a ray (``cv2.undistortPoints`` iterated to
1e-8 px), the ray is intersected with the target plane and the pattern is sampled at
the hit point; the samples are averaged (anti-aliasing), then seeded Gaussian noise is
added. Distortion is OpenCV's (k1, k2, p1, p2[, k3]); the right camera is placed by
``X_right = R X_left + T`` as in :class:`slitcli.rig.RawCalibration`. All geometry is
in the *raw left* camera frame (x right, y down, z forward, metres) unless a name says
otherwise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from slitcli.rig import RawCalibration, unit_plane
from slitcli.sim.texture import value_noise

_UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 20, 1e-8)


@dataclass(frozen=True)
class RawCamera:
    """One raw camera: intrinsics, distortion and its pose relative to the left camera.

    ``K`` is 3x3, ``D`` OpenCV distortion (k1, k2, p1, p2[, k3]), ``image_size_px``
    (width, height). ``R_from_left`` and ``T_from_left_m`` map left-camera points into
    this camera (``X_cam = R X_left + T``); identity and zero for the left camera.
    """

    K: tuple
    D: tuple
    image_size_px: tuple[int, int]
    R_from_left: tuple = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
    T_from_left_m: tuple = (0.0, 0.0, 0.0)


def stereo_cameras(raw: RawCalibration) -> tuple[RawCamera, RawCamera]:
    """The left and right :class:`RawCamera` of a raw stereo calibration."""
    left = RawCamera(K=raw.K1, D=raw.D1, image_size_px=raw.image_size_px)
    right = RawCamera(K=raw.K2, D=raw.D2, image_size_px=raw.image_size_px,
                      R_from_left=raw.R, T_from_left_m=raw.T)
    return left, right


@dataclass(frozen=True)
class Chessboard:
    """A printed chessboard: ``cols`` x ``rows`` *inner* corners, squares ``square_m``.

    Board frame: origin at the first inner corner, x along a row of corners, y along a
    column, z = 0 on the board (OpenCV's object-point convention), so the checker area
    spans ``[-square_m, cols * square_m] x [-square_m, rows * square_m]``. The square
    touching the top-left corner of that area is dark. ``margin_m`` is the white quiet
    zone around the checker area; ``dark_albedo`` and ``light_albedo`` are reflectances.
    """

    cols: int
    rows: int
    square_m: float
    margin_m: float = 0.02
    dark_albedo: float = 0.08
    light_albedo: float = 0.85

    def object_points(self) -> np.ndarray:
        """Inner corners in the board frame, shape (cols * rows, 3), row by row, metres."""
        j, i = np.mgrid[0:self.rows, 0:self.cols]
        return np.stack([i.ravel() * self.square_m, j.ravel() * self.square_m,
                         np.zeros(i.size)], axis=-1).astype(float)

    @property
    def centre_board_xyz(self) -> np.ndarray:
        """Centre of the corner grid in the board frame, metres (shape (3,))."""
        return np.array([(self.cols - 1) * self.square_m / 2,
                         (self.rows - 1) * self.square_m / 2, 0.0])


@dataclass(frozen=True)
class BoardPose:
    """Pose of a board: ``X_left = R(rvec) X_board + tvec`` (Rodrigues vector, metres)."""

    rvec: tuple[float, float, float]
    tvec_m: tuple[float, float, float]

    @property
    def R(self) -> np.ndarray:
        return cv2.Rodrigues(np.asarray(self.rvec, dtype=float))[0]

    @property
    def t(self) -> np.ndarray:
        return np.asarray(self.tvec_m, dtype=float)


def board_pose_facing(board: Chessboard, centre_left_xyz_m: tuple[float, float, float], *,
                      yaw_deg: float = 0.0, pitch_deg: float = 0.0,
                      roll_deg: float = 0.0) -> BoardPose:
    """A board pose with the corner-grid centre at a point, turned from facing the camera.

    With all angles zero the board is parallel to the image plane (board x = camera x,
    board y = camera y). ``yaw_deg`` turns it about the camera y axis, ``pitch_deg``
    about x, ``roll_deg`` about z (applied in that order: R = Ry Rx Rz).
    """
    a, b, c = (math.radians(v) for v in (yaw_deg, pitch_deg, roll_deg))
    ry = np.array([[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]])
    rx = np.array([[1, 0, 0], [0, math.cos(b), -math.sin(b)], [0, math.sin(b), math.cos(b)]])
    rz = np.array([[math.cos(c), -math.sin(c), 0], [math.sin(c), math.cos(c), 0], [0, 0, 1]])
    R = ry @ rx @ rz
    t = np.asarray(centre_left_xyz_m, dtype=float) - R @ board.centre_board_xyz
    rvec = cv2.Rodrigues(R)[0].ravel()
    return BoardPose(rvec=tuple(float(v) for v in rvec), tvec_m=tuple(float(v) for v in t))


@dataclass(frozen=True)
class LaserSheet:
    """The laser sheet ``normal . X = offset_m`` in the raw left camera frame.

    ``width_m`` is the Gaussian sigma of the sheet's thickness; ``power_dn`` the red
    added on a surface of albedo 1 at the sheet's centre.
    """

    normal: tuple[float, float, float]
    offset_m: float
    width_m: float = 0.003
    power_dn: float = 110.0

    @property
    def unit_normal(self) -> np.ndarray:
        """Normal scaled to unit length (shape (3,))."""
        return unit_plane(self.normal, self.offset_m)[0]

    @property
    def unit_offset_m(self) -> float:
        """Offset of the plane once its normal is scaled to unit length, metres."""
        return unit_plane(self.normal, self.offset_m)[1]


@dataclass(frozen=True)
class Floor:
    """The floor ``up . X = -height_m`` seen from the raw left camera (``up`` unit, metres).

    Textured with the renderer's seeded multi-octave value noise
    (:func:`slitcli.sim.texture.value_noise`) of feature size ``texture_m``.
    """

    up_left: tuple[float, float, float]
    height_m: float
    texture_m: float = 0.03
    albedo: float = 0.55
    contrast: float = 0.8
    seed: int = 0


def floor_for_mount(height_m: float, tilt_deg: float, roll_deg: float = 0.0, **kw: float) -> Floor:
    """The :class:`Floor` seen by a camera ``height_m`` above it, pitched down ``tilt_deg``
    and rolled ``roll_deg`` (the conventions of :class:`slitcli.rig.Mount`)."""
    t, r = math.radians(tilt_deg), math.radians(roll_deg)
    up = (-math.cos(t) * math.sin(r), -math.cos(t) * math.cos(r), -math.sin(t))
    return Floor(up_left=up, height_m=height_m, **kw)


@dataclass(frozen=True)
class TargetRenderParams:
    """Image formation: ``supersample`` samples per pixel side, light level (DN on an
    albedo-1 surface), background level, sensor noise sigma (DN) and its seed."""

    supersample: int = 3
    illumination_dn: float = 180.0
    background_dn: float = 95.0
    noise_sigma_dn: float = 1.5
    far_limit_m: float = 12.0


class TargetRenderer:
    """Renders targets for one raw camera; the per-sample rays are computed once.

    Parameters
    ----------
    camera : RawCamera
    params : TargetRenderParams
    """

    def __init__(self, camera: RawCamera, params: TargetRenderParams | None = None) -> None:
        self.camera = camera
        self.params = params or TargetRenderParams()
        w, h = camera.image_size_px
        s = self.params.supersample
        offs = (np.arange(s) + 0.5) / s - 0.5
        # samples ordered (row, col, sub-row, sub-col) so a reshape averages each pixel
        v = np.arange(h)[:, None, None, None] + offs[None, None, :, None]
        u = np.arange(w)[None, :, None, None] + offs[None, None, None, :]
        u, v = np.broadcast_arrays(u, v)
        pts = np.stack([u.ravel(), v.ravel()], axis=-1).reshape(-1, 1, 2)
        xy = cv2.undistortPoints(pts, np.asarray(camera.K, float), np.asarray(camera.D, float),
                                 criteria=_UNDISTORT_CRITERIA).reshape(-1, 2)
        rays_cam = np.concatenate([xy, np.ones((xy.shape[0], 1))], axis=1)
        R = np.asarray(camera.R_from_left, dtype=float)
        T = np.asarray(camera.T_from_left_m, dtype=float).ravel()
        # rays (3, N) and centre of this camera in the left frame; rows kept separate
        # because (N, 3) @ (3, 3) products are far slower than three axpy-style sums
        self._rays_left_xyz = np.ascontiguousarray((rays_cam @ R).T)
        self._origin_left_xyz = -R.T @ T
        self._shape = (h, w, s * s)

    # ------------------------------------------------------------------ targets
    def render_board(self, board: Chessboard, pose: BoardPose, *,
                     laser: LaserSheet | None = None, seed: int = 0) -> np.ndarray:
        """A raw BGR uint8 image (H, W, 3) of ``board`` at ``pose``, with the laser stripe."""
        o, d = self._origin_left_xyz, self._rays_left_xyz
        R, t = pose.R, pose.t
        # work in the board frame, where the board is z = 0
        o_b = R.T @ (o - t)
        with np.errstate(divide="ignore", invalid="ignore"):
            s = -o_b[2] / _dot3(R[:, 2], d)
        hit = np.isfinite(s) & (s > 0)
        bx = o_b[0] + s * _dot3(R[:, 0], d)
        by = o_b[1] + s * _dot3(R[:, 1], d)
        sq, mg = board.square_m, board.margin_m
        wx, wy = board.cols * sq, board.rows * sq
        in_checker = (bx >= -sq) & (bx < wx) & (by >= -sq) & (by < wy)
        on_board = hit & (bx >= -sq - mg) & (bx < wx + mg) & (by >= -sq - mg) & (by < wy + mg)
        with np.errstate(invalid="ignore"):
            parity = (np.floor(bx / sq) + np.floor(by / sq)) % 2 == 0
        albedo = np.where(in_checker & parity, board.dark_albedo, board.light_albedo)
        p = self.params
        grey = np.where(on_board, albedo * p.illumination_dn, p.background_dn)
        red = grey
        if laser is not None:
            n = laser.unit_normal
            with np.errstate(invalid="ignore"):
                dist = (n @ o - laser.unit_offset_m) + s * _dot3(n, d)
            glow = laser.power_dn * np.exp(-0.5 * (dist / laser.width_m) ** 2)
            red = grey + np.where(on_board, albedo * glow, 0.0)
        return self._finish(grey, grey, red, seed)

    def render_floor(self, floor: Floor, *, seed: int = 0) -> np.ndarray:
        """A raw BGR uint8 image (H, W, 3) of the textured floor (background past the
        horizon and beyond ``far_limit_m``)."""
        o, d = self._origin_left_xyz, self._rays_left_xyz
        up = np.asarray(floor.up_left, dtype=float)
        up = up / np.linalg.norm(up)
        denom = _dot3(up, d)
        with np.errstate(divide="ignore", invalid="ignore"):
            s = (-floor.height_m - o @ up) / denom
        hit = (denom < -1e-12) & (s > 0)
        s = np.where(hit, s, 0.0)
        hit &= s * np.sqrt(_dot3(np.ones(3), d * d)) < self.params.far_limit_m
        e1 = np.cross(up, [0.0, 0.0, 1.0])
        if np.linalg.norm(e1) < 1e-6:
            e1 = np.cross(up, [1.0, 0.0, 0.0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(up, e1)
        tex = value_noise(o @ e1 + s * _dot3(e1, d), o @ e2 + s * _dot3(e2, d),
                          seed=floor.seed, scale_m=floor.texture_m)
        albedo = floor.albedo * (1.0 + floor.contrast * (tex - 0.5))
        grey = np.where(hit, albedo * self.params.illumination_dn, self.params.background_dn)
        return self._finish(grey, grey, grey, seed)

    def _finish(self, blue: np.ndarray, green: np.ndarray, red: np.ndarray,
                seed: int) -> np.ndarray:
        h, w, n = self._shape
        img = np.stack([c.reshape(h, w, n).mean(axis=2) for c in (blue, green, red)], axis=-1)
        rng = np.random.default_rng(seed)
        img = img + rng.normal(0.0, self.params.noise_sigma_dn, size=img.shape)
        return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def _dot3(a: np.ndarray, rows_xyz: np.ndarray) -> np.ndarray:
    """``a . r`` for every column r of a (3, N) array."""
    return a[0] * rows_xyz[0] + a[1] * rows_xyz[1] + a[2] * rows_xyz[2]


# ---------------------------------------------------------------------- truth
def project_board_corners(camera: RawCamera, board: Chessboard, pose: BoardPose) -> np.ndarray:
    """True raw pixel positions of the inner corners, shape (cols * rows, 2)."""
    R = np.asarray(camera.R_from_left, float) @ pose.R
    t = np.asarray(camera.R_from_left, float) @ pose.t + np.asarray(camera.T_from_left_m,
                                                                     float).ravel()
    uv, _ = cv2.projectPoints(board.object_points(), cv2.Rodrigues(R)[0], t,
                              np.asarray(camera.K, float), np.asarray(camera.D, float))
    return uv.reshape(-1, 2)


def stripe_rows_on_board(K_rect: np.ndarray, R_rect_from_left: np.ndarray,
                         image_size_px: tuple[int, int], board: Chessboard, pose: BoardPose,
                         laser: LaserSheet, *, inset_m: float = 0.0) -> np.ndarray:
    """True row of the stripe centre per column of an undistorted (rectified) image.

    The stripe centre is the line where the laser plane meets the board plane; its
    image under the pinhole ``K_rect`` (camera rotated by ``R_rect_from_left`` about
    the left optical centre) is straight.

    Returns
    -------
    v_px : ndarray, shape (W,)
        Subpixel row per column ``u = 0..W-1``; NaN where the line is outside the
        checker area shrunk by ``inset_m`` or outside the image.
    """
    w, h = image_size_px
    n, dl = laser.unit_normal, laser.unit_offset_m
    R, t = pose.R, pose.t
    m = R[:, 2]
    direction = np.cross(n, m)
    a = np.stack([n, m, direction])
    p0 = np.linalg.solve(a, np.array([dl, m @ t, 0.0]))
    Rr = np.asarray(R_rect_from_left, dtype=float)
    a_r, b_r = Rr @ p0, Rr @ direction
    fx, fy, cx, cy = K_rect[0, 0], K_rect[1, 1], K_rect[0, 2], K_rect[1, 2]
    u = np.arange(w, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = ((u - cx) * a_r[2] - fx * a_r[0]) / (fx * b_r[0] - (u - cx) * b_r[2])
        x_rect = a_r[None, :] + lam[:, None] * b_r[None, :]
        v = fy * x_rect[:, 1] / x_rect[:, 2] + cy
    x_left = x_rect @ Rr
    bxy = (x_left - t) @ R
    sq = board.square_m
    ok = ((x_rect[:, 2] > 0) & (bxy[:, 0] >= -sq + inset_m)
          & (bxy[:, 0] <= board.cols * sq - inset_m) & (bxy[:, 1] >= -sq + inset_m)
          & (bxy[:, 1] <= board.rows * sq - inset_m) & (v >= 0) & (v <= h - 1))
    return np.where(ok, v, np.nan)


def random_board_poses(cameras: tuple[RawCamera, ...], board: Chessboard, count: int, *,
                       distance_m: tuple[float, float] = (0.35, 0.7),
                       max_angle_deg: float = 35.0, border_px: float = 12.0,
                       laser: LaserSheet | None = None, seed: int = 0) -> list[BoardPose]:
    """Seeded random board poses whose whole board (with margin) is seen by every camera.

    Poses are drawn with the board centre on rays spread over the left image, at a
    distance in ``distance_m``, turned by up to ``max_angle_deg`` about x and y (and
    up to 20 deg about z); candidates whose outer board corners come within
    ``border_px`` of an image edge in any camera are redrawn. With ``laser`` the board
    centre is put where its ray meets the laser sheet, so the stripe crosses the board.
    """
    rng = np.random.default_rng(seed)
    left = cameras[0]
    w, h = left.image_size_px
    K = np.asarray(left.K, dtype=float)
    sq, mg = board.square_m, board.margin_m
    x0, x1 = -sq - mg, board.cols * sq + mg
    y0, y1 = -sq - mg, board.rows * sq + mg
    outline = np.array([[x0, y0, 0], [x1, y0, 0], [x1, y1, 0], [x0, y1, 0],
                        [(x0 + x1) / 2, y0, 0], [(x0 + x1) / 2, y1, 0],
                        [x0, (y0 + y1) / 2, 0], [x1, (y0 + y1) / 2, 0]], dtype=float)
    poses: list[BoardPose] = []
    for _ in range(200 * count):
        if len(poses) == count:
            break
        u, v = rng.uniform(0.2 * w, 0.8 * w), rng.uniform(0.2 * h, 0.8 * h)
        ray = np.linalg.solve(K, [u, v, 1.0])
        if laser is None:
            centre = ray / np.linalg.norm(ray) * rng.uniform(*distance_m)
        else:
            along = laser.unit_offset_m / float(ray @ laser.unit_normal)
            centre = ray * along
            if not distance_m[0] <= np.linalg.norm(centre) <= distance_m[1]:
                continue
        pose = board_pose_facing(board, tuple(centre), yaw_deg=rng.uniform(-1, 1) * max_angle_deg,
                                 pitch_deg=rng.uniform(-1, 1) * max_angle_deg,
                                 roll_deg=rng.uniform(-20, 20))
        ok = True
        for cam in cameras:
            R = np.asarray(cam.R_from_left, float)
            pts = (outline @ pose.R.T + pose.t) @ R.T + np.asarray(cam.T_from_left_m, float)
            if np.any(pts[:, 2] <= 0.05):
                ok = False
                break
            uv, _ = cv2.projectPoints(pts, np.zeros(3), np.zeros(3), np.asarray(cam.K, float),
                                      np.asarray(cam.D, float))
            uv = uv.reshape(-1, 2)
            cw, ch = cam.image_size_px
            if (uv.min() < border_px or np.any(uv[:, 0] > cw - 1 - border_px)
                    or np.any(uv[:, 1] > ch - 1 - border_px)):
                ok = False
                break
        if ok:
            poses.append(pose)
    if len(poses) < count:
        raise ValueError(f"found only {len(poses)} of {count} board poses in view; widen "
                         "distance_m or reduce max_angle_deg")
    return poses


def demo_raw_calibration() -> RawCalibration:
    """A distorted, slightly misaligned 480x360 stereo camera (for tests and examples).

    Left: f = (380, 381) px, barrel distortion k1 = -0.22; right: f = (383, 384) px,
    k1 = -0.20; right camera 0.088 m to the right (the paper's baseline), rotated by
    (0.5, -1.0, 0.3) deg (Rodrigues). Rectification by :func:`cv2.stereoRectify`
    (``CALIB_ZERO_DISPARITY``, alpha 0).
    """
    from slitcli.calibrate.rectify import rectify_raw

    K1 = np.array([[380.0, 0.0, 241.0], [0.0, 381.0, 178.0], [0.0, 0.0, 1.0]])
    D1 = np.array([-0.22, 0.06, 0.0008, -0.0004, 0.0])
    K2 = np.array([[383.0, 0.0, 238.0], [0.0, 384.0, 182.0], [0.0, 0.0, 1.0]])
    D2 = np.array([-0.20, 0.05, -0.0005, 0.0006, 0.0])
    R = cv2.Rodrigues(np.radians([0.5, -1.0, 0.3]))[0]
    T = np.array([-0.088, 0.001, 0.0005])
    return rectify_raw(K1, D1, K2, D2, (480, 360), R, T)
