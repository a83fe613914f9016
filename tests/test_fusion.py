"""Eq. 11 fusion, case by case against hand-worked bins."""

import numpy as np
import pytest

from slitcli.errors import SlitcliError
from slitcli.fusion import (
    FusionParams,
    fuse,
    laser_reach_m,
    stereo_reaches_sheet,
    stripe_depth_agrees,
)

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


# ------------------------------------------------------------ the laser's certified reach
def test_no_stripe_in_the_frame_keeps_stereo():
    # the distractors frame through a dim camera: stereo 0.72 m (truth 0.74), the laser
    # found nothing. Its silence certifies nothing: stereo's range stands. With the
    # stripe seen to 1 m and beyond everywhere, the paper's clamp to 1.0 m holds.
    laser = np.array([NAN, NAN, NAN])
    stereo = np.array([0.72, 2.0, NAN])
    feat = np.ones(3, bool)
    dark = fuse(laser, stereo, feat, FusionParams(), laser_reach_m=np.full(3, NAN))
    np.testing.assert_allclose(dark.range_m, [0.72, 2.0, NAN], equal_nan=True)
    assert list(dark.source) == ["stereo", "stereo", "none"]
    assert np.isnan(dark.laser_free_m).all()
    lit = fuse(laser, stereo, feat, FusionParams(), laser_reach_m=np.full(3, 1.4))
    np.testing.assert_allclose(lit.range_m, [1.0, 2.0, NAN], equal_nan=True)
    np.testing.assert_allclose(lit.laser_free_m, [1.0, 1.0, 1.0])
    # no reach given: the paper's reading, as before
    paper = fuse(laser, stereo, feat, FusionParams())
    np.testing.assert_allclose(paper.range_m, lit.range_m, equal_nan=True)


def test_silence_certifies_only_as_far_as_the_reach():
    # reach 0.85 m: a stereo return at 0.72 m lies where the laser would have seen an
    # obstacle on its sheet, so nothing is nearer than 0.85 m; one at 0.90 m lies
    # beyond what the laser can tell and stands
    laser = np.array([NAN, NAN])
    stereo = np.array([0.72, 0.90])
    f = fuse(laser, stereo, np.ones(2, bool), FusionParams(), laser_reach_m=np.full(2, 0.85))
    np.testing.assert_allclose(f.range_m, [0.85, 0.90])
    np.testing.assert_allclose(f.laser_free_m, [0.85, 0.85])


def test_own_return_beyond_the_band_certifies_the_band():
    # the stripe seen at 1.3 m in this bin: the sheet passed through to 1.3 m here even
    # when the signal alone certifies less; no return and no reach: nothing certified
    laser = np.array([1.3, NAN])
    stereo = np.array([0.7, 0.7])
    f = fuse(laser, stereo, np.ones(2, bool), FusionParams(), laser_reach_m=np.array([0.8, NAN]))
    np.testing.assert_allclose(f.range_m, [1.0, 0.7])
    np.testing.assert_allclose(f.laser_free_m, [1.0, NAN], equal_nan=True)


def test_conservative_mode_records_the_reach_but_ignores_it():
    f = fuse(np.array([NAN]), np.array([0.72]), np.ones(1, bool),
             FusionParams(mode="conservative"), laser_reach_m=np.array([1.4]))
    np.testing.assert_allclose(f.range_m, [0.72])
    np.testing.assert_allclose(f.laser_free_m, [1.0])


def _strength_for(reach_m, range_m, required_dn, p=4.0):
    """The peak (DN) a column at ``range_m`` needs to certify ``reach_m``."""
    return required_dn * (reach_m / range_m) ** p


def test_laser_reach_from_the_stripe_signal_and_both_sides():
    # seed level 5 DN, noise 2 DN, certain_z 3: a stripe is sure to be found where its
    # peak reaches 5 + 3 x 2 = 11 DN. A column at 0.8 m peaking at 11 (1.2/0.8)^4 =
    # 55.69 DN certifies 1.2 m (the peak of a stripe 1.2 m away on that surface, at a
    # fall-off of range^-4, is 11 DN); at 11 (0.9/0.8)^4 DN, 0.9 m.
    params = FusionParams()
    # six bins; stripe columns in bin 1 (two columns: the stronger counts) and bin 4
    column_bin = np.array([-1, 1, 1, 4, -1])
    rng = np.array([NAN, 0.8, 0.8, 0.8, NAN])
    strength = np.array([NAN, _strength_for(1.2, 0.8, 11.0), 12.0,
                         _strength_for(0.9, 0.8, 11.0), NAN])
    reach = laser_reach_m(column_bin, rng, strength, 5.0, 2.0, 6, params)
    # bins 0, 1: the strongest on the upper side is bin 1's 1.2 m (nothing below bin 0);
    # bins 2-4: 1.2 m on the lower side, 0.9 m on the upper; bin 5, at the edge of the
    # view: only the lower side, whose strongest is bin 1's 1.2 m
    np.testing.assert_allclose(reach, [1.2, 1.2, 0.9, 0.9, 0.9, 1.2])
    # a gentler fall-off (range^-2) credits the same columns with more reach
    gentle = laser_reach_m(column_bin, rng, strength, 5.0, 2.0, 6,
                           FusionParams(falloff_exponent=2.0))
    np.testing.assert_allclose(gentle[[0, 3]], [0.8 * 1.5 ** 2, 0.8 * (0.9 / 0.8) ** 2])
    # no stripe column: nothing certified anywhere
    none = laser_reach_m(np.full(5, -1), np.full(5, NAN), np.full(5, NAN), 5.0, 2.0, 6, params)
    assert np.isnan(none).all()


def test_reach_parameters_are_checked():
    with pytest.raises(SlitcliError, match="falloff_exponent"):
        FusionParams(falloff_exponent=0.0)
    with pytest.raises(SlitcliError, match="certain_z"):
        FusionParams(certain_z=-1.0)


def _stripe_and_disparity(rng, pieces):
    """Stripe rows on the paper rig's laser plane and a disparity image whose values
    in the stripe's row and two rows either side are the plane's disparity times each
    piece's ratio, with 0.1 px of noise (NaN: stereo sees nothing there; NaN
    elsewhere); ``pieces`` is a list of (first column, last column, ratio)."""
    from slitcli.rig import paper_rig

    rig = paper_rig()
    w, h = rig.image_size_px
    v = np.full(w, np.nan)
    disp = np.full((h, w), np.nan, np.float32)
    for c0, c1, ratio in pieces:
        cols = np.arange(c0, c1 + 1)
        row = float(rng.uniform(150.0, 200.0))
        v[cols] = row + 0.02 * (cols - c0)
        z = rig.intersect_laser_plane(rig.pixel_rays_cam(cols, v[cols]))[:, 2]
        d = rig.left.fx_px * rig.baseline_m / z
        for k in range(-2, 3):
            disp[np.rint(v[cols]).astype(int) + k, cols] = d * ratio + rng.normal(0, 0.1,
                                                                                   cols.size)
    return rig, v, disp


@pytest.mark.parametrize("seed", range(4))
def test_stripe_depth_check_drops_light_on_farther_surfaces(seed):
    # the paper rig's stripe at rows 150-200 lies at 10-30 px of disparity: a piece on
    # a surface 10 % farther than the plane (floor texture below the sheet) is 1-3 px
    # off and dropped; a piece on the plane, one stereo sees nearer (a foreground's
    # disparity spread past its edge), one stereo cannot see and the longest piece stay
    from slitcli.laser.choose import stripe_pieces

    rng = np.random.default_rng(seed)
    rig, v, disp = _stripe_and_disparity(rng, [(10, 99, 0.9), (120, 139, 1.0),
                                               (160, 175, 0.9), (200, 215, 1.25),
                                               (240, 255, np.nan), (280, 289, 0.9)])
    cols, piece = stripe_pieces(v, 2, 3.0)
    keep = stripe_depth_agrees(v, disp, rig, cols, piece, FusionParams())
    assert keep[10:100].all()                     # the longest piece
    assert keep[120:140].all() and keep[200:216].all() and keep[240:256].all()
    assert not keep[160:176].any() and not keep[280:290].any()
    assert not keep[np.isnan(v)].any()
    # within the tolerances (5 % and 0.5 px) a piece stays: a rig whose stereo and laser
    # plane disagree by a few per cent loses nothing
    rig, v, disp = _stripe_and_disparity(rng, [(10, 99, 1.0), (160, 175, 0.97)])
    cols, piece = stripe_pieces(v, 2, 3.0)
    assert stripe_depth_agrees(v, disp, rig, cols, piece, FusionParams())[160:176].all()
    # too few columns that stereo sees: nothing to judge
    rig, v2, disp2 = _stripe_and_disparity(rng, [(10, 99, 1.0), (160, 175, 0.8)])
    disp2[:, 162:176] = np.nan
    cols, piece = stripe_pieces(v2, 2, 3.0)
    assert stripe_depth_agrees(v2, disp2, rig, cols, piece, FusionParams())[160:176].all()


def test_stripe_depth_check_parameters_are_checked():
    for bad in ({"depth_share": 0.0}, {"depth_share": 1.0}, {"depth_px": -1.0},
                {"depth_columns": 0}):
        with pytest.raises(SlitcliError):
            FusionParams(**bad)


def test_laser_silence_about_an_obstacle_at_the_sheet_is_not_trusted():
    # bins 0 and 1: stereo sees obstacles at 0.93 m the laser is silent about; bin 0's
    # reaches down to the sheet (stereo_at_sheet): its range stands, bin 1's is moved out
    laser, stereo = np.array([NAN, NAN, NAN]), np.array([0.93, 0.93, NAN])
    at = np.array([True, False, False])
    f = fuse(laser, stereo, np.ones(3, bool), FusionParams(), stereo_at_sheet=at)
    np.testing.assert_allclose(f.range_m, [0.93, 1.0, NAN], equal_nan=True)
    # conservative fusion keeps the nearer return anyway
    c = fuse(laser, stereo, np.ones(3, bool), FusionParams(mode="conservative"),
             stereo_at_sheet=at)
    np.testing.assert_allclose(c.range_m, [0.93, 0.93, NAN], equal_nan=True)


def _standing_and_overhang(rng: np.random.Generator):
    """Stereo points (H, W, 3) and obstacle mask of two obstacles, both 0.9 m ahead
    with their near faces 0.8-1.2 deg wide: in bins -10 .. -8 a box standing on the
    floor (points from 6 cm up), in bins 8 .. 10 a slab whose underside is 25 cm up;
    behind each, 2 m away, a wall reaching down to the floor (farther than the bins'
    nearest surface)."""
    h, w = 40, 60
    pts = np.zeros((h, w, 3), np.float32)
    mask = np.zeros((h, w), bool)
    for c, (bearing, z0) in enumerate([(-9.0, 0.06), (9.0, 0.25)]):
        b = np.radians(bearing + rng.uniform(-1.2, 1.2, (20, 20)))
        r = 0.9 + rng.normal(0.0, 0.004, (20, 20))
        z = z0 + np.linspace(0.0, 0.3, 20)[:, None] + rng.normal(0.0, 0.003, (20, 20))
        block = np.stack([r * np.cos(b), r * np.sin(b), z], axis=-1)
        pts[:20, c * 30:c * 30 + 20] = block
        mask[:20, c * 30:c * 30 + 20] = True
        wall_z = np.broadcast_to(np.linspace(0.0, 0.3, 20)[:, None], b.shape)
        wall = np.stack([2.0 * np.cos(b), 2.0 * np.sin(b), wall_z], axis=-1)
        pts[20:, c * 30:c * 30 + 20] = wall
        mask[20:, c * 30:c * 30 + 20] = True
    return pts, mask


@pytest.mark.parametrize("seed", range(4))
def test_stereo_reaches_sheet_tells_standing_from_overhanging(seed):
    from slitcli.ranges import BearingBins
    from slitcli.rig import paper_rig

    rig = paper_rig()
    n, d = rig.laser_plane_sensor()
    sheet_z = d / n[2]  # the sheet's height in front of the paper rig (5 cm, level)
    assert abs(sheet_z - 0.05) < 1e-9
    pts, mask = _standing_and_overhang(np.random.default_rng(seed))
    bins = BearingBins.for_rig(rig, 1.0)
    stereo = np.full(len(bins), np.nan)
    k = bins.index(np.array([-10.0, -9.0, -8.0, 8.0, 9.0, 10.0]))
    stereo[k] = 0.9
    at = stereo_reaches_sheet(pts, mask, bins.index, stereo, rig, FusionParams())
    # the standing box's bins reach the sheet, the slab's and the empty ones do not (the
    # wall behind the slab reaches the floor, but it is not the bin's nearest surface)
    assert at[k[:3]].all() and not at[k[3:]].any()
    assert at.sum() == 3
    # the standing box lifted 10 cm off the floor (a cart's shelf): out of the sheet
    lifted = pts.copy()
    lifted[:20, :20, 2] += 0.10
    assert not stereo_reaches_sheet(lifted, mask, bins.index, stereo, rig,
                                    FusionParams()).any()


def test_sheet_check_parameters_are_checked():
    for bad in ({"sheet_tolerance_m": 0.0}, {"sheet_near_share": -0.1}, {"sheet_min_px": 0}):
        with pytest.raises(SlitcliError):
            FusionParams(**bad)
