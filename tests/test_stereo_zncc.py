"""The support tests' block and centred correlations (slitcli.stereo._c.zncc, _c.boundary):
eight blocks at a time against one at a time (bit for bit: the lanes only speed up), both
against a float64 reference within the float32 rounding bound; and the SGM cost inputs of
one compiled pass against the box filter (issue 23)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from slitcli.stereo import _boundary, _sgm
from slitcli.stereo._c import zncc
from slitcli.stereo.cost import _QUANT
from slitcli.stereo.reasons import Reason

SEEDS = [0, 1, 2, 3, 4]
EPS32 = float(np.finfo(np.float32).eps)


def _images(rng, smooth):
    h, w = 60, 90
    if smooth:   # weak texture: near-flat blocks, correlations near the thresholds
        left = 128 + np.cumsum(rng.normal(0.0, 2.0, (h, w)), axis=1) / 3
    else:
        left = rng.integers(0, 256, (h, w))
    left = np.clip(np.rint(left), 0, 255).astype(np.float32)
    right = np.clip(np.roll(left, -7, axis=1) + rng.integers(-2, 3, (h, w)), 0, 255)
    return left, right.astype(np.float32)


def _requests(rng, gl, n):
    # centres inside, on and past the borders (clipped blocks take the scalar code);
    # subpixel and whole disparities, and negative ones
    yc = rng.integers(-6, gl.shape[0] + 6, n)
    xc = rng.integers(-4, gl.shape[1] + 4, n)
    d = rng.uniform(-3.0, 30.0, n).astype(np.float32)
    d[::5] = np.rint(d[::5])
    return yc, xc, d


def _zncc64(sums, cnt):
    """ZNCC and its float32 rounding bound from float64 block sums (sa, sb, saa, sbb,
    sab, the sums of |a b|) of ``cnt`` samples each."""
    sa, sb, saa, sbb, sab, sab_abs = sums
    n = np.maximum(cnt, 1)
    va, vb = saa - sa * sa / n, sbb - sb * sb / n
    cov = sab - sa * sb / n
    den = np.sqrt(np.maximum(va, 0) * np.maximum(vb, 0))
    # recursive float32 summation of cnt terms: each sum is off by at most
    # cnt * eps * (sum of |terms|); the variances and the covariance inherit that
    # error twice (the sum of squares and the square of the sum)
    gamma = (cnt + 4) * EPS32
    err_va, err_vb = 2 * gamma * saa, 2 * gamma * sbb
    err_cov = gamma * (sab_abs + np.abs(sa * sb) / n) * 2
    with np.errstate(divide="ignore", invalid="ignore"):
        ref = np.where(den > 1e-3, cov / den, 0.0)
        bound = (err_cov + np.abs(cov) * (err_va / (2 * va) + err_vb / (2 * vb))) / den
        # a block counts only where rounding cannot move it across the flat threshold
        # nor change its variances by more than a tenth
        clear = (va > 10 * err_va) & (vb > 10 * err_vb) & (den > 2e-3)
    return ref, 2 * bound + 1e-6, clear & (cnt >= 2)


def _block_sums64(gl, gr, yc, xc, d, rx, ry):
    """The blocks of slitcli.stereo._c.zncc.blocks, summed in float64."""
    h, w = gl.shape
    off = np.floor(-d.astype(np.float64)).astype(np.int64)
    t = -d.astype(np.float64) - off
    dy, dx = np.mgrid[-ry:ry + 1, -rx:rx + 1]
    yy = yc[:, None, None] + dy
    xx = xc[:, None, None] + dx
    c0 = np.maximum.reduce([xc - rx, np.zeros_like(xc), -off])[:, None, None]
    c1 = np.minimum.reduce([xc + rx, np.full_like(xc, w - 1), w - 2 - off])[:, None, None]
    use = (yy >= 0) & (yy < h) & (xx >= c0) & (xx <= c1)
    ys, xs = np.clip(yy, 0, h - 1), np.clip(xx, 0, w - 1)
    xr = np.clip(xx + off[:, None, None], 0, w - 2)
    a = np.where(use, gl[ys, xs], 0.0)
    b = np.where(use, (1 - t)[:, None, None] * gr[ys, xr] + t[:, None, None] * gr[ys, xr + 1],
                 0.0)
    sums = [v.sum(axis=(1, 2)) for v in (a, b, a * a, b * b, a * b, np.abs(a * b))]
    return sums, use.sum(axis=(1, 2))


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("smooth", [False, True])
@pytest.mark.parametrize(("rx", "ry"), [(1, 1), (1, 4), (2, 3)])
def test_blocks_eight_at_a_time_equal_one_at_a_time(seed, smooth, rx, ry):
    rng = np.random.default_rng(seed)
    gl, gr = _images(rng, smooth)
    n = 3001   # not a multiple of eight: a part-filled last vector
    yc, xc, d = _requests(rng, gl, n)
    ref = np.empty(n, np.float32)
    out = np.empty(n, np.float32)
    zncc.blocks_one_at_a_time(gl, gr, yc, xc, d, n, rx, ry, ref)
    zncc.blocks(gl, gr, yc, xc, d, n, rx, ry, out)
    # real correlations, not only flat blocks (float sums of nearly flat clipped blocks
    # may pass 1 slightly: the scalar code's result, kept)
    assert np.isfinite(ref).all() and np.abs(ref).max() > 0.5
    np.testing.assert_array_equal(out.view(np.int32), ref.view(np.int32))


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("smooth", [False, True])
@pytest.mark.parametrize(("rx", "ry"), [(1, 1), (1, 4), (2, 3)])
def test_blocks_are_the_correlation_within_float32_rounding(seed, smooth, rx, ry):
    rng = np.random.default_rng(seed)
    gl, gr = _images(rng, smooth)
    n = 2000
    yc, xc, d = _requests(rng, gl, n)
    out = np.full(n, np.nan, np.float32)
    zncc.blocks(gl, gr, yc, xc, d, n, rx, ry, out)
    sums, cnt = _block_sums64(gl.astype(np.float64), gr.astype(np.float64), yc, xc, d, rx, ry)
    ref, bound, clear = _zncc64(sums, cnt)
    assert clear.sum() > n // 4
    err = np.abs(out - ref)
    assert (err[clear] <= bound[clear]).all(), float((err - bound)[clear].max())
    # blocks of fewer than two samples (wholly outside the image) are 0
    assert (out[cnt < 2] == 0).all()


def test_block_of_a_shifted_copy_correlates_fully():
    # the right image is the left one shifted by a whole 7 px: every unclipped block at
    # d = 7 is the same samples, correlation 1 up to rounding (hand-derived)
    rng = np.random.default_rng(0)
    gl = rng.integers(0, 256, (40, 80)).astype(np.float32)
    gr = np.roll(gl, -7, axis=1)
    n = 500
    yc = rng.integers(3, 37, n)
    xc = rng.integers(10, 70, n)
    d = np.full(n, 7.0, np.float32)
    out = np.empty(n, np.float32)
    zncc.blocks(gl, gr, yc, xc, d, n, 1, 3, out)
    np.testing.assert_allclose(out, 1.0, atol=1e-5)


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("r", [1, 2, 4])
def test_centred_support_is_the_correlation_within_float32_rounding(seed, r):
    rng = np.random.default_rng(seed)
    gl, gr = _images(rng, seed % 2 == 1)
    h, w = gl.shape
    disp = rng.uniform(-2.0, 12.0, (h, w)).astype(np.float32)
    disp[rng.random((h, w)) < 0.05] = np.nan   # no shift
    got = _boundary.support_zncc(gl, gr, disp, r)
    # the right image warped by disp (bilinear in x, clamped), in float64
    xr = np.arange(w)[None, :] - np.nan_to_num(disp.astype(np.float64), nan=0.0)
    xr = np.clip(xr, 0, w - 1)
    x0 = np.minimum(xr.astype(np.int64), w - 2)
    t = xr - x0
    rows = np.arange(h)[:, None]
    g64 = gr.astype(np.float64)
    b = (1 - t) * g64[rows, x0] + t * g64[rows, x0 + 1]
    a = gl.astype(np.float64)
    k = (2 * r + 1, 2 * r + 1)

    def box(v):
        return cv2.boxFilter(v, cv2.CV_64F, k, normalize=False, borderType=cv2.BORDER_CONSTANT)

    sums = [box(v) for v in (a, b, a * a, b * b, a * b, np.abs(a * b))]
    cnt = box(np.ones_like(a))
    ref, bound, clear = _zncc64(sums, cnt)
    assert clear.sum() > h * w // 4
    err = np.abs(got - ref)
    assert (err[clear] <= bound[clear]).all(), float((err - bound)[clear].max())


def test_compiled_codes_are_the_reasons():
    assert _boundary.REASON_SUPPORT == Reason.SUPPORT
    assert _boundary.REASON_BOUNDARY == Reason.BOUNDARY


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
