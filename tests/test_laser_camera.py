"""The laser stripe through the renderer's camera model (issue 19): webcam and robot presets.

Frames of a wall and of a red box in front of it are rendered through a camera preset
(:mod:`slitcli.sim.camera`: Bayer mosaic and demosaicing, tone curve, signal-dependent
noise, JPEG 4:2:0) and the stripe found is scored against the renderer's exact truth:
the share of the columns whose stripe is visible (peak >= ``laser.visible_min_dn``)
that are found within 2 px, the median row error of those, and the columns reported
more than 2 px off the true row or where no laser light falls (wrong returns: a
wrong range is worse than a miss). Bounds follow from the camera model, not from last
run's numbers:

- A red Bayer pixel samples every second row: a stripe narrower than that pitch (the
  4 mm sheet at 0.8-1.2 m is 0.8-1.0 px) is seen through the red rows only and its
  interpolated centre leans towards the nearest red row, up to half the pitch (1 px)
  less the share the stripe's own width spreads over both: the median row error may
  reach ``BAYER_BIAS_PX``.
- JPEG 4:2:0 averages the chroma of two rows: the evidence (mostly chroma) of a narrow
  stripe is spread over the pair's rows, a further quarter pixel.
"""

from functools import cache

import numpy as np
import pytest
import yaml

from slitcli.laser import LaserGeometry, LaserParams, detect_laser
from slitcli.rig import paper_rig
from slitcli.sim.render import render_left
from slitcli.sim.scene import scene_from_dict

RIG = paper_rig()
PARAMS = LaserParams()
GEOM = LaserGeometry.from_rig(RIG, PARAMS)
SEEDS = [5, 6, 7, 8, 9]
GREY = (0.7, 0.68, 0.62)
RED = (0.85, 0.12, 0.1)
#: half the red Bayer pitch (the centre's lean towards the nearest red row) plus the
#: 4:2:0 chroma pair's quarter pixel, px
BAYER_BIAS_PX = 0.5 + 0.25
#: a column is wrong beyond this row error, px (at 0.8-1.2 m one pixel is 1-2 % of range)
WRONG_PX = 2.0


def _scene(seed, camera, forward_m, box):
    wall_m = forward_m + 0.7 if box else forward_m
    objects = [{"type": "wall", "from_xy_m": [wall_m, -3.0], "to_xy_m": [wall_m, 3.0],
                "height_m": 2.0, "surface": {"colour_rgb": list(GREY), "texture": "noise",
                                             "scale_m": 0.02, "contrast": 0.5}}]
    if box:
        objects.append({"type": "box", "centre_xy_m": [forward_m + 0.1, 0.0],
                        "size_m": [0.2, 0.7, 0.6], "yaw_deg": 0.0, "z_min_m": 0.0,
                        "surface": {"colour_rgb": list(RED), "texture": "noise",
                                    "scale_m": 0.02, "contrast": 0.3}})
    return {"slitcli_scene": 1, "name": "camera", "seed": seed, "objects": objects,
            "laser": {"power_dn": 900.0}, "image": {"camera": camera},
            "robot": {"frames": 1}}


@cache
def _scored(seed, camera, forward_m, box):
    """Render one frame and score the stripe found against the truth: visible columns,
    found within WRONG_PX, wrong columns (off by more, or without laser light), the
    absolute row errors of the found columns."""
    scene = scene_from_dict(yaml.safe_load(yaml.safe_dump(
        _scene(seed, camera, forward_m, box))))
    r = render_left(scene, RIG, scene.poses(1)[0])
    f = detect_laser(r.left_bgr, RIG, PARAMS, geometry=GEOM)
    t = r.truth.stripe_v_px
    vis = np.isfinite(t)
    err = np.abs(f.v_px - t)
    ok = vis & f.found & (err <= WRONG_PX)
    wrong = f.found & vis & (err > WRONG_PX)
    return int(vis.sum()), int(ok.sum()), int(wrong.sum()), err[ok]


def _pooled(camera, forward_m, box):
    rows = [_scored(s, camera, forward_m, box) for s in SEEDS]
    vis = sum(r[0] for r in rows)
    found = sum(r[1] for r in rows)
    wrong = sum(r[2] for r in rows)
    err = np.concatenate([r[3] for r in rows])
    return vis, found, wrong, err


#: the issue's floors on real photographs, asked of the camera-model renders too: found
#: within 2 px of the visible columns, and wrong columns (a wrong range) among them
FOUND_MIN = 0.85
WRONG_MAX = 0.01


def _fails(cause: str) -> pytest.MarkDecorator:
    """A camera-model case the extractor does not yet meet (docs/laser.md, Limits), with
    its measured cause; strict, so that it shows when fixed."""
    return pytest.mark.xfail(reason=f"issue 19, camera model: {cause}", strict=True)


TONE = ("the tone curve: on the bright red box the laser adds nearly grey DN (its red "
        "channel sits where the curve is flat, green and blue where it is steep), so "
        "the evidence, built for additive light of one colour, is flat or negative")
CHROMA = ("JPEG 4:2:0 at quality 80: the evidence (chroma) of a 1 px stripe is "
          "averaged over two rows and quantised to 8-10 DN, as large as the chroma "
          "clutter it is judged against; the luma keeps it")
FAINT = ("robot preset: evidence noise 10 DN, the stripe 30-40 DN per column: "
         "the significance per column 3-5, chosen on too few columns")


@pytest.mark.parametrize(("camera", "forward_m", "box"), [
    ("webcam", 0.8, False),
    pytest.param("webcam", 0.8, True, marks=_fails(TONE)),
    pytest.param("webcam", 1.2, False, marks=_fails(CHROMA)),
    pytest.param("robot", 0.8, False, marks=_fails(FAINT)),
    pytest.param("robot", 0.8, True, marks=_fails(FAINT + "; " + TONE)),
])
def test_camera_stripe_found_and_rows(camera, forward_m, box):
    vis, found, wrong, err = _pooled(camera, forward_m, box)
    assert vis >= 600 * len(SEEDS) // 5  # the truth shows the stripe across the view
    assert found / vis >= FOUND_MIN
    assert wrong <= WRONG_MAX * vis
    assert np.median(err) <= BAYER_BIAS_PX


@pytest.mark.parametrize("camera", ["webcam", "robot"])
@pytest.mark.parametrize("seed", SEEDS)
def test_camera_no_stripe_without_laser(camera, seed):
    """With the laser off nothing is reported through either preset (the red box, its
    texture and the JPEG's chroma clutter are not the laser)."""
    d = _scene(seed, camera, 0.8, True)
    d["laser"] = {**d["laser"], "enabled": False}
    scene = scene_from_dict(d)
    r = render_left(scene, RIG, scene.poses(1)[0])
    f = detect_laser(r.left_bgr, RIG, PARAMS, geometry=GEOM)
    assert not f.found.any()
