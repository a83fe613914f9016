"""Frames in: one source for sequence folders and ROS bags (:func:`open_frames`).

Every command that reads stereo pairs (``laser``, ``stereo``, ``detect``, ``calibrate
mount``) reads them through a :class:`FrameSource`:

- ``len(source)`` frames, numbered 0, 1, ... in the source's order (folders: the
  file names in natural order, ``frame_2`` before ``frame_10``; bags: the left
  stamps); that number is the ``frame`` column of every table;
- ``source.info`` per frame: :class:`FrameInfo` (index, name, time, and the identity
  of the input it was read from, for resumable batches);
- ``source.frames(`rig`)`` decodes the pairs lazily, one at a time, in order, checks
  their sizes against each other and the rig, and with ``rectify=True`` rectifies
  raw pairs with the rig's ``raw`` block, once per frame.

The previous-frame rule
-----------------------
A frame's results depend on its own stereo pair only. Eq. 4's continuity term with
the previous frame gets no previous stripe in any runner (``laser``, ``detect``, the
closed loop): the term changed no stripe column of 3394 true ones over 28 rendered
frames of three scenes (corridor, distractors, overhang; docs/notes/previous-frame.md),
and without it a frame's rows are the same whether it runs alone, in a resumed batch
or on any number of workers. :func:`slitcli.laser.detect_laser` still takes a
``previous`` stripe for callers that track the stripe themselves.
"""

from __future__ import annotations

import hashlib
from abc import ABC, abstractmethod
from collections.abc import Iterator
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from slitcli.errors import SlitcliError

if TYPE_CHECKING:
    from slitcli.io.bags import BagPairs
    from slitcli.io.sequence import StereoFrame
    from slitcli.rig import Rig

DEFAULT_LEFT_TOPIC = "/stereo/left/image_raw"
DEFAULT_RIGHT_TOPIC = "/stereo/right/image_raw"
DEFAULT_MAX_DT_S = 0.01


@dataclass(frozen=True)
class FrameInfo:
    """Who a frame is: its number, name, time and where it came from.

    Attributes
    ----------
    index : int
        Frame number (0, 1, ... in source order).
    name : str
        Name of the outputs of this frame (folders: the left image's file stem; bags:
        the zero-padded index).
    time_s : float
        Seconds (folders: ``times.csv``, NaN without it; bags: the left header stamp).
    identity : str
        What identifies the frame's input (file names; bag stamps in ns).
    """

    index: int
    name: str
    time_s: float
    identity: str


ON_BAD_FRAME = ("stop", "skip")


@dataclass(frozen=True)
class BadFrame:
    """A frame that could not be read (``on_bad="skip"``): its number, name and why."""

    index: int
    name: str
    reason: str


class FrameSource(ABC):
    """The stereo pairs of a sequence folder or a bag (:func:`open_frames`).

    An abstract base: a new kind of input implements :meth:`rig`, :meth:`frames` and
    :meth:`manifest` and sets ``path``, ``kind`` and ``info``; a subclass that leaves
    one out cannot be instantiated.
    """

    path: Path
    kind: str
    info: list[FrameInfo]

    def __len__(self) -> int:
        return len(self.info)

    @abstractmethod
    def rig(self, rig_path: str | Path | None = None) -> Rig:
        """The rig to use (``rig_path``; folders default to their ``rig.yaml``, else
        the paper rig)."""

    @abstractmethod
    def frames(self, rig: Rig | None = None, *, skip: frozenset[int] | set[int] = frozenset(),
               rectify: bool = False, on_bad: str = "stop"
               ) -> Iterator[StereoFrame | BadFrame]:
        """Decode the pairs in order, leaving out (and not decoding) those in ``skip``.

        With ``rig`` the image sizes are checked against it (its ``raw`` size when it
        has a raw calibration); ``rectify`` rectifies raw pairs with it. A pair that
        cannot be read (unreadable file, wrong size) raises :class:`SlitcliError`
        naming the file (``on_bad="stop"``), or is yielded as a :class:`BadFrame` and
        the frames after it follow (``on_bad="skip"``).
        """

    @abstractmethod
    def manifest(self) -> dict[str, Any]:
        """JSON-able identity of the input, for the manifests of resumable batches."""

    def notes(self) -> tuple[str, ...]:
        """What the user should know about the input (bags: images left unpaired)."""
        return ()

    def frame_digest(self, index: int) -> str:
        """What frame ``index``'s results depend on in the input (a resumed batch keeps a
        finished frame only while this is unchanged)."""
        return self.info[index].identity


def _check_on_bad(on_bad: str) -> None:
    if on_bad not in ON_BAD_FRAME:
        raise SlitcliError(f"`on_bad` {on_bad!r} is unknown; use 'stop' or 'skip'",
                           param="on_bad")


def _rectified(frames: Iterator[StereoFrame | BadFrame], rig: Rig | None, rectify: bool
               ) -> Iterator[StereoFrame | BadFrame]:
    if not rectify or rig is None or rig.raw is None:
        yield from frames
        return
    from slitcli.calibrate.rectify import RectificationMaps, rectify_pair

    maps = RectificationMaps.for_rig(rig)  # once per run, not per frame
    for fr in frames:
        if isinstance(fr, BadFrame):
            yield fr
            continue
        left, right = rectify_pair(rig, fr.left_bgr, fr.right_bgr, maps=maps)
        yield replace(fr, left_bgr=left, right_bgr=right)


class FolderFrames(FrameSource):
    """A folder of stereo pairs in one of the layouts of :mod:`slitcli.io.layouts`
    (``slitcli``: ``left/`` and ``right/`` with the same names, docs/sequence.md; EuRoC,
    KITTI raw, a flat folder of ``left*`` / ``right*``)."""

    kind = "folder"

    def __init__(self, folder: str | Path) -> None:
        from slitcli.io.layouts import detect_layout, read_layout
        from slitcli.io.sequence import StereoSequence

        self.path = Path(folder)
        self.layout = detect_layout(self.path)
        if self.layout == "slitcli":
            self.refs = StereoSequence(self.path).refs
            self._notes: tuple[str, ...] = ()
        else:
            self.refs, self._notes = read_layout(self.path, self.layout)
        self.info = [FrameInfo(r.index, r.name, r.time_s,
                               f"{r.left_path.name},{r.right_path.name}") for r in self.refs]

    def rig(self, rig_path: str | Path | None = None) -> Rig:
        from slitcli.rig import load_rig, paper_rig

        if rig_path is not None:
            return load_rig(rig_path)
        own = self.path / "rig.yaml"
        if own.exists() or own.is_symlink():  # a dangling link is an error, not "no rig"
            return load_rig(own)
        if self.layout != "slitcli":
            raise SlitcliError(f"{self.path}: a {self.layout} folder carries no slitcli rig; "
                               "give the camera's rig (`rig`)", param="rig")
        return paper_rig()

    def notes(self) -> tuple[str, ...]:
        return self._notes

    def frames(self, rig: Rig | None = None, *, skip: frozenset[int] | set[int] = frozenset(),
               rectify: bool = False, on_bad: str = "stop"
               ) -> Iterator[StereoFrame | BadFrame]:
        from slitcli.io.sequence import read_frame

        _check_on_bad(on_bad)

        def read() -> Iterator[StereoFrame | BadFrame]:
            for r in self.refs:
                if r.index in skip:
                    continue
                try:
                    yield read_frame(r, rig)
                except SlitcliError as e:
                    if on_bad == "stop":
                        raise
                    yield BadFrame(r.index, r.name, str(e))

        yield from _rectified(read(), rig, rectify)

    def check_sizes(self, rig: Rig) -> None:
        """Check every pair's image sizes from the file headers (no decoding), so a
        mismatch is found before anything is written."""
        from PIL import Image, UnidentifiedImageError

        want = tuple(rig.raw.image_size_px if rig.raw is not None else rig.image_size_px)
        key = "raw.image_size_px" if rig.raw is not None else "image_size_px"
        for ref in self.refs:
            sizes = []
            for path in (ref.left_path, ref.right_path):
                try:
                    with Image.open(path) as im:
                        sizes.append(tuple(im.size))
                except (OSError, UnidentifiedImageError):
                    raise SlitcliError(f"{path}: unreadable image (not a valid PNG or JPEG); "
                                       "re-export or remove it") from None
            (lw, lh), (rw, rh) = sizes
            if (lw, lh) != (rw, rh):
                raise SlitcliError(f"{ref.right_path}: size {rw}x{rh} differs from the left "
                                   f"image's {lw}x{lh}; left and right images must have the "
                                   "same size")
            if (lw, lh) != want:
                raise SlitcliError(f"{ref.left_path}: size {lw}x{lh} does not match the "
                                   f"rig's {key} {want[0]}x{want[1]}; use the rig these images "
                                   "were taken with (`rig`)", param="rig")

    def frame_digest(self, index: int) -> str:
        """SHA-256 of the pair's file names and bytes."""
        r = self.refs[index]
        h = hashlib.sha256()
        for p in (r.left_path, r.right_path):
            h.update(p.name.encode() + b"\0")
            try:
                h.update(p.read_bytes())
            except OSError:
                h.update(b"unreadable")
        return h.hexdigest()

    def manifest(self) -> dict[str, Any]:
        # the frames' bytes are checked one by one (frame_digest), so a fixed or replaced
        # image is computed again while the other finished frames are kept
        return {"kind": "folder", "layout": self.layout, "frames": len(self),
                "names": [i.name for i in self.info]}


class BagFrames(FrameSource):
    """Stereo pairs from two image topics of a ROS 1 or ROS 2 bag (:mod:`slitcli.io.bags`)."""

    kind = "bag"

    def __init__(self, path: str | Path, *, left_topic: str = DEFAULT_LEFT_TOPIC,
                 right_topic: str = DEFAULT_RIGHT_TOPIC,
                 max_dt_s: float = DEFAULT_MAX_DT_S) -> None:
        from slitcli.io.bags import pair_bag

        self.path = Path(path)
        self.pairs: BagPairs = pair_bag(self.path, left_topic, right_topic, max_dt_s)
        self.max_dt_s = float(max_dt_s)
        self.info = [FrameInfo(i, f"{i:06d}", int(ln) * 1e-9, f"{int(ln)},{int(rn)}")
                     for i, (ln, rn) in enumerate(zip(self.pairs.left_ns, self.pairs.right_ns,
                                                       strict=True))]

    def rig(self, rig_path: str | Path | None = None) -> Rig:
        if rig_path is None:
            raise SlitcliError(f"{self.path}: a bag carries no rig; give the camera's rig "
                               "(`rig`)", param="rig")
        from slitcli.rig import load_rig

        return load_rig(rig_path)

    def frames(self, rig: Rig | None = None, *, skip: frozenset[int] | set[int] = frozenset(),
               rectify: bool = False, on_bad: str = "stop"
               ) -> Iterator[StereoFrame | BadFrame]:
        from slitcli.io.bags import bag_frames

        _check_on_bad(on_bad)

        def decoded() -> Iterator[StereoFrame | BadFrame]:
            for fr in bag_frames(self.pairs, skip=set(skip)):
                if isinstance(fr, int):
                    continue
                if rig is not None:
                    want = rig.raw.image_size_px if rig.raw is not None else rig.image_size_px
                    got = (fr.left_bgr.shape[1], fr.left_bgr.shape[0])
                    if got != tuple(want) or fr.right_bgr.shape != fr.left_bgr.shape:
                        e = SlitcliError(
                            f"{self.path}: frame {fr.index}: images are {got[0]}x{got[1]} "
                            f"(right {fr.right_bgr.shape[1]}x{fr.right_bgr.shape[0]}), the "
                            f"rig's are {want[0]}x{want[1]}; give the rig of this camera "
                            "(`rig`)", param="rig")
                        if on_bad == "stop":
                            raise e
                        yield BadFrame(fr.index, fr.name, str(e))
                        continue
                yield fr

        yield from _rectified(decoded(), rig, rectify)

    def notes(self) -> tuple[str, ...]:
        report = self.pairs.pairing_report()
        return () if report is None else (report,)

    def manifest(self) -> dict[str, Any]:
        p = self.pairs
        stamps = hashlib.sha256(np.ascontiguousarray(p.left_ns).tobytes()
                                + np.ascontiguousarray(p.right_ns).tobytes()).hexdigest()
        return {"kind": "bag", "frames": len(self), "left_topic": p.left_topic,
                "right_topic": p.right_topic, "max_dt_s": self.max_dt_s, "stamps": stamps}


def open_frames(path: str | Path, *, left_topic: str = DEFAULT_LEFT_TOPIC,
                right_topic: str = DEFAULT_RIGHT_TOPIC,
                max_dt_s: float = DEFAULT_MAX_DT_S) -> FrameSource:
    """Open a sequence folder or a ROS bag as a :class:`FrameSource`.

    Parameters
    ----------
    path : path
        A sequence folder (``left/``, ``right/``, optional ``times.csv``, ``rig.yaml``;
        or the EuRoC, KITTI raw or flat ``left*`` / ``right*`` layouts of
        :mod:`slitcli.io.layouts`), a ROS 1 ``.bag``, a ROS 2 ``.db3`` / ``.mcap`` file
        or a ROS 2 bag folder.
    left_topic, right_topic : str
        Image topics of a bag.
    max_dt_s : float
        Largest left/right stamp difference that pairs two bag images, seconds.

    Raises
    ------
    SlitcliError
        A missing or malformed folder or bag, unpaired images.

    Examples
    --------
    >>> src = open_frames("sample_data/sequences/corridor")
    >>> len(src), src.info[0].name
    (8, '000000')
    """
    from slitcli.io.bags import is_bag

    p = Path(path)
    if is_bag(p):
        return BagFrames(p, left_topic=left_topic, right_topic=right_topic, max_dt_s=max_dt_s)
    return FolderFrames(p)


__all__ = ["ON_BAD_FRAME", "BadFrame", "BagFrames", "FolderFrames", "FrameInfo", "FrameSource",
           "open_frames"]
