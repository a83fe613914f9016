"""Step 4 of the stripe model: which candidates can be the laser.

:func:`valid_candidates` applies the tests that follow from the model (width, shape,
significance, colour, the sheet's thickness); :func:`laser_share` and
:func:`surface_continues` tell the laser's light from the surface's own colour;
:func:`own_light_candidates` asks a fit on the evidence averaged along the stripe to show in its
own column's evidence; :func:`one_crossing` keeps one of two overlapping fits of a
column. The choice along the stripe among the candidates that pass is
:mod:`slitcli.laser.choose`. The tests run compiled (:mod:`slitcli.laser._c.judge`);
this module keeps their constants and the glue.
"""
from __future__ import annotations

import numpy as np

from slitcli.laser._c.judge import colour_tests, one_crossing_table, shape_tests, surface_table
from slitcli.laser._c.judge import laser_share as laser_share  # (re-exported)
from slitcli.laser._c.light import own_light_table

#: a Gaussian's equivalent width (sum over peak) in sigmas, rounded
EQ_WIDTH = 2.5
#: a pixel integrates the profile over its extent: variance 1/12 px^2
PIXEL_VAR = 1.0 / 12.0
#: candidates this many times min_z significant (unclipped) estimate the laser colour;
#: at least COLOUR_SUPPORT of them are needed
COLOUR_Z = 2.0
COLOUR_SUPPORT = 8
#: the laser is red: its green and blue response at most this share of its red
MAX_LASER_GB = 0.6
#: colour residual allowed for noise alone, in noise sigmas of the core's mean
COLOUR_SIGMAS = 3.0


def valid_candidates(cand: np.ndarray, *, height_px: int, s_max: float, min_z: float,
                     max_chi2: float, min_th: float, min_delta_th: float,
                     colour_error: float, channel_sigma_dn: float,
                     sheet_px: np.ndarray | None, sheet_tolerance: float,
                     sheet_support: int = 0, blur_var_px2: float = 0.0,
                     max_hue_deg: float = 90.0, width_spread: float = np.inf,
                     laser_share_z: float = 0.0
                     ) -> tuple[np.ndarray, np.ndarray | None]:
    """Which candidates (W, K) can be the laser, and the laser colour used.

    Valid: a fitted sigma in ``[MIN_SIGMA_PX, s_max]``; an
    unclipped one a Gaussian within the model error (reduced chi-square ``max_chi2``);
    the light an unclipped core adds passes Eq. 2 (red chromaticity ``min_th``,
    ``min_delta_th``; a clipped core's unclipped rows are the clip's whitened
    shoulders, and its red flanks stood for the laser's colour when it was seeded),
    an unclipped core's light is at most ``max_hue_deg`` from red towards yellow (at
    ``COLOUR_SIGMAS`` noise sigmas; 90: no test) and, where the frame shows the laser's
    colour (the median of its strong unclipped candidates' core contrast over its red,
    from at least ``COLOUR_SUPPORT`` of them), shows the laser's share
    (:func:`laser_share`, at ``laser_share_z``; 0: no test) and, with ``colour_error``
    < 1, lies in the plane of that colour and the surface's within ``COLOUR_SIGMAS``
    noise sigmas plus ``colour_error`` of its size; with ``sheet_px`` (W, K: the
    sheet's sigma at the candidate's row, px, NaN unknown) a width that implies a sheet
    at most ``sheet_tolerance`` times thicker or thinner (unclipped ones) than the frame's
    strong columns do (when at least ``sheet_support`` of them show it, else the
    parameter), the pixel's extent and ``blur_var_px2`` (px^2: what the image's
    processing adds, :mod:`slitcli.laser.luma`) added to its variance; and at most
    ``width_spread`` times the median width of the frame's strong unclipped columns
    (inf: no such test). The levels are :class:`~slitcli.laser.params.LaserParams`'
    fields of the same names; the defaults here leave the last two tests out.

    Returns
    -------
    ok : ndarray, shape (W, K) bool
    laser_rgb : ndarray, shape (3,), or None
        The laser's colour (red 1), None where too few strong columns show it.
    """
    cand = np.ascontiguousarray(cand, dtype=np.float64)
    ok, laser = shape_tests(cand, sheet_px, height_px, s_max, min_z, max_chi2, min_th,
                            min_delta_th, sheet_tolerance, sheet_support, width_spread,
                            blur_var_px2, max_hue_deg, channel_sigma_dn)
    if laser is None:
        return ok, None
    # (the unit vector of the laser colour as numpy's norm gives it: the tests below
    # compare against it to the last bit, as they always did)
    lu = laser / np.linalg.norm(laser)
    colour_tests(cand, laser, lu, channel_sigma_dn, colour_error, laser_share_z, ok)
    return ok, laser


def one_crossing(cand: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """One crossing of the sheet per column and surface: of two valid candidates of one
    column whose Gaussians overlap (centres closer than the sum of their widths), the
    brighter and narrower is the stripe's core and the other is out.

    A fit that is wider and fainter than a second one inside it describes the same
    light plus more (the core and its halo, or two pieces of the stripe a row step
    apart in one column at an occlusion edge): its centre lies between them, where the
    light is not. Its significance, which grows with the light summed, would win the
    choice along the stripe. Returns ``ok`` (W, K) with those candidates False (a new
    array).
    """
    # (compiled: numpy's (W, K, K) comparisons cost ~0.2 ms a frame)
    return one_crossing_table(np.ascontiguousarray(cand, dtype=np.float64),
                              np.ascontiguousarray(ok, dtype=np.bool_).view(np.uint8))


def surface_continues(cand: np.ndarray, img_t: np.ndarray, row0: int,
                      channel_sigma_dn: float, need: np.ndarray | None = None, *,
                      step: float, min_dn: float) -> np.ndarray:
    """Whether the surface beneath each candidate (W, K) is one surface: the laser adds
    light to the surface it falls on, so the surface's colour (chromaticity) just above
    the stripe and just below it is the same; an edge between two surfaces of different
    colour (a red object's border on a grey floor) is not the laser, whatever light it
    seems to add.

    The colour is taken on the image ``img_t`` (W, H', 3, BGR, rows from ``row0``) in
    two rows each side, ``2.5 sigma + 2`` rows from the candidate's centre (beyond its
    light); the two sides differ when their chromaticities differ by more than ``step``
    plus four noise sigmas (``channel_sigma_dn``) in any channel. Sides too dark to show
    a colour (below ``min_dn`` per channel on average) are not judged
    (``LaserParams.surface_step``, ``surface_min_dn``). An edge along the stripe runs
    on, so the break must show in both neighbouring columns too (at the same rows):
    where an object's side crosses the stripe, its end column sees two surfaces alone. A
    clipped core is not judged: its light (the bloom and halo beyond the clip) reaches
    past its fitted width, unevenly above and below. Returns (W, K) bool, True where the
    surface continues or where it cannot be told, and where ``need`` (W, K), when given,
    is False (candidates that are out already are not judged).
    """
    need = np.ones(cand.shape[:2], np.bool_) if need is None else \
        np.ascontiguousarray(need, dtype=np.bool_)
    return surface_table(np.ascontiguousarray(cand, dtype=np.float64),
                         np.ascontiguousarray(img_t, dtype=np.uint8), row0, channel_sigma_dn,
                         need, float(step), float(min_dn))


# The own-light test (compiled: slitcli/laser/_c/light.pxd's own_light, inlined where gaps
# are filled and in light.pyx's table). The evidence averaged along the stripe (weights
# 1, 4, 6, 4, 1 over five columns) stands for a column only where the stripe runs on
# across them: one column past a stripe's end the average still holds 5/16 of the
# neighbours' light, though the column has none. So the peak of a Gaussian at a crossing
# (its row and width) in the averaged evidence must show in the column's own evidence:
# the own peak (weighted least squares of a Gaussian on a straight background, row
# variance sigma^2 + (shape_error A g)^2 as the profile fit's) may fall short of it by at
# most ``own_z`` standard errors (LaserParams.own_z). Inside a stripe the two agree
# within the noise; at a partly covered end column, whose own light is its coverage's
# share, the average's missing outward columns lower it by about as much. On a steep
# stripe the average's centre at an end column leans towards the inner columns' rows
# (by up to a pixel): the own light is looked for within OWN_REACH_PX of it, the best
# place kept.

#: rows either side of the averaged fit's centre where the column's own light is sought
OWN_REACH_PX = 1.0


def own_light_candidates(cand: np.ndarray, y: np.ndarray, y_avg: np.ndarray,
                         clipped: np.ndarray, mask: np.ndarray, row0: int, sigma_y: float,
                         shape_error: float, need: np.ndarray | None = None, *,
                         own_z: float) -> np.ndarray:
    """The own-light test (notes above, at ``own_z`` standard errors: one-sided, a
    column inside a stripe falls short by more than 3 of them 0.13 % of the time) of
    every candidate (W, K) fitted on the averaged evidence: True where it holds, and for
    every other candidate (a fit of the column's own evidence, whose noise ``sigma_y``
    its ``F_GNOISE`` holds, measured the column's own light; a clipped core is its own)
    and where ``need`` (W, K), when given, is False. Rows of ``cand`` count from the
    image's top, those of ``y`` from ``row0``."""
    ok = np.empty(cand.shape[:2], np.bool_)
    need = np.ones(cand.shape[:2], np.bool_) if need is None else need
    own_light_table(cand, y, y_avg, clipped, mask, row0, sigma_y, shape_error, own_z, need, ok)
    return ok
