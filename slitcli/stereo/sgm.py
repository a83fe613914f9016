"""Semi-global aggregation (Hirschmueller's SGM) over the paper's Eq. 10 cost.

The local matcher (``aggregation = "none"``) takes each pixel's best Eq. 10 window on
its own; on weak texture the best window is often not unique and the pixel is left
invalid. SGM (``aggregation = "sgm"``) adds to each pixel's cost curve the cheapest way
of reaching it along 8 (or 4) straight paths across the image, where the disparity may
change by 1 px from one pixel to the next for ``sgm_p1`` and by more for ``sgm_p2``
(both in units of the Eq. 10 cost, whose value for two uncorrelated windows of equal
energy is 2). A step of 1 px is cheap, so a slanted surface (a floor, a road: about
one pixel of disparity every seven rows for the paper rig) is followed row by row;
a larger jump costs ``sgm_p2`` and happens at depth edges only.

The Eq. 10 cost is that of the local matcher on the same prefiltered images (window
sums with zeros outside the image; SGM's own ``sgm_window_px`` window, 7 x 7: a
smaller window carries a foreground's disparity less far past its edge), quantised to
1/256; the winner then passes the same tests (window texture energy, uniqueness and
left-right consistency on the aggregated costs, the subpixel parabola) and the local
matcher's post-filter chain with one more step, the bracket test (:data:`SGM_FILTERS`,
slitcli.stereo._bracket): a pixel whose own neighbourhood does not carry the match is
kept where valid pixels on both sides of it agree with each other and with it, and so
is a small isolated region. Last, the subpixel offsets of the pixels valid on their
own are refitted to their own Eq. 10 costs (:func:`raw_subpixel`'s rule; the sums'
parabola is pulled to the whole pixel by the path penalties), computed in the winner
step while each row's costs are in cache, so the volumes are freed before the filters.

Cost: two fused passes (compiled kernels, slitcli/stereo/_c/sgm.pyx): the costs of each
row with the top-down sweep over them, then the bottom-up sweep with each row's winner
step; two volumes of H x W x D uint16 (20 MB at 320 x 240 x 64; with a second thread
three phases and a third volume, _match_fused). The separate stages
(:func:`cost_volume`, :func:`aggregate`, slitcli.stereo._sgm.winners_rows) give the
same disparities bit for bit.
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from slitcli.stereo.bands import frame_pool, kernel_threads, run_row_bands
from slitcli.stereo.filters import (
    DISPARITY_FILTERS,
    DisparityFilter,
    FilterInputs,
    run_disparity_filters,
)
from slitcli.stereo.reasons import Reason

if TYPE_CHECKING:
    from slitcli.stereo.matcher import DisparityResult, MatcherParams

COST_SCALE = 256.0   # quantisation of the Eq. 10 cost (units per 1.0 of cost)
COST_MAX = 2.0       # costs clip here: two uncorrelated windows of equal energy


class SgmWorkspace:
    """Memory for SGM's cost volumes, held by a caller across a sequence's frames.

    A frame's two or three H x W x D uint16 volumes (20-30 MB at 320 x 240 x 64) are
    taken from one buffer that stays allocated from one frame to the next: a new
    array per frame costs its page faults again wherever the allocator has returned
    the memory to the system (measured, interleaved with StereoSGBM: 320 x 240 / 64 d
    21.1 -> 19.1 ms a frame, 640 x 480 / 128 d 94 -> 78 ms). The buffer grows to the
    largest frame seen and is never shrunk; the kernels write every element they read,
    so what an earlier frame left there does not change a result (bit for bit).

    One frame at a time: a workspace is not shared by threads that match frames
    concurrently (each such thread holds its own). Pickled without its buffer (a
    process worker allocates its own).
    """

    __slots__ = ("_buffer",)

    def __init__(self) -> None:
        self._buffer: np.ndarray | None = None

    def volumes(self, shape: tuple[int, ...]) -> np.ndarray:
        """An uninitialised uint16 array of ``shape`` from the held buffer (a view:
        the next call reuses its memory)."""
        n = math.prod(shape)
        if self._buffer is None or self._buffer.size < n:
            self._buffer = None  # the old buffer is freed before the new one is taken
            self._buffer = np.empty(n, np.uint16)
        return self._buffer[:n].reshape(shape)

    def __getstate__(self) -> dict:
        return {}

    def __setstate__(self, _state: dict) -> None:
        self._buffer = None


def _cost_inputs(pl: np.ndarray, pr: np.ndarray, params: MatcherParams) -> dict:
    """What the cost kernels read: the prefiltered images, window energies and counts,
    the right image's rows reversed and padded (see slitcli.stereo._sgm.cost_rows)."""
    from slitcli.stereo import _sgm
    from slitcli.stereo.cost import ground_window_shifts, sheared_right_energies

    m, n = params.window_w_px // 2, params.window_h_px // 2
    num, dmin = int(params.num_disparities), int(params.min_disparity_px)
    pl = np.ascontiguousarray(pl, np.float32)
    pr = np.ascontiguousarray(pr, np.float32)
    h, w = pl.shape
    shifts = ground_window_shifts(params.sgm_ground_px_per_row or 0.0, n)
    pad = num + abs(dmin) + 1 + int(np.abs(shifts).max())
    el = np.empty((h, w), np.float32)
    count = np.empty((h, w), np.float32)
    # the right image's rows reversed, its energies and their inverse square roots
    # (0: no energy, or outside the image), padded with zeros on both sides
    prr, err, irr = np.zeros((3, h, w + 2 * pad), np.float32)
    _sgm.window_inputs(pl, pr, m, n, pad, el, count, prr, err, irr)
    shear = None
    if shifts.any():
        # the window sheared by the ground's disparity gradient from the horizon down
        # (slitcli.stereo.cost.ground_window_shifts), its cost the second hypothesis
        # for the disparities near the ground's
        horizon = params.sgm_ground_horizon_row_px or 0.0
        band = params.sgm_ground_band_px
        shear = (max(0, math.ceil(horizon)), shifts,
                 *sheared_right_energies(pr, m, n, shifts, pad),
                 float(params.sgm_ground_px_per_row), float(horizon),
                 float("inf") if band is None else float(band))
    return {"pl": pl, "prr": prr, "el": el, "err": err, "irr": irr, "pad": pad, "dmin": dmin,
            "num": num, "m": m, "n": n, "count": count, "shear": shear}


def cost_volume(pl: np.ndarray, pr: np.ndarray, params: MatcherParams,
                pool: ThreadPoolExecutor | None = None, threads: int = 1
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Quantised Eq. 10 costs (H, W, D) uint16 of prefiltered images, with the left
    window energies and pixel counts (H, W) float32 (for the texture test)."""
    from slitcli.stereo import _sgm

    c = _cost_inputs(pl, pr, params)
    h, w = pl.shape
    cost = np.empty((h, w, c["num"]), np.uint16)
    kernel = _sgm.cost_rows
    args = (c["pl"], c["prr"], c["el"], c["err"], c["irr"], c["pad"], c["dmin"], c["num"],
            c["m"], c["n"], COST_MAX, COST_SCALE)
    run_row_bands(lambda y0, y1: kernel(*args, y0, y1, cost, c["shear"]), h, pool, threads,
                  min_rows=2 * c["n"] + 1)
    return cost, c["el"], c["count"]


def aggregate(cost: np.ndarray, params: MatcherParams,
              pool: ThreadPoolExecutor | None = None,
              grey: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The top-down and bottom-up sweeps' path-cost sums, each (H, W, D) uint16.

    ``grey`` (H, W) uint8, the left image: with ``sgm_p2_edge_dn`` > 0 each step's P2
    is ``sgm_p2 g / (g + |grey step|)`` (at least P1 + 1), ``g = sgm_p2_edge_dn``."""
    from slitcli.stereo import _sgm

    p1 = round(params.sgm_p1 * COST_SCALE)
    p2 = round(params.sgm_p2 * COST_SCALE)
    eight = params.sgm_paths == 8
    g = float(params.sgm_p2_edge_dn) if grey is not None else 0.0
    if grey is None:
        grey = np.zeros(cost.shape[:2], np.uint8)
    s_a = np.empty_like(cost)
    s_b = np.empty_like(cost)
    kernel = _sgm.aggregate_pass
    if pool is not None:
        job = pool.submit(kernel, cost, p1, p2, eight, True, s_b, grey, g)
        kernel(cost, p1, p2, eight, False, s_a, grey, g)
        job.result()
    else:
        kernel(cost, p1, p2, eight, False, s_a, grey, g)
        kernel(cost, p1, p2, eight, True, s_b, grey, g)
    return s_a, s_b


def _bracket_pass(x: FilterInputs, reason: np.ndarray,
                  weak_codes: tuple[int, ...]) -> np.ndarray:
    """(H, W) bool: pixels of a code in ``weak_codes`` bracketed by ``reason == VALID``
    pixels (slitcli.stereo._bracket, reach/tol/span from ``sgm_bracket_*``)."""
    from slitcli.stereo import _bracket

    p = x.params
    keep = np.zeros(x.disparity_px.shape, np.bool_)
    weak = np.zeros(256, np.bool_)
    weak[list(weak_codes)] = True
    _bracket.bracket_rows(x.disparity_px, reason, int(Reason.VALID), weak,
                          int(p.sgm_bracket_px), np.float32(p.sgm_bracket_tol_px),
                          np.float32(p.sgm_bracket_span_px), keep)
    return keep


def _small_regions(x: FilterInputs) -> np.ndarray:
    """(H, W) bool: valid pixels that the speckle filter would remove now (regions of
    at most ``speckle_window_px`` pixels within ``speckle_range_px``; the speckle
    filter's own regions, marked without copying or changing the maps)."""
    from slitcli.stereo import _kernel

    p = x.params
    small = np.empty(x.disparity_px.shape, np.bool_)
    _kernel.speckle_small(x.disparity_px, x.invalid_reason, int(p.speckle_window_px),
                          max(1, math.ceil(p.speckle_range_px * 16.0)), small.view(np.uint8))
    return small


def _bracket(x: FilterInputs) -> None:
    """The bracket test, then the same test for small isolated regions.

    Pass 1: support and uniqueness rejections bracketed by valid pixels are valid
    again. Their fills connect neighbouring small regions (on a weakly textured floor
    the valid pixels are islands of a few pixels, and correct), so the speckle filter
    after this step keeps what it would have removed: also an isolated wrong match in
    a plain region, whose fill neighbours lie within ``speckle_range_px`` of it.
    Pass 2: a region the speckle filter would have removed before pass 1 is evidence
    of one small patch only; its pixels stay valid where the other valid pixels
    (fills included) bracket them, as for pass 1's candidates."""
    p = x.params
    small = small_job = None
    if p.speckle_window_px > 0:
        # on the frame's helper thread, while this one runs pass 1 (both only read
        # the codes; they change once both are done)
        if x.pool is not None:
            small_job = x.pool.submit(_small_regions, x)
        else:
            small = _small_regions(x)
    keep = _bracket_pass(x, x.invalid_reason, (int(Reason.SUPPORT), int(Reason.UNIQUENESS)))
    if small_job is not None:
        small = small_job.result()
    x.invalid_reason[keep] = Reason.VALID
    if small is None or not small.any():
        return
    # pass 2 tests the small regions' pixels only, searching from each (the scans of
    # pass 1 over the whole image find the same bracketing pixels)
    from slitcli.stereo._c.bracket import bracket_marked

    bracket_marked(x.disparity_px, x.invalid_reason, int(Reason.VALID), small.view(np.uint8),
                   int(p.sgm_bracket_px), np.float32(p.sgm_bracket_tol_px),
                   np.float32(p.sgm_bracket_span_px), int(Reason.SPECKLE))


#: The filters after the SGM winner step: the local matcher's chain with the bracket
#: test (``sgm_bracket_px``, slitcli.stereo._bracket) between the support test and the
#: speckle filter. Its candidates: pixels rejected by the support test (their own
#: neighbourhood does not carry the match) or by uniqueness (on a plain surface the
#: aggregated cost curve is flat around the winner); not left-right failures, which
#: are mostly occlusions the right camera cannot see.
SGM_FILTERS: tuple[DisparityFilter, ...] = (
    *DISPARITY_FILTERS[:-1],
    DisparityFilter("sgm_bracket", (Reason.SPECKLE,),
                    "pixels rejected by the support or the uniqueness test whose disparity "
                    "lies between those of valid pixels on both sides (row or column, "
                    "within sgm_bracket_px) that agree within sgm_bracket_span_px are "
                    "valid again; then regions the speckle filter would have removed "
                    "before (speckle_window_px) stay valid only where so bracketed",
                    lambda p: p.sgm_bracket_px > 0, _bracket),
    DISPARITY_FILTERS[-1],
)


def _match_fused(pl: np.ndarray, pr: np.ndarray, params: MatcherParams, grey: np.ndarray,
                 tests: tuple, outputs: tuple, pool: ThreadPoolExecutor | None = None,
                 threads: int = 1, refit: tuple = (None, 0.0),
                 workspace: SgmWorkspace | None = None) -> np.ndarray:
    """Cost, SGM and the winner step in two fused passes over the rows
    (slitcli/stereo/_c/sgm.pyx): the costs of each row and the top-down sweep over
    them while they are in cache; then the bottom-up sweep with each row's winner step,
    its sums kept for one row only. Two H x W x D volumes instead of three, each read
    once more instead of three times: in a frame the volumes do not stay in cache,
    and memory, not arithmetic, set the separate stages' times (measured: the
    stages took 1.5-2.3 times as long in the frame as each alone on hot data).

    With a second thread, three phases split at 2/5 of the height: (1) this thread the
    top part's costs and sweep, the other the bottom part's costs; (2) this thread the
    top-down sweep over the bottom part, the other the bottom-up sweep over it (sums
    into a third volume); (3) this thread the bottom part's winners, the other the
    bottom-up sweep and winners of the top part. The same results bit for bit.

    ``refit``: an (H, W) float32 array and ``den_min``: each row's winners refitted to
    its own costs (:func:`raw_subpixel`'s rule) in the winner step, while the row is
    in cache (the refit at the end of the frame took 1.2 ms of a 320 x 240 / 64 d
    frame, reading the 20 MB volume back); (None, 0.0): no refit.

    ``workspace``: the volumes' memory held by the caller (:class:`SgmWorkspace`);
    None: a new array for this frame. Returns the cost volume (a view of the
    workspace's buffer when there is one)."""
    from slitcli.stereo._c import sgm as _k

    c = _cost_inputs(pl, pr, params)
    h, w = pl.shape
    num = c["num"]
    one_thread = pool is None or threads < 2 or h < 4 * (2 * c["n"] + 1)
    # the volumes in one allocation: glibc (malloc's dynamic mmap threshold) then keeps
    # its pages mapped from one frame to the next (two or three separate volumes freed
    # together are returned to the system and faulted in again: measured 700-1200
    # page faults, ~5 ms of a 320 x 240 frame)
    shape = (2 if one_thread else 3, h, w, num)
    volumes = np.empty(shape, np.uint16) if workspace is None else workspace.volumes(shape)
    cost = volumes[0]
    s_a = volumes[1]
    p1 = round(params.sgm_p1 * COST_SCALE)
    p2 = round(params.sgm_p2 * COST_SCALE)
    eight = params.sgm_paths == 8
    g = float(params.sgm_p2_edge_dn)
    cargs = (c["pl"], c["prr"], c["el"], c["err"], c["irr"], c["pad"], c["dmin"], num, c["m"],
             c["n"], COST_MAX, COST_SCALE)
    shear = c["shear"]
    bargs = (p1, p2, eight, grey, g, c["el"], c["count"], *tests, *outputs)
    if one_thread:
        _k.cost_and_first_sweep(*cargs, p1, p2, eight, grey, g, cost, s_a, shear)
        _k.second_sweep_winners(cost, s_a, *bargs, *refit)
        return cost
    # the split row balances the phases: this thread's top rows carry costs and the
    # sweep, the other's bottom rows costs only; in phase 3 the other thread sweeps and
    # picks the top rows' winners. Per-thread CPU time, summed over the phases' larger
    # share (320 x 240 / 64 d): 5.7 ms split at the middle, 4.8 ms at 2/5
    half = 2 * h // 5
    col = _k.cost_columns(w, num, shear)
    hs = np.zeros(num, np.float32)
    state_a = _k.sweep_state(w, num)
    state_b = _k.sweep_state(w, num)
    s_b = volumes[2]
    job = pool.submit(_k.cost_rows, *cargs, half, h, cost, shear)
    _k.cost_start(c["pl"], c["prr"], c["pad"], c["dmin"], num, c["n"], 0, col, shear)
    _k.first_sweep_rows(*cargs, p1, p2, eight, grey, g, cost, s_a, 0, half, True, col,
                                hs, *state_a, shear)
    job.result()
    job = pool.submit(_k.second_sweep_rows, cost, s_a, *bargs, 0, h - half, False, s_b,
                      *state_b)
    _k.first_sweep_rows(*cargs, p1, p2, eight, grey, g, cost, s_a, half, h, False, col,
                                hs, *state_a, shear)
    job.result()
    job = pool.submit(_k.second_sweep_rows, cost, s_a, *bargs, h - half, h, True, s_b,
                      *state_b, *refit)
    _k.winners_rows(s_a, s_b, cost, c["el"], c["count"], *tests, half, h,
                                  *outputs, *refit)
    job.result()
    return cost


def raw_subpixel(disp: np.ndarray, cost: np.ndarray, dmin: int, den_min: float,
                 where: np.ndarray | None = None) -> None:
    """Subpixel offsets from the Eq. 10 costs where the winner is their local minimum.

    The winner step fits its parabola to the aggregated sums; with path penalties
    comparable to the cost's own curvature (``sgm_p1`` is added to the sums of d -+ 1
    wherever a path arrives at d) that parabola is too sharp and pulls the estimate
    towards the whole pixel. Where the winner ``bi`` is a local minimum of the pixel's
    own (quantised) Eq. 10 costs, the parabola through ``C(bi - 1), C(bi), C(bi + 1)``
    (the local matcher's, paper Eq. 10 locally quadratic in the shift) replaces it;
    elsewhere (weak texture: the aggregation, not the pixel's own window, chose the
    disparity) the sums' offset stays.

    Parameters
    ----------
    disp : ndarray, float32, shape (H, W), C order
        Winners with the sums' offsets (px, NaN: none); updated in place (compiled:
        slitcli/stereo/_c/subpixel.pyx).
    cost : ndarray, uint16, shape (H, W, D)
        Quantised Eq. 10 costs of disparities ``dmin .. dmin + D - 1``.
    dmin : int
        Smallest disparity searched, px.
    den_min : float
        Least curvature ``C(bi - 1) - 2 C(bi) + C(bi + 1)`` (quantised cost units) for
        the costs' parabola; ``sgm_p1`` (quantised) in match_sgm: where the pixel's own
        curvature is below the penalty a 1 px step costs, its costs do not locate the
        minimum better than the paths do.
    where : ndarray, bool, shape (H, W), optional
        Only these pixels are refitted (the others keep their offsets), in one pass
        without copies of the map.
    """
    from slitcli.stereo._c.subpixel import cost_subpixel

    cost_subpixel(disp, cost, int(dmin), float(den_min), float(round(COST_MAX * COST_SCALE)),
                  None if where is None else where.view(np.uint8))


def match_sgm(left_grey: np.ndarray, right_grey: np.ndarray,
              params: MatcherParams, pool: ThreadPoolExecutor | None = None, *,
              workspace: SgmWorkspace | None = None) -> DisparityResult:
    """Eq. 10 cost, SGM aggregation, winner-take-all, validity tests, post-filters.

    Parameters
    ----------
    left_grey, right_grey : ndarray, uint8, shape (H, W)
        Rectified grey images (right camera at +baseline along x).
    params : MatcherParams
        ``aggregation = "sgm"``; ``sgm_window_px``, ``sgm_p1``, ``sgm_p2``,
        ``sgm_paths``, ``sgm_subpixel``, ``sgm_bracket_*``; without a ground
        (``sgm_ground_px_per_row`` None) and ``sgm_ground`` 'auto', 'pair' or 'check':
        the pair's (slitcli.stereo.ground.with_pair_ground).
    pool : ThreadPoolExecutor, optional
        Helper threads held by the caller for a sequence
        (slitcli.stereo.matcher.compute_disparity).
    workspace : SgmWorkspace, optional
        The cost volumes' memory, held by the caller for a sequence.

    Returns
    -------
    DisparityResult
        ``match_cost``: the Eq. 10 cost of the winning disparity (to 1/256).
    """
    from slitcli.stereo.cost import _QUANT, DisparityResult, prefilter_image
    from slitcli.stereo.ground import with_pair_ground

    h, w = left_grey.shape
    disp = np.empty((h, w), np.float32)
    mcost = np.empty((h, w), np.float32)
    reason = np.empty((h, w), np.uint8)
    rdisp = np.empty((h, w), np.float32)
    threads = kernel_threads()
    with frame_pool(pool, threads) as pool:
        # no ground given (no rig, or sgm_ground 'pair'/'check'): the pair's, its first
        # pass on this frame's threads
        params = with_pair_ground(params, left_grey, right_grey, pool)
        if params.sgm_window_px > 0:
            # SGM's own window for the cost and for the filters that read the window size
            params = replace(params, window_w_px=params.sgm_window_px,
                             window_h_px=params.sgm_window_px)
        # SGM's own window texture test (default none): the paths carry a disparity
        # into windows without texture of their own, and uniqueness and left-right on
        # the aggregated costs judge it there
        params = replace(params, texture_min_dn=params.sgm_texture_min_dn)
        right_job = pool.submit(prefilter_image, right_grey, params) if pool else None
        pl = prefilter_image(left_grey, params)
        pr = right_job.result() if right_job else prefilter_image(right_grey, params)
        energy_min = ((params.texture_min_dn * _QUANT) ** 2 if params.prefilter != "none"
                      else 0.0)
        top = np.uint16(round(COST_MAX * COST_SCALE))
        tests = (int(params.min_disparity_px), np.float32(params.uniqueness_ratio),
                 float(params.lr_max_diff_px), params.subpixel == "parabola",
                 np.float32(energy_min), top, np.float32(COST_SCALE))
        grey = np.ascontiguousarray(left_grey)
        # the winners refitted to their own Eq. 10 costs, in the winner step (below)
        refit = params.subpixel == "parabola" and params.sgm_subpixel == "cost"
        refit_disp = np.empty((h, w), np.float32) if refit else None
        _match_fused(pl, pr, params, grey, tests, (disp, mcost, reason, rdisp), pool, threads,
                     (refit_disp, params.sgm_p1 * COST_SCALE), workspace)
        inputs = FilterInputs(left_grey, right_grey, pl, params, disp, reason, rdisp, pool,
                              threads)
        split = [f.name for f in SGM_FILTERS].index("sgm_bracket")
        run_disparity_filters(inputs, SGM_FILTERS[:split])
        # pixels whose own neighbourhood carries the match (before the bracket's fills)
        own = reason == Reason.VALID
        run_disparity_filters(inputs, SGM_FILTERS[split:])
        if refit:
            # the refit offsets replace the sums' after the filters: they compare a
            # pixel's disparity with its neighbours' (support warp, bracket, speckle),
            # where the sums' offsets, smoothed along the paths, serve better than each
            # pixel's own (measured: weakly textured road bad2-all 0.220 against 0.230
            # with the costs' offsets in the filters); and only where the pixel's own
            # costs carry the match: not on the bracket's fills, whose costs are flat
            # (rendered wrong plain pixels 4125 -> 4000). The filters change codes, and
            # disparities only to NaN, so a valid pixel's refit from the winner step is
            # its refit after them.
            np.copyto(disp, refit_disp, where=own & (reason == Reason.VALID))
    return DisparityResult(disp, reason, mcost)


__all__ = ["COST_MAX", "COST_SCALE", "SgmWorkspace", "aggregate", "cost_volume", "match_sgm"]
