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
    from slitcli import detect

    calls = []
    real = detect.detect_laser

    def counting(*a, **kw):
        calls.append(1)
        return real(*a, **kw)

    monkeypatch.setattr(detect, "detect_laser", counting)
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
