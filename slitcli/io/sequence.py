"""Stereo sequences on disk (DESIGN §12): ``left/`` and ``right/`` with the same file names.

A sequence folder holds ``left/`` and ``right/`` (PNG or JPEG, same names, frames in
natural name order: ``frame_2`` before ``frame_10``), an optional ``times.csv``
(``frame,time_s``) and an optional ``rig.yaml``. Frames are numbered 0, 1, ... in
that order; that index is the ``frame`` column of every table.
"""

from __future__ import annotations

import csv
import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from slitcli.errors import SlitcliError
from slitcli.io.yamlfile import brief
from slitcli.rig import Rig, load_rig, paper_rig

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")


@dataclass(frozen=True)
class StereoFrame:
    """One stereo pair. Images are BGR uint8, shape (height, width, 3)."""

    index: int
    name: str
    time_s: float
    left_bgr: np.ndarray
    right_bgr: np.ndarray


@dataclass(frozen=True)
class FrameRef:
    """Where one frame lives on disk (cheap to pass to worker processes)."""

    index: int
    name: str
    time_s: float
    left_path: Path
    right_path: Path


class StereoSequence:
    """A sequence folder; frames are read lazily, one at a time.

    Parameters
    ----------
    folder : path
        The sequence folder (``left/``, ``right/``, optional ``times.csv``, ``rig.yaml``).
    """

    def __init__(self, folder: str | Path) -> None:
        self.folder = Path(folder)
        if not self.folder.is_dir():
            raise SlitcliError(f"{self.folder}: sequence folder not found; give a folder "
                               "with left/ and right/ image folders")
        left_dir, right_dir = self.folder / "left", self.folder / "right"
        for d in (left_dir, right_dir):
            if not d.is_dir():
                raise SlitcliError(f"{d}: folder missing; a sequence needs left/ and right/ "
                                   "holding images with the same file names")
        lefts = _images(left_dir)
        rights = _images(right_dir)
        for found in (lefts, rights):
            _refuse_same_stem(found)
        if not lefts:
            raise SlitcliError(f"{left_dir}: no images (.png, .jpg) found; the sequence is empty")
        right_by_stem = {p.stem: p for p in rights}
        missing = [p for p in lefts if p.stem not in right_by_stem]
        if missing:
            raise SlitcliError(f"{right_dir / missing[0].name}: missing right frame for "
                               f"left/{missing[0].name} ({len(missing)} unpaired); every left "
                               "image needs a right image with the same name")
        extra = sorted(set(right_by_stem) - {p.stem for p in lefts})
        if extra:
            raise SlitcliError(f"{left_dir / extra[0]}: missing left frame for right/{extra[0]}"
                               f" ({len(extra)} unpaired); every right image needs a left image "
                               "with the same name")
        times = _read_times(self.folder / "times.csv", len(lefts))
        self.refs = [
            FrameRef(i, p.stem, float(times[i]), p, right_by_stem[p.stem])
            for i, p in enumerate(lefts)
        ]

    def __len__(self) -> int:
        return len(self.refs)

    def rig(self, rig_path: str | Path | None = None) -> Rig:
        """The rig to use: ``rig_path`` if given, else ``rig.yaml`` in the folder, else the
        paper rig."""
        if rig_path is not None:
            return load_rig(rig_path)
        own = self.folder / "rig.yaml"
        return load_rig(own) if own.exists() else paper_rig()

    def frames(self, rig: Rig | None = None) -> Iterator[StereoFrame]:
        """Read the frames in order (one pair in memory at a time)."""
        for ref in self.refs:
            yield read_frame(ref, rig)


def read_frame(ref: FrameRef, rig: Rig | None = None) -> StereoFrame:
    """Read one stereo pair and check its sizes against each other and the rig.

    With a rig that carries a ``raw`` calibration the images must have the raw size;
    otherwise they must have the rig's (rectified) ``image_size_px``.
    """
    left = read_image(ref.left_path)
    right = read_image(ref.right_path)
    if left.shape != right.shape:
        raise SlitcliError(f"{ref.right_path}: size {right.shape[1]}x{right.shape[0]} differs "
                           f"from the left image's {left.shape[1]}x{left.shape[0]}; left and "
                           "right images must have the same size")
    if rig is not None:
        want = rig.raw.image_size_px if rig.raw is not None else rig.image_size_px
        if (left.shape[1], left.shape[0]) != tuple(want):
            which = "raw.image_size_px" if rig.raw is not None else "image_size_px"
            raise SlitcliError(f"{ref.left_path}: size {left.shape[1]}x{left.shape[0]} does "
                               f"not match the rig's {which} {want[0]}x{want[1]}; use the rig "
                               "these images were taken with (`rig`)", param="rig")
    return StereoFrame(ref.index, ref.name, ref.time_s, left, right)


def read_image(path: Path) -> np.ndarray:
    """Read a colour image as BGR uint8 (grey images are replicated to 3 channels); the
    header is checked before decoding (:func:`slitcli.io.images.read_image_bgr`)."""
    from slitcli.io.images import read_image_bgr

    return read_image_bgr(path)


def natural_key(name: str) -> tuple:
    """Sort key that orders the digit runs of a name by value (``frame_2`` < ``frame_10``;
    zero-padded names keep their order)."""
    return tuple((0, int(t), t) if t.isdigit() else (1, 0, t)
                 for t in re.split(r"(\d+)", name) if t)


def _images(folder: Path) -> list[Path]:
    return sorted((p for p in folder.iterdir()
                   if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES and not
                   p.name.startswith(".")), key=lambda p: natural_key(p.name))


def _refuse_same_stem(images: list[Path]) -> None:
    """Two images of one name (``000001.jpg`` beside ``000001.png``) would be two frames
    paired with one image of the other side, and their outputs (named by the stem) would
    overwrite each other: refuse, naming both."""
    seen: dict[str, Path] = {}
    for p in images:
        if p.stem in seen:
            raise SlitcliError(f"{seen[p.stem]} and {p.name}: two images of frame "
                               f"'{p.stem}'; keep one of them (move the other out of "
                               f"{p.parent.name}/)")
        seen[p.stem] = p


def _read_times(path: Path, n: int) -> np.ndarray:
    """Frame times from ``times.csv``; NaN for every frame when the file is absent."""
    if not path.exists() and not path.is_symlink():
        return np.full(n, np.nan)
    if not path.is_file():
        raise SlitcliError(f"{path}: is not a file; times.csv must be a CSV file with columns "
                           "frame,time_s (or absent)")
    try:
        with open(path, newline="", encoding="utf-8-sig") as f:
            # blank lines are no rows (as in pandas.read_csv, which read this file before)
            rows = [r for r in csv.reader(f) if any(c.strip() for c in r)]
    except (csv.Error, UnicodeDecodeError, OSError):
        rows = []
    if not rows:
        raise SlitcliError(f"{path}: not a CSV with columns frame,time_s; fix or delete it")
    if rows[0] != ["frame", "time_s"]:
        raise SlitcliError(f"{path}: columns are {brief(rows[0])}, expected "
                           "frame,time_s; fix the header or delete the file")
    long = next((i for i, r in enumerate(rows) if len(r) > 2), None)
    if long is not None:
        raise SlitcliError(f"{path}: line {long + 1}: {len(rows[long])} cells, expected 2 "
                           "(frame,time_s); fix the file")
    # a short row's missing cell is empty, and so not a number
    frame_txt = [r[0] for r in rows[1:]]
    time_txt = [r[1] if len(r) > 1 else "" for r in rows[1:]]
    frame_num, time_num = _numbers(frame_txt), _numbers(time_txt)
    bad = ~np.isfinite(frame_num) | (frame_num != np.round(frame_num)) | (frame_num < 0) \
        | (frame_num >= n)
    if bad.any():
        line = int(np.flatnonzero(bad)[0]) + 2
        raise SlitcliError(f"{path}: line {line}: frame {brief(frame_txt[line - 2])} is "
                           f"not a whole number 0..{n - 1} (one per image pair, in name "
                           "order); fix the file")
    bad = ~np.isfinite(time_num)
    if bad.any():
        line = int(np.flatnonzero(bad)[0]) + 2
        raise SlitcliError(f"{path}: line {line}: time_s {brief(time_txt[line - 2])} "
                           "is not a number of seconds; fix the file")
    frames = frame_num.astype(np.int64)
    dup = np.flatnonzero(np.bincount(frames, minlength=n) > 1)
    if dup.size:
        raise SlitcliError(f"{path}: frame {int(dup[0])} is listed more than once; give each "
                           "frame one time")
    times = np.full(n, np.nan)
    times[frames] = time_num
    return times


# a decimal number, optionally signed, with an optional exponent, spaces around allowed;
# what pandas.to_numeric read from this file before (hexadecimal, "1_000" and words are
# not numbers; "inf" and "nan" are refused as not finite either way)
_NUMBER = re.compile(r"\s*[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?\s*")


def _numbers(cells: list[str]) -> np.ndarray:
    """The cells as float64 (correctly rounded, as Python reads them), NaN where a cell
    is not a decimal number."""
    return np.array([float(c) if _NUMBER.fullmatch(c) else np.nan for c in cells],
                    dtype=np.float64)
