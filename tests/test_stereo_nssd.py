"""The compiled Eq. 10 kernel (slitcli.stereo._nssd.nssd_rows) called directly: bands of
rows on threads, the right view's winners, empty windows, and its argument checks."""

from __future__ import annotations

import itertools
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from slitcli.stereo._nssd import nssd_rows
from slitcli.stereo.reasons import Reason

SEEDS = [0, 1, 2, 3, 4, 5]
SHIFT_PX = 4


def _outputs(shape: tuple[int, int]) -> list[np.ndarray]:
    # filled with values the kernel never writes, so an unwritten pixel shows
    return [np.full(shape, -7.0, np.float32), np.full(shape, -7.0, np.float32),
            np.full(shape, 250, np.uint8), np.full(shape, -7.0, np.float32)]


def _shifted_pair(seed: int, h: int = 30, w: int = 64) -> tuple[np.ndarray, np.ndarray]:
    """Integer-valued, zero-mean images (as the prefilter makes them); the right image
    is the left one moved SHIFT_PX to the left, with fresh values at the seam."""
    rng = np.random.default_rng(seed)
    pl = rng.integers(-100, 101, (h, w)).astype(np.float32)
    pr = np.roll(pl, -SHIFT_PX, axis=1)
    pr[:, -SHIFT_PX:] = rng.integers(-100, 101, (h, SHIFT_PX))
    return pl, np.ascontiguousarray(pr)


def _run(pl, pr, bands: int, *, dmin: int, num: int, m: int, n: int,
         subpixel: bool = True) -> list[np.ndarray]:
    h = pl.shape[0]
    prr = np.ascontiguousarray(pr[:, ::-1])
    out = _outputs(pl.shape)
    edges = np.linspace(0, h, bands + 1).astype(int)
    with ThreadPoolExecutor(max_workers=bands) as pool:
        jobs = [pool.submit(nssd_rows, pl, pr, prr, int(a), int(b), dmin, num, m, n, 0.1,
                            1.0, subpixel, np.float32(16.0), *out)
                for a, b in itertools.pairwise(edges)]
        for job in jobs:
            job.result()
    return out


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("dmin", [0, -3])
def test_bands_on_threads_give_the_bits_of_one_pass(seed, dmin):
    # every sum is an exact integer in float32, so the split cannot change a bit
    pl, pr = _shifted_pair(seed)
    one = _run(pl, pr, 1, dmin=dmin, num=16, m=3, n=2)
    four = _run(pl, pr, 4, dmin=dmin, num=16, m=3, n=2)
    for a, b in zip(one, four, strict=True):
        assert np.array_equal(a.view(np.uint8), b.view(np.uint8))
    assert (one[2] != 250).all()


@pytest.mark.parametrize("seed", SEEDS)
def test_left_and_right_winners_are_the_shift(seed):
    # an exact copy has SSD 0 at the shift, so its cost is SSD_EPS x the inverse norm,
    # far below any other disparity's: both views' winners are the shift wherever the
    # window and the partner's window lie inside both images
    m, n = 3, 2
    pl, pr = _shifted_pair(seed)
    w = pl.shape[1]
    disp, cost, reason, rdisp = _run(pl, pr, 2, dmin=0, num=12, m=m, n=n, subpixel=False)
    inner = slice(SHIFT_PX + m, w - m)
    assert (disp[:, inner] == SHIFT_PX).all()
    assert (reason[:, inner] == Reason.VALID).all()
    assert (cost[:, inner] < 1e-3 / 100.0).all()   # energies >= 1e4 per window
    assert (rdisp[:, m:w - SHIFT_PX - m] == SHIFT_PX).all()


@pytest.mark.parametrize("seed", SEEDS)
def test_empty_windows_have_no_candidate(seed):
    # two all-zero windows: (0 + SSD_EPS) x BIG_INV^2 overflows to +inf, no winner
    rng = np.random.default_rng(seed)
    h, w = int(rng.integers(10, 20)), int(rng.integers(30, 50))
    zero = np.zeros((h, w), np.float32)
    disp, cost, reason, rdisp = _run(zero, zero, 1, dmin=0, num=8, m=2, n=2)
    assert np.isnan(disp).all() and np.isnan(rdisp).all()
    assert np.isposinf(cost).all()
    assert (reason == Reason.NO_CANDIDATE).all()


def test_mismatched_arguments_are_refused():
    pl, pr = _shifted_pair(0)
    out = _outputs(pl.shape)
    with pytest.raises(ValueError, match="prr"):
        nssd_rows(pl, pr, pr[:, :-1].copy(), 0, 30, 0, 8, 2, 2, 0.1, 1.0, True,
                  np.float32(0.0), *out)
    with pytest.raises(ValueError, match=r"rows 0\.\.31"):
        nssd_rows(pl, pr, pr.copy(), 0, 31, 0, 8, 2, 2, 0.1, 1.0, True, np.float32(0.0),
                  *out)
