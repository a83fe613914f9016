"""Reading input images safely: the header is checked before anything is decoded.

A PNG or JPEG header states the image size in a few bytes; decoding allocates what it
states. :func:`read_image_bgr` therefore reads the header first (PNG's IHDR and JPEG's
SOF are parsed here; other formats through Pillow's lazy open, which does not decode),
refuses sizes above a pixel limit,
files that are not regular files and files far larger than any image of the allowed
size could be (a 20 GB sparse file named .png), and only then decodes, with OpenCV as
before. libpng writes its own warnings straight to the process's stderr; they are
held back during the decode so that the user sees slitcli's one line, not libpng's.
"""

from __future__ import annotations

import contextlib
import os
import stat
import sys
import warnings
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np

from slitcli.errors import SlitcliError

MAX_PIXELS = 50_000_000
"""Default pixel limit (width x height) of an input image: 8k x 6k."""
_BYTES_PER_PIXEL_BOUND = 8
"""No PNG or JPEG of N pixels is larger than 8 N bytes (16-bit RGBA, incompressible)."""
_HEADER_SLACK_BYTES = 4 * 1024 * 1024
_HEAD_BYTES = 1024 * 1024
"""Bytes read to find the size: a JPEG's SOF follows its metadata (EXIF <= 64 kB each)."""
"""Room for metadata chunks (EXIF, ICC profiles, thumbnails) beyond the pixel bound."""


def image_size_px(path: str | Path, *, max_pixels: int = MAX_PIXELS) -> tuple[int, int]:
    """(width, height) of an image from its header, after the checks of :func:`read_image_bgr`.

    Raises
    ------
    SlitcliError
        Naming the file: missing, not a regular file, unreadable or not an image, a
        header claiming more than ``max_pixels``, or a file too large for its format.
    """
    from PIL import Image, UnidentifiedImageError

    p = Path(path)
    try:
        st = p.stat()
    except FileNotFoundError:
        raise SlitcliError(f"{p}: image not found; check the sequence folder") from None
    except OSError as e:
        raise SlitcliError(f"{p}: cannot read the image ({e.strerror or e.__class__.__name__}); "
                           "check the path and permissions") from None
    if not stat.S_ISREG(st.st_mode):
        raise SlitcliError(f"{p}: is not a regular file; an image must be a PNG or JPEG file")
    if st.st_size == 0:
        raise SlitcliError(f"{p}: empty file, not an image; re-export or remove it")
    try:
        with p.open("rb") as fh:
            head = fh.read(_HEAD_BYTES)
        size = _png_size(head) or _jpeg_size(head)
        if size is None:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", Image.DecompressionBombWarning)
                with Image.open(p) as im:
                    size = (int(im.size[0]), int(im.size[1]))
        width, height = size
    except Image.DecompressionBombError:
        raise SlitcliError(f"{p}: the header claims an image of more than {max_pixels} "
                           "pixels; slitcli reads smaller images (re-export or remove it)") \
            from None
    except (OSError, UnidentifiedImageError, SyntaxError, ValueError):
        raise SlitcliError(f"{p}: unreadable image (not a valid PNG or JPEG); re-export or "
                           "remove it") from None
    if width < 1 or height < 1 or width * height > max_pixels:
        raise SlitcliError(f"{p}: the header claims a {width}x{height} image, more than the "
                           f"{max_pixels} pixels slitcli reads; re-export it smaller or remove "
                           "it")
    if st.st_size > width * height * _BYTES_PER_PIXEL_BOUND + _HEADER_SLACK_BYTES:
        raise SlitcliError(f"{p}: {st.st_size} bytes is far more than a {width}x{height} "
                           "image can take; the file is damaged or not an image")
    return width, height


def _png_size(head: bytes) -> tuple[int, int] | None:
    """(width, height) from a PNG's IHDR (always the first chunk), or None if not a PNG."""
    if head[:8] != b"\x89PNG\r\n\x1a\n" or head[12:16] != b"IHDR" or len(head) < 24:
        return None
    return int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")


def _jpeg_size(head: bytes) -> tuple[int, int] | None:
    """(width, height) from a JPEG's first SOF marker segment, or None.

    Segments are walked by their lengths (a few per file: APPn, DQT, DHT, SOF); the SOF
    holds precision (1 byte), height and width (2 bytes each, big-endian).
    """
    if head[:2] != b"\xff\xd8":
        return None
    pos = 2
    while pos + 9 <= len(head):
        if head[pos] != 0xFF:
            return None
        marker = head[pos + 1]
        if marker == 0xFF:  # fill byte
            pos += 1
            continue
        seg_len = int.from_bytes(head[pos + 2:pos + 4], "big")
        if 0xC0 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC):
            height = int.from_bytes(head[pos + 5:pos + 7], "big")
            width = int.from_bytes(head[pos + 7:pos + 9], "big")
            return width, height
        if seg_len < 2:
            return None
        pos += 2 + seg_len
    return None


def read_image_bgr(path: str | Path, *, max_pixels: int = MAX_PIXELS) -> np.ndarray:
    """Read a PNG or JPEG as a BGR uint8 array (H, W, 3); grey images become 3 channels.

    The header is validated first (see :func:`image_size_px`); the decoded image must
    have the size its header states.

    Parameters
    ----------
    path : path
    max_pixels : int
        Largest width x height accepted.

    Raises
    ------
    SlitcliError
        One line naming the file, for any file that is not a readable image of
        acceptable size.
    """
    p = Path(path)
    width, height = image_size_px(p, max_pixels=max_pixels)
    try:
        data = np.fromfile(p, dtype=np.uint8)
    except OSError as e:
        raise SlitcliError(f"{p}: cannot read the image ({e.strerror or e.__class__.__name__}); "
                           "check the path and permissions") from None
    with _quiet_native_stderr():
        try:
            img = cv2.imdecode(data, cv2.IMREAD_COLOR)
        except cv2.error:
            img = None
    if img is None or img.shape[:2] != (height, width):
        raise SlitcliError(f"{p}: unreadable image (damaged PNG or JPEG data); re-export or "
                           "remove it")
    return img


@contextlib.contextmanager
def _quiet_native_stderr() -> Iterator[None]:
    """Hold back what native code (libpng, libjpeg) writes to file descriptor 2.

    Python's own ``sys.stderr`` is flushed first; the native lines are dropped, since
    the caller reports the outcome in its own words.
    """
    try:
        fd = sys.stderr.fileno()
    except (AttributeError, OSError, ValueError):  # no real stderr (pytest capture, IDE)
        yield
        return
    sys.stderr.flush()
    saved = os.dup(fd)
    sink = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(sink, fd)
        try:
            yield
        finally:
            os.dup2(saved, fd)
    finally:
        os.close(sink)
        os.close(saved)
