"""Atomic file output: write to a temporary sibling, then rename into place.

A reader (or a re-run after a crash) never sees a half-written file: either the old
file, or the complete new one.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np
import pandas as pd

from slitcli.errors import SlitcliError


@contextlib.contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; rename it onto ``path`` on success.

    On an exception the temporary file is removed and ``path`` is left untouched.
    """
    final = Path(path)
    _ensure_parent(final)
    fd, tmp = tempfile.mkstemp(prefix=f".{final.name}.", suffix=".tmp", dir=final.parent)
    os.close(fd)
    tmp_path = Path(tmp)
    os.chmod(tmp_path, 0o666 & ~_umask())  # mkstemp makes 0600; outputs are ordinary files
    try:
        yield tmp_path
        os.replace(tmp_path, final)
    finally:
        if tmp_path.exists():
            tmp_path.unlink()


def write_bytes_atomic(path: str | Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def write_text_atomic(path: str | Path, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    write_bytes_atomic(path, text.encode("utf-8"))


def write_png_atomic(path: str | Path, image: np.ndarray) -> None:
    """Encode ``image`` (uint8 or uint16, grey or BGR) as PNG and write it atomically."""
    ok, buf = cv2.imencode(".png", image)
    if not ok:
        raise SlitcliError(f"{path}: OpenCV could not encode the image as PNG")
    write_bytes_atomic(path, buf.tobytes())


def write_csv_atomic(path: str | Path, table: pd.DataFrame, *, float_format: str = "%.6g") -> None:
    """Write a table as CSV atomically (NaN as an empty cell), with a fixed float format

    so that the same numbers always give the same bytes.
    """
    text = table.to_csv(index=False, float_format=float_format, na_rep="", lineterminator="\n")
    write_text_atomic(path, text)


@contextlib.contextmanager
def atomic_directory(path: str | Path, *, overwrite: bool = False) -> Iterator[Path]:
    """Yield a temporary folder next to ``path`` and rename it onto ``path`` on success.

    If ``path`` exists it is an error unless ``overwrite`` is set, in which case the old
    folder is replaced only once the new one is complete.
    """
    final = Path(path)
    if final.exists() and not overwrite:
        raise SlitcliError(f"{final}: already exists; choose another output folder or pass "
                           "`overwrite`", param="overwrite")
    if final.exists() and not final.is_dir():
        raise SlitcliError(f"{final}: exists and is not a folder; choose another output path")
    _ensure_parent(final)
    tmp = Path(tempfile.mkdtemp(prefix=f".{final.name}.", suffix=".tmp", dir=final.parent))
    os.chmod(tmp, 0o777 & ~_umask())
    try:
        yield tmp
        if final.exists():
            old = final.with_name(f".{final.name}.old")
            if old.exists():
                shutil.rmtree(old)
            os.replace(final, old)
            os.replace(tmp, final)
            shutil.rmtree(old)
        else:
            os.replace(tmp, final)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp)


def _umask() -> int:
    # os.umask can only be read by setting it; restore it at once
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _ensure_parent(path: Path) -> None:
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise SlitcliError(f"{path.parent}: cannot create the output folder ({e.strerror}); "
                           "check the path and permissions") from None
