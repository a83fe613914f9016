"""Rig file and geometry against the hand-derived numbers of DESIGN §2."""

import math
from dataclasses import replace

import numpy as np
import pytest
import yaml

from slitcli.errors import SlitcliError
from slitcli.rig import describe_rig, load_rig, paper_rig, rig_from_dict, save_rig


def test_paper_rig_derived_numbers():
    d = describe_rig(paper_rig())
    assert d["stripe_row_wall_1.0m_px"] == pytest.approx(167.93, abs=0.005)
    assert d["stripe_row_wall_0.8m_px"] == pytest.approx(195.31, abs=0.005)
    assert d["stripe_row_wall_0.6m_px"] == pytest.approx(236.08, abs=0.005)
    assert d["disparity_at_1m_px"] == pytest.approx(22.0)
    assert d["disparity_at_3m_px"] == pytest.approx(7.3333, abs=1e-4)
    assert d["hfov_deg"] == pytest.approx(2 * math.degrees(math.atan(160 / 250)))


def test_worked_laser_check_from_design():
    # pixel (159.5, 167.93) -> ray (0, 0.1937, 1) -> X = (0, 0.2218, 1.1449) -> range 1.000 m.
    # DESIGN §2 prints z = 1.1452; by hand z = 0.60 / (0.9397 * 0.19372 + 0.3420) = 1.14491,
    # and only that value gives the stated 1.000 m forward range.
    rig = paper_rig()
    ray = rig.pixel_rays_cam(159.5, 167.93)
    assert ray == pytest.approx([0.0, 0.19372, 1.0], abs=1e-5)
    x_cam = rig.intersect_laser_plane(ray)
    assert x_cam == pytest.approx([0.0, 0.2218, 1.1449], abs=1e-4)
    x_sensor = rig.cam_to_sensor(x_cam)
    assert x_sensor[0] == pytest.approx(1.0, abs=2e-4)
    assert x_sensor[2] == pytest.approx(0.05, abs=1e-9)  # laser sheet 5 cm above the floor


def test_closed_form_tilted_range_matches_ray_plane():
    # DESIGN §4: Z = H / tan(theta + atan((v - cy) / f)) for the horizontal sheet
    rig = paper_rig()
    v = np.linspace(125.0, 239.0, 40)
    pts = rig.cam_to_sensor(rig.intersect_laser_plane(rig.pixel_rays_cam(rig.left.cx_px, v)))
    expect = 0.6 / np.tan(math.radians(20) + np.arctan((v - 119.5) / 250.0))
    np.testing.assert_allclose(pts[:, 0], expect, atol=1e-12)


@pytest.mark.parametrize("seed", range(5))
def test_sensor_camera_frames_round_trip_and_axes(seed):
    rig = paper_rig()
    p = np.random.default_rng(seed).normal(size=(50, 3))
    np.testing.assert_allclose(rig.sensor_to_cam(rig.cam_to_sensor(p)), p, atol=1e-12)
    axis = rig.R_sensor_from_cam @ np.array([0.0, 0.0, 1.0])
    t = math.radians(20)
    np.testing.assert_allclose(axis, [math.cos(t), 0.0, -math.sin(t)], atol=1e-12)
    right = rig.R_sensor_from_cam @ np.array([1.0, 0.0, 0.0])
    np.testing.assert_allclose(right, [0.0, -1.0, 0.0], atol=1e-12)  # image right = sensor -y


def test_disparity_depth_inverse():
    rig = paper_rig()
    assert rig.depth_from_disparity(22.0) == pytest.approx(1.0)
    assert np.isnan(rig.depth_from_disparity(0.0))
    z = np.array([0.5, 1.0, 3.0])
    np.testing.assert_allclose(rig.depth_from_disparity(rig.disparity_from_depth(z)), z)


def test_yaml_round_trip_is_lossless(tmp_path):
    rig = paper_rig()
    raw = dict(
        image_size_px=(640, 480), K1=((500.1, 0.0, 320.3), (0.0, 501.7, 240.9), (0.0, 0.0, 1.0)),
        D1=(-0.1, 0.01, 1e-4, -2e-4, 0.0), K2=((499.9, 0.0, 318.2), (0.0, 500.2, 241.1),
                                               (0.0, 0.0, 1.0)),
        D2=(-0.09, 0.012, 0.0, 0.0, 0.0), R=tuple(map(tuple, np.eye(3))), T=(-0.088, 1e-4, 2e-4),
        R1=tuple(map(tuple, np.eye(3))), R2=tuple(map(tuple, np.eye(3))),
        P1=((250.0, 0.0, 159.5, 0.0), (0.0, 250.0, 119.5, 0.0), (0.0, 0.0, 1.0, 0.0)),
        P2=((250.0, 0.0, 159.5, -22.0), (0.0, 250.0, 119.5, 0.0), (0.0, 0.0, 1.0, 0.0)),
    )
    from slitcli.rig import RawCalibration

    rig = replace(rig, raw=RawCalibration(**raw),
                  mount=replace(rig.mount, roll_deg=1.2345678901234, forward_m=0.1))
    save_rig(rig, tmp_path / "rig.yaml")
    assert load_rig(tmp_path / "rig.yaml") == rig


BAD_CASES = [
    (lambda d: d.update(slitcli_rig=2), "slitcli_rig"),
    (lambda d: d["left"].update(fx_px=0.0), "left.fx_px"),
    (lambda d: d["mount"].update(tilt_deg=90.0), "mount.tilt_deg"),
    (lambda d: d.update(image_size_px=[-320, 240]), "image_size_px"),
    (lambda d: d.update(baseline_m=-0.088), "baseline_m"),
    (lambda d: d["laser"].update(normal=[0.0, 2.0, 0.0]), "laser.normal"),
    (lambda d: d["mount"].update(tilt=20.0), "mount.tilt"),
    (lambda d: d.pop("baseline_m"), "baseline_m"),
    (lambda d: d["left"].update(fx_px="wide"), "left.fx_px"),
]


@pytest.mark.parametrize("mutate,key", BAD_CASES)
def test_bad_rig_names_the_key(mutate, key):
    d = paper_rig().to_dict()
    mutate(d)
    with pytest.raises(SlitcliError) as e:
        rig_from_dict(d, source="bad.yaml")
    msg = str(e.value)
    assert "bad.yaml" in msg and key in msg and "\n" not in msg


def test_malformed_yaml_is_an_input_error(tmp_path):
    p = tmp_path / "rig.yaml"
    p.write_text("slitcli_rig: [1\n")
    with pytest.raises(SlitcliError, match="not valid YAML"):
        load_rig(p)
    p.write_text(yaml.safe_dump([1, 2]))
    with pytest.raises(SlitcliError, match="must be a mapping"):
        load_rig(p)


def test_bearing_bins_by_hand():
    # paper rig: cx = 159.5 of 320 columns, f = 250 px -> outer column edges at
    # +-atan(160 / 250) = +-32.62 deg; a bin is kept when its centre lies inside
    rig = paper_rig()
    right, left = rig.bearing_limits_deg()
    assert left == pytest.approx(math.degrees(math.atan(160 / 250)))
    assert right == pytest.approx(-left)
    for width, first, count in ((1.0, -32.0, 65), (2.0, -32.0, 33), (5.0, -30.0, 13)):
        centres, lo, hi = rig.bearing_bins(width)
        assert centres[0] == first and centres.size == count
        np.testing.assert_allclose(np.diff(centres), width)
        np.testing.assert_allclose(hi - lo, width)
        np.testing.assert_allclose((lo + hi) / 2, centres)
    for width in (0.0, -1.0, 1e-6, 11.0, float("nan")):
        with pytest.raises(SlitcliError, match="bin_deg"):
            rig.bearing_bins(width)
