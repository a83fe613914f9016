"""Stereo on rendered scenes (slitcli.sim): disparity, textureless surfaces, ranges.

Scene-level checks, apart from the matcher's unit tests (test_stereo_matcher.py): each
scene is rendered with 5 texture seeds (the scene's ``seed``), and the bounds are the
issue's limits, not one render's numbers.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from slitcli.rig import paper_rig
from slitcli.sim.render import render_frame
from slitcli.sim.scene import scene_from_dict
from slitcli.stereo.pipeline import process_stereo_pair


def _surface(texture: str, rgb: list[float], scale_m: float = 0.04,
             contrast: float = 0.5) -> dict:
    if texture == "plain":
        return {"colour_rgb": rgb, "texture": "plain"}
    return {"colour_rgb": rgb, "texture": "noise", "scale_m": scale_m, "contrast": contrast}


# A corridor with textured walls and floor, a textured box 1.5 m ahead (left of centre),
# a textured cylinder, and two large textureless boxes (0.8 m ahead on the right, 3.2 m
# ahead on the left); 2 DN sensor noise (the renderer's default).
SCENE = {
    "slitcli_scene": 1, "name": "stereo-test", "seed": 11,
    "floor": _surface("noise", [0.55, 0.5, 0.45], 0.03),
    "objects": [
        {"type": "wall", "from_xy_m": [0.0, 1.1], "to_xy_m": [6.0, 1.1], "height_m": 1.5,
         "surface": _surface("noise", [0.7, 0.66, 0.6])},
        {"type": "wall", "from_xy_m": [0.0, -1.1], "to_xy_m": [6.0, -1.1], "height_m": 1.5,
         "surface": _surface("noise", [0.66, 0.68, 0.7])},
        {"type": "wall", "from_xy_m": [6.0, -1.1], "to_xy_m": [6.0, 1.1], "height_m": 1.5,
         "surface": _surface("noise", [0.7, 0.7, 0.7])},
        {"type": "box", "centre_xy_m": [0.95, -0.35], "size_m": [0.3, 0.3, 0.5],
         "surface": _surface("plain", [0.75, 0.75, 0.72])},
        {"type": "box", "centre_xy_m": [1.6, 0.4], "size_m": [0.3, 0.4, 0.6], "yaw_deg": 15,
         "surface": _surface("noise", [0.55, 0.6, 0.5], 0.02, 0.7)},
        {"type": "cylinder", "centre_xy_m": [2.4, -0.3], "radius_m": 0.15, "height_m": 0.8,
         "surface": _surface("noise", [0.6, 0.5, 0.45], 0.02, 0.7)},
        {"type": "box", "centre_xy_m": [3.2, 0.45], "size_m": [0.3, 0.5, 0.7],
         "surface": _surface("plain", [0.5, 0.5, 0.55])},
    ],
    "robot": {"start": [0.0, 0.0, 0.0], "motion": "static", "frames": 1},
}


TEXTURE_SEEDS = [11, 12, 13, 14, 15]


@pytest.fixture(scope="module", params=TEXTURE_SEEDS)
def corridor(request):
    """Frame 0 of :data:`SCENE` (texture seed from the parameter) and the stereo
    pipeline's result on it."""
    scene = scene_from_dict({**SCENE, "seed": request.param}, "stereo-test scene")
    rig = paper_rig()
    frame = render_frame(scene, rig, scene.poses(1)[0], frame_index=0)
    return rig, frame, process_stereo_pair(frame.left_bgr, frame.right_bgr, rig)


def test_textured_surfaces_within_3m(corridor):
    _, frame, res = corridor
    t = frame.truth
    near = t.textured & (t.depth_m <= 3.0) & np.isfinite(t.disparity_px)
    valid = near & np.isfinite(res.disparity_px)
    assert valid.sum() / near.sum() >= 0.85
    err = np.abs(res.disparity_px[valid] - t.disparity_px[valid])
    assert np.median(err) <= 0.15          # <= 2 % depth error at 3 m
    assert (err > 1.0).mean() <= 0.03


def test_textureless_surfaces_are_invalid_not_guessed(corridor):
    _, frame, res = corridor
    t = frame.truth
    # every pixel whose truth sees a plain surface (the two plain boxes: silhouettes and
    # the crease between two differently shaded faces included, no erosion)
    plain = ~t.textured & np.isfinite(t.disparity_px)
    valid = np.isfinite(res.disparity_px)
    assert plain.sum() > 10000
    assert (~valid[plain]).mean() >= 0.95                  # issue 5
    # pixels at least 1 px inside a plain surface
    inner = cv2.erode(plain.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
    assert (~valid[inner]).mean() >= 0.97
    err = np.abs(res.disparity_px - t.disparity_px)
    guessed = plain & valid & (err > 1.0)
    assert guessed.sum() / plain.sum() <= 0.025


# One textureless object of each kind before the textured corridor of SCENE, lit by the
# laser; measured (docs/notes/stereo-kernels.md): 97.4 %, 96.1 %, 96.2 % and 98.6 % invalid.
_PLAIN_OBJECTS = {
    "box 0.5 m wide at 1.2 m": [
        {"type": "box", "centre_xy_m": [1.2, 0.0], "size_m": [0.4, 0.5, 0.6],
         "surface": _surface("plain", [0.7, 0.7, 0.68])}],
    "cylinder 0.2 m across at 0.9 m": [
        {"type": "cylinder", "centre_xy_m": [0.9, 0.1], "radius_m": 0.1, "height_m": 0.7,
         "surface": _surface("plain", [0.7, 0.7, 0.68])}],
    "two boxes at 2-3 m": [
        {"type": "box", "centre_xy_m": [2.0, -0.4], "size_m": [0.3, 0.4, 0.5], "yaw_deg": 20,
         "surface": _surface("plain", [0.5, 0.55, 0.6])},
        {"type": "box", "centre_xy_m": [2.8, 0.5], "size_m": [0.3, 0.6, 0.9],
         "surface": _surface("plain", [0.8, 0.75, 0.6])}],
    "cylinder 0.4 m across at 0.7 m, 6 DN noise": [
        {"type": "cylinder", "centre_xy_m": [0.7, -0.1], "radius_m": 0.2, "height_m": 0.5,
         "surface": _surface("plain", [0.7, 0.7, 0.68])}],
}


@pytest.mark.parametrize("seed", [5, 6, 7, 8, 9])
@pytest.mark.parametrize("name", list(_PLAIN_OBJECTS))
def test_single_textureless_objects_are_invalid_not_guessed(name, seed):
    scene_dict = {**SCENE, "seed": seed,
                  "objects": SCENE["objects"][:3] + _PLAIN_OBJECTS[name]}
    if "6 DN" in name:
        scene_dict["image"] = {"noise_sigma_dn": 6.0}
    scene = scene_from_dict(scene_dict, name)
    rig = paper_rig()
    frame = render_frame(scene, rig, scene.poses(1)[0], frame_index=0)
    res = process_stereo_pair(frame.left_bgr, frame.right_bgr, rig)
    t = frame.truth
    plain = ~t.textured & np.isfinite(t.disparity_px)
    valid = np.isfinite(res.disparity_px)
    err = np.abs(res.disparity_px - t.disparity_px)
    assert plain.sum() > 5000
    assert (~valid[plain]).mean() >= 0.95                  # issue 5
    # of the at most 5 % valid plain pixels (silhouettes, the stripe) at most half are
    # more than 1 px off: 2.5 % of the plain pixels, as for the corridor's plain boxes
    assert (plain & valid & (err > 1.0)).sum() / plain.sum() <= 0.025


def test_nearer_surfaces_do_not_spill_past_their_silhouettes(corridor):
    # a valid pixel whose disparity is more than 1 px above the truth and within 1 px of
    # a surface that the truth shows within 5 columns carries that nearer surface past
    # its silhouette (the correlation window straddles the depth edge)
    _, frame, res = corridor
    g = frame.truth.disparity_px
    d = res.disparity_px
    valid = np.isfinite(d) & np.isfinite(g)
    g_near = np.where(np.isfinite(g), g, -100.0)
    d_any = np.where(np.isfinite(d), d, -200.0)
    nearby = np.zeros_like(valid)
    for shift in range(-5, 6):
        nearby |= np.abs(np.roll(g_near, shift, axis=1) - d_any) < 1.0
    spilled = valid & (d - g > 1.0) & nearby
    # 0.18 % measured (0.67 % without the depth-edge and one-sided support tests); the
    # rest are pixels whose footprint straddles the silhouette
    assert spilled.sum() / valid.sum() <= 0.0025


def test_ranges_per_bearing_against_the_truth(corridor):
    _, frame, res = corridor
    t = frame.truth
    np.testing.assert_array_equal(res.bearing_deg, t.bearing_deg)
    both = np.isfinite(res.range_m) & np.isfinite(t.range_m)
    assert both.sum() >= 30
    # stereo never reports an obstacle much nearer than the nearest true one: at most
    # 5 cm or what 0.3 px of disparity means at that range (Z^2 / (f W) per px)
    z = t.range_m[both]
    slack = np.maximum(0.05, 0.3 * z**2 / (250.0 * 0.088))
    assert (res.range_m[both] >= z - slack).all()
    # bins whose nearest obstacle is textured (the box 1.5 m ahead, left of centre)
    box = both & (t.bearing_deg >= 7) & (t.bearing_deg <= 21)
    assert box.sum() == 15
    rel = np.abs(res.range_m[box] - t.range_m[box]) / t.range_m[box]
    assert np.median(rel) <= 0.01 and rel.max() <= 0.03
    # the obstacle mask against the truth's on pixels stereo measured
    valid = np.isfinite(res.disparity_px)
    agree = (res.obstacle_mask == t.obstacle_mask)[valid & (t.depth_m <= 3.0)]
    assert agree.mean() >= 0.95


@pytest.mark.parametrize("seed", [1, 2, 3, 4, 5])
def test_silhouette_trim_removes_spill_onto_a_plain_background(seed):
    # A textured box and cylinder at 1.5-2 m before a plain wall at 3.6 m (beyond the
    # stereo range, so never an obstacle itself): the window carries the objects'
    # disparity past their silhouettes onto the plain wall; cutting each row's runs at
    # the outermost intensity step removes most of that spill and keeps the objects.
    from slitcli.stereo.obstacles import ObstacleParams
    from slitcli.stereo.pipeline import StereoParams

    textured = _surface("noise", [0.55, 0.6, 0.5], 0.02, 0.7)
    scene = scene_from_dict({"slitcli_scene": 1, "seed": seed, "objects": [
        {"type": "box", "centre_xy_m": [1.5, 0.1], "size_m": [0.3, 0.4, 0.6], "yaw_deg": 20,
         "surface": textured},
        {"type": "cylinder", "centre_xy_m": [2.0, -0.5], "radius_m": 0.12, "height_m": 0.9,
         "surface": textured},
        {"type": "wall", "from_xy_m": [3.6, -4], "to_xy_m": [3.6, 4], "height_m": 2.0,
         "surface": _surface("plain", [0.5, 0.5, 0.52])}], "robot": {"frames": 1}})
    rig = paper_rig()
    frame = render_frame(scene, rig, scene.poses(1)[0])
    objects = np.isin(frame.truth.object_id, [1, 2])
    counts = {}
    for reach in (0, ObstacleParams().silhouette_reach_px):
        params = StereoParams(obstacles=ObstacleParams(silhouette_reach_px=reach))
        mask = process_stereo_pair(frame.left_bgr, frame.right_bgr, rig, params).obstacle_mask
        counts[reach] = ((mask & ~objects).sum(), (mask & objects).sum())
    trimmed = counts[ObstacleParams().silhouette_reach_px]
    assert counts[0][0] >= 100                      # the spill exists
    assert trimmed[0] <= 0.7 * counts[0][0]         # most of it goes
    assert trimmed[1] >= 0.97 * counts[0][1]        # the objects stay
