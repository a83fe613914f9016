"""The support tests' block correlations eight at a time (slitcli.stereo._zncc) against
one at a time, and the SGM cost inputs of one compiled pass against the box filter:
both only speed up, so the results must be the same bit for bit (issue 23)."""

from __future__ import annotations

import cv2
import numba as nb
import numpy as np
import pytest

from slitcli.stereo import _sgm, _zncc
from slitcli.stereo.cost import _QUANT

SEEDS = [0, 1, 2, 3, 4]


@nb.njit(fastmath=_zncc._FASTMATH)
def _one_at_a_time(gl, gr, yc, xc, d, rx, ry, out):
    # the scalar block as the support tests inlined it (same fastmath flags)
    for i in range(yc.shape[0]):
        out[i] = _zncc.zncc_block(gl, gr, yc[i], xc[i], d[i], rx, ry)


def _images(rng, smooth):
    h, w = 60, 90
    if smooth:   # weak texture: near-flat blocks, correlations near the thresholds
        left = 128 + np.cumsum(rng.normal(0.0, 2.0, (h, w)), axis=1) / 3
    else:
        left = rng.integers(0, 256, (h, w))
    left = np.clip(np.rint(left), 0, 255).astype(np.float32)
    right = np.clip(np.roll(left, -7, axis=1) + rng.integers(-2, 3, (h, w)), 0, 255)
    return left, right.astype(np.float32)


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("smooth", [False, True])
@pytest.mark.parametrize(("rx", "ry"), [(1, 1), (1, 4), (2, 3)])
def test_blocks_eight_at_a_time_equal_one_at_a_time(seed, smooth, rx, ry):
    rng = np.random.default_rng(seed)
    gl, gr = _images(rng, smooth)
    n = 3001   # not a multiple of eight: a part-filled last vector
    # centres inside, on and past the borders (clipped blocks take the scalar code);
    # subpixel and whole disparities, and negative ones
    yc = rng.integers(-6, gl.shape[0] + 6, n)
    xc = rng.integers(-4, gl.shape[1] + 4, n)
    d = rng.uniform(-3.0, 30.0, n).astype(np.float32)
    d[::5] = np.rint(d[::5])
    ref = np.empty(n, np.float32)
    out = np.empty(n, np.float32)
    _one_at_a_time(gl, gr, yc, xc, d, rx, ry, ref)
    _zncc.zncc_blocks(gl, gr, yc, xc, d, n, rx, ry, out)
    # real correlations, not only flat blocks (float sums of nearly flat clipped blocks
    # may pass 1 slightly: the scalar code's result, kept)
    assert np.isfinite(ref).all() and np.abs(ref).max() > 0.5
    np.testing.assert_array_equal(out.view(np.int32), ref.view(np.int32))


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize(("m", "n", "cap_q"), [(4, 4, 60), (7, 2, 60), (10, 10, 1000)])
def test_window_inputs_equal_the_box_filter(seed, m, n, cap_q):
    rng = np.random.default_rng(seed)
    h, w, pad = 37, 53, 20
    # prefiltered images hold whole numbers of quarter DN (slitcli.stereo.cost)
    pl = rng.integers(-cap_q, cap_q + 1, (h, w)).astype(np.float32)
    pr = rng.integers(-cap_q, cap_q + 1, (h, w)).astype(np.float32)
    pr[10:20, 5:30] = 0.0   # no energy: inverse root 0
    assert _QUANT == 4.0
    k = (2 * m + 1, 2 * n + 1)

    def box(a):
        return cv2.boxFilter(a, cv2.CV_32F, k, normalize=False,
                             borderType=cv2.BORDER_CONSTANT)

    el, count = np.empty((h, w), np.float32), np.empty((h, w), np.float32)
    prr, err, irr = np.zeros((3, h, w + 2 * pad), np.float32)
    _sgm.window_inputs(pl, pr, m, n, pad, el, count, prr, err, irr)
    er = box(pr * pr)
    with np.errstate(divide="ignore"):
        inv = np.where(er > 0, np.float32(1.0) / np.sqrt(er), np.float32(0.0))
    np.testing.assert_array_equal(el, box(pl * pl))
    np.testing.assert_array_equal(count, box(np.ones_like(pl)))
    for got, want in ((prr, pr), (err, er), (irr, inv.astype(np.float32))):
        np.testing.assert_array_equal(got[:, pad:pad + w], want[:, ::-1])
        assert not got[:, :pad].any() and not got[:, pad + w:].any()
