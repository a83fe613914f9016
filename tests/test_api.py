"""The public API (``import slitcli``): the notebook session of docs/api.md, colour order."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from laser_synth import make_frame, wall_stripe_rows

import slitcli
from slitcli.errors import SlitcliError

ROOT = Path(__file__).resolve().parent.parent
BUNDLED = ROOT / "sample_data" / "sequences" / "corridor"
RIG = slitcli.paper_rig()


@pytest.fixture(scope="module")
def corridor():
    rig = slitcli.load_rig(BUNDLED / "rig.yaml")
    det = slitcli.Detector(rig)
    src = slitcli.open_frames(BUNDLED)
    return rig, det, src


def test_docs_session_ranges_match_the_truth(corridor):
    """Detector(load_rig(p))(left, right).ranges, as in docs/api.md: the fused range
    of every frame against the renderer's truth (gt/ranges.csv): the laser ranges its
    band within 1 % and stereo to 3 m within 5 %, so the median fused error is below
    5 % in the bins where an obstacle lies within 3 m."""
    rig, det, src = corridor
    truth = pd.read_csv(BUNDLED / "gt" / "ranges.csv")
    rel = []
    for frame in src.frames(rig):
        r = det(frame.left_bgr, frame.right_bgr).ranges
        assert isinstance(r, slitcli.RangeTable) and len(r) == len(det.bins)
        np.testing.assert_array_equal(r.bearing_deg, det.bins.centres_deg)
        t = truth[truth["frame"] == frame.index].set_index("bearing_deg")["range_m"]
        true_m = t.reindex(r.bearing_deg).to_numpy()
        near = np.isfinite(true_m) & (true_m <= 3.0) & np.isfinite(r.fused_range_m)
        rel.append(np.abs(r.fused_range_m[near] - true_m[near]) / true_m[near])
        assert set(r.fused_source) <= {"laser", "stereo", "none"}
    rel = np.concatenate(rel)
    assert rel.size > 100 and np.median(rel) < 0.05


def test_api_rows_equal_the_command_line_table(corridor, tmp_path):
    """One core: the API's rows of a frame are the rows `detect` writes for it."""
    rig, det, src = corridor
    summary = slitcli.run_detect(BUNDLED, tmp_path / "det")
    table = pd.read_csv(summary.outputs[0])
    for frame in src.frames(rig, skip={0, 1, 2, 4, 5, 7}):
        mine = det(frame.left_bgr, frame.right_bgr).table(frame.index, frame.time_s)
        theirs = table[table["frame"] == frame.index].reset_index(drop=True)
        for c in ("bearing_deg", "laser_range_m", "stereo_range_m", "fused_range_m"):
            np.testing.assert_allclose(theirs[c], mine[c].astype(float), rtol=1e-5)
        assert list(theirs["fused_source"].fillna("none")) == list(mine["fused_source"])


def test_bad_image_names_the_parameter():
    det = slitcli.Detector(RIG)
    with pytest.raises(SlitcliError, match="`left_bgr` is") as e:
        det(np.zeros((480, 640), np.uint8), np.zeros((480, 640, 3), np.uint8))
    assert e.value.params == ("left_bgr",)
    with pytest.raises(SlitcliError) as e:
        slitcli.Detector(RIG, colour_order="bgra")
    assert e.value.param == "colour_order"


def _synthetic(seed: int, **kw) -> tuple[np.ndarray, float]:
    forward = float(np.random.default_rng(seed).uniform(0.65, 0.95))
    return make_frame(RIG, forward_m=forward, seed=seed, **kw).bgr, forward


@pytest.mark.parametrize("seed", range(5))
def test_rgb_image_is_refused_not_read_without_laser(seed):
    """An RGB image passed as BGR puts the red stripe in the blue slot, where Eq. 2
    finds nothing; the detector says so instead of returning no laser."""
    det = slitcli.Detector(RIG)
    bgr, forward = _synthetic(seed)
    las = det.laser(bgr)  # no error on the right order
    truth = wall_stripe_rows(RIG, forward)
    assert las.found.sum() >= 0.9 * np.isfinite(truth).sum()
    with pytest.raises(SlitcliError, match="looks like RGB") as e:
        det.laser(np.ascontiguousarray(bgr[..., ::-1]))
    assert e.value.param == "colour_order"
    # told the order, the RGB image gives the BGR result
    rgb = np.ascontiguousarray(bgr[..., ::-1])
    as_rgb = slitcli.Detector(RIG, colour_order="rgb")
    left, _ = as_rgb.prepare(rgb, rgb)
    np.testing.assert_array_equal(as_rgb.laser(left).v_px, las.v_px)


@pytest.mark.parametrize("seed", range(5))
def test_colour_check_passes_images_without_a_stripe(seed):
    """No laser at all, or a red object off the laser's rows seen in RGB order: nothing
    stripe-like appears either way, so no false alarm."""
    det = slitcli.Detector(RIG)
    dark, _ = _synthetic(seed, laser_dn=0.0)
    det.laser(np.ascontiguousarray(dark[..., ::-1]))
    red, _ = _synthetic(seed, laser_dn=0.0, red_rect_off_laser=(100, 20, 400, 120))
    det.laser(np.ascontiguousarray(red[..., ::-1]))
    assert not det.laser(dark).found.any()


@pytest.mark.parametrize("seed", range(5))
def test_colour_check_once_stops_after_a_lit_frame(seed, monkeypatch):
    """``colour_check="once"`` (sequence runs, the simulator): dark frames are checked
    (a second extraction each) until a lit frame shows the stripe as given; after it a
    dark frame costs one extraction. An RGB source is still refused at its first lit
    frame, however many dark frames come before it; ``"every"`` keeps checking."""
    from slitcli import colour_order, detect

    calls = []
    real = detect.detect_laser

    def counting(*a, **kw):
        calls.append(1)
        return real(*a, **kw)

    monkeypatch.setattr(detect, "detect_laser", counting)
    monkeypatch.setattr(colour_order, "detect_laser", counting)
    lit, _ = _synthetic(seed)
    dark, _ = _synthetic(seed, laser_dn=0.0)
    once = slitcli.Detector(RIG, colour_check="once")
    for img, extractions in ((dark, 2), (dark, 2), (lit, 1), (dark, 1), (dark, 1)):
        calls.clear()
        once.laser(img)
        assert len(calls) == extractions
    every = slitcli.Detector(RIG)
    every.laser(lit)
    calls.clear()
    every.laser(dark)
    assert len(calls) == 2
    rgb_source = slitcli.Detector(RIG, colour_check="once")
    rgb_source.laser(np.ascontiguousarray(dark[..., ::-1]))
    with pytest.raises(SlitcliError, match="looks like RGB"):
        rgb_source.laser(np.ascontiguousarray(lit[..., ::-1]))
    with pytest.raises(SlitcliError) as e:
        slitcli.Detector(RIG, colour_check="sometimes")
    assert e.value.param == "colour_check"


# The distractors scene (a red box crossed by the stripe near its lower edge) through the
# webcam preset (4:2:0 JPEG, crosstalk): on some noise seeds the search with red and blue
# swapped finds a line of 33-91 columns on the box (the stripe's chroma fringe and the
# box's edge), and on some the stripe is missed as given. Of noise seeds 0-199 these
# eleven have the swapped line (60 and 147 also miss the stripe as given: the reported
# refusal); the added light of that line is red as given, so the order is right.
WEBCAM_SWAPPED_LINE_SEEDS = (11, 17, 54, 60, 76, 111, 117, 121, 138, 147, 162)
# seeds whose stripe the extractor finds as given (so their RGB copy has a stripe to find)
WEBCAM_FOUND_SEEDS = (1, 3, 4, 11, 12, 17, 34)


@pytest.fixture(scope="module")
def webcam_distractors():
    import yaml

    from slitcli.sim.render import render_left
    from slitcli.sim.scene import scene_from_dict

    d = yaml.safe_load((ROOT / "sample_data" / "distractors.yaml").read_text())
    scene = scene_from_dict({**d, "image": {"camera": "webcam"}})
    pose = scene.poses(1)[0]
    frames: dict[int, np.ndarray] = {}

    def left_bgr(seed: int) -> np.ndarray:
        if seed not in frames:
            frames[seed] = render_left(scene, RIG, pose, frame_index=seed).left_bgr
        return frames[seed]
    return left_bgr


def _no_stripe(las):
    """``las`` with no column found: the extractor missing the stripe as given."""
    from dataclasses import replace
    return replace(las, v_px=np.full_like(las.v_px, np.nan))


@pytest.mark.parametrize("seed", WEBCAM_SWAPPED_LINE_SEEDS)
def test_webcam_bgr_frame_with_a_swapped_line_passes(seed, webcam_distractors):
    """A BGR webcam frame whose swapped search finds a line (>= 16 columns, so the
    count precondition alone would refuse it) passes: the line's added light as given
    is red-dominant. Checked with the stripe missed as given (the reported case) and
    through the detector."""
    from slitcli.detect import check_colour_order
    from slitcli.laser.frame import detect_laser

    bgr = webcam_distractors(seed)
    assert detect_laser(np.ascontiguousarray(bgr[..., ::-1]), RIG).found.sum() >= 16
    las = detect_laser(bgr, RIG)
    assert check_colour_order(bgr, _no_stripe(las), RIG) is False
    slitcli.Detector(RIG).laser(bgr)


@pytest.mark.parametrize("seed", WEBCAM_FOUND_SEEDS)
def test_webcam_rgb_frame_is_refused(seed, webcam_distractors):
    """The same frames in RGB order are refused, their stripe's added light read blue
    as given, also when the swapped stripe (the fringe) is what the extractor misses."""
    from slitcli.detect import check_colour_order
    from slitcli.laser.frame import detect_laser

    rgb = np.ascontiguousarray(webcam_distractors(seed)[..., ::-1])
    las = detect_laser(rgb, RIG)
    with pytest.raises(SlitcliError, match="looks like RGB") as e:
        check_colour_order(rgb, _no_stripe(las), RIG)
    assert e.value.param == "colour_order"
    # with what the extractor finds as given: a stray line of >= 16 columns (the red
    # box's edge, blue in this order) is measured itself and refused, a shorter one
    # leaves the frame unsettled (checked again on the next frame), never accepted
    n = int(las.found.sum())
    if n >= 8 and n < 16:
        assert check_colour_order(rgb, las, RIG) is False
    else:
        with pytest.raises(SlitcliError, match="looks like RGB"):
            check_colour_order(rgb, las, RIG)


def _blue_cylinder_frame(seed: int) -> np.ndarray:
    """A blue textured cylinder on a brown textured floor, 1.0-1.6 m ahead: the laser
    crosses it a few rows above its foot, so the band the colour check sums holds the
    cylinder above the stripe and the floor below it."""
    from slitcli.sim.render import render_left
    from slitcli.sim.scene import scene_from_dict

    rng = np.random.default_rng(seed)
    cylinder = {"type": "cylinder", "radius_m": 0.17, "height_m": 0.7,
                "centre_xy_m": [float(rng.uniform(1.0, 1.6)), float(rng.uniform(-0.1, 0.1))],
                "surface": {"colour_rgb": [0.39, 0.45, 0.75], "texture": "noise",
                            "scale_m": 0.02, "contrast": 0.5}}
    d = {"slitcli_scene": 1, "name": "foot", "seed": seed, "objects": [cylinder],
         "floor": {"colour_rgb": [0.55, 0.5, 0.45], "texture": "noise", "scale_m": 0.03,
                   "contrast": 0.5}}
    scene = scene_from_dict(d, "foot")
    return render_left(scene, RIG, scene.poses(1)[0]).left_bgr


@pytest.mark.parametrize("seed", range(8))
def test_colour_check_passes_a_stripe_along_an_objects_foot(seed):
    """A BGR frame whose stripe (or the line the swapped search finds: the foot's edge)
    runs within the summed band of a blue object's border with the floor is not refused:
    against the floor alone the blue object reads as added blue light, against the
    object alone the floor reads as added red, so neither side's reading is the line's
    own colour; the check counts only what both sides agree on (before it did, 3 of
    these 8 frames were refused as RGB)."""
    bgr = _blue_cylinder_frame(seed)
    las = slitcli.Detector(RIG).laser(bgr)  # raises SlitcliError when refused
    assert las.v_px.shape == (bgr.shape[1],)
