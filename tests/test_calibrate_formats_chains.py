"""Calibration files as people have them: Kalibr imu-cam chains (``%YAML:1.0`` header,
``T_imu_cam`` or ``T_cam_imu`` only), the equidistant lens model, OpenCV files in
``%YAML:1.0`` and YAML 1.2 with and without an image size. Values are our own."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from slitcli.calibrate.formats import import_raw
from slitcli.calibrate.rectify import rectify_points, rig_with_raw
from slitcli.cli import cli
from slitcli.rig import load_rig


def _pose(rvec, t) -> np.ndarray:
    """Camera pose in the IMU: camera x along IMU y (a quarter turn about z), tilted a bit."""
    m = np.eye(4)
    quarter = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    m[:3, :3] = quarter @ cv2.Rodrigues(np.asarray(rvec, dtype=float))[0]
    m[:3, 3] = t
    return m


def _rows(m: np.ndarray, indent: str = "    ") -> str:
    return "\n".join(f"{indent}- [{', '.join(repr(float(x)) for x in row)}]" for row in m)


# an imu-cam chain as VIO packages write it: OpenCV's header, cameras' poses in the IMU
T_IMU_C0 = _pose([0.0071, -0.0123, 0.0035], [-0.0213, -0.0647, 0.0098])
T_IMU_C1 = _pose([0.0052, -0.0109, 0.0061], [-0.0199, 0.0452, 0.0079])
CAM = {"radtan": ([-0.2834, 0.0740, 0.00019, 1.76e-05], [-0.2831, 0.0734, -0.00010, -3.2e-05]),
       "equidistant": ([-0.0132, 0.0211, -0.0154, 0.0041], [-0.0127, 0.0198, -0.0139, 0.0035])}


def _imucam_chain(model: str, key: str = "T_imu_cam", resolution: bool = True) -> str:
    d0, d1 = CAM[model]
    mats = {"T_imu_cam": (T_IMU_C0, T_IMU_C1),
            "T_cam_imu": (np.linalg.inv(T_IMU_C0), np.linalg.inv(T_IMU_C1))}[key]
    out = ["%YAML:1.0 # the header OpenCV's FileStorage needs", ""]
    for i, (m, d, intr) in enumerate(((mats[0], d0, [458.65, 457.30, 367.22, 248.38]),
                                      (mats[1], d1, [457.59, 456.13, 379.99, 255.24]))):
        out += [f"cam{i}:", f"  {key}: # pose of the camera in the IMU", _rows(m),
                f"  cam_overlaps: [{1 - i}]", "  camera_model: pinhole",
                f"  distortion_coeffs: [{', '.join(map(repr, d))}]",
                f"  distortion_model: {model}",
                f"  intrinsics: [{', '.join(map(repr, intr))}]"]
        if resolution:
            out.append("  resolution: [752, 480]")
        out += [f"  rostopic: /cam{i}/image_raw", "  timeshift_cam_imu: 0.0"]
    return "\n".join(out) + "\n"


def _invoke(*args: str):
    return CliRunner().invoke(cli, list(args))


@pytest.mark.parametrize("model", ["radtan", "equidistant"])
@pytest.mark.parametrize("key", ["T_imu_cam", "T_cam_imu"])
def test_imucam_chain_with_opencv_header_imports(tmp_path, model, key):
    path = tmp_path / "kalibr_imucam_chain.yaml"
    path.write_text(_imucam_chain(model, key))
    raw = import_raw([path])
    want = np.linalg.inv(T_IMU_C1) @ T_IMU_C0  # cam0 -> cam1
    np.testing.assert_allclose(raw.array("R"), want[:3, :3], atol=1e-12)
    np.testing.assert_allclose(raw.array("T"), want[:3, 3], atol=1e-12)
    assert raw.model == ("equidistant" if model == "equidistant" else "pinhole")
    assert raw.image_size_px == (752, 480)
    np.testing.assert_array_equal(raw.array("D1"), CAM[model][0])
    out = tmp_path / "rig.yaml"
    res = _invoke("rig", "import", str(path), "-o", str(out))
    assert res.exit_code == 0, res.output
    rig = load_rig(out)
    assert rig.baseline_m == pytest.approx(np.linalg.norm(want[:3, 3]), rel=1e-9)
    # round trips are exact: rig -> kalibr / ros -> rig
    for fmt, files in (("kalibr", ["camchain.yaml"]), ("ros", ["left.yaml", "right.yaml"])):
        d = tmp_path / fmt
        assert _invoke("rig", "export", str(out), "--format", fmt, "-o", str(d)).exit_code == 0
        back = tmp_path / f"{fmt}.yaml"
        res = _invoke("rig", "import", *[str(d / f) for f in files], "-o", str(back))
        assert res.exit_code == 0, res.output
        got = load_rig(back).raw
        if fmt == "kalibr":  # the chain holds K D R T: bit for bit
            assert got == rig.raw and load_rig(back).left == rig.left
            continue
        # camera_info holds R1 R2 P1 P2 (kept as they are); R, T come back as R2^T R1 and
        # R2^T (P2[0,3] / fx, 0, 0): R1, R2 are orthonormal to ~1e-14 (cv2.stereoRectify);
        # plumb_bob pads D to 5
        for k in ("K1", "K2", "R1", "R2", "P1", "P2"):
            assert np.array_equal(got.array(k), rig.raw.array(k)), k
        for k in ("R", "T"):
            np.testing.assert_allclose(got.array(k), rig.raw.array(k), rtol=0, atol=1e-12)
        for k in ("D1", "D2"):
            d = rig.raw.array(k)
            assert np.array_equal(got.array(k)[:d.size], d) and not got.array(k)[d.size:].any()


def test_chain_without_any_pose_or_resolution(tmp_path):
    text = _imucam_chain("radtan").replace("T_imu_cam", "T_imu_body")
    path = tmp_path / "c.yaml"
    path.write_text(text)
    res = _invoke("rig", "import", str(path), "-o", str(tmp_path / "o.yaml"))
    assert res.exit_code == 2 and "T_cn_cnm1" in res.output and "T_imu_cam" in res.output
    path.write_text(_imucam_chain("radtan", resolution=False))
    res = _invoke("rig", "import", str(path), "-o", str(tmp_path / "o.yaml"))
    assert res.exit_code == 2 and "--image-size" in res.output
    assert not (tmp_path / "o.yaml").exists()
    res = _invoke("rig", "import", str(path), "--image-size", "752,480", "-o",
                  str(tmp_path / "o.yaml"))
    assert res.exit_code == 0 and load_rig(tmp_path / "o.yaml").raw.image_size_px == (752, 480)


@pytest.mark.parametrize("seed", range(5))
def test_equidistant_rectification_makes_rows_agree(tmp_path, seed):
    """Points projected by cv2.fisheye into both raw cameras rectify onto one row, at the
    disparity f B / Z of Eq. 8 (in the rectified left frame)."""
    path = tmp_path / "chain.yaml"
    path.write_text(_imucam_chain("equidistant"))
    raw = import_raw([path])
    rig = rig_with_raw(raw)
    rng = np.random.default_rng(seed)
    # points in the rectified left frame, inside the view, 0.5 - 4 m away
    z = rng.uniform(0.5, 4.0, 200)
    u = rng.uniform(0.15, 0.85, 200) * rig.width_px
    v = rng.uniform(0.15, 0.85, 200) * rig.height_px
    X_rect = rig.pixel_rays_cam(u, v) * z[:, None]
    X_left = X_rect @ raw.array("R1")  # R1 maps raw left -> rectified left
    X_right = X_left @ raw.array("R").T + raw.array("T")
    pts = []
    for X, k, d in ((X_left, "K1", "D1"), (X_right, "K2", "D2")):
        p, _ = cv2.fisheye.projectPoints(X.reshape(-1, 1, 3), np.zeros(3), np.zeros(3),
                                         raw.array(k), raw.array(d).reshape(4, 1))
        pts.append(p.reshape(-1, 2))
    left = rectify_points(rig, pts[0], camera="left")
    right = rectify_points(rig, pts[1], camera="right")
    np.testing.assert_allclose(left, np.column_stack([u, v]), atol=1e-3)
    assert np.max(np.abs(left[:, 1] - right[:, 1])) < 1e-3
    np.testing.assert_allclose(left[:, 0] - right[:, 0], rig.focal_px * rig.baseline_m / z,
                               atol=1e-3)
    # the remap tables agree with the point mapping (sampled at rectified pixels)
    from slitcli.calibrate.rectify import rectification_maps

    maps = rectification_maps(rig)
    mx, my = cv2.convertMaps(maps.left_map1, maps.left_map2, cv2.CV_32FC1)
    ui, vi = np.round(left).astype(int).T
    back = np.column_stack([mx[vi, ui], my[vi, ui]])
    # the table at the nearest rectified pixel points within a raw pixel of the source
    assert np.max(np.abs(back - pts[0])) < 1.0


def _opencv_text(header: str, tagged: bool, size: bool) -> str:
    K1 = [[461.2, 0.0, 362.4], [0.0, 460.1, 251.9], [0.0, 0.0, 1.0]]
    K2 = [[460.7, 0.0, 371.3], [0.0, 459.8, 249.6], [0.0, 0.0, 1.0]]
    mats = {"M1": K1, "D1": [[-0.291, 0.087, 0.0004, -0.0002, 0.0]],
            "M2": K2, "D2": [[-0.288, 0.083, -0.0003, 0.0001, 0.0]],
            "R": cv2.Rodrigues(np.array([0.003, -0.011, 0.002]))[0].tolist(),
            "T": [[-0.1102], [0.0004], [-0.0007]]}
    lines = [header]
    if size:
        lines += ["image_width: 752", "image_height: 480"]
    for k, m in mats.items():
        a = np.asarray(m, dtype=float)
        data = ", ".join(repr(float(x)) for x in a.ravel())
        if tagged:
            lines += [f"{k}: !!opencv-matrix", f"   rows: {a.shape[0]}", f"   cols: {a.shape[1]}",
                      "   dt: d", f"   data: [ {data} ]"]
        else:
            lines += [f"{k}: {{rows: {a.shape[0]}, cols: {a.shape[1]}, data: [{data}]}}"]
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("header, tagged", [("%YAML:1.0", True), ("%YAML 1.2\n---", True),
                                            ("%YAML 1.2\n---", False)])
def test_opencv_files_in_both_yaml_versions_and_image_size(tmp_path, header, tagged):
    ref = tmp_path / "ref.yml"
    ref.write_text(_opencv_text("%YAML:1.0", True, True))
    want = import_raw([ref])
    path = tmp_path / "stereo.yml"
    path.write_text(_opencv_text(header, tagged, True))
    got = import_raw([path])
    assert got == want
    path.write_text(_opencv_text(header, tagged, False))
    out = tmp_path / "r.yaml"
    res = _invoke("rig", "import", str(path), "-o", str(out))
    assert res.exit_code == 2 and "--image-size" in res.output and not out.exists()
    res = _invoke("rig", "import", str(path), "--image-size", "752,480", "-o", str(out))
    assert res.exit_code == 0, res.output
    assert load_rig(out).raw == want
    res = _invoke("rig", "import", str(ref), "--image-size", "640,480", "-o",
                  str(tmp_path / "z.yaml"))
    assert res.exit_code == 2 and "drop --image-size" in res.output


def test_rig_file_keeps_the_lens_model(tmp_path):
    path = tmp_path / "chain.yaml"
    path.write_text(_imucam_chain("equidistant"))
    out = tmp_path / "rig.yaml"
    assert _invoke("rig", "import", str(path), "-o", str(out)).exit_code == 0
    doc = yaml.safe_load(out.read_text())
    assert doc["raw"]["model"] == "equidistant"
    doc["raw"]["D1"] = [0.1, 0.0, 0.0, 0.0, 0.0]
    out.write_text(yaml.safe_dump(doc))
    res = _invoke("rig", "show", str(out))
    assert res.exit_code == 2 and "raw.D1" in res.output
    res = _invoke("rig", "export", str(tmp_path / "chain_rig.yaml"), "--format", "opencv", "-o",
                  str(tmp_path / "cv"))
    assert res.exit_code == 2
