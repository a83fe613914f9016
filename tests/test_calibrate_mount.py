"""`calibrate mount`: height, tilt and roll from a rendered textured floor seen in stereo."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from click.testing import CliRunner

from slitcli.calibrate.mount import MountParams, calibrate_mount_frames, fit_floor_ransac
from slitcli.calibrate.rectify import rig_with_raw
from slitcli.cli import cli
from slitcli.rig import load_rig, save_rig
from slitcli.sim.targets import (
    TargetRenderer,
    demo_raw_calibration,
    floor_for_mount,
    stereo_cameras,
)

HEIGHT_M, TILT_DEG, ROLL_DEG = 0.65, 20.0, 1.5


@pytest.fixture(scope="module")
def floor_view():
    raw = demo_raw_calibration()
    lc, rc = stereo_cameras(raw)
    floor = floor_for_mount(HEIGHT_M, TILT_DEG, ROLL_DEG, seed=3)
    left = TargetRenderer(lc).render_floor(floor, seed=1)
    right = TargetRenderer(rc).render_floor(floor, seed=2)
    rig = rig_with_raw(raw)
    # truth in the rig's (rectified left) frame: the floor normal rotated by R1
    n = raw.array("R1") @ -np.asarray(floor.up_left)
    truth = {"tilt_deg": math.degrees(math.asin(n[2])),
             "roll_deg": math.degrees(math.atan2(n[0], n[1])), "height_m": HEIGHT_M}
    return {"rig": rig, "left": left, "right": right, "truth": truth}


def test_mount_from_rendered_floor(floor_view):
    res = calibrate_mount_frames(["f0"], [(floor_view["left"], floor_view["right"])],
                                 floor_view["rig"], MountParams())
    m, t = res.rig.mount, floor_view["truth"]
    assert abs(m.tilt_deg - t["tilt_deg"]) < 0.3
    assert abs(m.roll_deg - t["roll_deg"]) < 0.3
    assert abs(m.height_m - t["height_m"]) < 0.005
    assert res.floor.inliers > 0.8 * res.floor.points
    assert "tilt_deg" in "\n".join(res.report_lines())


def test_ransac_ignores_an_obstacle_and_far_noise():
    # 60 % floor points with depth-dependent noise, 40 % on a box face and scattered
    rig = rig_with_raw(demo_raw_calibration())
    rng = np.random.default_rng(4)
    t = math.radians(25.0)
    n = np.array([0.0, math.cos(t), math.sin(t)])
    e1 = np.array([1.0, 0.0, 0.0])
    e2 = np.cross(n, e1)
    a, b = rng.uniform(-1, 1, 6000), rng.uniform(-1.5, 1.5, 6000)
    floor = 0.5 * n + a[:, None] * e1 + b[:, None] * e2
    floor = floor[(floor[:, 2] > 0.4) & (floor[:, 2] < 2.8)]
    sigma = floor[:, 2:3] ** 2 * 0.3 / (rig.focal_px * rig.baseline_m)
    floor = floor + rng.normal(size=floor.shape) * sigma * floor / floor[:, 2:3]
    box = np.column_stack([rng.uniform(-0.3, 0.3, 2500), rng.uniform(-0.2, 0.3, 2500),
                           np.full(2500, 1.2) + rng.normal(0, 0.003, 2500)])
    junk = rng.uniform([-1, -1, 0.4], [1, 1, 2.8], size=(1000, 3))
    plane = fit_floor_ransac(np.vstack([floor, box, junk]), rig, MountParams(seed=1))
    assert math.degrees(math.acos(min(1.0, float(np.asarray(plane.normal) @ n)))) < 0.3
    assert abs(plane.height_m - 0.5) < 0.005


def test_cli_calibrate_mount(floor_view, tmp_path):
    seq = tmp_path / "seq"
    (seq / "left").mkdir(parents=True)
    (seq / "right").mkdir()
    cv2.imwrite(str(seq / "left" / "000.png"), floor_view["left"])
    cv2.imwrite(str(seq / "right" / "000.png"), floor_view["right"])
    rig_path = tmp_path / "rig.yaml"
    save_rig(floor_view["rig"], rig_path)
    res = CliRunner().invoke(cli, ["calibrate", "mount", "--rig", str(rig_path), str(seq)])
    assert res.exit_code == 0, res.output
    m = load_rig(rig_path).mount
    assert m.tilt_deg == pytest.approx(floor_view["truth"]["tilt_deg"], abs=0.3)
    assert m.height_m == pytest.approx(HEIGHT_M, abs=0.005)

    # a missing sequence: exit 2, one line, nothing written
    out = tmp_path / "new.yaml"
    res = CliRunner().invoke(cli, ["calibrate", "mount", "--rig", str(rig_path),
                                   str(tmp_path / "nope"), "-o", str(out)])
    assert res.exit_code == 2 and len(res.output.strip().splitlines()) == 1
    assert "nope" in res.output and not out.exists()
