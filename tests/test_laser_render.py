"""Issue 4's must-shows, on frames of the project's renderer (slitcli.sim) with exact truth.

The truth calls a column's stripe visible when its expected peak is at least the
scene's ``laser.visible_min_dn`` (20 DN, ten noise sigmas by default). Each case
measures, against it: the share of visible columns found; the columns reported where
no laser light falls at all (false returns: highlights, red objects, texture, edges)
and, apart, those where it falls below the visibility level (a real, faint stripe:
the truth computed again with ``visible_min_dn`` 1 DN); the row error of the found
columns (px) and the forward distance error (share of the range).
"""

from functools import cache
from pathlib import Path

import numpy as np
import pytest
import yaml

from slitcli.laser import LaserGeometry, LaserParams, detect_laser
from slitcli.rig import paper_rig
from slitcli.sim.render import frame_truth, render_left
from slitcli.sim.scene import scene_from_dict

ROOT = Path(__file__).resolve().parent.parent
RIG = paper_rig()
PARAMS = LaserParams()
GEOM = LaserGeometry.from_rig(RIG, PARAMS)
GREY = (0.7, 0.68, 0.62)
#: cases the re-layered, model-based extractor (issue 19) does not yet meet; kept as
#: expected failures so that they show when fixed (docs/laser.md, "Limits"); each
#: says what was measured on it


def regression(cause: str) -> pytest.MarkDecorator:
    """Expected failure of a rendered case, with its measured cause."""
    return pytest.mark.xfail(reason=f"issue 19 re-layering, docs/laser.md Limits: {cause}",
                             strict=True)


RED = (0.85, 0.12, 0.1)


def _wall(forward_m, *, noise_dn=2.0, power_dn=900.0, width_m=0.004, colour=GREY,
          contrast=0.6, laser=True):
    return {"slitcli_scene": 1, "name": "wall", "seed": 5,
            "objects": [{"type": "wall", "from_xy_m": [forward_m, -3.0],
                         "to_xy_m": [forward_m, 3.0], "height_m": 2.0,
                         "surface": {"colour_rgb": list(colour), "texture": "noise",
                                     "scale_m": 0.02, "contrast": contrast}}],
            "laser": {"power_dn": power_dn, "width_m": width_m, "enabled": laser},
            "image": {"noise_sigma_dn": noise_dn}, "robot": {"frames": 1}}


def _sample(name, power_dn=900.0):
    d = yaml.safe_load((ROOT / "sample_data" / f"{name}.yaml").read_text())
    d.setdefault("laser", {})["power_dn"] = power_dn
    return d


@cache
def _frame(key):
    """Render (once per test session) and detect one frame; key = (scene yaml, frame).
    Returns the frame, the detection and the rows of any laser light (>= 1 DN)."""
    text, frame = key
    d = yaml.safe_load(text)
    scene = scene_from_dict(d)
    pose = scene.poses(frame + 1)[frame]
    r = render_left(scene, RIG, pose, frame_index=frame)
    d["laser"] = {**d.get("laser", {}), "visible_min_dn": 1.0}
    lit_v = frame_truth(scene_from_dict(d), RIG, pose).stripe_v_px
    return r, detect_laser(r.left_bgr, RIG, PARAMS, geometry=GEOM), lit_v


def _run(scene_dict, frame=0):
    return _frame((yaml.safe_dump(scene_dict), frame))


def _stats(r, f, lit_v):
    t = r.truth.stripe_v_px
    vis = np.isfinite(t)
    both = vis & f.found
    err = f.v_px[both] - t[both]
    x_true = r.truth.stripe_sensor_xyz[both, 0]
    fwd = np.abs(f.x_m[both] - x_true) / x_true
    faint = f.found & ~vis & (np.abs(np.nan_to_num(f.v_px - lit_v, nan=99.0)) < 1.5)
    good = err[np.abs(err) < 1.5]
    return dict(vis=int(vis.sum()), found=both.sum() / max(vis.sum(), 1),
                false=int((f.found & ~vis & ~faint).sum()), faint=int(faint.sum()),
                wrong=int((np.abs(err) >= 1.5).sum()),
                rms=float(np.sqrt(np.mean(good ** 2))) if good.size else np.nan,
                fwd_median=float(np.median(fwd)) if fwd.size else np.nan)


@pytest.mark.parametrize(("case", "wall", "rms_max"), [
    # clean stripes, noise 2-3 DN: at 0.8 and 1.0 m the default 4 mm sheet gives
    # sigma 0.8-0.9 px; a 6 mm sheet at 0.9 m gives 1.2-1.3 px (the 1-1.5)
    ("0.8 m", dict(forward_m=0.8), 0.10),
    ("1.0 m", dict(forward_m=1.0), 0.10),
    pytest.param("0.9 m, 6 mm sheet, noise 3",
                 dict(forward_m=0.9, width_m=0.006, power_dn=500.0, noise_dn=3.0), 0.10,
                 marks=regression("rows RMS 0.10-0.17 px over seeds 5-9 (found 97.5-100 %); "
                                  "the extractor before the re-layering: 0.07-0.09 px")),
    # saturated (the red core clipped across the image) and noisy stripes
    ("0.6 m saturated", dict(forward_m=0.6), 0.20),
    ("0.8 m noise 8", dict(forward_m=0.8, noise_dn=8.0), 0.20),
])
@pytest.mark.parametrize("seed", [5, 6, 7, 8, 9])
def test_rendered_walls_rows_and_forward_distance(case, wall, rms_max, seed):
    r, f, lit = _run({**_wall(**wall), "seed": seed})
    s = _stats(r, f, lit)
    assert s["vis"] >= 300, case
    assert s["found"] >= 0.99, case
    assert s["false"] == 0 and s["faint"] == 0 and s["wrong"] == 0, case
    assert s["rms"] <= rms_max, case
    assert s["fwd_median"] <= 0.005, case
    if case.endswith("saturated"):
        assert f.saturated[f.found].mean() >= 0.9


SAMPLE_FRAMES = [("fig4", 900.0, 0), ("fig4", 500.0, 0), ("distractors", 900.0, 0),
                 ("distractors", 500.0, 0), ("corridor", 900.0, 0), ("corridor", 500.0, 20)]


@regression("fig4 at 500 DN: a 3.3-sigma fit on the averaged evidence two columns past "
            "a clipped stripe end (column 145, its own light within 3 standard errors); "
            "corridor at 900 DN: a bright reddish first row of the floor under a greenish "
            "object (chromaticity step 0.04, below the surface test's 0.1) in columns 131-134")
def test_rendered_sample_scenes_found_and_no_false_columns():
    # the sample scenes at the default laser power (900 DN at 0.6 m) and at 500 DN
    stats = [_stats(*_run(_sample(name, power_dn), frame))
             for name, power_dn, frame in SAMPLE_FRAMES]
    vis = sum(s["vis"] for s in stats)
    found = sum(s["found"] * s["vis"] for s in stats) / vis
    assert found >= 0.99
    for s, case in zip(stats, SAMPLE_FRAMES, strict=True):
        assert s["found"] >= 0.98, case  # one or two end columns of an object at most
        # no column without laser light: highlights, the far red box, the floor's
        # texture, wall/floor edges
        assert s["false"] == 0, case
        assert s["wrong"] == 0, case
        assert s["rms"] <= 0.20, case
        assert s["fwd_median"] <= 0.005, case
    # where a surface's stripe fades through the visibility level (20 DN) a few
    # columns just below it may be reported (real, at their range)
    assert sum(s["faint"] for s in stats) <= 0.01 * vis


def test_rendered_fig4_box_fronts():
    _, f, _ = _run(_sample("fig4"))
    x = f.x_m[f.found]
    # the two box fronts, 0.6 m and 0.8 m ahead
    assert np.sum(np.abs(x - 0.6) < 0.003) >= 40 and np.sum(np.abs(x - 0.8) < 0.004) >= 40


@pytest.mark.parametrize("power_dn", [900.0, 500.0])
def test_rendered_red_box_laser_not_the_box(power_dn):
    # distractors: the laser crosses a wide red box (its red channel saturates at 900 DN
    # power, the stripe shows in the green/blue crosstalk); a second red box and two
    # lamp highlights are out of the laser's reach
    r, f, _ = _run(_sample("distractors", power_dn))
    t = r.truth.stripe_v_px
    cols = np.flatnonzero(np.isfinite(t))
    rows = np.clip(np.rint(t[cols]).astype(int), 0, RIG.height_px - 1)
    on_red = cols[r.truth.object_id[rows, cols] == 1]  # object 0 is the red box (id k + 1)
    assert on_red.size >= 150
    hit = np.abs(np.nan_to_num(f.v_px[on_red] - t[on_red], nan=9.0)) < 1.0
    assert hit.mean() >= 0.95


def test_rendered_wide_red_wall_with_and_without_the_laser():
    # a red wall filling the view (texture contrast 0.6) 0.8 m ahead: its texture is
    # red like the laser (colour cannot cancel it), the stripe saturates on it
    r, f, lit = _run(_wall(0.8, colour=RED))
    s = _stats(r, f, lit)
    assert s["found"] >= 0.95 and s["false"] == 0 and s["wrong"] == 0
    assert s["rms"] <= 0.30
    # the same wall without the laser, and a more strongly textured one: no column
    for wall in (dict(forward_m=0.8, colour=RED, laser=False),
                 dict(forward_m=0.7, colour=RED, contrast=0.9, laser=False)):
        _, f, _ = _run(_wall(**wall))
        assert not f.found.any()


def _red_box(contrast, power_dn, noise_dn):
    # a red box 0.6 m wide, its front 0.8 m ahead, 1 cm noise texture
    return {"slitcli_scene": 1, "seed": 5,
            "objects": [{"type": "box", "centre_xy_m": [0.9, 0.0], "size_m": [0.2, 0.6, 0.5],
                         "yaw_deg": 0.0,
                         "surface": {"colour_rgb": list(RED), "texture": "noise",
                                     "scale_m": 0.01, "contrast": contrast}}],
            "laser": {"power_dn": power_dn}, "image": {"noise_sigma_dn": noise_dn},
            "robot": {"frames": 1}}


@pytest.mark.parametrize(("contrast", "power_dn", "noise_dn"), [
    # the stripe clips on the box (truth peaks 175-240 DN over a red level of 80-200);
    # texture blobs next to the core reach more red contrast than the clipped pixels
    pytest.param(0.8, 900.0, 8.0, marks=regression(
        "clipped cores on red texture of contrast 0.8 centred 0.5-2.5 px off (texture "
        "clips beside the core): 75 % of the box columns within 0.5 px")),
    (0.5, 500.0, 5.0),
])
@pytest.mark.parametrize("seed", [5, 6, pytest.param(7, marks=regression(
    "texture seed 7: one box column 1.7 px off the stripe and one end column 8 px off it, "
    "both on the red texture (contrast 0.5)")), 8, 9])
def test_rendered_red_textured_box_laser_not_the_texture(contrast, power_dn, noise_dn, seed):
    r, f, _ = _run({**_red_box(contrast, power_dn, noise_dn), "seed": seed})
    t = r.truth.stripe_v_px
    cols = np.flatnonzero(np.isfinite(t))
    rows = np.clip(np.rint(t[cols]).astype(int), 0, RIG.height_px - 1)
    on_box = cols[r.truth.object_id[rows, cols] == 1]
    assert on_box.size >= 150
    dv = np.abs(np.nan_to_num(f.v_px[on_box] - t[on_box], nan=9.0))
    assert (dv < 0.5).mean() >= 0.95
    # no column off the stripe: every reported row is on the truth's stripe, or is the
    # end column next to the box's last lit column (it sees part of the lit face)
    found = np.flatnonzero(f.found)
    on_stripe = np.abs(np.nan_to_num(f.v_px[found] - t[found], nan=9.0)) < 1.5
    beside = np.zeros(found.size, bool)
    for d in (-1, 1):
        nb = np.clip(found + d, 0, t.size - 1)
        beside |= np.isnan(t[found]) & (np.abs(np.nan_to_num(f.v_px[found] - t[nb], nan=9.0))
                                         < 1.5)
    assert (on_stripe | beside).all()
    assert beside.sum() <= 2


def _floor_highlights(floor_rgb, noise_dn, highlights):
    """A bare textured floor lit by white highlights (radius m, brightness), no laser."""
    return {"slitcli_scene": 1, "name": "highlights", "seed": 3,
            "floor": {"colour_rgb": list(floor_rgb), "texture": "noise", "scale_m": 0.01,
                      "contrast": 0.3},
            "highlights": [{"position_xyz_m": [x, y, 0.0], "radius_m": rad, "brightness": b}
                           for x, y, rad, b in highlights],
            "laser": {"enabled": False}, "image": {"noise_sigma_dn": noise_dn},
            "robot": {"frames": 1}}


@pytest.mark.parametrize(("floor_rgb", "noise_dn"), [((0.44, 0.61, 0.68), 6.6),
                                                     ((0.46, 0.43, 0.63), 6.0),
                                                     ((0.36, 0.65, 0.4), 4.8)])
@pytest.mark.parametrize("seed", [3, 4, 5, 6, 7])
def test_rendered_saturated_white_highlights_are_not_the_laser(floor_rgb, noise_dn, seed):
    # white highlights on a blue, violet or green floor at 0.9-1.8 m, clipped over
    # 4-12 rows: a clipped red channel alone is no laser core (its fringe is white,
    # not red on both sides), nor is a flat top that a Gaussian of the sheet's width
    # could only span with a peak thousands of times the saturation level
    spots = [(0.92, -0.54, 0.04, 1.07), (0.94, 0.24, 0.0135, 1.84), (1.33, 0.34, 0.013, 1.53),
             (1.05, 0.26, 0.037, 0.92), (1.80, -0.48, 0.035, 2.13), (1.20, 0.0, 0.03, 2.5)]
    r, f, _ = _run({**_floor_highlights(floor_rgb, noise_dn, spots), "seed": seed})
    assert (r.left_bgr[..., 2] >= PARAMS.saturation_dn).sum() >= 30  # the spots do clip
    assert not f.found.any()
