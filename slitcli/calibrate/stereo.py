"""``slitcli calibrate stereo``: intrinsics, extrinsics and rectification from chessboards.

Per camera :func:`cv2.calibrateCamera` (k1, k2, p1, p2 and optionally k3), then a joint
:func:`cv2.stereoCalibrate` refinement of both cameras and the pose ``R, T`` of the
right camera, then :func:`cv2.stereoRectify` (see :mod:`.rectify`). Views where either
camera does not see the whole board are named and skipped; too few usable views are
refused.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from slitcli.calibrate.board import BoardSpec, find_corners, list_views, load_views
from slitcli.calibrate.rectify import rectify_pair, rectify_points, rectify_raw, rig_with_raw
from slitcli.errors import SlitcliError
from slitcli.rig import Rig, load_rig

_CRITERIA = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-10)


@dataclass(frozen=True)
class StereoCalibrationParams:
    """Options of the stereo calibration.

    ``min_views``: usable views (board seen by both cameras) required.
    ``k3``: also estimate the third radial coefficient (wide-angle lenses); otherwise
    it is fixed at 0 (k1, k2, p1, p2: OpenCV's plumb_bob with k3 = 0, Kalibr's radtan).
    ``alpha``: :func:`cv2.stereoRectify` free scaling (0 = only valid pixels).
    """

    board: BoardSpec
    min_views: int = 5
    k3: bool = False
    alpha: float = 0.0


@dataclass(frozen=True)
class ViewReport:
    """One stereo view: used or skipped (with the reason), its RMS reprojection errors."""

    name: str
    used: bool
    reason: str = ""
    rms_left_px: float = float("nan")
    rms_right_px: float = float("nan")


PLACEHOLDER_NOTE = ("the rig's mount and laser plane are placeholders (the paper rig's, or "
                    "`base_rig`'s), not calibrated: run `slitcli calibrate laser` and "
                    "`slitcli calibrate mount`, or set them with `slitcli rig set`")
PLACEHOLDER_COMMENT = (
    "# mount and laser were NOT calibrated by `slitcli calibrate stereo`: they are\n"
    "# placeholders (the paper rig's, or the --base rig's). Measure them with\n"
    "# `slitcli calibrate laser` and `slitcli calibrate mount`, or set them with\n"
    "# `slitcli rig set RIG --mount-height-m H --tilt-deg T --laser-height-m Z`.\n")


@dataclass(frozen=True)
class EpipolarError:
    """Row difference |dy| of matching board corners after rectification, pixels.

    In a perfectly rectified pair every corner lies on the same row in both images;
    ``dy`` measures what the stereo matcher (which searches one row) will see.
    """

    median_px: float
    p95_px: float
    max_px: float
    corners: int


def epipolar_error(rig: Rig, corners_left_raw: list[np.ndarray],
                   corners_right_raw: list[np.ndarray]) -> EpipolarError:
    """|dy| statistics of corresponding raw corners mapped into the rectified pair.

    Parameters
    ----------
    corners_left_raw, corners_right_raw : per view, (N, 2) or (N, 1, 2) raw pixels of
        the same corners in the same order.
    """
    left = np.concatenate([rectify_points(rig, c.reshape(-1, 2), camera="left")
                           for c in corners_left_raw])
    right = np.concatenate([rectify_points(rig, c.reshape(-1, 2), camera="right")
                            for c in corners_right_raw])
    dy = np.abs(left[:, 1] - right[:, 1])
    return EpipolarError(median_px=float(np.median(dy)), p95_px=float(np.percentile(dy, 95)),
                         max_px=float(dy.max()), corners=int(dy.size))


def rectified_preview(rig: Rig, left_bgr: np.ndarray, right_bgr: np.ndarray, *,
                      spacing_px: int = 24) -> np.ndarray:
    """The rectified pair side by side with horizontal lines every ``spacing_px`` rows.

    A feature must sit on the same line in both halves; returns (H, 2 W, 3) uint8 BGR.
    """
    lr, rr = rectify_pair(rig, left_bgr, right_bgr)
    assert rr is not None
    pair = np.concatenate([np.atleast_3d(lr), np.atleast_3d(rr)], axis=1)
    if pair.shape[2] == 1:
        pair = np.repeat(pair, 3, axis=2)
    pair = np.ascontiguousarray(pair.astype(np.uint8))
    rows = np.arange(spacing_px // 2, pair.shape[0], spacing_px)
    # alternate colours so a line can be followed across the seam
    pair[rows[0::2]] = (0, 255, 0)
    pair[rows[1::2]] = (255, 0, 255)
    return pair


@dataclass(frozen=True)
class StereoCalibration:
    """The result: the rig and the reprojection statistics (pixels)."""

    rig: Rig
    rms_px: float
    rms_left_mono_px: float
    rms_right_mono_px: float
    views: tuple[ViewReport, ...]
    epipolar: EpipolarError | None = None
    preview: np.ndarray | None = None
    notes: tuple[str, ...] = (PLACEHOLDER_NOTE,)

    def report_lines(self) -> list[str]:
        """Human-readable summary: overall and per-view RMS, skipped views, the result."""
        raw = self.rig.raw
        assert raw is not None
        used = [v for v in self.views if v.used]
        lines = [f"views: {len(used)} used of {len(self.views)}",
                 f"rms_reprojection_px: {self.rms_px:.4f} (stereo); mono left "
                 f"{self.rms_left_mono_px:.4f}, right {self.rms_right_mono_px:.4f}",
                 "per view rms_px (left, right):"]
        lines += [f"  {v.name}: {v.rms_left_px:.4f} {v.rms_right_px:.4f}" for v in used]
        lines += [f"skipped {v.name}: {v.reason}" for v in self.views if not v.used]
        K1, K2 = raw.array("K1"), raw.array("K2")
        lines.append(f"left  fx fy cx cy: {K1[0, 0]:.3f} {K1[1, 1]:.3f} {K1[0, 2]:.3f} "
                     f"{K1[1, 2]:.3f}  D1: {np.round(raw.array('D1'), 5).tolist()}")
        lines.append(f"right fx fy cx cy: {K2[0, 0]:.3f} {K2[1, 1]:.3f} {K2[0, 2]:.3f} "
                     f"{K2[1, 2]:.3f}  D2: {np.round(raw.array('D2'), 5).tolist()}")
        c = self.rig.left
        lines.append(f"rectified: fx {c.fx_px:.3f} fy {c.fy_px:.3f} cx {c.cx_px:.3f} "
                     f"cy {c.cy_px:.3f}, baseline_m {self.rig.baseline_m:.5f}")
        if self.epipolar is not None:
            e = self.epipolar
            lines.append(f"rectified epipolar error |dy| px: median {e.median_px:.4f}, p95 "
                         f"{e.p95_px:.4f}, max {e.max_px:.4f} ({e.corners} corners)")
        return lines


def _board_views(names: list[str], left_bgr: list[np.ndarray], right_bgr: list[np.ndarray],
                 board: BoardSpec) -> tuple[list[ViewReport], list[int], list[np.ndarray],
                                            list[np.ndarray]]:
    """Corners of the board in both images of each view; views missing it are reported."""
    reports: list[ViewReport] = []
    used_idx: list[int] = []
    pts_l: list[np.ndarray] = []
    pts_r: list[np.ndarray] = []
    for i, (name, li, ri) in enumerate(zip(names, left_bgr, right_bgr, strict=True)):
        cl, cr = find_corners(li, board), find_corners(ri, board)
        if cl is None or cr is None:
            side = "left and right" if cl is None and cr is None else \
                ("left" if cl is None else "right")
            reports.append(ViewReport(name, False, f"no {board.cols}x{board.rows} board found "
                                      f"in the {side} image"))
            continue
        if np.dot(cl[-1] - cl[0], cr[-1] - cr[0]) < 0:
            cr = cr[::-1].copy()
        reports.append(ViewReport(name, True))
        used_idx.append(i)
        pts_l.append(cl.astype(np.float32).reshape(-1, 1, 2))
        pts_r.append(cr.astype(np.float32).reshape(-1, 1, 2))
    return reports, used_idx, pts_l, pts_r


def calibrate_stereo_images(names: list[str], left_bgr: list[np.ndarray],
                            right_bgr: list[np.ndarray], params: StereoCalibrationParams, *,
                            base: Rig | None = None, source: str = "views") -> StereoCalibration:
    """Calibrate from in-memory stereo views (same names order, same sizes).

    Parameters
    ----------
    names : view names used in reports.
    left_bgr, right_bgr : raw images, each (H, W, 3) uint8.
    params : StereoCalibrationParams
    base : rig providing mount, laser and limits (default: the paper rig).
    source : what to name in errors (e.g. the folders).

    Returns
    -------
    StereoCalibration
    """
    if len(left_bgr) != len(right_bgr):
        raise SlitcliError(f"{source}: {len(left_bgr)} left views but {len(right_bgr)} right "
                           "views; give one right image per left image")
    h, w = left_bgr[0].shape[:2]
    if right_bgr[0].shape[:2] != (h, w):
        raise SlitcliError(f"{source}: right images are {right_bgr[0].shape[1]}x"
                           f"{right_bgr[0].shape[0]}, left images {w}x{h}; both cameras must "
                           "have one image size")
    board = params.board
    reports, used_idx, pts_l, pts_r = _board_views(names, left_bgr, right_bgr, board)
    if not used_idx:
        raise SlitcliError(f"{source}: no {board.cols}x{board.rows} chessboard found in any of "
                           f"the {len(names)} views; check `board` (inner corners, COLSxROWS) "
                           "and that the whole board is in view", param="board")
    if len(used_idx) < params.min_views:
        skipped = ", ".join(v.name for v in reports if not v.used)
        raise SlitcliError(f"{source}: only {len(used_idx)} of {len(names)} views show the "
                           f"board in both cameras (skipped: {skipped}); at least "
                           f"{params.min_views} are needed, add views")
    obj = [board.object_points().reshape(-1, 1, 3)] * len(used_idx)
    size = (w, h)
    flags = 0 if params.k3 else cv2.CALIB_FIX_K3
    rms_l, K1, D1, *_ = cv2.calibrateCameraExtended(obj, pts_l, size, None, None, flags=flags,
                                                    criteria=_CRITERIA)
    rms_r, K2, D2, *_ = cv2.calibrateCameraExtended(obj, pts_r, size, None, None, flags=flags,
                                                    criteria=_CRITERIA)
    out = cv2.stereoCalibrateExtended(
        obj, pts_l, pts_r, K1, D1, K2, D2, size, None, None,
        flags=flags | cv2.CALIB_USE_INTRINSIC_GUESS, criteria=_CRITERIA)
    rms, K1s, D1s, K2s, D2s, R, T = out[:7]
    per_view = np.asarray(out[-1], dtype=float).reshape(-1, 2)
    if not np.isfinite(rms) or rms > 2.0 * max(rms_l, rms_r) + 0.5:
        # the joint refinement can wander off with few views; keep the mono intrinsics
        out = cv2.stereoCalibrateExtended(
            obj, pts_l, pts_r, K1, D1, K2, D2, size, None, None,
            flags=flags | cv2.CALIB_FIX_INTRINSIC, criteria=_CRITERIA)
        rms, K1s, D1s, K2s, D2s, R, T = out[:7]
        per_view = np.asarray(out[-1], dtype=float).reshape(-1, 2)
    raw = rectify_raw(K1s, D1s.ravel()[:5], K2s, D2s.ravel()[:5], size, R, T,
                      alpha=params.alpha, source=source)
    rig = rig_with_raw(raw, base, name=(base.name if base is not None else "calibrated"),
                       source=source)
    epi = epipolar_error(rig, pts_l, pts_r)
    first = used_idx[0]
    preview = rectified_preview(rig, left_bgr[first], right_bgr[first])
    k = 0
    final: list[ViewReport] = []
    for v in reports:
        if v.used:
            final.append(ViewReport(v.name, True, "", float(per_view[k, 0]),
                                    float(per_view[k, 1])))
            k += 1
        else:
            final.append(v)
    return StereoCalibration(rig=rig, rms_px=float(rms), rms_left_mono_px=float(rms_l),
                             rms_right_mono_px=float(rms_r), views=tuple(final),
                             epipolar=epi, preview=preview)


def preview_path(out_rig: str | Path) -> Path:
    """Where ``calibrate stereo`` writes the rectified preview: ``<rig stem>_rectified.png``."""
    p = Path(out_rig)
    return p.with_name(f"{p.stem}_rectified.png")


def run_calibrate_stereo(left_dir: str | Path, right_dir: str | Path, out_rig: str | Path,
                         params: StereoCalibrationParams, *,
                         base_rig: str | Path | None = None) -> StereoCalibration:
    """``slitcli calibrate stereo``: read both folders, calibrate, write the rig atomically.

    Views pair up in name order; the two folders must hold the same number of images.
    Writes the rig (headed by a comment that mount and laser are placeholders) and the
    rectified preview of the first usable view (:func:`preview_path`). Nothing is
    written when any check fails.
    """
    lv, rv = list_views(left_dir, "left"), list_views(right_dir, "right")
    if len(lv) != len(rv):
        raise SlitcliError(f"{right_dir}: {len(rv)} right images but {len(lv)} in {left_dir}; "
                           "give one right image per left image (paired in name order)")
    base = load_rig(base_rig) if base_rig is not None else None
    left, right = load_views(lv), load_views(rv)
    names = [a.name if a.name == b.name else f"{a.name}|{b.name}"
             for a, b in zip(lv, rv, strict=True)]
    result = calibrate_stereo_images(names, left, right, params, base=base,
                                     source=f"{left_dir} + {right_dir}")
    from slitcli.io.atomic import write_png_atomic, write_text_atomic

    assert result.preview is not None
    write_png_atomic(preview_path(out_rig), result.preview)
    write_text_atomic(Path(out_rig), PLACEHOLDER_COMMENT + result.rig.to_yaml())
    return result
