"""Stereo on rendered scenes (slitcli.sim): disparity, textureless surfaces, ranges."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from slitcli.rig import paper_rig
from slitcli.sim.render import render_frame
from slitcli.sim.scene import load_scene
from slitcli.stereo.pipeline import process_stereo_pair

SAMPLE = Path(__file__).resolve().parents[1] / "sample_data" / "corridor.yaml"


@pytest.fixture(scope="module")
def corridor():
    """Frame 0 of the corridor scene: textured walls, floor, boxes and cylinders, two
    textureless boxes (0.95 m and 3.2 m ahead); 2 DN sensor noise."""
    scene = load_scene(SAMPLE)
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
    plain = ~t.textured & np.isfinite(t.disparity_px)
    valid = np.isfinite(res.disparity_px)
    assert plain.sum() > 10000
    # every pixel of the plain boxes, silhouettes and the crease between two shaded
    # faces included (those carry real edges that match correctly)
    assert (~valid[plain]).mean() >= 0.90
    # pixels at least 1 px inside a plain surface
    inner = cv2.erode(plain.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
    assert (~valid[inner]).mean() >= 0.93
    err = np.abs(res.disparity_px - t.disparity_px)
    guessed = plain & valid & (err > 1.0)
    assert guessed.sum() / plain.sum() <= 0.04


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
