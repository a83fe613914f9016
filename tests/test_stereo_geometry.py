"""Distance image (Eq. 8), obstacle mask, ranges per bearing and raw rectification."""

from __future__ import annotations

import math
from dataclasses import replace

import cv2
import numpy as np
import pytest
from stereo_synth import texture

from slitcli.calibrate.rectify import RectificationMaps, rectify_pair
from slitcli.errors import SlitcliError
from slitcli.rig import RawCalibration, paper_rig
from slitcli.stereo.geometry import StereoGeometry
from slitcli.stereo.obstacles import (
    ObstacleParams,
    bearing_ranges,
    depth_from_disparity,
    floor_check,
    obstacle_points,
    trim_silhouettes,
)


def geo(rig):
    """The rig's stereo geometry with 1-degree bins."""
    return StereoGeometry.for_rig(rig)


def wall_and_floor_disparity(rig, wall_x_m: float) -> tuple[np.ndarray, np.ndarray]:
    """True disparity of a floor plus a wall ``wall_x_m`` ahead (sensor x), and its mask.

    Each pixel's ray (sensor frame, from the camera at height h) meets the floor
    z = 0 at s = h / -r_z and the wall x = wall_x_m at s = wall_x_m / r_x; the nearer
    hit is what the camera sees. Depth along the optical axis is s (rays have z_cam = 1).
    """
    w, h = rig.image_size_px
    rays = rig.pixel_rays_cam(np.arange(w)[None, :], np.arange(h)[:, None])
    rs = rays @ rig.R_sensor_from_cam.T
    with np.errstate(divide="ignore"):
        s_floor = np.where(rs[..., 2] < 0, rig.mount.height_m / -rs[..., 2], np.inf)
        s_wall = np.where(rs[..., 0] > 0, wall_x_m / rs[..., 0], np.inf)
    s = np.minimum(s_floor, s_wall)
    return rig.baseline_m * rig.focal_px / s, s_wall < s_floor


def test_depth_is_eq8():
    rig = paper_rig()
    d = np.array([[22.0, 7.3333333, np.nan, 0.0, -1.0]], dtype=np.float32)
    depth = depth_from_disparity(d, rig)
    np.testing.assert_allclose(depth[0, :2], [1.0, 3.0], rtol=1e-6)
    assert np.isnan(depth[0, 2:]).all()


def test_wall_ranges_mask_and_floor():
    rig = paper_rig()
    wall = 1.5
    disp, sees_wall = wall_and_floor_disparity(rig, wall)
    params = ObstacleParams()
    depth, pts, obstacle, feature = obstacle_points(disp.astype(np.float32), geo(rig), params)
    # reprojection is exact: wall points at x = 1.5 m, floor points at z = 0
    np.testing.assert_allclose(pts[sees_wall][:, 0], wall, atol=1e-4)
    np.testing.assert_allclose(pts[~sees_wall][:, 2], 0.0, atol=1e-4)
    z = pts[..., 2]
    # floor test of the module notes: z < margin + 2 sigma_d |r_z| D^2 / (f W)
    w, h = rig.image_size_px
    rays = rig.pixel_rays_cam(np.arange(w)[None, :], np.arange(h)[:, None])
    r_z = np.abs((rays @ rig.R_sensor_from_cam.T)[..., 2])
    floor_z = params.floor_margin_m + 2 * 0.25 * r_z * depth**2 / (250.0 * 0.088)
    expect = sees_wall & (z >= floor_z + 1e-4) & (z < params.robot_height_m - 1e-4)
    assert (obstacle == expect)[np.abs(z - floor_z) > 1e-4].all()
    assert expect.sum() > 10000
    assert not obstacle[~sees_wall].any()           # the floor is never an obstacle
    assert not obstacle[sees_wall & (z > params.robot_height_m)].any()
    br = bearing_ranges(pts, obstacle, feature, geo(rig), params)
    np.testing.assert_array_equal(br.bearing_deg, np.arange(-32, 33))
    # nearest wall point in the bin [b - 0.5, b + 0.5]: 1.5 / cos of the bin edge
    # nearer to 0; the 10th percentile of the bin's points lies within 1 cm above it
    # (read from 2 mm histogram cells: exact to 1 mm)
    edge = np.maximum(np.abs(br.bearing_deg) - 0.5, 0.0)
    nearest = wall / np.cos(np.radians(edge))
    inner = np.abs(br.bearing_deg) <= 31
    assert np.isfinite(br.range_m[inner]).all()
    assert (br.range_m[inner] >= nearest[inner] - 0.001).all()
    assert (br.range_m[inner] <= nearest[inner] + 0.01).all()
    assert br.has_features[inner].all()


def test_points_beyond_range_or_without_enough_pixels_are_no_return():
    rig = paper_rig()
    disp, _ = wall_and_floor_disparity(rig, 3.5)  # beyond the rig's 3 m stereo range
    _depth, pts, obstacle, feature = obstacle_points(disp.astype(np.float32), geo(rig),
                                                    ObstacleParams())
    assert not obstacle.any()
    br = bearing_ranges(pts, obstacle, feature, geo(rig), ObstacleParams())
    assert np.isnan(br.range_m).all()
    assert br.has_features[np.abs(br.bearing_deg) <= 31].all()  # the far wall is seen
    # a handful of stray pixels cannot make an obstacle (min_obstacle_px = 8)
    disp2 = np.full(disp.shape, np.nan, np.float32)
    disp2[100:102, 150:153] = 22.0
    _, pts2, obs2, feat2 = obstacle_points(disp2, geo(rig), ObstacleParams())
    assert obs2.sum() == 6
    br2 = bearing_ranges(pts2, obs2, feat2, geo(rig), ObstacleParams())
    assert np.isnan(br2.range_m).all()
    assert not br2.has_features.any()


def _one_bin_points(ranges_m: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Obstacle points with the given horizontal ranges on pixels of the 0 deg bin
    (column 159 of the paper rig, straight ahead), their masks."""
    h, w = 240, 320
    pts = np.full((h, w, 3), np.nan, np.float32)
    mask = np.zeros((h, w), bool)
    rows = np.arange(ranges_m.size) + 60
    pts[rows, 159, 0] = ranges_m
    pts[rows, 159, 1] = 0.0
    pts[rows, 159, 2] = 0.3
    mask[rows, 159] = True
    return pts, mask, mask.copy()


def test_a_partial_near_object_is_ranged_from_its_own_points():
    # One bin: a face seen at a grazing angle (15 points evenly over 1.35-1.50 m) in
    # front of a wall at 2.9 m (85 points). The bin's 10th percentile (rank 9 of 100)
    # lands on the face, but 9 face points deep: 1.35 + 9 x 0.15 / 14 = 1.446 m. The
    # face's own 10th percentile (rank 1 of 15) is 1.35 + 0.15 / 14 = 1.361 m.
    rig = paper_rig()
    cell = 0.001 + 1e-9   # read from 2 mm histogram cells: exact to half a cell
    face = 1.35 + np.arange(15) * 0.15 / 14
    ranges = np.r_[face, np.full(85, 2.9)]
    pts, obstacle, feature = _one_bin_points(ranges)
    k = 32   # the 0 deg bin of -32..32
    br = bearing_ranges(pts, obstacle, feature, geo(rig), ObstacleParams())
    assert br.obstacle_px[k] == 100
    assert abs(br.range_m[k] - face[1]) <= cell
    # without the surface split, the plain percentile of the bin (the old rule)
    plain = bearing_ranges(pts, obstacle, feature, geo(rig), ObstacleParams(surface_gap_px=0.0))
    assert abs(plain.range_m[k] - face[9]) <= cell
    # a near object below the percentile's share (8 of 100 points) is still outvoted:
    # the split never admits points the plain percentile would not reach
    pts2, obs2, feat2 = _one_bin_points(np.r_[face[:8], np.full(92, 2.9)])
    br2 = bearing_ranges(pts2, obs2, feat2, geo(rig), ObstacleParams())
    assert abs(br2.range_m[k] - 2.9) <= cell
    # a surface that only steps by less than the gap is one surface: ranges 2.0-2.9 m
    # in 0.05 m steps (disparity steps of 0.13-0.27 px) give the plain percentile
    ramp = np.repeat(np.arange(2.0, 2.91, 0.05), 5)
    pts3, obs3, feat3 = _one_bin_points(ramp)
    one = bearing_ranges(pts3, obs3, feat3, geo(rig), ObstacleParams())
    ref = bearing_ranges(pts3, obs3, feat3, geo(rig), ObstacleParams(surface_gap_px=0.0))
    assert one.range_m[k] == ref.range_m[k]
    with pytest.raises(SlitcliError, match="surface gap"):
        ObstacleParams(surface_gap_px=-1.0)


@pytest.mark.parametrize("seed", [0, 1, 2, 3, 4])
def test_floor_pixels_given_an_objects_disparity_are_floor(seed):
    # A hand-made rectified pair: the right image a random texture, the left image the
    # floor seen through the rig (each left pixel is the right image at the floor's
    # disparity, Eq. 8 on the floor plane), except an object over columns 150-169,
    # rows 140-199 at 20 px. The matcher's fattening is mimicked by marking 4 more
    # columns (170-173) with the object's disparity: they see floor.
    rig = paper_rig()
    w, h = rig.image_size_px
    rng = np.random.default_rng(seed)
    right = cv2.GaussianBlur(rng.uniform(0, 255, (h, w)), (0, 0), 1.0)
    dfl = StereoGeometry.for_rig(rig).floor_disparity_px.astype(np.float64)
    # the floor's disparity is Eq. 8 at the depth where the pixel's ray meets the floor
    rays = rig.pixel_rays_cam(np.array([160.0]), np.array([200.0]))[0]
    rz = (rays @ rig.R_sensor_from_cam.T)[2]
    assert dfl[200, 160] == pytest.approx(250.0 * 0.088 * -rz / 0.65, rel=1e-5)
    assert (dfl[:28] == 0).all() and (dfl[30:] > 0).all()   # the horizon at row 28.5
    disp = np.where(dfl > 0, dfl, np.nan)
    disp[140:200, 150:170] = 20.0
    xs = np.arange(w)[None, :] - np.nan_to_num(disp)
    left = np.stack([np.interp(xs[y], np.arange(w), right[y]) for y in range(h)])
    disp[140:200, 170:174] = 20.0            # fattening: floor pixels at the object's disparity
    mask = np.zeros((h, w), bool)
    mask[140:200, 150:174] = True
    out = floor_check(mask, left, right, disp, geo(rig), ObstacleParams(floor_check_ratio=0.5))
    # the object is kept wherever its 5-row column lies on it (its top and bottom 2 rows
    # straddle the floor: either hypothesis may win there)
    assert out[142:198, 150:170].all()
    # the fattened floor columns are floor where the floor lies at least 1 px
    # (floor_check_min_px) farther than the object; nearer its foot the floor test decides
    rows = np.arange(142, 198)
    far = rows[dfl[rows, 171] <= 19.0]
    assert far.size >= 30
    assert not out[far][:, 170:174].any()
    assert mask[140:200, 150:174].all()      # input not modified
    off = floor_check(mask, left, right, disp, geo(rig), ObstacleParams())  # off by default
    assert (off == mask).all()
    with pytest.raises(SlitcliError, match="floor check"):
        ObstacleParams(floor_check_half_px=-1)


def test_obstacle_runs_are_cut_back_to_the_silhouette_on_plain_backgrounds():
    # One row, hand-made: a textured object over columns 10..19 (grey alternating 60/140),
    # a plain background (100 DN) elsewhere. The matcher has carried the object's
    # disparity 3 px past each silhouette (columns 7..22 obstacle); beyond, no disparity.
    grey = np.full((1, 40), 100.0)
    grey[0, 10:20] = np.where(np.arange(10) % 2, 140.0, 60.0)
    disp = np.full((1, 40), np.nan)
    disp[0, 7:23] = 20.0
    mask = np.zeros((1, 40), bool)
    mask[0, 7:23] = True
    out = trim_silhouettes(mask, grey, disp, ObstacleParams())
    assert np.array_equal(np.flatnonzero(out[0]), np.arange(10, 20))
    assert mask[0, 7:23].all()  # input not modified
    # a disparity beside the run (a matched background) leaves that end alone
    disp2 = disp.copy()
    disp2[0, 23] = 5.0
    out = trim_silhouettes(mask, grey, disp2, ObstacleParams())
    assert np.array_equal(np.flatnonzero(out[0]), np.arange(10, 23))
    # a fattening wider than the reach keeps the run: its edge is not within reach
    out = trim_silhouettes(mask, grey, disp, ObstacleParams(silhouette_reach_px=2))
    assert out[0, 7:23].all()
    # steps must exceed silhouette_step_dn: at 90 DN none does (40 DN silhouettes, 80 DN
    # texture), so no edge is seen and the run is kept
    out = trim_silhouettes(mask, grey, disp, ObstacleParams(silhouette_step_dn=90.0))
    assert out[0, 7:23].all()
    # a run that reaches the image border is kept at that end
    mask3 = np.zeros((1, 40), bool)
    mask3[0, :23] = True
    disp3 = np.where(mask3, 20.0, np.nan)
    out = trim_silhouettes(mask3, grey, disp3, ObstacleParams())
    assert np.array_equal(np.flatnonzero(out[0]), np.arange(0, 20))
    # off
    out = trim_silhouettes(mask, grey, disp, ObstacleParams(silhouette_reach_px=0))
    assert np.array_equal(out, mask)


@pytest.mark.parametrize("seed", [0, 1, 2, 3, 4])
def test_floor_test_allows_for_disparity_noise(seed):
    rig = paper_rig()
    disp, sees_wall = wall_and_floor_disparity(rig, 2.9)
    noisy = disp + np.random.default_rng(seed).normal(0.0, 0.25, disp.shape)
    _, _pts, obstacle, _ = obstacle_points(noisy.astype(np.float32), geo(rig), ObstacleParams())
    # 0.25 px of disparity noise lifts far floor points by centimetres; the test widens
    # its margin with depth, so almost no floor pixel becomes an obstacle
    assert obstacle[~sees_wall].mean() <= 0.01


@pytest.mark.parametrize("bin_deg", [0.5, 1.0, 2.0])
def test_stereo_pixels_use_the_one_bin_rule(bin_deg):
    # every pixel's bin is slitcli.ranges' floor(b / w + 1/2): a bearing on a boundary
    # goes to the larger-bearing bin, as for the laser and the truth
    from slitcli.ranges import BearingBins

    rig = paper_rig()
    g = StereoGeometry.for_rig(rig, bin_deg)
    bins = BearingBins.for_rig(rig, bin_deg)
    np.testing.assert_array_equal(g.pixel_bin, bins.index(g.bearing_deg))
    np.testing.assert_array_equal(g.bins.centres_deg, bins.centres_deg)
    # the pixel nearest a boundary on each side of it lands in the bins on either side,
    # and an obstacle placed on a pixel is counted in that pixel's bin
    b = g.bearing_deg.astype(np.float64)
    edge = (bins.first + 3 + 0.5) * bin_deg
    row = 120
    left_of = np.flatnonzero(b[row] >= edge)
    right_of = np.flatnonzero(b[row] < edge)
    u_in, u_out = left_of.max(), right_of.min()
    assert g.pixel_bin[row, u_in] == 4 and g.pixel_bin[row, u_out] == 3
    pts = np.full((*g.bearing_deg.shape, 3), np.nan, np.float32)
    mask = np.zeros(g.bearing_deg.shape, bool)
    rows = np.arange(60, 80)
    mask[rows, u_in] = True
    pts[rows, u_in] = [1.0, 0.0, 0.3]
    p = ObstacleParams(bin_width_deg=bin_deg)
    br = bearing_ranges(pts, mask, mask, g, p)
    assert br.obstacle_px[4] == rows.size - (g.pixel_bin[rows, u_in] != 4).sum()
    assert br.obstacle_px.sum() == rows.size
    with pytest.raises(SlitcliError, match="another rig or bin width"):
        bearing_ranges(pts, mask, mask, g, ObstacleParams(bin_width_deg=bin_deg * 2))


# ------------------------------------------------------------------ rectification
def raw_rig_with_distortion():
    """Paper rig whose raw cameras have radial distortion and a slight relative yaw."""
    rig = paper_rig()
    size = rig.image_size_px
    k = rig.left.K
    dist = np.array([-0.12, 0.03, 0.0005, -0.0004, 0.0])
    yaw = math.radians(0.8)
    r = np.array([[math.cos(yaw), 0, math.sin(yaw)], [0, 1, 0], [-math.sin(yaw), 0,
                                                                  math.cos(yaw)]])
    t = np.array([-rig.baseline_m, 0.0, 0.0])
    r1, r2, p1, p2, *_ = cv2.stereoRectify(k, dist, k, dist, size, r, t.reshape(3, 1), alpha=0,
                                           flags=cv2.CALIB_ZERO_DISPARITY)

    def freeze(a):
        a = np.asarray(a, float)
        return tuple(map(freeze, a)) if a.ndim > 1 else tuple(float(v) for v in a)

    raw = RawCalibration(image_size_px=size, K1=freeze(k), D1=freeze(dist), K2=freeze(k),
                         D2=freeze(dist), R=freeze(r), T=freeze(t), R1=freeze(r1),
                         R2=freeze(r2), P1=freeze(p1), P2=freeze(p2))
    return replace(rig, raw=raw), k, dist, r1, p1


@pytest.mark.parametrize("seed", [0, 1, 2, 3, 4])
def test_raw_images_are_rectified_with_the_rig_calibration(seed):
    rig, k, dist, r1, p1 = raw_rig_with_distortion()
    w, h = rig.image_size_px
    # the raw left image of a texture that is fixed in the *rectified* left image:
    # raw pixel -> undistorted, rectified normalised coordinates -> rectified pixel
    u, v = np.meshgrid(np.arange(w, dtype=float), np.arange(h, dtype=float))
    raw_px = np.stack([u.ravel(), v.ravel()], axis=1)[:, None, :]
    rect = cv2.undistortPoints(raw_px, k, dist, R=r1, P=p1).reshape(h, w, 2)
    raw_left = np.clip(np.rint(texture(rect[..., 0], rect[..., 1], seed=seed)), 0,
                       255).astype(np.uint8)
    raw_bgr = cv2.cvtColor(raw_left, cv2.COLOR_GRAY2BGR)
    left_rect, _ = rectify_pair(rig, raw_bgr, raw_bgr)
    truth = texture(u, v, seed=seed)
    err = np.abs(left_rect[..., 0].astype(float) - truth)[20:-20, 20:-20]
    # what is left is the bilinear resampling of a texture up to 0.22 cycles/px
    assert np.median(err) <= 2.5
    # without rectification the same comparison is far off (the test can fail)
    assert np.median(np.abs(raw_left.astype(float) - truth)[20:-20, 20:-20]) > 5.0
    # geometry of the tables: rectified pixel -> raw pixel (fixed point, 1/32 px) ->
    # back through the calibration lands on the same rectified pixel
    maps = RectificationMaps.for_rig(rig)
    ys, xs = np.mgrid[10:h - 10:23, 10:w - 10:29]
    m1, m2 = maps.left_map1[ys, xs].astype(float), maps.left_map2[ys, xs].astype(int)
    raw_x = m1[..., 0] + (m2 & 31) / 32.0
    raw_y = m1[..., 1] + (m2 >> 5) / 32.0
    back = cv2.undistortPoints(np.stack([raw_x, raw_y], -1).reshape(-1, 1, 2), k, dist,
                               R=r1, P=p1).reshape((*raw_x.shape, 2))
    assert np.abs(back[..., 0] - xs).max() <= 0.05
    assert np.abs(back[..., 1] - ys).max() <= 0.05
    # built once per rig with its stereo geometry, and read-only
    geo = StereoGeometry.for_rig(rig)
    assert geo.rectification is not None and not geo.rectification.left_map1.flags.writeable
    np.testing.assert_array_equal(geo.rectification.left_map1, maps.left_map1)
    again, _ = rectify_pair(rig, raw_bgr, maps=geo.rectification)
    np.testing.assert_array_equal(again, left_rect)
    assert StereoGeometry.for_rig(paper_rig()).rectification is None


def test_rectify_checks_the_raw_size():
    rig, *_ = raw_rig_with_distortion()
    img = np.zeros((200, 300, 3), np.uint8)
    with pytest.raises(SlitcliError, match=r"raw\.image_size_px"):
        rectify_pair(rig, img, img)
    with pytest.raises(SlitcliError, match="image_size_px is 320x240"):
        rectify_pair(paper_rig(), img, img)
    with pytest.raises(SlitcliError, match="right image is 300x200"):
        rectify_pair(paper_rig(), np.zeros((240, 320), np.uint8), img)


@pytest.mark.parametrize("seed", [0, 1, 2, 3, 4])
def test_pipeline_rectifies_raw_pairs_before_matching(seed):
    from stereo_synth import plane_pair

    from slitcli.stereo.pipeline import process_stereo_pair

    rig = paper_rig()
    k = rig.left.K
    eye = np.eye(3)
    p1 = np.hstack([k, np.zeros((3, 1))])
    p2 = np.hstack([k, [[-rig.focal_px * rig.baseline_m], [0.0], [0.0]]])
    t = lambda a: tuple(map(tuple, np.asarray(a, float)))  # noqa: E731
    # raw images 20 px wider and taller than the rectified ones, same intrinsics with
    # the principal point shifted by (10, 10): rectification is a pure crop
    kr = k.copy()
    kr[:2, 2] += 10.0
    raw = RawCalibration(image_size_px=(340, 260), K1=t(kr), D1=(0.0,) * 5, K2=t(kr),
                         D2=(0.0,) * 5, R=t(eye), T=(-rig.baseline_m, 0.0, 0.0), R1=t(eye),
                         R2=t(eye), P1=t(p1), P2=t(p2))
    raw_rig = replace(rig, raw=raw)
    left, right = plane_pair(14.5, width=340, height=260, seed=seed)
    bgr = [cv2.cvtColor(a, cv2.COLOR_GRAY2BGR) for a in (left, right)]
    res = process_stereo_pair(bgr[0], bgr[1], raw_rig)
    assert res.disparity_px.shape == (240, 320)
    valid = np.isfinite(res.disparity_px)
    assert valid[:, 32:].mean() >= 0.95
    assert np.median(np.abs(res.disparity_px[valid] - 14.5)) <= 0.1
    with pytest.raises(SlitcliError, match=r"raw\.image_size_px is 340x260"):
        process_stereo_pair(bgr[0][:240, :320], bgr[1][:240, :320], raw_rig)


def test_pair_is_converted_to_grey_once(monkeypatch):
    """The matcher and the mask filters read one grey pair: two conversions per frame
    (left and right), not four; the result is that of the colour pair."""
    from stereo_synth import plane_pair

    from slitcli.stereo import cost
    from slitcli.stereo.pipeline import process_stereo_pair

    rig = paper_rig()
    # counts conversions and compares with the colour pair's result: an identity for any
    # pixels, so one seed suffices
    left, right = plane_pair(14.5, width=320, height=240)
    bgr = [cv2.cvtColor(a, cv2.COLOR_GRAY2BGR) for a in (left, right)]
    calls = []
    real = cost.cv2.cvtColor

    def counting(img, code, *a, **kw):
        if code == cv2.COLOR_BGR2GRAY:
            calls.append(img.shape)
        return real(img, code, *a, **kw)

    monkeypatch.setattr(cost.cv2, "cvtColor", counting)
    res = process_stereo_pair(bgr[0], bgr[1], rig)
    assert len(calls) == 2
    monkeypatch.undo()
    grey = process_stereo_pair(left, right, rig)
    np.testing.assert_array_equal(res.disparity_px, grey.disparity_px)
    np.testing.assert_array_equal(res.obstacle_mask, grey.obstacle_mask)


def test_pickled_geometry_stays_read_only():
    # `--jobs` workers receive the geometry by pickle, which returns writable arrays;
    # the geometry is shared by every frame and must stay unchangeable there too
    import pickle

    geo = StereoGeometry.for_rig(paper_rig())
    back = pickle.loads(pickle.dumps(geo))
    arrays = [v for v in vars(back).values() if isinstance(v, np.ndarray)]
    assert len(arrays) >= 5
    assert not any(a.flags.writeable for a in arrays)
    np.testing.assert_array_equal(back.pixel_bin, geo.pixel_bin)
