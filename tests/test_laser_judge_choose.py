"""The compiled tests and choice of the stripe (slitcli/laser/_c/judge.pyx, choose.pyx).

The kernels' constants agree with the Python modules'; each kernel is checked against a
plain reference written here (numpy's median, a brute-force search over every path) or a
hand-derived value, over several seeds.
"""
from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from slitcli.laser import choose, judge, profile
from slitcli.laser._c import choose as c_choose
from slitcli.laser._c import judge as c_judge
from slitcli.laser.params import LaserParams
from slitcli.laser.profile import (
    F_AMP,
    F_CHI2,
    F_FLAT,
    F_GNOISE,
    F_KB,
    F_KG,
    F_KR,
    F_NCORE,
    F_NOISE,
    F_POS,
    F_SAT,
    F_SE_POS,
    F_TB,
    F_TG,
    F_TR,
    F_WIDTH,
    F_Z,
    N_FIELDS,
)

SEEDS = range(6)
#: the default levels of the tests and the choice (LaserParams)
DEFAULTS = LaserParams()
SURFACE = {"step": DEFAULTS.surface_step, "min_dn": DEFAULTS.surface_min_dn}


def test_compiled_constants_are_the_python_ones():
    """The field indices and constants compiled into the kernels are those the Python
    modules define (one side changed alone would read the wrong field)."""
    for name, value in c_judge.constants().items():
        src = profile if name.startswith("F_") or name == "MIN_SIGMA_PX" else judge
        assert getattr(src, name) == value, name
    for name, value in c_choose.constants().items():
        src = profile if name.startswith("F_") else choose
        assert getattr(src, name) == value, name
    assert len(c_judge.constants()) >= 20 and len(c_choose.constants()) >= 10


def _table(rng: np.random.Generator, w: int, k: int, h: int) -> np.ndarray:
    """A candidate table of plausible fits: most on a stripe across the view, red."""
    c = np.zeros((w, k, N_FIELDS))
    c[..., F_POS] = np.linspace(0.3 * h, 0.6 * h, w)[:, None] + rng.normal(0, 3, (w, k))
    c[..., F_WIDTH] = rng.uniform(0.8, 2.5, (w, k))
    c[..., F_Z] = rng.exponential(10, (w, k))
    c[..., F_SE_POS] = rng.exponential(0.1, (w, k))
    c[..., F_CHI2] = rng.exponential(1, (w, k))
    c[..., F_SAT] = rng.random((w, k)) < 0.1
    c[..., F_NOISE] = rng.uniform(1, 3, (w, k))
    c[..., F_GNOISE] = rng.uniform(1, 3, (w, k))
    c[..., F_AMP] = rng.uniform(5, 100, (w, k))
    c[..., F_TR] = rng.uniform(20, 100, (w, k))
    c[..., F_TG] = c[..., F_TR] * rng.uniform(0.0, 0.3, (w, k))
    c[..., F_TB] = c[..., F_TR] * rng.uniform(0.0, 0.3, (w, k))
    c[..., F_KR] = rng.uniform(50, 150, (w, k))
    c[..., F_KG] = rng.uniform(50, 150, (w, k))
    c[..., F_KB] = rng.uniform(50, 150, (w, k))
    c[..., F_NCORE] = rng.integers(1, 5, (w, k))
    c[..., F_FLAT] = 0
    return c


@pytest.mark.parametrize("seed", SEEDS)
def test_shape_tests_width_spread_and_laser_colour_by_numpys_median(seed):
    """Unclipped candidates wider than width_spread x the median width of the strong
    unclipped ones that pass fail; the laser colour is numpy's median (to the bit) of
    green and blue over red of the strong unclipped candidates left; none with fewer
    than COLOUR_SUPPORT of them."""
    rng = np.random.default_rng(seed)
    w, k, h = int(rng.integers(20, 300)), int(rng.integers(1, 5)), 240
    c = _table(rng, w, k, h)
    wide = rng.random((w, k)) < 0.15
    c[..., F_WIDTH][wide] = rng.uniform(4.0, 9.0, wide.sum())
    min_z, s_max = 2.0, 10.0
    args = (h, s_max, min_z, 3.0, 0.4, 0.1, 1.5, 0)
    ok_all, _ = c_judge.shape_tests(c, None, *args, math.inf)
    ok, laser = c_judge.shape_tests(c, None, *args, DEFAULTS.width_spread)
    unclipped = c[..., F_SAT] == 0
    strong = unclipped & (c[..., F_Z] >= judge.COLOUR_Z * min_z)
    widest = DEFAULTS.width_spread * np.median(c[..., F_WIDTH][ok_all & strong])
    assert np.array_equal(ok, ok_all & ~(unclipped & (c[..., F_WIDTH] > widest)))
    assert (ok_all & ~ok).any()
    strong &= ok
    assert strong.sum() >= judge.COLOUR_SUPPORT
    g = np.median(c[..., F_TG][strong] / c[..., F_TR][strong])
    b = np.median(c[..., F_TB][strong] / c[..., F_TR][strong])
    assert laser is not None
    assert laser[0] == 1.0 and laser[1] == min(g, judge.MAX_LASER_GB) and \
        laser[2] == min(b, judge.MAX_LASER_GB)
    # too few strong columns: no colour
    few = c[: judge.COLOUR_SUPPORT - 1, :1].copy()
    _, none = c_judge.shape_tests(few, None, *args, DEFAULTS.width_spread)
    assert none is None


@pytest.mark.parametrize("seed", SEEDS)
def test_model_tests_follow_eq2_and_the_width_range(seed):
    """A fit passes alone only inside the image, with a width in [MIN_SIGMA_PX, s_max],
    a shape within max_chi2 (unless clipped or flat) and Eq. 2 on its core's light,
    unless its core is clipped (red, F_SAT 1, or white, F_SAT 2: the unclipped rows of
    the core are the clip's shoulders, whose colour is the tone curve's)."""
    rng = np.random.default_rng(seed)
    w, k, h = 200, 3, 240
    c = _table(rng, w, k, h)
    c[..., F_SAT][rng.random((w, k)) < 0.1] = 2.0
    c[..., F_WIDTH] = rng.uniform(0.1, 6.0, (w, k))
    c[..., F_POS] = rng.uniform(-5, h + 5, (w, k))
    c[..., F_TG] = c[..., F_TR] * rng.uniform(0.0, 1.5, (w, k))
    c[..., F_CHI2] = rng.uniform(0, 6, (w, k))
    s_max, max_chi2, min_th, min_dth = 4.0, 3.0, 0.4, 0.1
    ok, _ = c_judge.shape_tests(c, None, h, s_max, 1e9, max_chi2, min_th, min_dth, 1.5, 0,
                                DEFAULTS.width_spread)  # (min_z huge: no width spread test)
    pos, s, sat = c[..., F_POS], c[..., F_WIDTH], c[..., F_SAT] > 0
    tot = c[..., F_TR] + c[..., F_TG] + c[..., F_TB]
    r = c[..., F_TR] / tot
    eq2 = (tot > 0) & (r > min_th) & (r - np.maximum(c[..., F_TG], c[..., F_TB]) / tot > min_dth)
    want = (pos >= -0.5) & (pos <= h - 0.5) & (s >= profile.MIN_SIGMA_PX) & (s <= s_max) & \
        (sat | (c[..., F_CHI2] <= max_chi2)) & (eq2 | sat)
    assert np.array_equal(ok, want)
    assert 0.1 < want.mean() < 0.9
    # clipped cores, red and white, that pass only because Eq. 2 is not asked of them
    for level in (1.0, 2.0):
        assert (want & ~eq2 & (c[..., F_SAT] == level)).any()


@pytest.mark.parametrize("seed", SEEDS)
def test_sheet_test_bounds_the_width_by_the_sheet(seed):
    """With the sheet's sigma known, an unclipped candidate passes only with a width
    between the sheet's / tolerance and x tolerance (pixel extent added, widened by two
    standard errors); an unknown sheet (NaN) does not judge."""
    rng = np.random.default_rng(seed)
    w, k, h = 150, 2, 240
    c = _table(rng, w, k, h)
    c[..., F_SAT] = 0
    c[..., F_SE_POS] = 0.0
    c[..., F_CHI2] = 0.0
    sheet = np.full((w, k), 1.0)
    sheet[::7] = np.nan
    tol = 1.5
    # (sheet_support beyond the table: the parameter's sheet is the only reference)
    ok, _ = c_judge.shape_tests(c, sheet, h, 4.0, 1e9, 3.0, 0.0, -1.0, tol, 10 ** 6,
                                DEFAULTS.width_spread)
    lo, hi = math.sqrt(1 / tol ** 2 + 1 / 12), math.sqrt(tol ** 2 + 1 / 12)
    s = c[..., F_WIDTH]
    want = np.isnan(sheet) | ((s >= lo) & (s <= hi))
    assert np.array_equal(ok, want)


def _with_hue(hue_deg: np.ndarray, blue: np.ndarray) -> np.ndarray:
    """(n, 3) RGB over red 1 with blue ``blue`` and the hue ``atan2(sqrt 3 (g - b),
    2 r - g - b)`` of ``hue_deg``: green solved from the hue's tangent."""
    t = np.tan(np.radians(hue_deg))
    g = (t * (2.0 - blue) + math.sqrt(3.0) * blue) / (math.sqrt(3.0) + t)
    return np.stack([np.ones_like(g), g, blue], axis=1)


@pytest.mark.parametrize("seed", SEEDS)
def test_hue_test_keeps_red_light_and_drops_yellow(seed):
    """An unclipped core's light whose hue lies beyond max_hue_deg towards yellow by
    more than COLOUR_SIGMAS noise sigmas fails; red, magenta and orange light within it
    passes, as does yellow light too faint to tell (a 1 DN core), a clipped core, and
    everything at max_hue_deg 90."""
    rng = np.random.default_rng(seed)
    n, h, sigma, limit = 60, 240, 2.0, 40.0
    hue = np.tile([-30.0, 0.0, 25.0, 60.0, 75.0, 60.0], n // 6)
    size = np.tile([40.0, 40.0, 40.0, 40.0, 40.0, 1.0], n // 6) * rng.uniform(1, 2, n)
    c = np.zeros((n, 1, N_FIELDS))
    c[:, 0, [F_TR, F_TG, F_TB]] = size[:, None] * _with_hue(hue, rng.uniform(0, 0.2, n))
    c[:, 0, F_POS] = rng.uniform(20, 200, n)
    c[:, 0, F_WIDTH] = rng.uniform(1.0, 2.0, n)
    c[:, 0, F_NCORE] = rng.integers(2, 6, n)
    # (Eq. 2 passes everything: min_th 0, min_delta_th -1)
    args = (None, h, 4.0, 1e9, 3.0, 0.0, -1.0, 1.5, 0, DEFAULTS.width_spread, 0.0)
    ok, _ = c_judge.shape_tests(c, *args, limit, sigma)
    yellow = (hue > limit) & (size > 10.0)
    assert np.array_equal(ok[:, 0], ~yellow)
    assert c_judge.shape_tests(c, *args, 90.0, sigma)[0].all()
    c[:, 0, F_SAT] = 1.0
    assert c_judge.shape_tests(c, *args, limit, sigma)[0].all()


@pytest.mark.parametrize("seed", SEEDS)
def test_colour_tests_keep_light_in_the_plane_of_laser_and_surface(seed):
    """A core contrast in the plane of the laser's and the surface's colours passes; one
    leaving it by more than COLOUR_SIGMAS noise sigmas of the core's mean plus
    colour_error of its size fails, by less passes."""
    rng = np.random.default_rng(seed)
    laser = np.array([1.0, *rng.uniform(0, 0.4, 2)])
    lu = laser / np.linalg.norm(laser)
    n = 40
    c = np.zeros((n, 1, N_FIELDS))
    k = rng.uniform(30, 200, (n, 3))
    t = rng.uniform(10, 60, (n, 1)) * laser + rng.uniform(-0.3, 0.3, (n, 1)) * k
    across = np.cross(laser, k)
    across /= np.linalg.norm(across, axis=1, keepdims=True)
    ncore, chan, colour_error = 4.0, 2.0, 0.05
    lim = judge.COLOUR_SIGMAS * chan / math.sqrt(ncore) + colour_error * np.linalg.norm(t, axis=1)
    share = np.tile([0.0, 0.0, 0.5, 2.0], n // 4)  # in the plane, inside, beyond the limit
    t_off = t + (share * lim)[:, None] * across
    c[:, 0, [F_TR, F_TG, F_TB]] = t_off
    c[:, 0, [F_KR, F_KG, F_KB]] = k
    c[:, 0, F_NCORE] = ncore
    ok = np.ones((n, 1), bool)
    c_judge.colour_tests(c, laser, lu, chan, colour_error, 0.0, ok)
    assert np.array_equal(ok[:, 0], share < 1.0)
    # colour_error 1 (the default): no plane test, whatever the residual
    far = c.copy()
    far[:, 0, [F_TR, F_TG, F_TB]] = t + (4.0 * np.linalg.norm(t, axis=1))[:, None] * across
    ok = np.ones((n, 1), bool)
    c_judge.colour_tests(far, laser, lu, chan, 1.0, 0.0, ok)
    assert ok.all()
    ok = np.ones((n, 1), bool)
    c_judge.colour_tests(far, laser, lu, chan, 0.5, 0.0, ok)
    assert not ok.any()
    # a clipped core's (red, F_SAT 1, or white, 2) light is the clip's: not judged
    far[::4, 0, F_SAT] = 1.0
    far[1::4, 0, F_SAT] = 2.0
    ok = np.ones((n, 1), bool)
    c_judge.colour_tests(far, laser, lu, chan, 0.5, DEFAULTS.laser_share_z, ok)
    assert np.array_equal(ok[:, 0], far[:, 0, F_SAT] > 0)


@pytest.mark.parametrize("seed", SEEDS)
def test_laser_share_tells_the_surfaces_own_light(seed):
    """On a grey surface, light of the surface's own colour (a brighter patch) well
    above the noise is not the laser's; red light of the same size is; on a red surface
    the colours cannot tell the two apart (True)."""
    rng = np.random.default_rng(seed)
    laser = np.array([1.0, rng.uniform(0, 0.2), rng.uniform(0, 0.2)])
    lu = laser / np.linalg.norm(laser)
    grey = np.full(3, rng.uniform(50, 150))
    size = rng.uniform(30, 80)
    own = size * grey / np.linalg.norm(grey)
    red = size * lu
    assert not judge.laser_share(own, grey, laser, lu, 3.0, 2.0, DEFAULTS.laser_share_z)
    assert judge.laser_share(red, grey, laser, lu, 3.0, 2.0, DEFAULTS.laser_share_z)
    # a surface within 0.03 rad of the laser's colour: L . e too small to judge
    red_surface = 100.0 * laser + np.array([0.0, 3.0, 0.0])
    assert judge.laser_share(own, red_surface, laser, lu, 3.0, 2.0, DEFAULTS.laser_share_z)


@pytest.mark.parametrize("seed", SEEDS)
def test_surface_continues_sees_two_surfaces(seed):
    """A candidate on a border between a grey and a red surface (running along the
    stripe) is not the laser; one on a single surface, or near the image's edge (a side
    outside), is; a clipped core is not judged."""
    rng = np.random.default_rng(seed)
    w, h = 40, 60
    img_t = np.empty((w, h, 3), np.uint8)
    img_t[:] = rng.integers(90, 110)
    border = int(rng.integers(25, 35))
    img_t[:, border:] = (40, 40, 160)  # BGR red below the border
    c = np.zeros((w, 2, N_FIELDS))
    c[:, 0, F_POS] = border - 0.5
    c[:, 1, F_POS] = 12.0  # inside the grey
    c[:, :, F_WIDTH] = 1.0
    out = judge.surface_continues(c, img_t, 0, 2.0, **SURFACE)
    assert not out[:, 0].any() and out[:, 1].all()
    # the levels: grey and red differ by 0.33 in chromaticity; a larger step, or sides
    # (grey about 100 DN a channel) darker than min_dn, leave the border unjudged
    assert judge.surface_continues(c, img_t, 0, 2.0, step=0.4, min_dn=10.0).all()
    assert judge.surface_continues(c, img_t, 0, 2.0, step=0.1, min_dn=115.0).all()
    # rows from row0: the same scene seen from image row 10
    c2 = c.copy()
    c2[..., F_POS] += 10
    assert np.array_equal(judge.surface_continues(c2, img_t, 10, 2.0, **SURFACE), out)
    # a side beyond the image is not judged; nor are candidates not needed
    c[:, 1, F_POS] = 1.0
    assert judge.surface_continues(c, img_t, 0, 2.0, **SURFACE)[:, 1].all()
    need = np.zeros((w, 2), bool)
    assert judge.surface_continues(c, img_t, 0, 2.0, need, **SURFACE).all()
    # a clipped core (red or white) is not judged: its bloom lights the rows beside it
    for level in (1.0, 2.0):
        clipped = c.copy()
        clipped[:, 0, F_SAT] = level
        assert judge.surface_continues(clipped, img_t, 0, 2.0, **SURFACE)[:, 0].all()


def test_links_by_jump_or_slope():
    """Rows link within max_jump_px, or within sqrt(3) x the summed widths."""
    assert choose.links(2.0, 0.1, 0.1, 2.0) and not choose.links(2.01, 0.1, 0.1, 2.0)
    assert choose.links(-3.4, 1.0, 1.0, 1.0)  # 3.4 <= 2 sqrt(3)
    assert not choose.links(3.5, 1.0, 1.0, 1.0)


def _path_score(cand, path, prev_v, z_weak, beta, cont, jump):
    """Eq. 4's objective of one path (-1 none), as choose.best_path defines it; None
    where two chosen neighbours do not link."""
    total = 0.0
    for u, q in enumerate(path):
        if q < 0:
            continue
        z = cand[u, q, F_Z] * cand[u, q, F_NOISE] / cand[u, q, F_GNOISE]
        f = 0.0
        if prev_v.size == cand.shape[0] and np.isfinite(prev_v[u]):
            d = (cand[u, q, F_POS] - prev_v[u]) / cont
            f = math.exp(-0.5 * d * d)
        total += 0.5 * (z * z * (1 + beta * f) - z_weak ** 2)
        if u > 0 and path[u - 1] >= 0:
            r = path[u - 1]
            dv = cand[u, q, F_POS] - cand[u - 1, r, F_POS]
            if not choose.links(dv, cand[u, q, F_WIDTH], cand[u - 1, r, F_WIDTH], jump):
                return None
            total -= 0.5 * (dv / cont) ** 2
    return total


@pytest.mark.parametrize("seed", SEEDS)
def test_best_path_is_the_best_of_all_paths(seed):
    """Viterbi's choice scores as the best of every path (brute force over 3^6)."""
    rng = np.random.default_rng(seed)
    w, k = 6, 2
    c = _table(rng, w, k, 100)
    c[..., F_POS] = 50 + rng.normal(0, 2.5, (w, k))
    c[..., F_Z] = rng.uniform(0.5, 6, (w, k))
    ok = rng.random((w, k)) < 0.85
    prev = np.empty(0) if seed % 2 else 50 + rng.normal(0, 1, w)
    z_weak, beta, cont, jump = 1.5, 0.5, 2.0, 3.0
    pick = np.empty(w, np.int64)
    choose.best_path(c, ok, prev, z_weak, beta, cont, jump, pick)
    allowed = [[-1] + [q for q in range(k) if ok[u, q] and c[u, q, F_Z] >= z_weak]
               for u in range(w)]
    best = max(s for path in itertools.product(*allowed)
               if (s := _path_score(c, path, prev, z_weak, beta, cont, jump)) is not None)
    got = _path_score(c, list(pick), prev, z_weak, beta, cont, jump)
    assert got is not None and got == pytest.approx(best, rel=1e-12, abs=1e-9)


@pytest.mark.parametrize("seed", SEEDS)
def test_choose_stripe_keeps_the_stripe_and_drops_short_clutter(seed):
    """A continuous weak stripe across the view is chosen; a short run of strong clutter
    away from it is struck out (its segment too short), and the stripe keeps its
    columns; outputs are NaN where nothing is chosen."""
    rng = np.random.default_rng(seed)
    w, k = 120, 2
    c = _table(rng, w, k, 240)
    c[:, 0, F_POS] = 100 + 0.1 * np.arange(w) + rng.normal(0, 0.05, w)
    c[:, 0, F_Z] = rng.uniform(4, 6, w)
    c[:, 0, F_SE_POS] = 0.05
    c[:, 1, F_POS] = 180 + rng.normal(0, 0.05, w)
    c[:, 1, F_Z] = 1.0
    # three clutter columns far from the stripe, each more significant than it, but
    # short of both a segment's length and strong_z
    c[50:53, 1, F_Z] = 20.0
    c[..., F_NOISE] = c[..., F_GNOISE] = 2.0
    c[..., F_SAT] = 0
    ok = np.ones((w, k), bool)
    ok[:, 1] = False
    ok[50:53, 1] = True
    ok[90:100, 0] = False  # the stripe is hidden here
    v, amp, sat = np.empty(w), np.empty(w), np.empty(w, bool)
    choose.choose_stripe(c, ok, np.empty(0), 0.5, 1.5, 2.0, 3.0, 10, 3.0, 25.0, 20,
                         DEFAULTS.choice_rounds, v, amp, sat)
    on = np.isfinite(v)
    assert np.array_equal(on, ok[:, 0])
    assert np.max(np.abs(v[on] - c[on, 0, F_POS])) < 0.2
    assert np.array_equal(amp[on], c[on, 0, F_AMP]) and np.isnan(amp[~on]).all()
    assert not sat.any()
    # a frame whose longest segment is shorter than min_stripe_cols shows no stripe
    choose.choose_stripe(c, ok, np.empty(0), 0.5, 1.5, 2.0, 3.0, 10, 3.0, 25.0, w,
                         DEFAULTS.choice_rounds, v, amp, sat)
    assert np.isnan(v).all() and np.isnan(amp).all()


@pytest.mark.parametrize("seed", range(5))
def test_one_crossing_keeps_the_core_of_overlapping_fits(seed):
    # per column: a core (narrow, bright), a wider, fainter fit whose centre lies within
    # the sum of the two widths (the core and its halo, or two stripe pieces a row step
    # apart), and a third fit far away; in other columns the wide fit lies beyond the
    # sum of the widths (a second surface's light), or the core failed the tests
    rng = np.random.default_rng(seed)
    w = 60
    c = np.full((w, 3, N_FIELDS), np.nan)
    s0 = rng.uniform(0.8, 2.0, w)
    s1 = s0 * rng.uniform(1.5, 4.0, w)
    a0 = rng.uniform(60.0, 200.0, w)
    v0 = rng.uniform(100.0, 140.0, w)
    gap = np.where(np.arange(w) < w // 2, rng.uniform(0.1, 0.95, w),
                   rng.uniform(1.05, 3.0, w)) * (s0 + s1)
    c[:, 0, F_POS], c[:, 0, F_WIDTH], c[:, 0, F_AMP] = v0, s0, a0
    c[:, 1, F_POS] = v0 + rng.choice([-1.0, 1.0], w) * gap
    c[:, 1, F_WIDTH], c[:, 1, F_AMP] = s1, a0 * rng.uniform(0.2, 0.9, w)
    c[:, 2, F_POS], c[:, 2, F_WIDTH], c[:, 2, F_AMP] = v0 + 60.0, s1, a0 * 0.5
    ok = np.ones((w, 3), bool)
    ok[::7, 0] = False  # a core that failed: it takes no other fit out
    ok_in = ok.copy()
    out = judge.one_crossing(c, ok)
    overlap = np.arange(w) < w // 2
    assert np.array_equal(out[:, 0], ok[:, 0])
    assert np.array_equal(out[:, 1], ~(overlap & ok[:, 0]))
    assert out[:, 2].all()
    assert np.array_equal(ok, ok_in)  # the input is not changed


@pytest.mark.parametrize("seed", SEEDS)
def test_choose_stripe_sums_a_long_faint_stripe(seed):
    """A segment's significance is summed along it (``sqrt(sum z^2)``) and compared with
    that of the shortest segment kept (``min_segment_cols`` columns at ``min_z``): a
    stripe whose columns are each below ``min_z`` but above ``weak_z`` is kept when it
    is long enough to carry that much evidence, and dropped when it is not."""
    rng = np.random.default_rng(seed)
    w, k, min_seg, min_z, z_weak = 160, 1, 10, 5.0, 3.0
    c = _table(rng, w, k, 240)
    c[:, 0, F_POS] = 120 + 0.05 * np.arange(w) + rng.normal(0, 0.05, w)
    c[..., F_NOISE] = c[..., F_GNOISE] = 2.0
    c[..., F_SAT] = 0
    c[:, 0, F_SE_POS] = 0.05
    z = rng.uniform(3.5, 4.5, w)  # RMS about 4: under min_z column by column
    c[:, 0, F_Z] = z
    ok = np.ones((w, k), bool)
    # a run of n columns (the rest hidden) is kept iff sum z^2 >= min_seg * min_z^2
    for n in (8, 12, 16, 40):
        ok[:] = False
        ok[20:20 + n, 0] = True
        v, amp, sat = np.empty(w), np.empty(w), np.empty(w, bool)
        choose.choose_stripe(c, ok, np.empty(0), 0.5, z_weak, 2.0, 3.0, min_seg, min_z,
                             4 * min_z, 0, DEFAULTS.choice_rounds, v, amp, sat)
        kept = np.sum(z[20:20 + n] ** 2) >= min_seg * min_z ** 2 and n >= min_seg
        assert np.array_equal(np.isfinite(v), ok[:, 0] & kept), n
