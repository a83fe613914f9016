"""`calibrate laser`: the laser plane from rendered board poses crossed by the stripe."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from click.testing import CliRunner

from slitcli.calibrate import laser_plane
from slitcli.calibrate.board import BoardSpec, find_corners
from slitcli.calibrate.board_pose import board_pose_left, board_pose_stereo
from slitcli.calibrate.laser_plane import (
    LaserPlaneParams,
    board_mask,
    board_pose_rectified,
    calibrate_laser_images,
    fit_plane_svd,
)
from slitcli.calibrate.rectify import rectify_pair, rig_with_raw
from slitcli.cli import cli
from slitcli.errors import SlitcliError
from slitcli.rig import load_rig, save_rig
from slitcli.sim.targets import (
    Chessboard,
    LaserSheet,
    TargetRenderer,
    demo_raw_calibration,
    random_board_poses,
    stereo_cameras,
    stripe_rows_on_board,
)

BOARD = Chessboard(7, 5, 0.04)
SPEC = BoardSpec(7, 5, 0.04)
TILT, ROLL = math.radians(20.0), math.radians(2.0)
# truth in the raw left camera frame: a sheet 0.6 m below the camera, pitched and rolled
LASER = LaserSheet(normal=(math.sin(ROLL) * math.cos(TILT), math.cos(ROLL) * math.cos(TILT),
                           math.sin(TILT)), offset_m=0.6)


#: the board-pose draws the scene is tested on (issue 18: >= 5 seeds)
SEEDS = (5, 6, 7, 8, 9)
#: required accuracy of the laser plane (issue 8): normal angle (deg), offset (m)
FLOOR_DEG, FLOOR_M = 0.3, 0.003


@pytest.fixture(scope="module")
def scenes():
    """Scenes by seed, rendered once per module: 5 board poses seen by both cameras,
    crossed by the stripe, with left and right raw images."""
    raw = demo_raw_calibration()
    rig = rig_with_raw(raw)
    lc, rc = stereo_cameras(raw)
    renderers = (TargetRenderer(lc), TargetRenderer(rc))
    made: dict[int, dict] = {}

    def get(seed: int) -> dict:
        if seed not in made:
            poses = random_board_poses((lc, rc), BOARD, 5, distance_m=(0.75, 1.5),
                                       max_angle_deg=25, laser=LASER, seed=seed)
            left, right = ([r.render_board(BOARD, p, laser=LASER, seed=100 * k + i)
                            for i, p in enumerate(poses)] for k, r in enumerate(renderers))
            made[seed] = {"rig": rig, "poses": poses, "images": left, "right": right,
                          "seed": seed}
        return made[seed]

    return get


@pytest.fixture(scope="module", params=SEEDS)
def scene(request, scenes):
    return scenes(request.param)


@pytest.fixture(scope="module")
def scene5(scenes):
    """One scene, for tests of plumbing whose outcome does not depend on the poses."""
    return scenes(5)


def red_centroid_rows(rectified_bgr: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Test stand-in for the laser module: per column, the centroid of the red excess
    ``r - max(g, b)`` around its peak (NaN where the peak is weak)."""
    img = rectified_bgr.astype(float)
    excess = np.where(mask, img[..., 2] - np.maximum(img[..., 0], img[..., 1]), 0.0)
    peak = excess.max(axis=0)
    w = np.where(excess >= 0.3 * peak[None, :], excess, 0.0)
    rows = np.arange(img.shape[0], dtype=float)[:, None]
    with np.errstate(invalid="ignore", divide="ignore"):
        v = (w * rows).sum(axis=0) / w.sum(axis=0)
    return np.where(peak > 12.0, v, np.nan)


def _angle_and_offset_error(result, rig) -> tuple[float, float]:
    n_raw = rig.raw.array("R1").T @ np.asarray(result.fit.normal)  # rig frame -> raw left
    ang = math.degrees(math.acos(min(1.0, float(n_raw @ LASER.unit_normal))))
    return ang, abs(result.fit.offset_m - LASER.unit_offset_m)


def _true_rows(scene, rng=None):
    """Extractor stand-in: the exact stripe rows of each pose, in view order; with
    ``rng``: + 0.3 px noise and 5 % wild rows (4-15 px off)."""
    rig = scene["rig"]
    truth = iter([stripe_rows_on_board(rig.left.K, rig.raw.array("R1"), rig.image_size_px,
                                       BOARD, p, LASER) for p in scene["poses"]])

    def rows(_img, _mask):
        v = next(truth)
        if rng is None:
            return v
        v = v + rng.normal(0.0, 0.3, v.shape)
        wild = rng.random(v.shape) < 0.05
        return np.where(wild, v + rng.uniform(4, 15, v.shape), v)

    return rows


@pytest.mark.parametrize("cameras", ["stereo", "left"])
def test_plane_from_true_stripe_rows_with_noise_and_outliers(scene, cameras):
    """The fit's own boundary: per-column rows = exact truth + 0.3 px noise + 5 % wild
    rows, so only the board poses (from the corners) and the fit remain. Bound: the
    issue-8 floors for board poses from both cameras. Left-only poses are documented as
    less accurate: their board-plane std is up to 2x the stereo one (the covariances of
    test_stereo_board_pose_against_truth_and_its_covariance), so 2x the floors."""
    rig = scene["rig"]
    rng = np.random.default_rng(scene["seed"])
    names = [f"p{i}" for i in range(len(scene["images"]))]
    right = scene["right"] if cameras == "stereo" else None
    res = calibrate_laser_images(names, scene["images"], rig, LaserPlaneParams(board=SPEC),
                                 right_images_bgr=right, extractor=_true_rows(scene, rng))
    assert all(v.pose == cameras for v in res.views)
    ang, off = _angle_and_offset_error(res, rig)
    widen = 1.0 if cameras == "stereo" else 2.0
    assert ang < widen * FLOOR_DEG and off < widen * FLOOR_M
    assert res.fit.inliers < res.fit.points  # the wild rows were rejected
    assert res.fit.residual_std_m < 0.002


def test_stereo_board_pose_against_truth_and_its_covariance(scene):
    """Each view's board plane from both cameras, against the true pose.

    Derived bound: the pose's Gauss-Newton covariance (corner noise alone) gives the
    per-axis std ``s_a`` of the board normal and ``s_d`` of the plane at the board
    centre. For white corner noise the normal's error (2 dof) exceeds ``3.4 s_a`` with
    probability 0.3 % and the offset exceeds ``3 s_d`` with 0.3 %; corner detection also
    has a bias (measured: 0.02-0.05 px, a scale of up to 0.1 %), allowed for with twice
    those bounds. And a second camera only adds information: the covariance of the
    stereo pose is below that of the left camera's alone.
    """
    rig = scene["rig"]
    R1 = rig.raw.array("R1")
    for img, right, pose in zip(scene["images"], scene["right"], scene["poses"], strict=True):
        cl, cr = find_corners(img, SPEC), find_corners(right, SPEC)
        est = board_pose_stereo(cl, cr, rig, SPEC)
        mono = board_pose_left(cl, rig, SPEC)
        assert est is not None and est.cameras == 2
        R_true, t_true = R1 @ pose.R, R1 @ pose.t
        centre = R_true @ BOARD.centre_board_xyz + t_true
        s_a, s_d = est.plane_std(centre)
        ang = math.acos(min(1.0, abs(float(est.R[:, 2] @ R_true[:, 2]))))
        assert ang < 2 * 3.4 * s_a
        assert abs(float((centre - est.t_m) @ est.R[:, 2])) < 2 * 3 * s_d
        m_a, m_d = mono.plane_std(centre)
        assert s_a < m_a and s_d < m_d


def test_plane_from_rendered_images_three_poses(scene):
    rig = scene["rig"]
    res = calibrate_laser_images(["a", "b", "c"], scene["images"][:3], rig,
                                 LaserPlaneParams(board=SPEC), right_images_bgr=scene["right"][:3],
                                 extractor=red_centroid_rows)
    ang, off = _angle_and_offset_error(res, rig)
    assert ang < FLOOR_DEG and off < FLOOR_M
    assert all(v.used and v.points > 30 for v in res.views)
    np.testing.assert_allclose(res.rig.laser.normal, res.fit.normal)
    assert "residual_std_mm" in "\n".join(res.report_lines())


def test_plane_from_rendered_images_with_the_laser_module(scene):
    # the production path: stripe rows from slitcli.laser (paper Eqs. 1-4) on the board
    rig = scene["rig"]
    res = calibrate_laser_images(["a", "b", "c"], scene["images"][:3], rig,
                                 LaserPlaneParams(board=SPEC), right_images_bgr=scene["right"][:3])
    ang, off = _angle_and_offset_error(res, rig)
    assert ang < FLOOR_DEG and off < FLOOR_M
    assert res.fit.residual_std_m < 0.002


def test_rendered_stripe_matches_its_truth_rows(scene):
    # the renderer's stripe (Gaussian sheet on the board) is centred on the true line
    rig = scene["rig"]
    for img, pose in zip(scene["images"][:2], scene["poses"][:2], strict=True):
        R_b, t_b = board_pose_rectified(find_corners(img, SPEC), rig, SPEC)
        rect, _ = rectify_pair(rig, img)
        found = red_centroid_rows(rect, board_mask(rig, R_b, t_b, SPEC, inset_m=0.01))
        truth = stripe_rows_on_board(rig.left.K, rig.raw.array("R1"), rig.image_size_px, BOARD,
                                     pose, LASER, inset_m=0.01)
        both = np.isfinite(found) & np.isfinite(truth)
        assert both.sum() > 40
        assert np.median(np.abs(found[both] - truth[both])) < 0.3


def test_single_pose_refused(scene5):
    """Plumbing (one pose is refused whatever the pose): one seed suffices."""
    scene = scene5
    with pytest.raises(SlitcliError, match="only 1 usable board pose"):
        calibrate_laser_images(["a"], scene["images"][:1], scene["rig"],
                               LaserPlaneParams(board=SPEC), extractor=red_centroid_rows)


@pytest.mark.parametrize("seed", range(5))
def test_collinear_points_refused_by_singular_value_ratio(seed):
    rng = np.random.default_rng(1 + seed)
    t = rng.uniform(-0.2, 0.2, 300)
    line = np.array([0.1, 0.4, 1.0]) + t[:, None] * np.array([1.0, 0.02, 0.05])
    with pytest.raises(SlitcliError, match="singular-value ratio"):
        fit_plane_svd(line + rng.normal(0, 3e-4, line.shape))


def test_view_without_stripe_or_board_is_skipped(scene5):
    """Plumbing (a blank view is skipped whatever the other poses): one seed suffices."""
    scene = scene5
    rig = scene["rig"]
    blank = np.full_like(scene["images"][0], 95)
    res = calibrate_laser_images(["a", "b", "c", "blank"], [*scene["images"][:3], blank], rig,
                                 LaserPlaneParams(board=SPEC), extractor=red_centroid_rows)
    skipped = [v for v in res.views if not v.used]
    assert [v.name for v in skipped] == ["blank"] and "no 7x5 board" in skipped[0].reason


def test_cli_calibrate_laser(scene5, tmp_path, monkeypatch):
    """Plumbing: folders, pairing by name, the report, the rig written (or untouched on
    error). The plane's accuracy over seeds is the library tests'; one seed suffices."""
    scene = scene5
    monkeypatch.setattr(laser_plane, "extract_stripe_rows", red_centroid_rows)
    rig_path = tmp_path / "rig.yaml"
    save_rig(scene["rig"], rig_path)
    for side in ("left", "right"):
        (tmp_path / "views" / side).mkdir(parents=True)
        for i, img in enumerate(scene["images" if side == "left" else "right"]):
            cv2.imwrite(str(tmp_path / "views" / side / f"{i}.png"), img)
    (tmp_path / "views" / "right" / "4.png").unlink()  # view 4: left camera only
    out = tmp_path / "laser_rig.yaml"
    res = CliRunner().invoke(cli, ["calibrate", "laser", "--rig", str(rig_path),
                                   str(tmp_path / "views"), "--board", "7x5", "--square-m",
                                   "0.04", "-o", str(out)])
    assert res.exit_code == 0, res.output
    assert "residual_std_mm" in res.output
    assert "from both cameras in 4, from the left camera alone in 1" in res.output
    assert "4: " in res.output and "left (no right image)" not in res.output
    rig = load_rig(out)
    n_raw = rig.raw.array("R1").T @ np.asarray(rig.laser.normal)
    assert math.degrees(math.acos(min(1.0, float(n_raw @ LASER.unit_normal)))) < FLOOR_DEG
    assert rig.laser.offset_m == pytest.approx(0.6, abs=FLOOR_M)

    res = CliRunner().invoke(cli, ["calibrate", "laser", "--rig", str(rig_path),
                                   str(tmp_path / "views"), "--board", "7x5", "--square-m",
                                   "0.04", "-o", str(out), "--left-only"])
    assert res.exit_code == 0, res.output
    assert "from both cameras in 0, from the left camera alone in 5" in res.output

    # a single pose: exit 2, one line, the rig untouched
    one = tmp_path / "one"
    one.mkdir()
    cv2.imwrite(str(one / "0.png"), scene["images"][0])
    before = rig_path.read_bytes()
    res = CliRunner().invoke(cli, ["calibrate", "laser", "--rig", str(rig_path), str(one),
                                   "--board", "7x5", "--square-m", "0.04"])
    assert res.exit_code == 2
    assert len(res.output.strip().splitlines()) == 1 and "single pose" in res.output
    assert rig_path.read_bytes() == before
