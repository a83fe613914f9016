"""slitcli.laser.candidates: the seed screen (the seeded Gaussian's own significance)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from slitcli.laser.candidates import _linear_z


def _lstsq_z(y: np.ndarray, use: np.ndarray, j0: int, v: float, s: float,
             sigma: float) -> float:
    """The same significance by the textbook route: least squares of (1, row - v,
    Gaussian) on the used rows, the amplitude over sigma sqrt(inv(X' X)[2, 2])."""
    rows = np.arange(y.size, dtype=float)[use] + j0
    x = np.stack([np.ones(rows.size), rows - v, np.exp(-0.5 * ((rows - v) / s) ** 2)], 1)
    coef = np.linalg.lstsq(x, y[use].astype(float), rcond=None)[0]
    cov = np.linalg.inv(x.T @ x)
    return coef[2] / (sigma * math.sqrt(cov[2, 2]))


@pytest.mark.parametrize("seed", range(5))
def test_linear_z_is_the_least_squares_significance(seed):
    rng = np.random.default_rng(seed)
    m = int(rng.integers(12, 30))
    j0 = int(rng.integers(0, 200))
    s = float(rng.uniform(0.6, 3.0))
    v = j0 + float(rng.uniform(4.0, m - 4.0))
    rows = np.arange(m) + j0
    y = (rng.uniform(-5, 5) + rng.uniform(-0.3, 0.3) * (rows - v)
         + rng.uniform(0, 30) * np.exp(-0.5 * ((rows - v) / s) ** 2)
         + rng.normal(0, 2.0, m)).astype(np.float32)
    use = rng.random(m) > 0.15
    use[:3] = True
    got = _linear_z(y, use, j0, v, s, 2.0, np.empty(m))
    assert got == pytest.approx(_lstsq_z(y, use, j0, v, s, 2.0), rel=1e-9, abs=1e-9)


@pytest.mark.parametrize("seed", range(5))
def test_linear_z_of_noise_is_unit_normal(seed):
    # on a line plus white noise of sigma the statistic is N(0, 1): its sample mean and
    # standard deviation over n draws lie within 5 standard errors (1 / sqrt(n) and
    # 1 / sqrt(2 n)) of 0 and 1
    rng = np.random.default_rng(100 + seed)
    n, m, sigma = 2000, 19, 3.0
    rows = np.arange(m)
    z = np.empty(n)
    use = np.ones(m, bool)
    e = np.empty(m)
    for k in range(n):
        y = (5.0 + 0.2 * rows + rng.normal(0, sigma, m)).astype(np.float64)
        z[k] = _linear_z(y, use, 0, 9.3, 1.2, sigma, e)
    assert abs(z.mean()) < 5.0 / math.sqrt(n)
    assert abs(z.std() - 1.0) < 5.0 / math.sqrt(2 * n)


def test_linear_z_needs_six_rows():
    y = np.array([0.0, 1.0, 9.0, 1.0, 0.0, 0.0])
    use = np.ones(6, bool)
    use[0] = False
    assert _linear_z(y, use, 0, 2.0, 1.0, 1.0, np.empty(6)) == 0.0


def _clipped_gap_scene(rng: np.random.Generator, rows_up: list[int]):
    """Six columns of a 60-row transposed image (W, H', 3) on a flat 50 DN surface; the
    stripe found at the outer columns (rows 30 and 30 +- 0.4), clipped (red 255) at
    rows 28-32 of columns 1-4 with red flanks ``rows_up`` (rows 26, 27) above and 200,
    120 below."""
    w, n = 6, 60
    img = np.full((w, n, 3), 50, np.uint8)
    img[1:5, 28:33, 2] = 255
    img[1:5, 26, 2], img[1:5, 27, 2] = rows_up
    img[1:5, 33, 2], img[1:5, 34, 2] = 200, 120
    bg = np.full((3 * w, n), 50, np.uint8)
    clipped = img[..., 2] >= 255
    mask = np.ones((w, n), bool)
    zeros = np.zeros((w, n), np.float32)
    cand = np.full((w, 3, 17), np.nan)
    cand[:, 0, 0] = 30.0
    cand[:, 0, 2] = 1.5
    v = np.array([30.0, np.nan, np.nan, np.nan, np.nan, 30.0 + rng.uniform(-0.4, 0.4)])
    return img, bg, clipped, mask, zeros, cand, v


@pytest.mark.parametrize("seed", range(4))
def test_gap_through_a_clipped_core_takes_its_plateau(seed):
    """A gap column clipped where the stripe must pass takes the clipped core's plateau
    centre (the level half way from the surface to the clip, crossed by linear
    interpolation: hand-derived below) and is marked saturated; without the image, or
    where the run is too long or its centre more than a pixel from the interpolated row,
    it is not filled (the evidence here is flat: no fit holds)."""
    from slitcli.laser.candidates import fill_gaps

    rng = np.random.default_rng(seed)
    up = int(rng.integers(121, 200))
    img, bg, clipped, mask, zeros, cand, v0 = _clipped_gap_scene(rng, [120, up])
    level = 0.5 * (50 + 255)
    # the crossings: above between rows 26 and 27, below between 33 and 34
    top = 26 + (level - 120) / (up - 120) if up > level else 27 + (level - up) / (255 - up)
    bottom = 33 + (200 - level) / (200 - 120)
    want = 0.5 * (top + bottom)

    def run(v, clip=clipped, **kw):
        v = v.copy()
        amp = np.full(6, 40.0)
        sat = np.zeros(6, bool)
        fill_gaps(v, amp, cand, zeros, zeros, clip, mask, 1.0, 1.0, 0, 4, 3.0, 2.0, 0.1,
                  2.0, 3.0, **kw, sat=sat.view(np.uint8))
        return v, sat

    # max_gap 4: columns 1-4 lie between the found 0 and 5
    v, sat = run(v0, img=img, bg=bg, sat_dn=255.0)
    assert np.allclose(v[1:5], want, atol=1e-9), (v, want)
    assert sat[1:5].all() and not sat[[0, 5]].any()
    v, sat = run(v0)
    assert np.isnan(v[1:5]).all() and not sat.any()
    # a run longer than a clipped seed's (5 s_max = 10 rows) is no core
    long_img = img.copy()
    long_img[1:5, 20:40, 2] = 255
    v, _ = run(v0, long_img[..., 2] >= 255, img=long_img, bg=bg, sat_dn=255.0)
    assert np.isnan(v[1:5]).all()
    # the stripe passing through the core's edge, 1.4-2 px off its centre: not its core
    far = v0 + 1.8
    v, _ = run(far, img=img, bg=bg, sat_dn=255.0)
    assert np.isnan(v[1:5]).all()
