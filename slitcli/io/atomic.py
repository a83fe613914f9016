"""Atomic file output: write to a temporary sibling, then rename into place.

A reader (or a re-run after a crash) never sees a half-written file: either the old
file, or the complete new one.

Temporary names are short and slitcli's own: ``.slitcli-<pid>-<token>.tmp`` (about 30
bytes whatever the final name, so a final name of 255 bytes still has a temporary
sibling). A process killed with SIGKILL leaves such names behind; :func:`sweep_temp`
removes those whose process is gone, and nothing else.

An output folder written by :func:`atomic_directory` lists its own top-level entries in
``OWNED_LIST`` (docs/sequence.md); ``overwrite`` replaces those entries only, never
another file in the folder, and never one of the command's inputs.
"""

from __future__ import annotations

import contextlib
import errno
import os
import re
import secrets
import shutil
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import cv2
import numpy as np

from slitcli.errors import SlitcliError

if TYPE_CHECKING:  # callers pass their DataFrame; detect's path never imports pandas
    import pandas as pd

OWNED_LIST = ".slitcli-outputs"
"""File in an output folder naming, one a line, the entries slitcli wrote there."""
_TEMP_RE = re.compile(r"^\.slitcli-(\d{1,10})-[0-9a-f]{8}\.tmp$")


def temp_name() -> str:
    """A fresh temporary name of this process: ``.slitcli-<pid>-<8 hex>.tmp``."""
    return f".slitcli-{os.getpid()}-{secrets.token_hex(4)}.tmp"


@contextlib.contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; rename it onto ``path`` on success.

    On an exception the temporary file is removed and ``path`` is left untouched.
    """
    final = Path(path)
    _ensure_parent(final)
    tmp_path = final.parent / temp_name()
    with _naming(tmp_path, final):
        fd = os.open(tmp_path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)  # umask applies
    os.close(fd)
    try:
        with _naming(tmp_path, final):
            yield tmp_path
            os.replace(tmp_path, final)
    finally:
        with contextlib.suppress(FileNotFoundError):
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


# ---------------------------------------------------------------------- debris
def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's live process
        return True
    except OverflowError:
        return False
    return True


def _stale(entry: Path, pid: int) -> bool:
    """True when the process that made ``entry`` is gone.

    A live pid holds its names unless it started after the entry was last modified
    (the pid was reused): on Linux ``/proc/<pid>`` is created when the process starts.
    """
    if pid == os.getpid():
        return False
    if not _pid_alive(pid):
        return True
    try:
        started = os.stat(f"/proc/{pid}").st_ctime
        touched = entry.lstat().st_mtime
    except OSError:
        return False
    return started > touched + 1.0


def sweep_temp(folder: str | Path) -> list[Path]:
    """Remove slitcli's stale temporary files and folders directly inside ``folder``.

    Only names of the form ``.slitcli-<pid>-<8 hex>.tmp`` are touched, and only when
    their process is gone (see :func:`temp_name`). A missing or unreadable folder is
    not an error. Returns what was removed.
    """
    removed = []
    try:
        names = os.listdir(folder)
    except OSError:
        return removed
    for name in names:
        m = _TEMP_RE.match(name)
        if m is None:
            continue
        entry = Path(folder) / name
        if not _stale(entry, int(m.group(1))):
            continue
        try:
            if entry.is_dir() and not entry.is_symlink():
                shutil.rmtree(entry)
            else:
                entry.unlink()
            removed.append(entry)
        except OSError:
            continue
    return removed


# ---------------------------------------------------------------------- outputs vs inputs
def _resolved(path: str | Path) -> Path:
    return Path(os.path.abspath(Path(path).expanduser())).resolve()


def _within(path: Path, folder: Path) -> bool:
    return path == folder or folder in path.parents


def check_output_file(out: str | Path, *, inputs: Iterable[str | Path] = (),
                      overwrite: bool = False) -> Path:
    """Refuse an output file that is one of the inputs, a folder, or exists without ``overwrite``.

    Paths are compared after resolving symbolic links and ``..``, so ``-o ./x.csv`` and a
    link to ``x.csv`` are both the input ``x.csv``. Also sweeps stale temporary names
    next to ``out``. Returns ``out`` as a Path.
    """
    p = Path(out)
    target = _resolved(p)
    for src in inputs:
        if src is not None and _resolved(src) == target:
            raise SlitcliError(f"{p}: is also this command's input {src}; write the output "
                               "to another file")
    if p.is_dir():
        raise SlitcliError(f"{p}: is a folder; give a file name for the output")
    if p.exists() and not overwrite:
        raise SlitcliError(f"{p}: already exists; set `overwrite` to replace it or choose "
                           "another output file", param="overwrite")
    sweep_temp(p.parent)
    return p


def _owned(folder: Path) -> set[str]:
    """Entries an earlier slitcli run wrote into ``folder`` (its OWNED_LIST)."""
    try:
        text = (folder / OWNED_LIST).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return set()
    return {n for n in text.splitlines() if n and "/" not in n and n not in (".", "..")}


def _refuse_inputs(final: Path, names: Iterable[str], inputs: list[Path]) -> None:
    for name in names:
        entry = _resolved(final / name)
        for src in inputs:
            if _within(src, entry):
                raise SlitcliError(f"{src}: is this command's input and lies in "
                                   f"{final / name}, which the output would replace; copy it "
                                   "elsewhere or choose another output folder")


def check_output_folder(path: str | Path, *, overwrite: bool = False,
                        inputs: Iterable[str | Path] = ()) -> list[Path]:
    """The checks :func:`atomic_directory` makes first, for callers that compute before writing.

    Refuses (:class:`SlitcliError`) an existing ``path`` without ``overwrite``, a ``path``
    that is a file, equals an input or lies inside one, and an input inside an entry an
    earlier slitcli run wrote into ``path``. Returns the inputs, resolved.
    """
    final = Path(path)
    srcs = [_resolved(s) for s in inputs if s is not None]
    if final.exists() and not final.is_dir():
        raise SlitcliError(f"{final}: exists and is not a folder; choose another output path")
    if final.exists() and not overwrite:
        raise SlitcliError(f"{final}: already exists; choose another output folder or pass "
                           "`overwrite`", param="overwrite")
    for src in srcs:
        if _resolved(final) == src or _within(_resolved(final), src):
            raise SlitcliError(f"{final}: is this command's input {src}; choose another "
                               "output folder")
    if final.exists():
        _refuse_inputs(final, _owned(final), srcs)
    return srcs


@contextlib.contextmanager
def atomic_directory(path: str | Path, *, overwrite: bool = False,
                     inputs: Iterable[str | Path] = ()) -> Iterator[Path]:
    """Yield a temporary folder next to ``path``; move its entries into ``path`` on success.

    A new ``path`` appears complete, in one rename. If ``path`` exists it is an error
    unless ``overwrite`` is set; then the entries the new run wrote, and those an earlier
    slitcli run listed in ``OWNED_LIST``, are replaced once the new run is complete, and
    every other file in ``path`` is left alone. An entry of the same name that slitcli
    did not write, or one of ``inputs`` inside an entry to be replaced, is refused
    (:class:`SlitcliError`) before anything is changed.
    """
    final = Path(path)
    srcs = check_output_folder(final, overwrite=overwrite, inputs=inputs)
    _ensure_parent(final)
    sweep_temp(final.parent)
    tmp = final.parent / temp_name()
    with _naming(tmp, final):
        tmp.mkdir(mode=0o777)  # umask applies
    try:
        with _naming(tmp, final):
            yield tmp
            names = sorted(n for n in os.listdir(tmp) if n != OWNED_LIST)
            (tmp / OWNED_LIST).write_text("".join(f"{n}\n" for n in names), encoding="utf-8")
            if not final.exists():
                os.replace(tmp, final)
            else:
                _replace_owned(final, tmp, names, srcs)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)


def _replace_owned(final: Path, tmp: Path, names: list[str], srcs: list[Path]) -> None:
    old = _owned(final)
    foreign = [n for n in names if n not in old and os.path.lexists(final / n)]
    if foreign:
        raise SlitcliError(f"{final / foreign[0]}: exists and was not written by slitcli; "
                           "move it away or choose another output folder")
    _refuse_inputs(final, set(names) | old, srcs)
    sweep_temp(final)
    trash = final / temp_name()
    trash.mkdir()
    for n in sorted(old | set(names)):
        if os.path.lexists(final / n):
            os.replace(final / n, trash / n)
    for n in [*names, OWNED_LIST]:
        os.replace(tmp / n, final / n)
    shutil.rmtree(trash, ignore_errors=True)


@contextlib.contextmanager
def _naming(tmp: Path, final: Path) -> Iterator[None]:
    """Report an OSError on a temporary path under the final path the user gave."""
    try:
        yield
    except OSError as e:
        name = e.filename
        if isinstance(name, str) and name.startswith(str(tmp)):
            raise OSError(e.errno, e.strerror, str(final) + name[len(str(tmp)):]) from None
        raise


def _ensure_parent(path: Path) -> None:
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise SlitcliError(f"{path.parent}: cannot create the output folder ({e.strerror}); "
                           "check the path and permissions") from None


# ---------------------------------------------------------------------- OS errors
_OS_FIXES = {
    errno.ENOSPC: "free some space and run again (finished results are kept)",
    errno.EDQUOT: "free some space (disk quota) and run again",
    errno.EROFS: "the file system is read-only; write to another folder",
    errno.EACCES: "check the permissions or write to another folder",
    errno.EPERM: "check the permissions or write to another folder",
    errno.ENAMETOOLONG: "use a shorter name",
    errno.EMFILE: "too many open files; raise the limit (ulimit -n) or use fewer jobs",
    errno.ENOMEM: "not enough memory; use fewer jobs or smaller inputs",
    errno.EIO: "the device reported an I/O error; check the disk",
}


def os_error_message(e: OSError) -> str | None:
    """One line for an OSError caused by the environment (disk full, read-only...), or None.

    The line names the file the OS named and says what to do; None for other errors
    (those are bugs and stay internal errors).
    """
    fix = _OS_FIXES.get(e.errno) if e.errno is not None else None
    if fix is None:
        return None
    where = e.filename if e.filename is not None else "(no file named by the system)"
    if e.filename2 is not None:
        where = f"{where} -> {e.filename2}"
    return f"{where}: {e.strerror or os.strerror(e.errno)}; {fix}"
