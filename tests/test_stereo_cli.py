"""`slitcli stereo` end to end through click, and its refusals of bad input."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner
from stereo_synth import plane_pair

from slitcli.cli import cli
from slitcli.rig import paper_rig, save_rig
from slitcli.stereo.geometry import StereoGeometry
from slitcli.stereo.obstacles import ObstacleParams, obstacle_points

DISPARITIES = (11.0, 14.5, 18.25)  # fronto-parallel planes at 2.0, 1.52 and 1.21 m


def geo(rig):
    """The rig's stereo geometry with 1-degree bins."""
    return StereoGeometry.for_rig(rig)


def make_sequence(root: Path, disparities=DISPARITIES, size=(320, 240)) -> Path:
    seq = root / "seq"
    (seq / "left").mkdir(parents=True)
    (seq / "right").mkdir()
    for i, d in enumerate(disparities):
        left, right = plane_pair(d, width=size[0], height=size[1], seed=i)
        cv2.imwrite(str(seq / "left" / f"f{i:03d}.png"), cv2.cvtColor(left, cv2.COLOR_GRAY2BGR))
        cv2.imwrite(str(seq / "right" / f"f{i:03d}.png"),
                    cv2.cvtColor(right, cv2.COLOR_GRAY2BGR))
    return seq


def run(*args: str):
    return CliRunner().invoke(cli, [str(a) for a in args])


def test_stereo_writes_the_design_folders(tmp_path):
    seq = make_sequence(tmp_path)
    out = tmp_path / "out"
    res = run("stereo", seq, "-o", out)
    assert res.exit_code == 0, res.output
    rig = paper_rig()
    names = ["f000.png", "f001.png", "f002.png"]
    for sub in ("disparity", "distance", "mask"):
        assert sorted(p.name for p in (out / sub).iterdir()) == names
    for name, d in zip(names, DISPARITIES, strict=True):
        disp_png = cv2.imread(str(out / "disparity" / name), cv2.IMREAD_UNCHANGED)
        dist_png = cv2.imread(str(out / "distance" / name), cv2.IMREAD_UNCHANGED)
        mask_png = cv2.imread(str(out / "mask" / name), cv2.IMREAD_UNCHANGED)
        assert disp_png.dtype == np.uint16 and dist_png.dtype == np.uint16
        assert mask_png.dtype == np.uint8 and set(np.unique(mask_png)) <= {0, 255}
        valid = disp_png > 0
        assert valid[:, 40:].mean() >= 0.95
        disp = disp_png[valid] / 256.0
        assert np.median(np.abs(disp - d)) <= 0.1
        z_mm = 1000.0 * rig.baseline_m * rig.focal_px / d
        assert np.median(np.abs(dist_png[valid].astype(float) - z_mm)) <= 0.02 * z_mm
        assert ((dist_png > 0) == valid).all()
        # the mask is the obstacle test of the written disparity (hand-checked geometry)
        _, _, expect, _ = obstacle_points(np.where(valid, disp_png / 256.0, np.nan)
                                          .astype(np.float32), geo(rig), ObstacleParams())
        assert ((mask_png == 255) == expect).mean() >= 0.999
        assert expect.sum() > 1000
    table = pd.read_csv(out / "stereo_ranges.csv")
    assert list(table.columns) == ["frame", "time_s", "bearing_deg", "stereo_range_m",
                                   "stereo_has_features", "obstacle_px", "feature_px"]
    assert table["frame"].tolist() == sorted(table["frame"].tolist())
    assert len(table) == 3 * 65
    # a plane at depth D along the tilted axis: its nearest point per bin is no farther
    # than D cos(20 deg) ahead... and the centre bin's range is at most the depth
    centre = table[table["bearing_deg"] == 0]
    depths = rig.baseline_m * rig.focal_px / np.array(DISPARITIES)
    assert (centre["stereo_range_m"].to_numpy() <= depths + 0.02).all()
    assert (centre["stereo_range_m"].to_numpy() >= 0.5 * depths).all()


def test_rerun_skips_finished_frames_and_refuses_other_settings(tmp_path):
    seq = make_sequence(tmp_path, disparities=(12.0, 13.0))
    out = tmp_path / "out"
    assert run("stereo", seq, "-o", out).exit_code == 0
    before = (out / "disparity" / "f001.png").stat().st_mtime_ns
    (out / "disparity" / "f000.png").unlink()   # as if killed while writing frame 0
    res = run("stereo", seq, "-o", out)
    assert res.exit_code == 0
    assert "2 frames (1 already done)" in res.output
    assert (out / "disparity" / "f000.png").exists()
    assert (out / "disparity" / "f001.png").stat().st_mtime_ns == before
    res = run("stereo", seq, "-o", out, "--window", "7")
    assert res.exit_code == 2
    assert "--overwrite" in res.output and len(res.output.strip().splitlines()) == 1
    assert run("stereo", seq, "-o", out, "--window", "7", "--overwrite").exit_code == 0


@pytest.mark.parametrize("matcher", ["bm", "sgbm"])
def test_opencv_matchers_through_the_command(tmp_path, matcher):
    seq = make_sequence(tmp_path, disparities=(14.5,))
    out = tmp_path / "out"
    assert run("stereo", seq, "-o", out, "--matcher", matcher).exit_code == 0
    disp = cv2.imread(str(out / "disparity" / "f000.png"), cv2.IMREAD_UNCHANGED)
    assert np.median(np.abs(disp[disp > 0] / 256.0 - 14.5)) <= 0.3


def test_sgm_aggregation_through_the_command(tmp_path):
    import json

    seq = make_sequence(tmp_path, disparities=(14.5,))
    out = tmp_path / "out"
    res = run("stereo", seq, "-o", out, "--aggregation", "sgm")
    assert res.exit_code == 0, res.output
    disp = cv2.imread(str(out / "disparity" / "f000.png"), cv2.IMREAD_UNCHANGED)
    assert (disp > 0)[:, 40:].mean() >= 0.95
    assert np.median(np.abs(disp[disp > 0] / 256.0 - 14.5)) <= 0.1
    # the settings are recorded, so a re-run can tell
    manifest = json.loads((out / ".slitcli" / "stereo" / "manifest.json").read_text())
    assert manifest["params"]["matcher"]["aggregation"] == "sgm"
    # another aggregation is another setting: refused without --overwrite
    assert run("stereo", seq, "-o", out).exit_code == 2


def _one_line_exit_2(res, out: Path, fragment: str) -> None:
    assert res.exit_code == 2, res.output
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("slitcli: error:")
    assert fragment in lines[0]
    assert "Traceback" not in res.output
    assert not out.exists()  # nothing written


def test_mismatched_left_right_sizes(tmp_path):
    seq = make_sequence(tmp_path, disparities=(12.0, 13.0))
    right = cv2.imread(str(seq / "right" / "f001.png"))
    cv2.imwrite(str(seq / "right" / "f001.png"), right[:, :300])
    out = tmp_path / "out"
    _one_line_exit_2(run("stereo", seq, "-o", out), out, "differs from the left image")


def test_size_differs_from_the_rig(tmp_path):
    seq = make_sequence(tmp_path, disparities=(12.0,), size=(300, 200))
    out = tmp_path / "out"
    _one_line_exit_2(run("stereo", seq, "-o", out), out, "does not match the rig")
    rig_file = tmp_path / "rig.yaml"
    save_rig(paper_rig(), rig_file)
    _one_line_exit_2(run("stereo", seq, "-o", out, "--rig", rig_file), out, "image_size_px")


def test_missing_right_frame(tmp_path):
    seq = make_sequence(tmp_path, disparities=(12.0, 13.0))
    (seq / "right" / "f001.png").unlink()
    out = tmp_path / "out"
    _one_line_exit_2(run("stereo", seq, "-o", out), out, "missing right frame")


@pytest.mark.parametrize("args,fragment", [
    (["--num-disparities", "0"], "--num-disparities 0"),
    (["--num-disparities", "-16"], "--num-disparities -16"),
    (["--window", "8"], "--window 8: the window width must be an odd"),
    (["--window", "9x6"], "--window 6: the window height must be an odd"),
    (["--window", "401"], "wider than the image"),
    (["--window", "9x301"], "taller than the image"),
    (["--window", "nine"], "--window 'nine'"),
    (["--num-disparities", "400"], "exceeds the image width"),
    (["--matcher", "bm", "--num-disparities", "40"], "multiple of 16"),
    (["--matcher", "bm", "--aggregation", "sgm"], "aggregation 'sgm'"),
])
def test_bad_options(tmp_path, args, fragment):
    seq = make_sequence(tmp_path, disparities=(12.0,))
    out = tmp_path / "out"
    _one_line_exit_2(run("stereo", seq, "-o", out, *args), out, fragment)


def test_help_names_units_and_example():
    res = run("stereo", "--help")
    assert res.exit_code == 0
    for text in ("Example: slitcli stereo", "px", "DN", "disparity x 256", "mm"):
        assert text in res.output
