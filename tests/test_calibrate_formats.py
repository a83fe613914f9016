"""`rig import` / `rig export`: ROS camera_info, OpenCV FileStorage and Kalibr camchain."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from slitcli.calibrate.formats import export_texts
from slitcli.calibrate.rectify import rectify_raw, rig_with_raw
from slitcli.cli import cli
from slitcli.errors import SlitcliError
from slitcli.rig import load_rig, paper_rig, save_rig
from slitcli.sim.targets import demo_raw_calibration

KEYS = ("K1", "D1", "K2", "D2", "R", "T")


@pytest.fixture()
def rig_file(tmp_path):
    base = replace(paper_rig(), name="lab")
    rig = rig_with_raw(demo_raw_calibration(), base)
    path = tmp_path / "rig.yaml"
    save_rig(rig, path)
    return path


def _invoke(*args: str):
    return CliRunner().invoke(cli, list(args))


@pytest.mark.parametrize("fmt,files", [("ros", ["left.yaml", "right.yaml"]),
                                       ("opencv", ["intrinsics.yml", "extrinsics.yml"]),
                                       ("kalibr", ["camchain.yaml"])])
def test_export_then_import_round_trip(rig_file, tmp_path, fmt, files):
    out = tmp_path / fmt
    res = _invoke("rig", "export", str(rig_file), "--format", fmt, "-o", str(out))
    assert res.exit_code == 0, res.output
    assert sorted(p.name for p in out.iterdir()) == sorted(files)
    back = tmp_path / f"{fmt}.yaml"
    # the files are given in reverse order: import must not depend on it
    res = _invoke("rig", "import", *[str(out / f) for f in files[::-1]], "-o", str(back),
                  "--base", str(rig_file))
    assert res.exit_code == 0, res.output
    a, b = load_rig(rig_file), load_rig(back)
    for key in KEYS:
        x, y = a.raw.array(key).ravel(), b.raw.array(key).ravel()
        n = max(x.size, y.size)  # Kalibr's radtan has 4 coefficients, k3 = 0 here
        np.testing.assert_allclose(np.pad(y, (0, n - y.size)), np.pad(x, (0, n - x.size)),
                                   rtol=0, atol=1e-9, err_msg=key)
    assert b.baseline_m == pytest.approx(a.baseline_m, abs=1e-9)
    assert b.left.fx_px == pytest.approx(a.left.fx_px, abs=1e-6)
    assert b.mount == a.mount and b.laser == a.laser


def test_ros_baseline_comes_from_right_projection(rig_file):
    texts = export_texts(load_rig(rig_file), "ros")
    right = yaml.safe_load(texts["right.yaml"])
    P = np.asarray(right["projection_matrix"]["data"]).reshape(3, 4)
    assert -P[0, 3] / P[0, 0] == pytest.approx(load_rig(rig_file).baseline_m, abs=1e-12)
    assert right["distortion_model"] == "plumb_bob"


def test_opencv_files_are_real_filestorage(rig_file, tmp_path):
    _invoke("rig", "export", str(rig_file), "--format", "opencv", "-o", str(tmp_path / "cv"))
    text = (tmp_path / "cv" / "intrinsics.yml").read_text()
    assert "!!opencv-matrix" in text
    with pytest.raises(yaml.YAMLError):
        yaml.safe_load(text)
    fs = cv2.FileStorage(str(tmp_path / "cv" / "extrinsics.yml"), cv2.FILE_STORAGE_READ)
    np.testing.assert_allclose(fs.getNode("T").mat().ravel(),
                               load_rig(rig_file).raw.array("T"), atol=1e-15)
    # Q reprojects a rectified pixel with disparity d to depth f * B / d (Eq. 8)
    Q = fs.getNode("Q").mat()
    rig = load_rig(rig_file)
    X = Q @ np.array([200.0, 150.0, 20.0, 1.0])
    assert X[2] / X[3] == pytest.approx(rig.focal_px * rig.baseline_m / 20.0, rel=1e-9)


def test_unsupported_models_rejected(rig_file, tmp_path):
    _invoke("rig", "export", str(rig_file), "--format", "ros", "-o", str(tmp_path / "ros"))
    left = yaml.safe_load((tmp_path / "ros" / "left.yaml").read_text())
    left["distortion_model"] = "fisheye"
    (tmp_path / "ros" / "left.yaml").write_text(yaml.safe_dump(left))
    out = tmp_path / "x.yaml"
    res = _invoke("rig", "import", str(tmp_path / "ros" / "left.yaml"),
                  str(tmp_path / "ros" / "right.yaml"), "-o", str(out))
    assert res.exit_code == 2 and "distortion_model 'fisheye' is not supported" in res.output
    assert len(res.output.strip().splitlines()) == 1 and not out.exists()

    _invoke("rig", "export", str(rig_file), "--format", "kalibr", "-o", str(tmp_path / "k"))
    chain = yaml.safe_load((tmp_path / "k" / "camchain.yaml").read_text())
    for cam, key, value in (("cam0", "camera_model", "omni"),
                            ("cam1", "distortion_model", "fov")):
        bad = yaml.safe_load(yaml.safe_dump(chain))
        bad[cam][key] = value
        (tmp_path / "k" / "bad.yaml").write_text(yaml.safe_dump(bad))
        res = _invoke("rig", "import", str(tmp_path / "k" / "bad.yaml"), "-o", str(out))
        assert res.exit_code == 2 and f"{cam}.{key} '{value}' is not supported" in res.output
        assert not out.exists()


def test_kalibr_export_refuses_k3(tmp_path):
    raw = demo_raw_calibration()
    D1 = raw.array("D1").copy()
    D1[4] = 0.01
    raw = rectify_raw(raw.array("K1"), D1, raw.array("K2"), raw.array("D2"),
                      raw.image_size_px, raw.array("R"), raw.array("T"))
    with pytest.raises(SlitcliError, match="radtan cannot hold it"):
        export_texts(rig_with_raw(raw), "kalibr")
    path = tmp_path / "k3.yaml"
    save_rig(rig_with_raw(raw), path)
    res = _invoke("rig", "export", str(path), "--format", "kalibr", "-o", str(tmp_path / "out"))
    assert res.exit_code == 2 and not (tmp_path / "out").exists()


def test_rectified_rig_without_raw_exports_an_ideal_pair(tmp_path):
    path = tmp_path / "paper.yaml"
    save_rig(paper_rig(), path)
    assert _invoke("rig", "export", str(path), "--format", "ros", "-o",
                   str(tmp_path / "r")).exit_code == 0
    res = _invoke("rig", "import", str(tmp_path / "r" / "left.yaml"),
                  str(tmp_path / "r" / "right.yaml"), "-o", str(tmp_path / "back.yaml"))
    assert res.exit_code == 0, res.output
    back = load_rig(tmp_path / "back.yaml")
    assert back.left == paper_rig().left and back.baseline_m == pytest.approx(0.088, abs=1e-12)


def test_bad_import_files(tmp_path):
    junk = tmp_path / "junk.yaml"
    junk.write_text("hello: [1, 2\n")
    res = _invoke("rig", "import", str(junk), "-o", str(tmp_path / "o.yaml"))
    assert res.exit_code == 2 and "junk.yaml" in res.output
    res = _invoke("rig", "import", str(tmp_path / "missing.yaml"), "-o", str(tmp_path / "o.yaml"))
    assert res.exit_code == 2 and "missing.yaml: file not found" in res.output
    assert not (tmp_path / "o.yaml").exists()
