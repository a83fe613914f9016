"""Single-frame regressions of the laser extractor on rendered frames.

Each test renders one frame that once failed (its scene, seed and pose fixed) and
checks that the failure stays fixed. They are regressions, not properties: a property
of the extractor is tested over several seeds in test_laser.py and test_laser_render.py;
a frame here stands only for itself, so one seed is what it means.
"""

from __future__ import annotations

import numpy as np
from test_laser_render import GEOM, PARAMS, RIG, _stats, regression

from slitcli.laser import detect_laser
from slitcli.sim.render import frame_truth, render_frame
from slitcli.sim.scene import scene_from_dict


@regression("three columns (297-299) on the far red box's edge, 80-144 DN of red with "
            "no laser light, are reported; two columns at the near box's left part 2 px off; "
            "74 % of the visible columns found")
def test_rendered_stripe_between_a_red_objects_edges():
    # a green wall 1.0-1.2 m ahead behind a low red textured box (1.1 m, 23 cm tall)
    # and a red cylinder: in the columns where the stripe on the wall (truth peak
    # ~30 DN, noise 2.4 DN) runs between the box's top edge and its floor edge, those
    # two edges are the strongest red evidence of the column; on an edge between two
    # surfaces they are never the stripe and must not take the stripe's fitted slot
    d = {"slitcli_scene": 1, "seed": 29,
         "floor": {"colour_rgb": [0.39, 0.31, 0.3], "texture": "noise", "scale_m": 0.03,
                   "contrast": 0.28},
         "objects": [
             {"type": "box", "centre_xy_m": [1.0760552856339256, -0.4850894500401714],
              "size_m": [0.2654240856454811, 0.054151175023748416, 0.2277712433663049],
              "yaw_deg": 49.46090124198304,
              "surface": {"colour_rgb": [0.7474576968719026, 0.17348860407981528,
                                         0.0708248947224501],
                          "texture": "noise", "scale_m": 0.04, "contrast": 0.66}},
             {"type": "wall", "from_xy_m": [1.2067822015292407, -0.35855558257505254],
              "to_xy_m": [0.9733612204193179, 0.0962126493452875],
              "height_m": 1.5018293993955072,
              "surface": {"colour_rgb": [0.61, 0.84, 0.42], "texture": "noise",
                          "scale_m": 0.01, "contrast": 0.38}},
             {"type": "cylinder", "centre_xy_m": [0.593056738570011, 0.18455705559230642],
              "radius_m": 0.1007997797043195, "height_m": 0.7530258040301525,
              "surface": {"colour_rgb": [0.8651779202959844, 0.07662302623586903,
                                         0.19078877255208654],
                          "texture": "noise", "scale_m": 0.02, "contrast": 0.27}},
             {"type": "box", "centre_xy_m": [2.2753527669717557, 1.264464036852306],
              "size_m": [0.3, 0.4, 0.5507476503586939], "yaw_deg": -25.430183234806833,
              "surface": {"colour_rgb": [0.8934728038165678, 0.12, 0.1], "texture": "noise",
                          "scale_m": 0.02, "contrast": 0.56}}],
         "highlights": [], "laser": {"power_dn": 641.6987160731328, "enabled": True},
         "image": {"noise_sigma_dn": 2.426209742805686},
         "robot": {"start": [0, 0, 0], "motion": "straight", "speed_mps": 0.1, "frames": 2,
                   "frame_rate_hz": 5.0}}
    # the robot's second frame, with the first frame's stripe passed in (continuity,
    # Eq. 4), as `slitcli laser` runs a sequence
    scene = scene_from_dict(d)
    poses = scene.poses(2)
    r0 = render_frame(scene, RIG, poses[0], frame_index=0)
    r = render_frame(scene, RIG, poses[1], frame_index=1)
    prev = detect_laser(r0.left_bgr, RIG, PARAMS, geometry=GEOM)
    f = detect_laser(r.left_bgr, RIG, PARAMS, previous=prev, geometry=GEOM)
    d["laser"] = {**d["laser"], "visible_min_dn": 1.0}
    lit = frame_truth(scene_from_dict(d), RIG, poses[1]).stripe_v_px
    s = _stats(r, f, lit)
    assert s["vis"] >= 120 and s["false"] == 0 and s["wrong"] == 0
    # the stripe on the box (the columns right of 230): its two edges used to take
    # both fitted slots, and none of its 56 columns was found; its left part, where the
    # box's red texture (contrast 0.66) swamps the 30 DN stripe, is still missed
    t = r.truth.stripe_v_px
    box = np.isfinite(t) & (np.arange(t.size) > 230)
    assert box.sum() >= 50
    assert (f.found & box).sum() >= 0.5 * box.sum()
    assert np.abs(f.v_px[f.found & box] - t[f.found & box]).max() < 1.0
