"""The matcher's depth edges: the foreground kept inside its silhouette, no spill of a
textured square onto a plain background, and the pixels the depth-edge test marks
(synthetic pairs with exact truth; the matcher's other unit tests are in
test_stereo_matcher.py)."""

from __future__ import annotations

import numpy as np
import pytest
from stereo_synth import occlusion_pair

from slitcli.stereo.matcher import MatcherParams, compute_disparity
from slitcli.stereo.reasons import Reason

SEEDS = [0, 1, 2, 3, 4, 5]


def _fattening(res, fg_px: float, bg_px: float, box: tuple[int, int, int, int]):
    """Per row of the square (away from its top and bottom): valid pixels outside the
    square that carry the square's disparity, left and right of it (px), and the share
    of rows whose first and last square columns are valid at the square's disparity."""
    x0, x1, y0, y1 = box
    d = res.disparity_px[y0 + 10:y1 - 10]
    fg = np.isfinite(d) & (np.abs(d - fg_px) < np.abs(d - bg_px))
    return (fg[:, :x0].sum(axis=1), fg[:, x1:].sum(axis=1),
            fg[:, x0].mean(), fg[:, x1 - 1].mean())


EDGES_OFF = dict(boundary_ratio=0.0, support_side_min_zncc=0.0)
EDGE_BOX = (140, 220, 60, 180)
EDGE_FG_PX, EDGE_BG_PX, EDGE_NOISE_DN = 20.0, 8.0, 2.0


def _edge_scene(seed: int, noise_dn: float = EDGE_NOISE_DN):
    """A strongly textured square (60 DN) at 20 px in front of a weakly textured plane
    (10 DN) at 8 px; both textures and the noise drawn from ``seed``."""
    return occlusion_pair(EDGE_BG_PX, EDGE_FG_PX, EDGE_BOX, noise_dn=noise_dn, seed=seed,
                          foreground_contrast_dn=60.0, background_contrast_dn=10.0)


def _texture_reach_px(p: MatcherParams) -> int:
    """How far past a silhouette the square's texture reaches into a pixel's cost: half
    the window plus half the mean prefilter's box (4 + 4 px for the defaults)."""
    return p.window_w_px // 2 + p.prefilter_size_px // 2


def _column_residual(a: np.ndarray, b: np.ndarray, y: int, xa: int, xb: float,
                     half_rows: int) -> float:
    """Mean squared difference over rows y -+ half_rows between column xa of ``a`` and
    ``b`` at the fractional column xb (linear in x): the depth-edge test's residual."""
    f = int(np.floor(xb))
    t = xb - f
    rows = slice(y - half_rows, y + half_rows + 1)
    col = (1.0 - t) * b[rows, f].astype(float) + t * b[rows, f + 1].astype(float)
    return float(np.mean((a[rows, xa].astype(float) - col) ** 2))


def _decisive_evidence_dn2(p: MatcherParams, noise_dn: float) -> float:
    """The noise-free column residual E (DN^2) above which the depth-edge test must
    prefer the farther surface whatever the noise, for a column of N = window_h_px rows.

    Each image carries noise of variance s2 = noise_dn^2 + 1/12 (rounding), so a pixel
    difference has variance 2 s2. At the farther surface's own disparity the column's
    residual is the noise alone: mean 2 s2, standard deviation 2 s2 sqrt(2 / N). At the
    pixel's (foreground) disparity it is E + 2 s2 plus a cross term 2 mean(D e) of
    standard deviation 2 sqrt(2 s2 E / N). The test kills when the farther residual is
    below ``boundary_ratio`` times the pixel's own; at three standard deviations each
    way that is certain when
    2 s2 (1 + 3 k) <= ratio (E + 2 s2 (1 - 3 k) - 6 sqrt(2 s2 E / N)), k = sqrt(2 / N),
    a quadratic in sqrt(E) (E* = 100 DN^2 for 2 DN noise, 9 rows, ratio 0.5).
    """
    n, r = p.window_h_px, p.boundary_ratio
    s2 = noise_dn ** 2 + 1.0 / 12.0
    k = np.sqrt(2.0 / n)
    q = np.sqrt(2.0 * s2 / n)
    c = r * 2.0 * s2 * (1.0 - 3.0 * k) - 2.0 * s2 * (1.0 + 3.0 * k)
    root = (6.0 * r * q + np.sqrt(36.0 * r * r * q * q - 4.0 * r * c)) / (2.0 * r)
    # and the pixel's own residual must pass the noise floor (boundary_noise_dn)
    return float(max(root * root, p.boundary_noise_dn ** 2))


def _undecidable_survivors(res, p: MatcherParams, seed: int, check_left: bool) -> list:
    """The fattened pixels of ``res`` (valid outside the square at its disparity) that
    the depth-edge test could have decided but kept (module notes of
    slitcli.stereo._boundary; the evidence on the noise-free pair of the same seed):

    - right of the square a fattened pixel's left column is compared with the
      background's disparity; it is decidable where a valid farther neighbour lies
      within ``boundary_radius_px`` columns and the column's noise-free residual at the
      pixel's disparity reaches :func:`_decisive_evidence_dn2` (the background's own is
      0: it is visible in the right image);
    - left of the square (``check_left``) the pixel is hidden from the right camera, so
      only the right-image column its match lands on can be tested: where that column
      shows the square itself, neither hypothesis explains the left pixel and the test
      has nothing to decide; elsewhere it is decidable by the same evidence rule (the
      right view's candidates are not visible here, so this half is checked only with a
      radius that reaches every fattened pixel).
    """
    x0, x1, y0, y1 = EDGE_BOX
    clean_l, clean_r, truth = _edge_scene(seed, noise_dn=0.0)
    e_min = _decisive_evidence_dn2(p, EDGE_NOISE_DN)
    hh, rad = p.window_h_px // 2, p.boundary_radius_px
    d = res.disparity_px
    fat = np.isfinite(d) & (np.abs(d - EDGE_FG_PX) < np.abs(d - EDGE_BG_PX)) & (truth
                                                                                 == EDGE_BG_PX)
    fat[:y0 + hh] = False
    fat[y1 - hh:] = False
    bad = []
    for y, x in zip(*np.nonzero(fat), strict=True):
        dx = float(d[y, x])
        if x >= x1:
            near = d[y, max(0, x - rad):x + rad + 1]
            has_farther = bool((np.isfinite(near) & (near < dx - p.boundary_step_px)).any())
            own = _column_residual(clean_l, clean_r, y, x, x - dx, hh)
            if has_farther and own >= e_min:
                bad.append((int(y), int(x), dx, own))
        elif check_left:
            xr = int(np.rint(x - dx))
            if x0 - EDGE_FG_PX <= xr < x1 - EDGE_FG_PX:
                continue  # lands on the square in the right image
            own = _column_residual(clean_r, clean_l, y, xr, xr + dx, hh)
            if own >= e_min:
                bad.append((int(y), int(x), dx, own))
    return bad


@pytest.mark.parametrize("seed", SEEDS)
def test_depth_edges_keep_the_foreground_inside_its_silhouette(seed):
    """A 9 x 9 window (after a 9 x 9 mean prefilter) matches the square's strong
    texture up to :func:`_texture_reach_px` = 8 px past its edges. The depth-edge test
    removes those pixels wherever one window-tall column carries the evidence
    (:func:`_undecidable_survivors`); the rest, measured over 40 seeds, sit in the
    first two columns past the silhouette, where the background's column barely
    changes over the 12 px step (its texture is 10 DN) or the match lands on the square
    in the right image."""
    p = MatcherParams(num_disparities=32)
    reach = _texture_reach_px(p)
    x0, x1, _, _ = EDGE_BOX
    left, right, _ = _edge_scene(seed)
    res = compute_disparity(left, right, p)
    off = compute_disparity(left, right, MatcherParams(num_disparities=32, **EDGES_OFF))
    # without the depth-edge and one-sided support tests the square fattens ...
    off_l, off_r, _, _ = _fattening(off, EDGE_FG_PX, EDGE_BG_PX, EDGE_BOX)
    assert off_l.mean() >= 0.5 and off_r.mean() >= 0.5
    for r in (res, off):
        # ... never beyond the texture's reach (filters only ever remove pixels)
        fat_l, fat_r, _, _ = _fattening(r, EDGE_FG_PX, EDGE_BG_PX, EDGE_BOX)
        d = r.disparity_px
        fg = np.isfinite(d) & (np.abs(d - EDGE_FG_PX) < np.abs(d - EDGE_BG_PX))
        assert not fg[:, :x0 - reach].any() and not fg[:, x1 + reach:].any()
    fat_l, fat_r, _, _ = _fattening(res, EDGE_FG_PX, EDGE_BG_PX, EDGE_BOX)
    assert fat_l.sum() < off_l.sum() and fat_r.sum() < off_r.sum()
    # with the defaults, every fattened pixel right of the square that its own column
    # decides is removed (the left side's right-view candidates are not observable)
    assert _undecidable_survivors(res, p, seed, check_left=False) == []
    # with a search radius that covers the reach, every decidable pixel on both sides
    wide = MatcherParams(num_disparities=32, boundary_radius_px=reach)
    assert _undecidable_survivors(compute_disparity(left, right, wide), wide, seed,
                                  check_left=True) == []


@pytest.mark.parametrize("seed", SEEDS)
def test_textured_square_on_a_plain_background_does_not_spill(seed):
    """On a plain background only the square's texture is in a window near it, so the
    matcher alone gives the first columns past each silhouette the square's disparity
    (about one column per row); the support tests must remove most of it, and nothing
    can be fattened beyond the texture's reach (:func:`_texture_reach_px`, 8 px).

    The depth-edge test has no background evidence here, so only the support tests act:
    a pixel whose one-sided block still holds the square's texture through the prefilter
    box (4 px) can pass them. "Most" is asserted as at least half, per side, of what the
    matcher keeps with the edge tests off (measured over 60 seeds: at most 0.26).
    """
    box = (140, 220, 60, 180)
    left, right, _ = occlusion_pair(8.0, 20.0, box, noise_dn=2.0, background_contrast_dn=0.0,
                                    seed=seed)
    p = MatcherParams(num_disparities=32)
    res = compute_disparity(left, right, p)
    fat_l, fat_r, first, last = _fattening(res, 20.0, 8.0, box)
    assert first >= 0.9 and last >= 0.9
    # without the edge tests the first column past each silhouette sees texture only
    # from the square (the background is plain), so it takes the square's disparity in
    # every row where the matcher's own tests keep it, as they keep >= 90 % of the
    # square's edge columns (``first``, ``last``): the bound below then has power
    off_l, off_r, _, _ = _fattening(compute_disparity(
        left, right, MatcherParams(num_disparities=32, **EDGES_OFF)), 20.0, 8.0, box)
    assert off_l.mean() >= 0.9 and off_r.mean() >= 0.9
    assert fat_l.mean() <= 0.5 * off_l.mean() and fat_r.mean() <= 0.5 * off_r.mean()
    # the plain background is not matched at all beyond the texture's reach
    reach = _texture_reach_px(p)
    x0, x1 = box[0], box[1]
    assert not res.valid[70:170, :x0 - reach].any() and not res.valid[70:170, x1 + reach:].any()


@pytest.mark.parametrize("seed", SEEDS)
def test_depth_edge_test_marks_its_pixels(seed):
    """The depth-edge test (Reason.BOUNDARY) acts on the square's fattened band and
    never removes a pixel of the square that carried the square's disparity.

    A pixel of the square is marked only (a) within half a column height (4 rows) of
    its top or bottom edge, where the window-tall column straddles the edge, or (b)
    where it carried a disparity more than half a ``boundary_step_px`` off the truth: a
    neighbour at the true disparity then lies more than a step nearer or farther. The
    fattened pixels it removes lie within the texture's reach
    (:func:`_texture_reach_px`, 8 px) of the square, or of the 12 px band left of it
    that the right camera cannot see. Elsewhere on the weak background a mark needs a
    subpixel disagreement of more than a step between neighbours; those are not
    asserted on.
    """
    p = MatcherParams(num_disparities=32)
    reach, hh = _texture_reach_px(p), p.window_h_px // 2
    reach_rows = hh + p.prefilter_size_px // 2
    x0, x1, y0, y1 = EDGE_BOX
    left, right, truth = _edge_scene(seed)
    res = compute_disparity(left, right, p)
    before = compute_disparity(left, right, MatcherParams(num_disparities=32,
                                                          boundary_ratio=0.0)).disparity_px
    marked = res.invalid_reason == Reason.BOUNDARY
    was_fat = (np.isfinite(before) & (truth == EDGE_BG_PX)
               & (np.abs(before - EDGE_FG_PX) < np.abs(before - EDGE_BG_PX)))
    removed = marked & was_fat
    # it acts: each removed fattened pixel is one the test marked (not another filter)
    assert removed.sum() >= 1
    assert (~(was_fat & ~np.isfinite(res.disparity_px))
            | np.isin(res.invalid_reason, (Reason.BOUNDARY, Reason.SPECKLE))).all()
    ys, xs = np.nonzero(removed)
    band = int(EDGE_FG_PX - EDGE_BG_PX)   # hidden from the right camera
    assert ((xs >= x0 - band - reach) & (xs < x1 + reach)).all()
    assert ((ys >= y0 - reach_rows) & (ys < y1 + reach_rows)).all()
    rows = np.arange(truth.shape[0])[:, None]
    straddles = (rows < y0 + hh) | (rows >= y1 - hh)
    off_truth = np.abs(before - truth) > 0.5 * p.boundary_step_px
    on_square = marked & (truth == EDGE_FG_PX)
    assert not (on_square & ~straddles & ~off_truth).any()
