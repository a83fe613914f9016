"""The blur-edge mask filter (slitcli.stereo.obstacles.blur_edge_reach_px, trim_blur_edges).

A textured box and cylinder at 1.4-2 m before a wall at 3.6 m (beyond the stereo range,
so never an obstacle itself), rendered through the camera presets with 5 texture and
noise seeds each; every count is taken against the renderer's truth (object ids and
true disparity), and the bounds follow from what the filter may remove (one column at
each end of a run), not from one render's numbers.
"""

from __future__ import annotations

import numpy as np
import pytest

from slitcli.rig import paper_rig
from slitcli.sim.render import render_frame
from slitcli.sim.scene import scene_from_dict
from slitcli.stereo.obstacles import (
    ObstacleParams,
    blur_edge_reach_px,
    neighbour_light_share,
    trim_blur_edges,
)
from slitcli.stereo.pipeline import StereoParams, process_stereo_pair

SEEDS = [1, 2, 3, 4, 5]


def _surface(rgb: list[float], scale_m: float = 0.02, contrast: float = 0.6) -> dict:
    return {"colour_rgb": rgb, "texture": "noise", "scale_m": scale_m, "contrast": contrast}


def _frame(seed: int, camera: str | None):
    d = {"slitcli_scene": 1, "seed": seed,
         "floor": _surface([0.55, 0.5, 0.45], 0.03, 0.5),
         "objects": [
             {"type": "box", "centre_xy_m": [1.4, 0.15], "size_m": [0.3, 0.4, 0.6],
              "surface": _surface([0.45, 0.6, 0.4])},
             {"type": "cylinder", "centre_xy_m": [2.0, -0.5], "radius_m": 0.12,
              "height_m": 0.9, "surface": _surface([0.6, 0.5, 0.45])},
             {"type": "wall", "from_xy_m": [3.6, -4], "to_xy_m": [3.6, 4], "height_m": 2.0,
              "surface": _surface([0.6, 0.6, 0.62], 0.05, 0.3)}],
         "robot": {"frames": 1}}
    if camera:
        d["image"] = {"camera": camera}
    scene = scene_from_dict(d, "blur-edge scene")
    rig = paper_rig()
    return rig, render_frame(scene, rig, scene.poses(1)[0])


def _counts(rig, frame, min_snr: float) -> tuple[int, int, int]:
    """(obstacle pixels off the objects, obstacle pixels > 1 px nearer than the truth,
    obstacle pixels on the objects)."""
    params = StereoParams(obstacles=ObstacleParams(blur_edge_min_snr=min_snr))
    res = process_stereo_pair(frame.left_bgr, frame.right_bgr, rig, params)
    objects = np.isin(frame.truth.object_id, [1, 2])
    mask = res.obstacle_mask
    fattened = mask & (res.disparity_px - frame.truth.disparity_px > 1.0)
    return int((mask & ~objects).sum()), int(fattened.sum()), int((mask & objects).sum())


@pytest.mark.parametrize("w", [0.0, 0.05, 0.12, 0.2, 0.28])
def test_neighbour_light_share_inverts_the_kernels_correlation(w):
    # white noise through (w, 1 - 2w, w): its lag-1 correlation, measured, gives w back
    # within the sampling error of a correlation over 2e5 samples (~0.002 -> ~0.005 in w)
    for seed in SEEDS:
        noise = np.random.default_rng(seed).normal(size=200_002)
        blurred = np.convolve(noise, [w, 1 - 2 * w, w], mode="valid")
        rho = np.corrcoef(blurred[:-1], blurred[1:])[0, 1]
        assert neighbour_light_share(rho) == pytest.approx(w, abs=0.01)


def test_trim_blur_edges_removes_one_column_beside_unmatched_pixels():
    mask = np.zeros((4, 12), bool)
    mask[:, 2:9] = True
    disp = np.full((4, 12), 10.0, np.float32)
    disp[0, 1] = np.nan          # row 0: unmatched on the left only
    disp[1, 9] = np.nan          # row 1: unmatched on the right only
    # row 2: matched on both sides (a depth edge or the floor): kept whole
    disp[3, :2] = np.nan         # row 3: unmatched to the border on both sides: kept
    disp[3, 9:] = np.nan
    out = trim_blur_edges(mask, disp, 1)
    assert out[0].tolist() == [False] * 3 + [True] * 6 + [False] * 3
    assert out[1].tolist() == [False] * 2 + [True] * 6 + [False] * 4
    assert (out[2:] == mask[2:]).all()
    assert (trim_blur_edges(mask, disp, 0) == mask).all()
    assert mask[:, 2:9].all()    # input untouched


@pytest.mark.parametrize("seed", SEEDS)
def test_webcam_spill_past_silhouettes_is_trimmed(seed):
    # Through the webcam preset the blur carries the objects' texture past their
    # silhouettes onto the wall (far beyond the stereo range): obstacle pixels off the
    # objects, fattened against the true disparity. The filter is on (reach 1) and
    # removes most of them; it takes at most one column at each end of a run, so
    # objects 20 or more columns wide keep at least 90 % of their pixels.
    rig, frame = _frame(seed, "webcam")
    assert blur_edge_reach_px(*_pair_disparity(rig, frame), ObstacleParams()) == 1
    off_spill, off_fat, off_obj = _counts(rig, frame, np.inf)
    spill, fat, obj = _counts(rig, frame, ObstacleParams().blur_edge_min_snr)
    assert off_spill >= 100 and off_fat >= 100     # the fattening exists
    assert spill <= 0.5 * off_spill
    assert fat <= 0.6 * off_fat
    assert obj >= 0.9 * off_obj


@pytest.mark.parametrize("camera", [None, "robot"])
@pytest.mark.parametrize("seed", SEEDS)
def test_no_blur_tail_leaves_the_mask_alone(seed, camera):
    # plain renders (no demosaicing: uncorrelated noise) and the robot preset (its
    # noise hides a one-column tail) give reach 0: the mask is the filter-off mask
    rig, frame = _frame(seed, camera)
    assert blur_edge_reach_px(*_pair_disparity(rig, frame), ObstacleParams()) == 0
    assert _counts(rig, frame, ObstacleParams().blur_edge_min_snr) == _counts(rig, frame,
                                                                              np.inf)


def _pair_disparity(rig, frame):
    """The grey pair and the pipeline's disparities (what the mask filter reads)."""
    from slitcli.stereo.matcher import to_grey

    res = process_stereo_pair(frame.left_bgr, frame.right_bgr, rig)
    return to_grey(frame.left_bgr), to_grey(frame.right_bgr), res.disparity_px
