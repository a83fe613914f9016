"""slitcli.laser's compiled kernels (slitcli/laser/_c): their constants are the Python
modules', and the profile fit recovers a noiseless stripe."""

from __future__ import annotations

import numpy as np
import pytest

from slitcli.laser import candidates, judge, profile
from slitcli.laser._c import candidates as compiled


def test_compiled_constants_are_the_python_ones():
    got = compiled.constants()
    fields = [n for n in dir(profile) if n.startswith("F_")]
    assert len(fields) == profile.N_FIELDS
    for name in [*fields, "N_FIELDS", "N_PAR", "MAX_ITER", "MIN_ROWS", "CONVERGED_PX",
                 "MIN_SIGMA_PX"]:
        assert got[name] == getattr(profile, name), name
    for name in ("NMS_HALF", "FLANK_ROWS", "NOISE_HALF", "N_SEEDS", "SEED_MIN_SIGMA_PX",
                 "SEED_EFFICIENCY", "MEAN_TO_SIGMA", "CLIP_SIGMAS"):
        assert got[name] == getattr(candidates, name), name
    assert got["OWN_REACH_PX"] == judge.OWN_REACH_PX


@pytest.mark.parametrize("seed", range(6))
def test_fit_recovers_a_noiseless_stripe(seed):
    # every column: a Gaussian of row v0, width s, peak a on the line c + b (v - v0),
    # exactly the profile model; the fit stops once its step is below CONVERGED_PX and
    # converges quadratically there, so the centre is within CONVERGED_PX, and the
    # width and peak within the float32 rounding of the evidence (relative 1e-6) times
    # the condition of the fit
    rng = np.random.default_rng(seed)
    w, h = 6, 64
    v0 = rng.uniform(20.0, 44.0, w)
    s = rng.uniform(0.8, 2.5, w)
    a = rng.uniform(20.0, 80.0, w)
    c = rng.uniform(-3.0, 3.0, w)
    b = rng.uniform(-0.05, 0.05, w)
    rows = np.arange(h)
    y = (c[:, None] + b[:, None] * (rows - v0[:, None])
         + a[:, None] * np.exp(-0.5 * ((rows - v0[:, None]) / s[:, None]) ** 2))
    y = np.ascontiguousarray(y, np.float32)
    img = np.zeros((w, h, 3), np.uint8)
    bg = np.zeros((3 * w, h), np.uint8)
    clipped = np.zeros((w, h), bool)
    mask = np.ones((w, h), bool)
    out = np.empty((w, 3, profile.N_FIELDS))
    candidates.column_candidates(img, bg, y, y, clipped, mask, 0.5, 0.5, 5.0, 10.0, 255,
                                 4.0, 0.1, 100.0, 3.0, out)
    best = out[:, 0]
    assert np.all(np.abs(best[:, profile.F_POS] - v0) < profile.CONVERGED_PX)
    assert np.allclose(best[:, profile.F_WIDTH], s, rtol=1e-3)
    assert np.allclose(best[:, profile.F_AMP], a, rtol=1e-3)
    assert np.all(best[:, profile.F_SAT] == 0.0)
    # the residuals are float32 rounding only: chi-square far below 1
    assert np.all(best[:, profile.F_CHI2] < 1e-3)
    # one fit per crossing: any other candidate is a pixel or more away
    other = out[:, 1:, profile.F_POS]
    assert np.all(np.isnan(other) | (np.abs(other - v0[:, None]) >= 1.0))
