"""Calibration views on disk and chessboard corner detection.

A board is given by its *inner* corner counts (``9x6``: 9 corners along a row, 6
along a column) and its square size in metres. Corners are found with
:func:`cv2.findChessboardCorners` refined by :func:`cv2.cornerSubPix` (window scaled
to the square size in pixels), falling back to :func:`cv2.findChessboardCornersSB`.
Corner order is made canonical (OpenCV's row-by-row object points, the first corner
next to a dark outer square) so that left and right views of one pose agree.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from slitcli.errors import SlitcliError
from slitcli.io.sequence import IMAGE_SUFFIXES, read_image

_SUBPIX_CRITERIA = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 1e-4)


@dataclass(frozen=True)
class BoardSpec:
    """A chessboard: ``cols`` x ``rows`` inner corners, squares of ``square_m`` metres."""

    cols: int
    rows: int
    square_m: float

    def __post_init__(self) -> None:
        if self.cols < 3 or self.rows < 3:
            raise SlitcliError(f"`board` {self.cols}x{self.rows}: a board needs at least 3x3 "
                               "inner corners; count the inner corners (where 4 squares meet)",
                               param="board")
        if not self.square_m > 0:
            raise SlitcliError(f"`square_m` {self.square_m:g}: the square size must be a "
                               "positive length in metres, e.g. 0.025", param="square_m")

    @classmethod
    def parse(cls, text: str, square_m: float) -> BoardSpec:
        """``"9x6"`` -> BoardSpec(9, 6, square_m)."""
        m = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", text)
        if m is None:
            raise SlitcliError(f"`board` {text!r}: give the inner corner counts as COLSxROWS, "
                               "e.g. 9x6", param="board")
        return cls(int(m.group(1)), int(m.group(2)), float(square_m))

    @property
    def pattern_size(self) -> tuple[int, int]:
        return (self.cols, self.rows)

    def object_points(self) -> np.ndarray:
        """Inner corners in the board frame (cols * rows, 3), row by row, metres, z = 0."""
        j, i = np.mgrid[0:self.rows, 0:self.cols]
        return np.stack([i.ravel() * self.square_m, j.ravel() * self.square_m,
                         np.zeros(i.size)], axis=-1).astype(np.float32)

    def contains(self, board_xy_m: np.ndarray, *, inset_m: float = 0.0) -> np.ndarray:
        """Whether board-frame points (..., 2+) lie on the printed checker area."""
        p = np.asarray(board_xy_m, dtype=float)
        sq = self.square_m
        return ((p[..., 0] >= -sq + inset_m) & (p[..., 0] <= self.cols * sq - inset_m)
                & (p[..., 1] >= -sq + inset_m) & (p[..., 1] <= self.rows * sq - inset_m))


@dataclass(frozen=True)
class View:
    """One calibration image: its name (file stem) and path."""

    name: str
    path: Path


def list_views(folder: str | Path, what: str) -> list[View]:
    """The images (PNG/JPEG) of a folder in name order; ``what`` names it in errors."""
    d = Path(folder)
    if not d.is_dir():
        raise SlitcliError(f"{d}: {what} folder not found; give a folder of PNG or JPEG images")
    files = sorted(p for p in d.iterdir() if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES
                   and not p.name.startswith("."))
    if not files:
        raise SlitcliError(f"{d}: no images (.png, .jpg) in the {what} folder")
    return [View(p.stem, p) for p in files]


def load_views(views: list[View]) -> list[np.ndarray]:
    """Read every view as BGR uint8; all must have one size (first mismatch named)."""
    images = [read_image(v.path) for v in views]
    h, w = images[0].shape[:2]
    for v, img in zip(views, images, strict=True):
        if img.shape[:2] != (h, w):
            raise SlitcliError(f"{v.path}: size {img.shape[1]}x{img.shape[0]} differs from "
                               f"{views[0].path.name}'s {w}x{h}; all views of a camera must "
                               "have one size")
    return images


def find_corners(image: np.ndarray, board: BoardSpec) -> np.ndarray | None:
    """Subpixel inner corners of ``board`` in an image, or None if it is not seen.

    Parameters
    ----------
    image : ndarray (H, W) or (H, W, 3) BGR, uint8
    board : BoardSpec

    Returns
    -------
    corners_px : ndarray, shape (cols * rows, 2), float64, or None
        In OpenCV object-point order, starting next to a dark outer square.
    """
    gray = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY) if image.ndim == 3 else image
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
    # the fast check rejects images without a board quickly, but also some small, far
    # boards; those are retried in full before the sector-based detector, whose corners
    # on boards with squares of ~10 px were measured 0.2 % too far apart (a board that
    # looks 0.2 % nearer: 3 mm at 1.5 m) where cornerSubPix's are within 0.05 %
    ok, c = cv2.findChessboardCorners(gray, board.pattern_size,
                                      flags=flags | cv2.CALIB_CB_FAST_CHECK)
    if not ok:
        ok, c = cv2.findChessboardCorners(gray, board.pattern_size, flags=flags)
    if ok:
        pts = c.reshape(-1, 2).astype(np.float64)
        half = int(np.clip(0.4 * _min_spacing(pts, board), 2, 11))
        c = cv2.cornerSubPix(gray, c.astype(np.float32), (half, half), (-1, -1),
                             _SUBPIX_CRITERIA)
    else:
        ok, c = cv2.findChessboardCornersSB(gray, board.pattern_size,
                                            flags=cv2.CALIB_CB_ACCURACY)
        if not ok:
            return None
    pts = c.reshape(-1, 2).astype(np.float64)
    return _canonical_order(gray, pts, board)


def _min_spacing(pts: np.ndarray, board: BoardSpec) -> float:
    grid = pts.reshape(board.rows, board.cols, 2)
    dx = np.linalg.norm(np.diff(grid, axis=1), axis=-1)
    dy = np.linalg.norm(np.diff(grid, axis=0), axis=-1)
    return float(min(dx.min(), dy.min()))


def _canonical_order(gray: np.ndarray, pts: np.ndarray, board: BoardSpec) -> np.ndarray:
    """Reverse the corner list when the outer square next to corner 0 is light.

    For a board with one odd and one even square count the two outer corner squares
    differ in colour, which fixes the order; for symmetric boards both are dark and
    OpenCV's order is kept (left/right agreement is then checked by the caller).
    """
    grid = pts.reshape(board.rows, board.cols, 2)

    def outer_level(g: np.ndarray) -> float:
        # half a diagonal step outwards from the corner lands inside the outer square
        p = g[0, 0] + 0.5 * (g[0, 0] - g[1, 1])
        x = int(np.clip(round(p[0]), 0, gray.shape[1] - 1))
        y = int(np.clip(round(p[1]), 0, gray.shape[0] - 1))
        return float(gray[max(y - 1, 0):y + 2, max(x - 1, 0):x + 2].mean())

    first = outer_level(grid)
    last = outer_level(grid[::-1, ::-1])
    if first > last:
        return pts[::-1].copy()
    return pts
