"""The overlay video: each left image with what detection made of it (OpenCV only).

Per frame: the rectified left image; the stereo obstacle mask tinted magenta (from
``mask/``, when the run saved it); the detected laser stripe as cyan dots (from
``laser.csv``, when saved); each bearing bin's fused range (Eq. 11) as an arc over the
bin's wedge, drawn where that range meets the laser plane (so an arc from the laser
lies on the stripe), yellow for a laser range and green for a stereo range, with the
distance in metres over each run of similar bins; the frame's time in the top left
corner. The image is enlarged by a whole factor so the labels are legible.
"""

from __future__ import annotations

import math
import os
import tempfile
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from slitcli.errors import SlitcliError
from slitcli.rig import Rig

MASK_BGR = (255, 0, 255)
STRIPE_BGR = (255, 255, 0)
SOURCE_BGR = {0: (0, 230, 255), 1: (60, 220, 60)}  # laser yellow, stereo green
FONT = cv2.FONT_HERSHEY_SIMPLEX


@dataclass(frozen=True, kw_only=True)
class OverlayParams:
    """Look of the overlay frames.

    Attributes
    ----------
    min_width_px : int
        The frame is enlarged by the smallest whole factor that makes it at least this
        wide (labels need the room).
    mask_alpha : float
        Opacity of the obstacle tint, 0-1.
    arc_points : int
        Points per bin arc.
    label_step_m : float
        Neighbouring bins whose ranges differ by less than this share one label.
    """

    min_width_px: int = 960
    mask_alpha: float = 0.35
    arc_points: int = 7
    label_step_m: float = 0.1

    def __post_init__(self) -> None:
        if not 0.0 <= self.mask_alpha <= 1.0:
            raise SlitcliError(f"mask_alpha {self.mask_alpha} must be within 0-1")
        if self.arc_points < 2 or self.min_width_px < 1 or not self.label_step_m > 0:
            raise SlitcliError("arc_points >= 2, min_width_px >= 1 and label_step_m > 0 "
                               "are needed")


def scale_for(width_px: int, params: OverlayParams) -> int:
    """The whole enlargement factor of the frames."""
    return max(1, math.ceil(params.min_width_px / max(width_px, 1)))


def arc_pixels(rig: Rig, bearing_deg: np.ndarray, bin_deg: float, range_m: np.ndarray,
               n_points: int = 7) -> np.ndarray:
    """Image points of each bin's arc at its range, in the laser plane.

    Parameters
    ----------
    rig : Rig
        Rectified rig (the arcs are drawn on rectified images).
    bearing_deg : ndarray (B,)
        Bin centres, sensor frame, positive left.
    bin_deg : float
    range_m : ndarray (B,)
        Horizontal range from the sensor origin, metres; NaN = no arc.
    n_points : int

    Returns
    -------
    ndarray (B, n_points, 2) float64
        (u, v) pixels; NaN where there is no range or the point is behind the camera.
    """
    frac = np.linspace(-0.5, 0.5, n_points)
    theta = np.radians(bearing_deg[:, None] + bin_deg * frac[None, :])
    r = np.asarray(range_m, dtype=np.float64)[:, None]
    x, y = r * np.cos(theta), r * np.sin(theta)
    n_s, d_s = rig.laser_plane_sensor()
    # the height where the laser plane passes over (x, y); a level sheet is a constant
    z = (d_s - n_s[0] * x - n_s[1] * y) / n_s[2] if abs(n_s[2]) > 1e-9 else np.zeros_like(x)
    u, v = rig.project_cam(rig.sensor_to_cam(np.stack([x, y, z], axis=-1)))
    return np.stack([u, v], axis=-1)


def label_runs(range_m: np.ndarray, source: np.ndarray, step_m: float
               ) -> list[tuple[int, int, int]]:
    """Runs of neighbouring ranged bins with one source and ranges within ``step_m``.

    Returns ``(first, last, nearest)`` bin indices per run, nearest runs first.
    """
    r = np.asarray(range_m, dtype=np.float64)
    ok = np.isfinite(r)
    if not ok.any():
        return []
    brk = np.ones(r.size, dtype=bool)
    brk[1:] = (~ok[1:]) | (~ok[:-1]) | (source[1:] != source[:-1]) | (
        np.abs(np.diff(np.where(ok, r, 0.0))) >= step_m)
    run_id = np.cumsum(brk)
    idx = np.flatnonzero(ok)
    _, first = np.unique(run_id[idx], return_index=True)
    last = np.r_[first[1:], idx.size] - 1
    key = np.where(ok, r, np.inf)
    out = []
    for f, la in zip(idx[first], idx[last], strict=True):
        near = f + int(np.argmin(key[f:la + 1]))
        out.append((int(f), int(la), int(near)))
    return sorted(out, key=lambda t: float(r[t[2]]))


def draw_overlay(left_bgr: np.ndarray, *, rig: Rig, bearing_deg: np.ndarray, bin_deg: float,
                 fused_range_m: np.ndarray, fused_source: np.ndarray,
                 stripe_uv: np.ndarray | None, mask: np.ndarray | None, time_s: float,
                 frame: int, params: OverlayParams | None = None) -> np.ndarray:
    """One overlay frame (module docstring).

    Parameters
    ----------
    left_bgr : ndarray (H, W, 3) uint8
        Rectified left image.
    fused_range_m, fused_source : ndarray (B,)
        One frame of the range table (source 0 laser, 1 stereo, 2 none).
    stripe_uv : ndarray (N, 2), optional
        Stripe points (u, v), px, of ``laser.csv``.
    mask : ndarray (H, W) bool, optional
        The stereo obstacle mask.
    time_s : float
        Frame time, seconds (NaN: not written).

    Returns
    -------
    ndarray (s H, s W, 3) uint8, BGR, with ``s`` = :func:`scale_for`.
    """
    p = OverlayParams() if params is None else params
    h, w = left_bgr.shape[:2]
    s = scale_for(w, p)
    img = left_bgr.copy()
    if mask is not None and mask.shape == (h, w) and mask.any():
        tint = np.array(MASK_BGR, dtype=np.float64)
        img[mask] = np.rint((1 - p.mask_alpha) * img[mask] + p.mask_alpha * tint).astype(
            np.uint8)
    img = cv2.resize(img, (w * s, h * s), interpolation=cv2.INTER_LINEAR)
    arcs = (arc_pixels(rig, bearing_deg, bin_deg, fused_range_m, p.arc_points) + 0.5) * s - 0.5
    for code, colour in SOURCE_BGR.items():
        sel = (fused_source == code) & np.isfinite(arcs).all(axis=(1, 2))
        lines = [a for a in np.rint(arcs[sel] * 16).astype(np.int32)]
        if lines:
            cv2.polylines(img, lines, False, colour, 2 + s // 2, cv2.LINE_AA, shift=4)
    if stripe_uv is not None and len(stripe_uv):
        pts = np.rint((np.asarray(stripe_uv, dtype=np.float64) + 0.5) * s - 0.5).astype(
            np.int32)
        inside = (pts[:, 0] >= 0) & (pts[:, 0] < w * s) & (pts[:, 1] >= 0) & (
            pts[:, 1] < h * s)
        pts = pts[inside]
        r = 1 + s // 3
        for dy in range(-r + 1, r):  # a small square per stripe column, over the arcs
            yy = np.clip(pts[:, 1] + dy, 0, h * s - 1)
            for dx in range(-r + 1, r):
                img[yy, np.clip(pts[:, 0] + dx, 0, w * s - 1)] = STRIPE_BGR
    _labels(img, arcs, fused_range_m, fused_source, p, s)
    _corner(img, time_s, frame, s)
    _legend(img, s)
    return img


def _text_box(img: np.ndarray, text: str, org: tuple[int, int], scale: float,
              colour: tuple[int, int, int]) -> None:
    (tw, th), base = cv2.getTextSize(text, FONT, scale, 1)
    x, y = org
    cv2.rectangle(img, (x - 2, y - th - 3), (x + tw + 2, y + base), (0, 0, 0), -1)
    cv2.putText(img, text, (x, y), FONT, scale, colour, 1, cv2.LINE_AA)


def _labels(img: np.ndarray, arcs: np.ndarray, range_m: np.ndarray, source: np.ndarray,
            p: OverlayParams, s: int) -> None:
    """Distance labels, nearest first, skipping any that would cover an earlier one."""
    scale = 0.3 + 0.1 * s
    taken: list[tuple[int, int, int, int]] = []
    hgt, wid = img.shape[:2]
    for _first, _last, near in label_runs(range_m, source, p.label_step_m):
        pts = arcs[near]
        if not np.isfinite(pts).all():
            continue
        text = f"{range_m[near]:.2f}"
        (tw, th), _ = cv2.getTextSize(text, FONT, scale, 1)
        x = int(np.clip(pts[:, 0].mean() - tw / 2, 2, wid - tw - 4))
        y = int(np.clip(pts[:, 1].min() - 6, th + 4, hgt - 4))
        box = (x - 3, y - th - 4, x + tw + 3, y + 4)
        if any(box[0] < b[2] and b[0] < box[2] and box[1] < b[3] and b[1] < box[3]
               for b in taken):
            continue
        taken.append(box)
        _text_box(img, text, (x, y), scale, SOURCE_BGR.get(int(source[near]), (255, 255, 255)))


def _corner(img: np.ndarray, time_s: float, frame: int, s: int) -> None:
    t = f"t {time_s:.3f} s  " if math.isfinite(time_s) else ""
    _text_box(img, f"{t}frame {frame}", (6, 8 + 12 * s), 0.3 + 0.12 * s, (255, 255, 255))


def _legend(img: np.ndarray, s: int) -> None:
    scale = 0.25 + 0.08 * s
    items = (("laser range (m)", SOURCE_BGR[0]), ("stereo range (m)", SOURCE_BGR[1]),
             ("laser stripe", STRIPE_BGR), ("obstacle mask", MASK_BGR))
    wid = img.shape[1]
    tw = max(cv2.getTextSize(t, FONT, scale, 1)[0][0] for t, _ in items)
    x0, line = wid - tw - 14 - 6 * s, 6 + 6 * s
    cv2.rectangle(img, (x0 - 4, 2), (wid - 2, 6 + line * len(items)), (0, 0, 0), -1)
    for k, (text, colour) in enumerate(items):
        y = 4 + line * (k + 1)
        cv2.rectangle(img, (x0, y - line // 2 - 2), (x0 + 4 * s, y - 2), colour, -1)
        cv2.putText(img, text, (x0 + 4 * s + 4, y), FONT, scale, (255, 255, 255), 1,
                    cv2.LINE_AA)


def write_video(path: str | Path, frames: Iterable[np.ndarray], *, fps: float,
                on_frame: Callable[[], None] | None = None) -> int:
    """Encode BGR frames (all one size) as MPEG-4 ('mp4v') and check it decodes.

    Written under a temporary name and renamed when OpenCV has read every frame back.

    Returns
    -------
    int
        Frames written.
    """
    final = Path(path)
    fd, tmp_name = tempfile.mkstemp(prefix=f".{final.stem}.", suffix=".tmp.mp4",
                                    dir=final.parent)
    os.close(fd)
    tmp = Path(tmp_name)
    mask = os.umask(0)
    os.umask(mask)
    os.chmod(tmp, 0o666 & ~mask)  # mkstemp makes 0600; the video is an ordinary file
    writer = None
    n = 0
    try:
        for img in frames:
            if writer is None:
                size = (img.shape[1], img.shape[0])
                writer = cv2.VideoWriter(str(tmp), cv2.VideoWriter_fourcc(*"mp4v"), float(fps),
                                         size)
                if not writer.isOpened():
                    raise SlitcliError(f"{final}: OpenCV cannot write MPEG-4 video here (its "
                                       "FFmpeg backend is missing); install "
                                       "opencv-python-headless from PyPI")
            if (img.shape[1], img.shape[0]) != size:
                img = cv2.resize(img, size, interpolation=cv2.INTER_AREA)
            writer.write(img)
            n += 1
            if on_frame is not None:
                on_frame()
        if writer is not None:
            writer.release()
            writer = None
        got = count_video_frames(tmp) if n else 0
        if got < n:
            raise SlitcliError(f"{final}: OpenCV read back {got} of {n} frames of the video it "
                               "wrote; the FFmpeg backend is broken")
        os.replace(tmp, final)
    finally:
        if writer is not None:
            writer.release()
        tmp.unlink(missing_ok=True)
    return n


def count_video_frames(path: str | Path) -> int:
    """Frames OpenCV decodes from a video file."""
    cap = cv2.VideoCapture(str(path))
    n = 0
    try:
        while cap.grab():
            n += 1
    finally:
        cap.release()
    return n


__all__ = ["OverlayParams", "arc_pixels", "count_video_frames", "draw_overlay",
           "label_runs", "write_video"]
