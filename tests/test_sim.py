"""The renderer against hand-derived geometry (DESIGN §2, §10)."""

import math
from dataclasses import replace

import cv2
import numpy as np
import pytest

from slitcli.errors import SlitcliError
from slitcli.rig import paper_rig
from slitcli.sim.render import frame_truth, render_frame, render_left, render_pair
from slitcli.sim.scene import Pose2D, scene_from_dict
from slitcli.sim.truth import true_ranges


def wall_scene(x_m: float, **extra) -> dict:
    d = {"slitcli_scene": 1, "seed": 3, "image": {"noise_sigma_dn": 0.0},
         "objects": [{"type": "wall", "from_xy_m": [x_m, -3.0], "to_xy_m": [x_m, 3.0],
                      "height_m": 2.0, "surface": {"colour_rgb": [0.6, 0.6, 0.6],
                                                   "texture": "plain"}}]}
    d.update(extra)
    return d


@pytest.mark.parametrize("seed", range(5))
def test_stripe_on_wall_at_1m_truth_and_rendered_centre(seed):
    rig = paper_rig()
    lit = scene_from_dict(wall_scene(1.0, seed=seed))
    dark = scene_from_dict(wall_scene(1.0, laser={"enabled": False}, seed=seed))
    a = render_left(lit, rig, Pose2D(0, 0, 0))
    b = render_left(dark, rig, Pose2D(0, 0, 0))
    # truth from geometry
    assert a.truth.stripe_v_px[159] == pytest.approx(167.93, abs=0.05)
    assert a.truth.stripe_v_px[160] == pytest.approx(167.93, abs=0.05)
    # the rendered stripe alone: laser-on minus laser-off red channel
    diff = a.left_bgr[:, :, 2].astype(float) - b.left_bgr[:, :, 2].astype(float)
    v = np.arange(diff.shape[0])
    for u in (159, 160):
        col = diff[:, u]
        assert col.max() > 20  # clearly visible at 1 m
        centre = (col * v).sum() / col.sum()
        assert centre == pytest.approx(167.93, abs=0.05)


@pytest.mark.parametrize(("seed", "camera"), [(1, None), (2, "webcam"), (3, "robot")])
def test_render_left_and_render_pair_are_render_frames_parts(seed, camera):
    # the left view alone, and the two images without the truth: the same noise draws,
    # so the same images and truth to the bit, through a camera model too (its own
    # noise, mosaic and codec), on a noisy plain wall and a textured floor, at the second
    # frame of a sequence
    rig = paper_rig()
    extra = {"image": {"noise_sigma_dn": 2.0, **({"camera": camera} if camera else {})}}
    scene = scene_from_dict(wall_scene(1.3, seed=seed, **extra))
    pose = Pose2D(0.1, -0.05, 0.02)
    pair = render_frame(scene, rig, pose, frame_index=1)
    view = render_left(scene, rig, pose, frame_index=1)
    left, right = render_pair(scene, rig, pose, frame_index=1)
    assert np.array_equal(left, pair.left_bgr)
    assert np.array_equal(right, pair.right_bgr)
    assert not np.array_equal(left, right)
    assert np.array_equal(view.left_bgr, pair.left_bgr)
    assert not np.array_equal(render_left(scene, rig, pose, frame_index=2).left_bgr,
                              pair.left_bgr)
    for name in pair.truth.__dataclass_fields__:
        a, b = getattr(pair.truth, name), getattr(view.truth, name)
        if isinstance(a, np.ndarray):
            assert np.array_equal(a, b, equal_nan=True), name
        else:
            assert a == b, name


@pytest.mark.parametrize("seed", range(5))
def test_plain_wall_is_textured_only_where_the_stripe_lights_it(seed):
    # A plain wall at 1 m, 2 DN noise: the stripe (about 0.75 px sigma, peak >> 6 DN) is
    # image texture in a band a few rows tall around its centre row; every other pixel of
    # the wall is plain, and with the laser off the whole wall is.
    rig = paper_rig()
    noisy = {"image": {"noise_sigma_dn": 2.0}, "seed": seed}
    lit = frame_truth(scene_from_dict(wall_scene(1.0, **noisy)), rig, Pose2D(0, 0, 0))
    dark = frame_truth(scene_from_dict(wall_scene(1.0, laser={"enabled": False}, **noisy)),
                       rig, Pose2D(0, 0, 0))
    wall = lit.object_id == 1  # the floor keeps its default noise texture
    assert not dark.textured[wall].any()
    rows = np.nonzero(lit.textured[:, 160] & wall[:, 160])[0]
    assert rows.size >= 3 and rows.size <= 8
    assert np.all(np.abs(rows - lit.stripe_v_px[160]) <= 4)
    assert rows.min() < lit.stripe_v_px[160] < rows.max()
    assert lit.textured[wall].mean() < 0.05


def test_stripe_truth_matches_closed_form_across_columns():
    # the truth comes from the scene's geometry alone, which no seed draws: one suffices
    rig = paper_rig()
    t = frame_truth(scene_from_dict(wall_scene(0.8)), rig, Pose2D(0, 0, 0))
    cols = np.nonzero(np.isfinite(t.stripe_v_px))[0]
    assert len(cols) > 200
    expect = np.array([rig.stripe_row_on_wall(0.8, u) for u in cols])
    np.testing.assert_allclose(t.stripe_v_px[cols], expect, atol=1e-6)
    np.testing.assert_allclose(t.stripe_sensor_xyz[cols, 0], 0.8, atol=1e-9)
    np.testing.assert_allclose(t.stripe_sensor_xyz[cols, 2], 0.05, atol=1e-9)


@pytest.mark.parametrize("seed", [5, 6, 7, 8, 9])
def test_disparity_truth_and_brute_force_shift_search(seed):
    # a textured wall parallel to the image plane: an untilted rig, a wall at x = Z
    z = 1.7
    rig = paper_rig()
    rig = replace(rig, mount=replace(rig.mount, tilt_deg=0.0, height_m=0.6))
    scene = scene_from_dict({
        "slitcli_scene": 1, "seed": seed, "image": {"noise_sigma_dn": 0.0},
        "laser": {"enabled": False},
        "objects": [{"type": "wall", "from_xy_m": [z, -4.0], "to_xy_m": [z, 4.0],
                     "height_m": 3.0, "surface": {"texture": "noise", "scale_m": 0.02,
                                                  "contrast": 0.7}}]})
    fr = render_frame(scene, rig, Pose2D(0, 0, 0))
    fb_z = rig.focal_px * rig.baseline_m / z
    wall = fr.truth.object_id == 1
    np.testing.assert_allclose(fr.truth.disparity_px[wall], fb_z, rtol=1e-12)
    # brute force: for every candidate shift, 9x9 SSD of left(u) vs right(u - d)
    left = cv2.cvtColor(fr.left_bgr, cv2.COLOR_BGR2GRAY).astype(np.float32)
    right = cv2.cvtColor(fr.right_bgr, cv2.COLOR_BGR2GRAY).astype(np.float32)
    h, w = left.shape
    shifts = np.arange(fb_z - 1.5, fb_z + 1.5, 0.02)
    xs, ys = np.meshgrid(np.arange(w, dtype=np.float32), np.arange(h, dtype=np.float32))
    costs = []
    for d in shifts:
        warped = cv2.remap(right, xs - np.float32(d), ys, cv2.INTER_CUBIC,
                           borderMode=cv2.BORDER_REPLICATE)
        costs.append(cv2.boxFilter((left - warped) ** 2, -1, (9, 9), normalize=False))
    best = shifts[np.argmin(np.stack(costs), axis=0)]
    inner = wall.copy()
    inner[:, : int(fb_z) + 10] = False
    inner[:5], inner[-5:], inner[:, -5:] = False, False, False
    assert np.median(np.abs(best[inner] - fb_z)) < 0.1


def test_range_truth_of_a_box_matches_hand_geometry():
    rig = paper_rig()
    scene = scene_from_dict({"slitcli_scene": 1, "objects": [
        {"type": "box", "centre_xy_m": [1.15, 0.1], "size_m": [0.3, 0.6, 0.5]}]})
    centres, lo, hi = rig.bearing_bins()
    r = true_ranges(scene, Pose2D(0, 0, 0), lo, hi)
    # front face x = 1.0, y in [-0.2, 0.4]: a bin's nearest point is on the face at the
    # bin edge nearer to bearing 0 (or at bearing 0 itself)
    for b, got in zip(centres, r, strict=True):
        inner = 0.0 if lo[centres == b][0] <= 0 <= hi[centres == b][0] else \
            min(abs(lo[centres == b][0]), abs(hi[centres == b][0]))
        y_edge = math.tan(math.radians(inner)) * (1 if b >= 0 else -1)
        on_face = -0.2 <= y_edge <= 0.4
        if on_face:
            assert got == pytest.approx(1.0 / math.cos(math.radians(inner)), abs=1e-3)
    assert np.nanmin(r) == pytest.approx(1.0, abs=1e-9)
    # the bin containing the left edge (bearing atan(0.4) = 21.8 deg): nearest point is
    # on the front face at the bin's lower edge 21.5 deg
    k = int(np.nonzero(centres == 22)[0][0])
    assert r[k] == pytest.approx(1.0 / math.cos(math.radians(21.5)), abs=1e-3)
    assert np.isnan(r[centres == 25]).all()  # nothing there


def test_robot_pose_moves_the_truth_consistently():
    # geometric truth (ranges), which no seed draws: one seed suffices
    rig = paper_rig()
    scene = scene_from_dict(wall_scene(2.0))
    moved = frame_truth(scene, rig, Pose2D(1.0, 0.0, 0.0))
    assert np.nanmin(moved.range_m) == pytest.approx(1.0, abs=1e-9)
    turned = frame_truth(scene, rig, Pose2D(0.0, 0.0, math.radians(10)))
    # bin -10 deg now looks along world x (perpendicular to the wall), bin -9 deg covers
    # world bearings 0.5-1.5 deg
    k = int(np.nonzero(turned.bearing_deg == -10)[0][0])
    assert turned.range_m[k] == pytest.approx(2.0, abs=1e-9)
    assert turned.range_m[k + 1] == pytest.approx(2.0 / math.cos(math.radians(0.5)), abs=1e-9)


def test_overhang_is_not_hit_by_the_laser_but_is_an_obstacle():
    rig = paper_rig()
    scene = scene_from_dict({"slitcli_scene": 1, "objects": [
        {"type": "box", "centre_xy_m": [1.0, 0.0], "size_m": [0.4, 0.8, 0.3],
         "z_min_m": 0.25}]})
    t = frame_truth(scene, rig, Pose2D(0, 0, 0))
    assert np.nanmin(t.range_m) == pytest.approx(0.8, abs=1e-9)
    assert np.all(np.isnan(t.stripe_v_px))  # the sheet at 5 cm passes below it


@pytest.mark.parametrize("patch,key", [
    ({"slitcli_scene": 2}, "slitcli_scene"),
    ({"objects": [{"type": "box", "centre_xy_m": [1, 0], "size_m": [0.3, -0.3, 0.5]}]},
     "objects[0].size_m"),
    ({"objects": [{"type": "sphere"}]}, "objects[0].type"),
    ({"image": {"supersample": 0}}, "image.supersample"),
    ({"laser": {"widht_m": 0.01}}, "laser.widht_m"),
])
def test_bad_scene_names_the_key(patch, key):
    d = {"slitcli_scene": 1}
    d.update(patch)
    with pytest.raises(SlitcliError) as e:
        scene_from_dict(d, source="s.yaml")
    assert "s.yaml" in str(e.value) and key in str(e.value)


def test_bundled_sequence_is_reproduced_by_the_renderer():
    from pathlib import Path

    from slitcli.io.sequence import read_image
    from slitcli.rig import load_rig
    from slitcli.sim.scene import load_scene

    seq = Path(__file__).resolve().parent.parent / "sample_data" / "sequences" / "corridor"
    scene = load_scene(seq / "scene.yaml")
    rig = load_rig(seq / "rig.yaml")
    k = 5
    fr = render_frame(scene, rig, scene.poses()[k], frame_index=k)
    np.testing.assert_array_equal(fr.left_bgr, read_image(seq / "left" / f"{k:06d}.png"))
    np.testing.assert_array_equal(fr.right_bgr, read_image(seq / "right" / f"{k:06d}.png"))
    truth = np.load(seq / "gt" / f"frame_{k:06d}.npz")
    np.testing.assert_array_equal(fr.truth.range_m, truth["range_m"])
    np.testing.assert_array_equal(fr.truth.stripe_v_px, truth["stripe_v_px"])
