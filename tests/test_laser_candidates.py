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
