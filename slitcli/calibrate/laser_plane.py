"""``slitcli calibrate laser``: the laser plane from chessboard views crossed by the stripe.

For each view (a left image, and the right image of the same moment when there is one):

1. the board's inner corners are found on the raw images, mapped to rectified pixels and
   the board pose in the rig's (rectified left) camera frame is estimated from both
   cameras (triangulated corners, refined on the reprojection error in both images:
   :mod:`slitcli.calibrate.board_pose`), or from the left camera alone
   (:func:`cv2.solvePnP`, less accurate in depth and tilt) when there is no right image;
2. the stripe is extracted per image column on the rectified image (the laser module,
   paper Eqs. 1-4), giving subpixel rows ``v_px``;
3. each stripe pixel's ray ``K^-1 (u, v, 1)`` is intersected with the board plane; points
   off the printed checker area are dropped (the stripe may continue on the background).

The points of all views are fitted with a plane ``n . X = d`` by SVD with iterative
2-sigma outlier rejection (sigma from the median absolute residual, so that rejection
does not shrink it). Degenerate input — one pose, or points that are nearly collinear
— is refused by a singular-value ratio test: the stripe of one board pose is a line,
which leaves the plane's rotation about it undetermined.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import cv2
import numpy as np

from slitcli.calibrate.board import BoardSpec, View, find_corners, list_views
from slitcli.calibrate.board_pose import BoardPoseEstimate, board_pose_left, board_pose_stereo
from slitcli.calibrate.rectify import rectify_pair
from slitcli.errors import SlitcliError
from slitcli.io.sequence import read_image
from slitcli.rig import Rig, load_rig, save_rig

#: (rectified BGR image (H, W, 3) uint8, search mask (H, W) bool: the board) ->
#: stripe row per column (W,), NaN where none
StripeExtractor = Callable[[np.ndarray, np.ndarray], np.ndarray]


def extract_stripe_rows(rectified_bgr: np.ndarray, search_mask: np.ndarray) -> np.ndarray:
    """Per-column subpixel stripe rows of a rectified left image (the laser module).

    This is the one place where calibration calls the laser extraction (paper Eqs. 1-4).
    The search is limited to the board (``search_mask``): the rig's own laser plane,
    which the detector would otherwise use to bound its search, is what is being
    calibrated.
    """
    try:
        from slitcli import laser  # type: ignore[attr-defined]
    except ImportError:
        raise SlitcliError("this slitcli has no laser extraction module (slitcli.laser); "
                           "`calibrate laser` needs it: update slitcli") from None
    found = laser.extract_stripe(rectified_bgr, laser.LaserParams(), search_mask=search_mask)
    return np.asarray(found.v_px, dtype=float)


def board_mask(rig: Rig, R_board: np.ndarray, t_board: np.ndarray, board: BoardSpec, *,
               inset_m: float = 0.0) -> np.ndarray:
    """Pixels (H, W) bool of the rectified left image covered by the checker area."""
    sq = board.square_m
    x0, x1 = -sq + inset_m, board.cols * sq - inset_m
    y0, y1 = -sq + inset_m, board.rows * sq - inset_m
    quad = np.array([[x0, y0, 0.0], [x1, y0, 0.0], [x1, y1, 0.0], [x0, y1, 0.0]])
    u, v = rig.project_cam(quad @ R_board.T + t_board)
    mask = np.zeros((rig.height_px, rig.width_px), dtype=np.uint8)
    if np.all(np.isfinite(u)) and np.all(np.isfinite(v)):
        cv2.fillConvexPoly(mask, np.round(np.stack([u, v], axis=-1)).astype(np.int32), 1)
    return mask.astype(bool)


@dataclass(frozen=True)
class LaserPlaneParams:
    """Options of the laser-plane calibration.

    ``min_views``: board poses with stripe points required (one pose is degenerate).
    ``min_points_per_view``: stripe points on the board for a view to count.
    ``reject_sigma``: outlier threshold in robust standard deviations (2-sigma rule).
    ``max_iterations``: rejection rounds.
    ``min_spread_ratio``: smallest accepted ratio of the second to the first singular
    value of the centred points (0 = collinear, a single pose).
    ``inset_squares``: stripe points closer than this many squares to the edge of the
    checker area are dropped (the board edge and quiet zone are not measured).
    """

    board: BoardSpec
    min_views: int = 2
    min_points_per_view: int = 10
    reject_sigma: float = 2.0
    max_iterations: int = 20
    min_spread_ratio: float = 0.05
    inset_squares: float = 0.25


@dataclass(frozen=True)
class PlaneFit:
    """A fitted plane ``normal . X = offset_m`` (unit normal, offset > 0), camera frame."""

    normal: tuple[float, float, float]
    offset_m: float
    residual_std_m: float
    inliers: int
    points: int
    spread_ratio: float
    inlier_mask: np.ndarray


def fit_plane_svd(points_xyz: np.ndarray, *, reject_sigma: float = 2.0,
                  max_iterations: int = 20, min_spread_ratio: float = 0.05,
                  source: str = "laser points") -> PlaneFit:
    """Least-squares plane by SVD with iterative outlier rejection.

    Parameters
    ----------
    points_xyz : ndarray, shape (N, 3), metres, camera frame.
    reject_sigma : points with ``|residual| > reject_sigma * sigma`` are outliers; sigma
        is ``1.4826 * median |residual|`` over all points for the current fit.
    max_iterations : rejection rounds (stops early when the inlier set is stable).
    min_spread_ratio : refuse when ``s2 / s1 < min_spread_ratio`` (``s`` the singular
        values of the centred inliers): the points are (nearly) on a line.
    source : named in errors.

    Returns
    -------
    PlaneFit
        ``residual_std_m`` is the RMS distance of the inliers to the plane.
    """
    p = np.asarray(points_xyz, dtype=float).reshape(-1, 3)
    p = p[np.all(np.isfinite(p), axis=1)]
    if p.shape[0] < 3:
        raise SlitcliError(f"{source}: only {p.shape[0]} stripe points; a plane needs points "
                           "from at least two board poses")
    keep = np.ones(p.shape[0], dtype=bool)
    normal = np.zeros(3)
    centroid = np.zeros(3)
    spread = 0.0
    for _ in range(max(1, max_iterations)):
        centroid = p[keep].mean(axis=0)
        _, s, vt = np.linalg.svd(p[keep] - centroid, full_matrices=False)
        spread = float(s[1] / s[0]) if s[0] > 0 else 0.0
        if spread < min_spread_ratio:
            raise SlitcliError(f"{source}: the stripe points are nearly collinear (singular-"
                               f"value ratio {spread:.4f} < {min_spread_ratio:g}), as from a "
                               "single board pose; add views with the board at different "
                               "distances")
        normal = vt[2]
        r = (p - centroid) @ normal
        sigma = 1.4826 * float(np.median(np.abs(r)))
        new_keep = np.abs(r) <= reject_sigma * max(sigma, 1e-12)
        if new_keep.sum() < 3:
            break
        if np.array_equal(new_keep, keep):
            break
        keep = new_keep
    offset = float(normal @ centroid)
    if offset < 0:
        normal, offset = -normal, -offset
    r = p[keep] @ normal - offset
    return PlaneFit(normal=tuple(float(v) for v in normal), offset_m=offset,
                    residual_std_m=float(np.sqrt(np.mean(r**2))), inliers=int(keep.sum()),
                    points=int(p.shape[0]), spread_ratio=spread, inlier_mask=keep)


def board_pose_rectified(corners_raw_px: np.ndarray, rig: Rig,
                         board: BoardSpec) -> tuple[np.ndarray, np.ndarray]:
    """Board pose from the left camera alone: ``X = R X_board + t`` (rig camera frame).

    See :func:`slitcli.calibrate.board_pose.board_pose_left`; kept for callers that
    want ``(R, t)``.
    """
    est = board_pose_left(corners_raw_px, rig, board)
    return est.R, est.t_m


def stripe_points_on_board(v_px: np.ndarray, rig: Rig, R_board: np.ndarray,
                           t_board: np.ndarray, board: BoardSpec, *,
                           inset_m: float = 0.0) -> np.ndarray:
    """Intersect the rays of per-column stripe rows with the board plane.

    Parameters
    ----------
    v_px : ndarray, shape (W,)
        Stripe row per column ``u = 0..W-1`` of the rectified left image, NaN = none.
    rig : Rig
    R_board, t_board : board pose in the rig's camera frame (``X = R X_board + t``).
    board : BoardSpec
    inset_m : keep only points at least this far inside the checker area.

    Returns
    -------
    points_cam_xyz : ndarray, shape (M, 3)
        Lit points on the board, rig (rectified left) camera frame, metres.
    """
    v = np.asarray(v_px, dtype=float).ravel()
    u = np.arange(v.size, dtype=float)
    ok = np.isfinite(v)
    rays = rig.pixel_rays_cam(u[ok], v[ok])
    m = R_board[:, 2]
    denom = rays @ m
    with np.errstate(divide="ignore", invalid="ignore"):
        s = float(m @ t_board) / denom
    x = rays * s[:, None]
    bxy = (x - t_board) @ R_board
    keep = (np.abs(denom) > 1e-9) & (s > 0) & board.contains(bxy, inset_m=inset_m)
    return x[keep]


@dataclass(frozen=True)
class LaserViewReport:
    """One view: used or skipped (reason), stripe points kept, its RMS residual (mm),
    and how its board pose was found (``pose``: ``stereo`` or ``left``, with the note
    why a stereo view fell back to ``left``) with its reprojection RMS (px)."""

    name: str
    used: bool
    reason: str = ""
    points: int = 0
    residual_rms_mm: float = float("nan")
    pose: str = ""
    reprojection_rms_px: float = float("nan")


@dataclass(frozen=True)
class LaserCalibration:
    """The fitted plane, the rig carrying it, and per-view statistics."""

    rig: Rig
    fit: PlaneFit
    views: tuple[LaserViewReport, ...]

    def report_lines(self) -> list[str]:
        n = self.fit.normal
        tilt = math.degrees(math.asin(max(-1.0, min(1.0, n[2]))))
        used = [v for v in self.views if v.used]
        stereo = sum(v.pose == "stereo" for v in used)
        lines = [f"views: {len(used)} used of {len(self.views)} (board pose from both cameras "
                 f"in {stereo}, from the left camera alone in {len(used) - stereo})",
                 f"laser plane (rig camera frame): normal [{n[0]:.5f}, {n[1]:.5f}, {n[2]:.5f}]"
                 f", offset_m {self.fit.offset_m:.5f} (normal {tilt:.3f} deg from the image "
                 "plane)",
                 f"residual_std_mm: {1000 * self.fit.residual_std_m:.3f} over "
                 f"{self.fit.inliers} of {self.fit.points} points (2-sigma rejection); "
                 f"singular-value ratio {self.fit.spread_ratio:.3f}",
                 "per view: points, residual_rms_mm, pose, reprojection_rms_px"]
        lines += [f"  {v.name}: {v.points} {v.residual_rms_mm:.3f} {v.pose} "
                  f"{v.reprojection_rms_px:.3f}" for v in used]
        lines += [f"skipped {v.name}: {v.reason}" for v in self.views if not v.used]
        return lines


def view_board_pose(left_bgr: np.ndarray, right_bgr: np.ndarray | None, rig: Rig,
                    board: BoardSpec) -> tuple[BoardPoseEstimate | None, str]:
    """The board pose of one view: from both cameras when it can, else from the left.

    Returns
    -------
    pose, how : the pose (None: no board in the left image) and ``stereo``, ``left``,
        or ``left (why the right image was not used)``.
    """
    corners = find_corners(left_bgr, board)
    if corners is None:
        return None, ""
    if right_bgr is not None:
        right = find_corners(right_bgr, board)
        if right is None:
            why = "no board in the right image"
        else:
            est = board_pose_stereo(corners, right, rig, board)
            if est is not None:
                return est, "stereo"
            why = "left and right corners are not one pose for this rig"
        return board_pose_left(corners, rig, board), f"left ({why})"
    return board_pose_left(corners, rig, board), "left"


def calibrate_laser_images(names: list[str], images_bgr: list[np.ndarray], rig: Rig,
                           params: LaserPlaneParams, *,
                           right_images_bgr: list[np.ndarray | None] | None = None,
                           extractor: StripeExtractor | None = None,
                           source: str = "views") -> LaserCalibration:
    """Fit the laser plane from board views (raw if ``rig.raw`` is set).

    Parameters
    ----------
    names : view names for reports.
    images_bgr : (H, W, 3) uint8 images of the left camera (the stripe is read here).
    rig : the stereo-calibrated rig; its laser plane is replaced.
    params : LaserPlaneParams
    right_images_bgr : the right camera's images of the same views (None entries, or
        None for all: left camera only). With both images a view's board pose comes
        from both cameras (:func:`~slitcli.calibrate.board_pose.board_pose_stereo`),
        more accurate in depth and tilt than from the left camera alone.
    extractor : stripe rows per column of a rectified image within a mask; default
        :func:`extract_stripe_rows` (the laser module).
    source : named in errors.
    """
    extract = extractor if extractor is not None else extract_stripe_rows
    board = params.board
    rights = list(right_images_bgr) if right_images_bgr is not None else [None] * len(names)
    want = rig.raw.image_size_px if rig.raw is not None else rig.image_size_px
    reports: list[LaserViewReport] = []
    per_view: list[np.ndarray] = []
    for name, img, right in zip(names, images_bgr, rights, strict=True):
        for side, im in (("", img), ("right ", right)):
            if im is not None and (im.shape[1], im.shape[0]) != tuple(want):
                raise SlitcliError(f"{source}/{name}: {side}size {im.shape[1]}x{im.shape[0]} "
                                   f"does not match the rig's {want[0]}x{want[1]}; use the rig "
                                   "of this camera (`rig`)", param="rig")
        est, how = view_board_pose(img, right, rig, board)
        if est is None:
            reports.append(LaserViewReport(name, False, f"no {board.cols}x{board.rows} board "
                                           "found"))
            continue
        rect, _ = rectify_pair(rig, img)
        v = extract(rect, board_mask(rig, est.R, est.t_m, board))
        pts = stripe_points_on_board(v, rig, est.R, est.t_m, board,
                                     inset_m=params.inset_squares * board.square_m)
        if pts.shape[0] < params.min_points_per_view:
            reports.append(LaserViewReport(name, False, f"only {pts.shape[0]} stripe points on "
                                           "the board (laser off, or the stripe misses it)"))
            continue
        reports.append(LaserViewReport(name, True, points=int(pts.shape[0]), pose=how,
                                       reprojection_rms_px=est.reprojection_rms_px))
        per_view.append(pts)
    if not per_view:
        detail = "; ".join(f"{r.name}: {r.reason}" for r in reports[:3])
        raise SlitcliError(f"{source}: no view shows both the board and the laser stripe "
                           f"({detail}); check `board` and that the stripe crosses the board",
                           param="board")
    if len(per_view) < params.min_views:
        raise SlitcliError(f"{source}: only {len(per_view)} usable board pose(s); the laser "
                           f"plane needs at least {max(params.min_views, 2)} poses at different"
                           " distances (a single pose only gives a line)")
    pts_all = np.concatenate(per_view)
    fit = fit_plane_svd(pts_all, reject_sigma=params.reject_sigma,
                        max_iterations=params.max_iterations,
                        min_spread_ratio=params.min_spread_ratio, source=source)
    n = np.asarray(fit.normal)
    final: list[LaserViewReport] = []
    k = 0
    for r in reports:
        if r.used:
            res = per_view[k] @ n - fit.offset_m
            final.append(replace(r, residual_rms_mm=float(1000 * np.sqrt(np.mean(res**2)))))
            k += 1
        else:
            final.append(r)
    laser = replace(rig.laser, normal=fit.normal, offset_m=fit.offset_m)
    return LaserCalibration(rig=replace(rig, laser=laser), fit=fit, views=tuple(final))


def laser_views(images_dir: str | Path, *,
                use_right: bool = True) -> list[tuple[View, Path | None]]:
    """The views: left images and, where there is one, the right image of the same name.

    ``images_dir/left/`` (and ``images_dir/right/``) if it exists, else ``images_dir``
    alone (left camera only). Right images pair with left ones by file stem; a left view
    without a right partner (or ``use_right=False``) gets None.
    """
    d = Path(images_dir)
    if not (d / "left").is_dir():
        return [(v, None) for v in list_views(d, "laser views")]
    left = list_views(d / "left", "laser views (left)")
    right: dict[str, Path] = {}
    if use_right and (d / "right").is_dir():
        right = {v.name: v.path for v in list_views(d / "right", "laser views (right)")}
    return [(v, right.get(v.name)) for v in left]


def run_calibrate_laser(rig_path: str | Path, images_dir: str | Path, params: LaserPlaneParams,
                        *, out_rig: str | Path | None = None,
                        use_right: bool = True) -> LaserCalibration:
    """``slitcli calibrate laser``: fit the plane and write it into the rig (atomically).

    ``out_rig`` defaults to ``rig_path`` (updated in place). Nothing is written on error.
    ``use_right=False`` ignores ``images_dir/right/`` (board poses from the left camera
    alone, less accurate).
    """
    rig = load_rig(rig_path)
    views = laser_views(images_dir, use_right=use_right)
    images = [read_image(v.path) for v, _ in views]
    rights = [None if r is None else read_image(r) for _, r in views]
    result = calibrate_laser_images([v.name for v, _ in views], images, rig, params,
                                    right_images_bgr=rights, source=str(images_dir))
    save_rig(result.rig, out_rig if out_rig is not None else rig_path)
    return result
