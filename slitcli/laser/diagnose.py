"""Why a run found no stripe: the warning ``laser`` and ``detect`` print (stderr, exit 0).

:func:`stripe_absence` looks at the frames of a run; when most of them show no stripe it
says so and, where the frames tell, why: grey images (red, green and blue equal: a grey
or infrared stream) cannot carry a red stripe; otherwise no red line stood out of the
measured noise, so the laser may be off, blocked or too weak for the exposure, or its
light falls outside the searched rows.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from slitcli.laser._c.evidence import grey_share_holds

#: a pixel whose channels differ by at most this much is grey (DN; JPEG and
#: demosaicing of a grey stream leave a little)
GREY_DN = 2
#: an image is grey when this share of its (sampled) pixels is
GREY_SHARE = 0.999
#: every GREY_STEP-th row and column is sampled
GREY_STEP = 4
#: frames without a stripe whose images are read again to tell whether they are grey
#: (evenly spaced over the run)
GREY_SAMPLE = 12


def is_grey(bgr: np.ndarray) -> bool:
    """Whether an image (H, W, 3) uint8 is grey: its channels equal within ``GREY_DN``
    on ``GREY_SHARE`` of its pixels (every ``GREY_STEP``-th row and column)."""
    x = np.asarray(bgr)
    if x.dtype == np.uint8 and x.ndim == 3 and x.shape[2] == 3:
        # (compiled: it stops at the first rows that settle it; numpy took ~0.15 ms a
        # 320x240 frame)
        return grey_share_holds(x, GREY_STEP, GREY_DN, GREY_SHARE)
    x = x[::GREY_STEP, ::GREY_STEP].astype(np.int16)
    d = np.maximum(np.abs(x[..., 2] - x[..., 1]), np.abs(x[..., 2] - x[..., 0]))
    return bool(np.mean(d <= GREY_DN) >= GREY_SHARE)


@dataclass(frozen=True)
class StripeAbsence:
    """The frames of a run without a stripe.

    Attributes
    ----------
    frames : int
        Frames in the run.
    without_stripe : int
        Frames in which no column has a stripe.
    grey : int
        Of those, frames whose image is grey (:func:`is_grey`).
    message : str
        One line for the user: how many frames, and why where the frames tell.
    """

    frames: int
    without_stripe: int
    grey: int
    message: str


def stripe_absence(found_columns: Sequence[int], grey: Sequence[bool], *,
                   search: str = "rig", min_share: float = 0.5,
                   checked: Sequence[bool] | None = None) -> StripeAbsence | None:
    """Say whether most frames of a run had no stripe, and why where it can tell.

    Parameters
    ----------
    found_columns : sequence of int
        Per frame, the number of columns with a stripe (``LaserFrame.found.sum()``).
    grey : sequence of bool
        Per frame, whether its image is grey (``LaserFrame.grey_image``).
    search : {"rig", "full"}
        The rows searched (``LaserParams.search``), for the advice.
    min_share : float
        The warning is given when more than this share of the frames has no stripe.
    checked : sequence of bool, optional
        Per frame, whether ``grey`` was looked at (default: every frame); the reason is
        judged on the frames without a stripe that were checked.

    Returns
    -------
    StripeAbsence or None
        None when the run is empty or most frames show a stripe.
    """
    found = np.asarray(found_columns, dtype=np.int64)
    g = np.asarray(grey, dtype=bool)
    if found.shape != g.shape:
        raise ValueError("found_columns and grey must have one entry per frame")
    n = int(found.size)
    none = found == 0
    k = int(none.sum())
    if n == 0 or k <= min_share * n:
        return None
    c = np.ones(n, bool) if checked is None else np.asarray(checked, dtype=bool)
    if c.shape != g.shape:
        raise ValueError("checked must have one entry per frame")
    k_grey = int((none & g & c).sum())
    k_checked = int((none & c).sum())
    head = f"no laser stripe in {k} of {n} frames"
    if 2 * k_grey > k_checked:
        of = "them" if k_checked == k else f"the {k_checked} checked"
        why = (f"{k_grey} of {of} are grey images (red = green = blue), which cannot carry a "
               "red stripe: give the colour camera's images, not a grey or infrared stream")
    else:
        where = ("the rows where the rig's laser plane lies within `max_search_range_m` "
                 "were" if search == "rig" else "every row was")
        why = ("no red line stood out of the noise measured on the images: the laser may be "
               "off or blocked, or too weak for the exposure; " + where + " searched" +
               (" (`search` full searches every row: a camera whose geometry differs from "
                "the rig)" if search == "rig" else ""))
    return StripeAbsence(frames=n, without_stripe=k, grey=k_grey, message=f"{head}: {why}")


def absence_notes(found_columns: Sequence[int],
                  grey_of: Callable[[list[int]], Sequence[bool]], *,
                  search: str = "rig") -> tuple[str, ...]:
    """The warning of a run (``laser``, ``detect``): :func:`stripe_absence` with the
    images of up to ``GREY_SAMPLE`` frames without a stripe (evenly spaced) checked for
    grey; ``()`` when most frames show a stripe.

    Parameters
    ----------
    found_columns : sequence of int
        Per frame read, its stripe columns (or laser bins).
    grey_of : callable
        ``grey_of(positions)``: whether the images at those positions of
        ``found_columns`` are grey (:func:`is_grey`); called only when the warning is
        given.
    search : {"rig", "full"}
    """
    found = np.asarray(found_columns, dtype=np.int64)
    none = np.flatnonzero(found == 0)
    if found.size == 0 or none.size <= 0.5 * found.size:
        return ()
    pick = np.unique(none[np.linspace(0, none.size - 1, min(GREY_SAMPLE, none.size))
                          .round().astype(int)])
    grey = np.zeros(found.size, bool)
    checked = np.zeros(found.size, bool)
    grey[pick] = np.asarray(grey_of([int(i) for i in pick]), dtype=bool)
    checked[pick] = True
    r = stripe_absence(found, grey, search=search, checked=checked)
    return () if r is None else (r.message,)
