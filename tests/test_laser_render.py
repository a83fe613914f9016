"""Laser extraction against the project's renderer (slitcli.sim), exact stripe truth."""

from pathlib import Path

import numpy as np
import pytest

from slitcli.laser import LaserGeometry, LaserParams, detect_laser
from slitcli.rig import paper_rig
from slitcli.sim.render import render_frame
from slitcli.sim.scene import load_scene, scene_from_dict

ROOT = Path(__file__).resolve().parent.parent
RIG = paper_rig()
PARAMS = LaserParams()
GEOM = LaserGeometry.from_rig(RIG, PARAMS)


def _wall(forward_m, *, texture="noise", noise_dn=2.0, seed=1):
    return scene_from_dict({
        "slitcli_scene": 1, "name": "wall", "seed": seed,
        "objects": [{"type": "wall", "from_xy_m": [forward_m, -3.0], "to_xy_m": [forward_m, 3.0],
                     "height_m": 2.0,
                     "surface": {"colour_rgb": [0.7, 0.68, 0.62], "texture": texture,
                                 "scale_m": 0.02, "contrast": 0.6}}],
        "image": {"noise_sigma_dn": noise_dn}, "robot": {"frames": 1}})


def _detect(scene, frame_index=0):
    pose = scene.poses(frame_index + 1)[frame_index]
    r = render_frame(scene, RIG, pose, frame_index=frame_index)
    return r, detect_laser(r.left_bgr, RIG, PARAMS, geometry=GEOM)


def _stats(r, f):
    t = r.truth.stripe_v_px
    vis = np.isfinite(t)
    both = vis & f.found
    err = f.v_px[both] - t[both]
    return vis, both, err


@pytest.mark.parametrize(("forward_m", "texture"), [(0.6, "plain"), (0.8, "plain"),
                                                    (0.8, "noise")])
def test_rendered_wall_row_rms_and_forward_distance(forward_m, texture):
    r, f = _detect(_wall(forward_m, texture=texture))
    vis, both, err = _stats(r, f)
    assert vis.sum() == 320
    assert both.sum() / vis.sum() >= 0.99
    assert not (f.found & ~vis).any()
    assert np.sqrt(np.mean(err**2)) <= 0.10
    x_true = r.truth.stripe_sensor_xyz[both, 0]
    assert np.median(np.abs(f.x_m[both] - x_true) / x_true) <= 0.005
    assert np.median(np.abs(f.x_m[both] - forward_m) / forward_m) <= 0.005


def test_rendered_wall_at_1m_faint_edges():
    # the stripe fades with range: at 1 m the image corners hold peaks near 16 DN
    r, f = _detect(_wall(1.0))
    vis, both, err = _stats(r, f)
    assert both.sum() / vis.sum() >= 0.97
    assert not (f.found & ~vis).any()
    assert np.sqrt(np.mean(err**2)) <= 0.15
    x_true = r.truth.stripe_sensor_xyz[both, 0]
    assert np.median(np.abs(f.x_m[both] - x_true) / x_true) <= 0.005


def test_rendered_fig4_scene():
    r, f = _detect(load_scene(ROOT / "sample_data" / "fig4.yaml"))
    vis, both, err = _stats(r, f)
    assert both.sum() / vis.sum() >= 0.99
    assert np.sqrt(np.mean(err[np.abs(err) < 1.5] ** 2)) <= 0.10
    assert np.sum(np.abs(err) >= 1.5) == 0
    # the two box fronts (0.6 m and 0.8 m ahead) come out at their distances
    x = f.x_m[both]
    assert np.any(np.abs(x - 0.6) < 0.005) and np.any(np.abs(x - 0.8) < 0.005)


def test_rendered_distractors_red_box_highlights():
    scene = load_scene(ROOT / "sample_data" / "distractors.yaml")
    r, f = _detect(scene)
    vis, both, err = _stats(r, f)
    t = r.truth.stripe_v_px
    cols = np.flatnonzero(vis)
    rows = np.clip(np.rint(t[cols]).astype(int), 0, RIG.height_px - 1)
    on_red = cols[r.truth.object_id[rows, cols] == 1]  # object 0 is the red box (id k + 1)
    assert on_red.size >= 40
    hit = np.abs(f.v_px[on_red] - t[on_red]) < 1.0
    assert hit.mean() >= 0.95
    assert both.sum() / vis.sum() >= 0.99
    assert not (f.found & ~vis).any()  # no column from the highlights or the far red box
    assert np.sum(np.abs(err) >= 1.5) == 0
