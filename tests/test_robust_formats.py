"""rig import: malformed OpenCV files are one line naming the file, never a crash of OpenCV."""

from __future__ import annotations

import pytest
from robust_helpers import child_one_error_line, invoke, one_error_line, run_slitcli

from slitcli.calibrate.formats import _nesting_depth


def test_deep_opencv_file_does_not_crash_opencv(tmp_path):
    """cv2.FileStorage's recursive parser segfaults (exit 139) 200,000 levels down."""
    path = tmp_path / "intrinsics.yml"
    path.write_text("%YAML:1.0\n---\nM1: " + "[" * 200_000 + "]" * 200_000 + "\n")
    proc = run_slitcli(["rig", "import", "--format", "opencv", path, "-o", tmp_path / "r.yaml"])
    assert "nests 200000 levels" in child_one_error_line(proc, names=str(path))
    assert not (tmp_path / "r.yaml").exists()


@pytest.mark.parametrize("text, depth", [
    ("a: [1, 2, [3]]\n", 2),
    ("<?xml version=\"1.0\"?>\n<opencv_storage><M1><data>1</data></M1></opencv_storage>\n", 3),
    ("a:\n  b:\n    c:\n      - 1\n", 3),
    ("<a>" * 50 + "</a>" * 50, 50),
])
def test_nesting_depth_bounds_the_real_depth(text, depth):
    assert _nesting_depth(text) >= depth


def test_deep_xml_is_refused(tmp_path):
    path = tmp_path / "e.xml"
    path.write_text("<?xml version=\"1.0\"?>\n<opencv_storage>" + "<a>" * 5000 + "</a>" * 5000
                    + "</opencv_storage>\n")
    proc = run_slitcli(["rig", "import", "--format", "opencv", path, "-o", tmp_path / "r.yaml"])
    child_one_error_line(proc, names="levels deep")


MALFORMED = {
    "short matrix": "M1: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [1, 2]\n",
    "huge matrix": "M1: !!opencv-matrix\n   rows: 300000000\n   cols: 3000000\n   dt: d\n"
                   "   data: [1, 2]\n",
    "bad dt": "M1: !!opencv-matrix\n   rows: 1\n   cols: 1\n   dt: zz\n   data: [1]\n",
    "huge width": "image_width: 1e400\nimage_height: 10\nM1: 3\n",
    "not yaml": "M1: [1, 2\n",
    "width text": "image_width: abc\nimage_height: 10\n",
}


@pytest.mark.parametrize("body", MALFORMED.values(), ids=MALFORMED.keys())
def test_malformed_filestorage_is_exit_2(tmp_path, body):
    path = tmp_path / "calib.yml"
    path.write_text("%YAML:1.0\n---\n" + body)
    one_error_line(invoke(["rig", "import", "--format", "opencv", path, "-o",
                           tmp_path / "r.yaml"]), names=str(path))
    assert not (tmp_path / "r.yaml").exists()


def test_oversized_calibration_file(tmp_path):
    path = tmp_path / "calib.yml"
    path.write_text("%YAML:1.0\n---\n# " + "x" * (2 * 1024 * 1024) + "\n")
    one_error_line(invoke(["rig", "import", path, "-o", tmp_path / "r.yaml"]), names="bytes")


def test_alias_in_a_ros_file_is_refused(tmp_path):
    path = tmp_path / "left.yaml"
    path.write_text("camera_matrix: &m {rows: 3}\ndistortion_coefficients: *m\n")
    line = one_error_line(invoke(["rig", "import", "--format", "ros", path, path, "-o",
                                  tmp_path / "r.yaml"]), names=str(path))
    assert "alias" in line
