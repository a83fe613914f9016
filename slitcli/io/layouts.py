"""The folder layouts stereo recordings come in, detected (never guessed) from the folder.

============  ==========================================================================
layout        what the folder holds
============  ==========================================================================
``slitcli``   ``left/`` and ``right/`` with the same file names, optional ``times.csv``
              (``frame,time_s``) and ``rig.yaml`` (docs/sequence.md)
``euroc``     EuRoC / ASL: ``cam0/data/<ns>.png`` with ``cam0/data.csv``
              (``#timestamp [ns],filename``), ``cam1`` likewise (also under ``mav0/``);
              pairs share a stamp, ``time_s`` = stamp
``kitti``     KITTI raw: ``image_02/data/<n>.png`` and ``image_03/data/<n>.png`` (colour;
              ``image_00`` / ``image_01``, grey, when there is no colour pair), each with
              ``timestamps.txt`` (``YYYY-MM-DD hh:mm:ss.fffffffff``, UTC); ``time_s`` =
              the left camera's stamp, seconds since 1970
``flat``      one folder of ``left*`` and ``right*`` images, paired by what follows
              ``left`` / ``right`` in the name (``left_0001.png`` - ``right_0001.png``)
============  ==========================================================================

Frames are numbered in natural name order (``frame_2`` before ``frame_10``) for
``slitcli`` and ``flat``, in stamp order for ``euroc``, in file order for ``kitti``. A
folder that matches none of the layouts, or more than one, is refused with a message
listing them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from slitcli.errors import SlitcliError
from slitcli.io.sequence import IMAGE_SUFFIXES, FrameRef, natural_key

LAYOUTS = ("slitcli", "euroc", "kitti", "flat")
_HELP = ("slitcli (left/ and right/ with the same names), euroc (cam0/data + cam0/data.csv, "
         "cam1), kitti (image_02/data + timestamps.txt, image_03), flat (left* and right* "
         "images in one folder)")


def _images(folder: Path) -> list[Path]:
    return sorted((p for p in folder.iterdir() if p.is_file() and not p.name.startswith(".")
                   and p.suffix.lower() in IMAGE_SUFFIXES), key=lambda p: natural_key(p.name))


def _euroc_root(folder: Path) -> Path | None:
    for root in (folder, folder / "mav0"):
        if (root / "cam0" / "data").is_dir() and (root / "cam1" / "data").is_dir():
            return root
    return None


def _kitti_pair(folder: Path) -> tuple[Path, Path] | None:
    for left, right in (("image_02", "image_03"), ("image_00", "image_01")):
        if (folder / left / "data").is_dir() and (folder / right / "data").is_dir():
            return folder / left, folder / right
    return None


def _flat_images(folder: Path, side: str) -> dict[str, Path]:
    return {p.stem[len(side):]: p for p in _images(folder) if p.stem.lower().startswith(side)}


def detect_layout(folder: str | Path) -> str:
    """Which of :data:`LAYOUTS` the folder is.

    Raises
    ------
    SlitcliError
        No layout or several layouts match.
    """
    f = Path(folder)
    if not f.is_dir():
        raise SlitcliError(f"{f}: sequence folder not found; give a folder in one of the "
                           f"layouts {_HELP}, or a bag")
    found = []
    if (f / "left").is_dir() or (f / "right").is_dir():
        found.append("slitcli")
    if _euroc_root(f) is not None:
        found.append("euroc")
    if _kitti_pair(f) is not None:
        found.append("kitti")
    if _flat_images(f, "left") or _flat_images(f, "right"):
        found.append("flat")
    if not found:
        raise SlitcliError(f"{f}: no stereo images in a known layout; use one of {_HELP}")
    if len(found) > 1:
        raise SlitcliError(f"{f}: the folder matches several layouts ({', '.join(found)}); "
                           f"keep one of them in it ({_HELP})")
    return found[0]


def _euroc_stamps(cam: Path) -> dict[int, Path]:
    """``data.csv`` of one EuRoC camera: stamp (ns) -> image path."""
    csv = cam / "data.csv"
    if not csv.exists():
        # without data.csv the file names are the stamps
        out = {}
        for p in _images(cam / "data"):
            if not p.stem.isdigit():
                raise SlitcliError(f"{p}: an EuRoC image without {csv.name} must be named "
                                   "by its stamp in ns; add the camera's data.csv")
            out[int(p.stem)] = p
        return out
    out = {}
    for n, line in enumerate(csv.read_text().splitlines(), start=1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        parts = [x.strip() for x in line.split(",")]
        if len(parts) < 2 or not parts[0].isdigit():
            raise SlitcliError(f"{csv}: line {n}: expected 'timestamp_ns,filename'; fix the "
                               "line")
        out[int(parts[0])] = cam / "data" / parts[1]
    return out


def _euroc(folder: Path) -> tuple[list[FrameRef], tuple[str, ...]]:
    root = _euroc_root(folder)
    assert root is not None
    left, right = _euroc_stamps(root / "cam0"), _euroc_stamps(root / "cam1")
    stamps = sorted(set(left) & set(right))
    if not stamps:
        raise SlitcliError(f"{root}: cam0 and cam1 share no stamp; an EuRoC pair is two "
                           "images with the same timestamp")
    refs = [FrameRef(i, str(t), t * 1e-9, left[t], right[t]) for i, t in enumerate(stamps)]
    n_l, n_r = len(left) - len(stamps), len(right) - len(stamps)
    notes = (f"{root}: {n_l} of {len(left)} cam0 and {n_r} of {len(right)} cam1 images have "
             "no image of the other camera with the same stamp; they are left out",) \
        if n_l or n_r else ()
    return refs, notes


def _kitti_times(cam: Path, n: int) -> np.ndarray:
    path = cam / "timestamps.txt"
    if not path.exists():
        return np.full(n, np.nan)
    lines = [ln.strip() for ln in path.read_text().splitlines() if ln.strip()]
    if len(lines) != n:
        raise SlitcliError(f"{path}: {len(lines)} stamps for {n} images; KITTI raw has one "
                           "line per image")
    try:
        ns = np.array([ln.replace(" ", "T") for ln in lines], dtype="datetime64[ns]")
    except ValueError:
        raise SlitcliError(f"{path}: stamps are not 'YYYY-MM-DD hh:mm:ss.fffffffff'; fix "
                           "the file") from None
    return ns.astype(np.int64) * 1e-9


def _kitti(folder: Path) -> tuple[list[FrameRef], tuple[str, ...]]:
    pair = _kitti_pair(folder)
    assert pair is not None
    lcam, rcam = pair
    lefts = _images(lcam / "data")
    rights = {p.stem: p for p in _images(rcam / "data")}
    missing = [p for p in lefts if p.stem not in rights]
    if missing or len(rights) != len(lefts):
        raise SlitcliError(f"{rcam / 'data'}: {len(rights)} images for {len(lefts)} in "
                           f"{lcam / 'data'}; KITTI pairs share a file name")
    times = _kitti_times(lcam, len(lefts))
    return [FrameRef(i, p.stem, float(times[i]), p, rights[p.stem])
            for i, p in enumerate(lefts)], ()


def _flat(folder: Path) -> tuple[list[FrameRef], tuple[str, ...]]:
    left, right = _flat_images(folder, "left"), _flat_images(folder, "right")
    keys = sorted(set(left) & set(right), key=natural_key)
    lonely = sorted(set(left) ^ set(right), key=natural_key)
    if lonely:
        k = lonely[0]
        have, want = ("left", "right") if k in left else ("right", "left")
        path = (left if k in left else right)[k]
        raise SlitcliError(f"{path}: no {want} image for this {have} one ({len(lonely)} "
                           f"unpaired); name pairs {have}{k}.png and {want}{k}.png")
    from slitcli.io.sequence import _read_times

    times = _read_times(folder / "times.csv", len(keys))
    return [FrameRef(i, left[k].stem, float(times[i]), left[k], right[k])
            for i, k in enumerate(keys)], ()


def read_layout(folder: str | Path, layout: str) -> tuple[list[FrameRef], tuple[str, ...]]:
    """The frames of a folder in a layout other than ``slitcli`` (which
    :class:`slitcli.io.sequence.StereoSequence` reads), and notes about left-out images."""
    f = Path(folder)
    return {"euroc": _euroc, "kitti": _kitti, "flat": _flat}[layout](f)


__all__ = ["LAYOUTS", "detect_layout", "read_layout"]
