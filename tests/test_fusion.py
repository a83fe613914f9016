"""Eq. 11 fusion, case by case against hand-worked bins."""

import numpy as np
import pytest

from slitcli.errors import SlitcliError
from slitcli.fusion import FusionParams, fuse

NAN = np.nan
# bins: (laser, stereo, has_features)
CASES = [
    (0.8, NAN, False),   # 0 textureless: laser only
    (NAN, NAN, False),   # 1 textureless, no laser: nothing
    (0.8, 2.0, True),    # 2 laser in band, stereo farther -> laser
    (0.8, 0.7, True),    # 3 laser in band, stereo nearer -> stereo
    (NAN, 2.0, True),    # 4 no laser, stereo far -> stereo
    (NAN, 0.7, True),    # 5 no laser, stereo near (overhang!) -> paper clamps to 1.0
    (NAN, NAN, True),    # 6 nothing
    (1.3, 2.0, True),    # 7 laser beyond its band: treated as no laser return
    (NAN, 3.5, True),    # 8 stereo beyond its range: ignored
    (NAN, 2.0, False),   # 9 a stereo return in a bin flagged featureless: it saw features
]


def _run(mode):
    laser, stereo, feat = (np.array(c) for c in zip(*CASES, strict=True))
    return fuse(laser, stereo, feat.astype(bool), FusionParams(mode=mode))


def test_paper_mode_bins():
    f = _run("paper")
    expect = [0.8, NAN, 0.8, 0.7, 2.0, 1.0, NAN, 2.0, NAN, 2.0]
    np.testing.assert_allclose(f.range_m, expect, equal_nan=True)
    assert list(f.source) == ["laser", "none", "laser", "stereo", "stereo", "stereo", "none",
                              "stereo", "none", "stereo"]


def test_conservative_mode_is_the_plain_minimum():
    f = _run("conservative")
    expect = [0.8, NAN, 0.8, 0.7, 2.0, 0.7, NAN, 1.3, NAN, 2.0]
    np.testing.assert_allclose(f.range_m, expect, equal_nan=True)
    assert f.source[5] == "stereo" and f.source[7] == "laser"


def test_stereo_return_on_the_laser_surface_keeps_the_laser_range():
    # f B = 22 px m: at 0.70 m the disparity is 31.43 px. Stereo 0.68 m is 0.92 px
    # nearer (the same surface, its percentile a little short): the laser's 0.70 stands.
    # Stereo 0.66 m is 1.90 px nearer, still within 2 px; 0.65 m is 2.42 px nearer: a
    # distinct nearer obstacle (an overhang), stereo's range wins. Conservative: minimum.
    laser = np.full(3, 0.70)
    stereo = np.array([0.68, 0.66, 0.65])
    feat = np.ones(3, bool)
    f = fuse(laser, stereo, feat, FusionParams(focal_baseline_px_m=22.0))
    np.testing.assert_allclose(f.range_m, [0.70, 0.70, 0.65])
    assert list(f.source) == ["laser", "laser", "stereo"]
    f = fuse(laser, stereo, feat, FusionParams(focal_baseline_px_m=22.0, same_surface_px=0.5))
    np.testing.assert_allclose(f.range_m, [0.68, 0.66, 0.65])
    c = fuse(laser, stereo, feat, FusionParams(mode="conservative"))
    np.testing.assert_allclose(c.range_m, stereo)


def test_impossible_same_surface_parameters_are_input_errors():
    with pytest.raises(SlitcliError, match="same_surface_px"):
        FusionParams(same_surface_px=-1.0)
    with pytest.raises(SlitcliError, match="baseline"):
        FusionParams(focal_baseline_px_m=0.0)


def test_unknown_mode_is_an_input_error():
    with pytest.raises(SlitcliError, match="`mode` 'best'"):
        FusionParams(mode="best")


def test_laser_silence_nearer_than_its_sight_is_not_trusted():
    # the stripe of an obstacle at 0.62 m falls below the image where the laser's sight
    # begins at 0.65 m: stereo's 0.62 m stands; where sight begins at 0.60 m it is clamped
    laser, stereo, feat = np.array([NAN, NAN]), np.array([0.62, 0.62]), np.array([True, True])
    f = fuse(laser, stereo, feat, FusionParams(), laser_sight_m=np.array([0.65, 0.60]))
    np.testing.assert_allclose(f.range_m, [0.62, 1.0])
    assert list(f.source) == ["stereo", "stereo"]


def test_laser_silence_beside_a_lit_bin_is_not_trusted():
    # bin 0: laser sees an object at 0.90 m; bin 1: its edge, seen by stereo only;
    # bin 3 (not beside a lit bin): the paper's clamp holds
    laser = np.array([0.90, NAN, NAN, NAN])
    stereo = np.array([0.91, 0.93, NAN, 0.93])
    f = fuse(laser, stereo, np.ones(4, bool), FusionParams())
    np.testing.assert_allclose(f.range_m, [0.90, 0.93, NAN, 1.0], equal_nan=True)
    assert list(f.source) == ["laser", "stereo", "none", "stereo"]


def test_laser_sight_geometry_matches_the_stripe_row():
    from slitcli.laser import laser_sight_range_m
    from slitcli.rig import paper_rig

    rig = paper_rig()
    bearings = np.array([-30.0, -10.0, 0.0, 15.0, 30.0])
    sight = laser_sight_range_m(rig, bearings, margin_px=2.0)
    # straight ahead: the stripe row on a wall at the sight range is the last row in sight
    row = rig.stripe_row_on_wall(float(sight[2]))
    assert rig.height_px - 3.3 <= row <= rig.height_px - 3.0
    # a roll-free rig's stripe row depends on the forward distance only
    np.testing.assert_allclose(sight * np.cos(np.radians(bearings)), sight[2], atol=2e-3)
