"""Import and export of stereo calibrations: ROS camera_info, OpenCV FileStorage, Kalibr.

All three carry the raw calibration (``K1 D1 K2 D2 R T``, :class:`slitcli.rig.RawCalibration`
conventions: ``X_right = R X_left + T``); the rectified rig is rebuilt from it with
:mod:`.rectify`. Mount, laser and range limits are not in these files: they come from
a base rig (default: the paper rig). Formats, as written and read (docs/calibration.md):

``ros``
    ``left.yaml`` and ``right.yaml``, camera_info YAML (camera_calibration_parsers):
    ``image_width``, ``image_height``, ``camera_name``, ``camera_matrix``,
    ``distortion_model`` (``plumb_bob`` or ``rational_polynomial``),
    ``distortion_coefficients``, ``rectification_matrix`` (R1 / R2) and
    ``projection_matrix`` (P1 / P2). The baseline is ``-P[0,3] / P[0,0]`` of the right
    camera; on import ``R = R2^T R1`` and ``T = R2^T (P2[0,3] / P2[0,0], 0, 0)``.
``opencv``
    ``intrinsics.yml`` (``M1 D1 M2 D2``, ``image_width``, ``image_height``) and
    ``extrinsics.yml`` (``R T R1 R2 P1 P2 Q``), :class:`cv2.FileStorage` YAML as in
    OpenCV's stereo_calib sample; read with :class:`cv2.FileStorage` (PyYAML cannot parse
    ``!!opencv-matrix``). One file holding all keys is read too.
``kalibr``
    ``camchain.yaml``: ``cam0``/``cam1`` with ``camera_model: pinhole``,
    ``intrinsics [fu, fv, pu, pv]``, ``distortion_model: radtan`` (``distortion_coeffs
    [k1, k2, r1, r2]``) or ``equidistant`` (``[k1, k2, k3, k4]``, :mod:`cv2.fisheye`),
    ``resolution [w, h]``, and the pose of cam1: ``cam1.T_cn_cnm1`` (4x4, cam0 to cam1:
    exactly ``[R T; 0 1]``), else from both cameras' IMU poses, ``T_cam_imu`` (Kalibr's
    camchain-imucam: ``R T = T_c1_imu T_c0_imu^-1``) or ``T_imu_cam`` (OpenVINS-style
    chains: ``T_imu_c1^-1 T_imu_c0``). Files may start with OpenCV's ``%YAML:1.0``
    line. Rectification is recomputed on import.

Other camera or distortion models (omni, eucm, ds, fov, ...) are refused. A file without
an image size (OpenCV files without ``image_width``/``image_height``, camchains without
``resolution``) takes ``image_size_px`` (``--image-size``).
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml

from slitcli.calibrate.rectify import ideal_raw, rectify_raw, rig_with_raw
from slitcli.errors import SlitcliError
from slitcli.io.atomic import write_text_atomic
from slitcli.io.yamlfile import MAX_DEPTH, load_yaml_text, read_text_bounded
from slitcli.rig import RawCalibration, Rig, load_rig

FORMATS = ("ros", "opencv", "kalibr")
MAX_CALIBRATION_BYTES = 1024 * 1024
"""Largest calibration file read (a stereo calibration is a few kB)."""
_ROS_MODELS = {"plumb_bob": (4, 5), "rational_polynomial": (8,), "equidistant": (4,)}
# OpenCV's FileStorage writes "%YAML:1.0", which is not a YAML directive (PyYAML refuses it)
_OPENCV_DIRECTIVE = re.compile(r"\A\s*%YAML:\s*1\.\d+[^\n]*")


# ---------------------------------------------------------------------- helpers
def _read_text(path: Path) -> str:
    return read_text_bounded(path, kind="file", missing_hint="check the path",
                             max_bytes=MAX_CALIBRATION_BYTES)


def _yaml(path: Path, text: str) -> Any:
    return load_yaml_text(_OPENCV_DIRECTIVE.sub("", text, count=1), str(path))


def _nesting_depth(text: str) -> int:
    """An upper bound of how deeply a YAML or XML text nests, from its characters alone.

    OpenCV's FileStorage parsers recurse once per level and overflow the C stack (a
    segmentation fault, no message) near 100,000 levels, so a file is measured before
    it is handed over: flow brackets ``[ {``, XML elements, and block indentation
    (leading spaces and ``- `` markers) each bound the depth. Characters inside quoted
    strings are counted too, which can only overestimate.
    """
    b = np.frombuffer(text.encode("utf-8", "replace"), dtype=np.uint8)
    step = np.zeros(b.shape, dtype=np.int64)
    step[(b == ord("[")) | (b == ord("{"))] = 1
    step[(b == ord("]")) | (b == ord("}"))] = -1
    flow = int(np.cumsum(step).max(initial=0))
    block = 0
    for line in text.splitlines():
        stripped = line.lstrip(" -\t")
        block = max(block, (len(line) - len(stripped)) // 2)
    return max(flow, _xml_depth(text), block)


def _xml_depth(text: str) -> int:
    """Deepest element nesting of an XML text (tags counted, not parsed)."""
    depth = deepest = 0
    pos = text.find("<")
    while pos != -1:
        end = text.find(">", pos)
        if end == -1:
            break
        tag = text[pos + 1:end]
        if tag.startswith("/"):
            depth -= 1
        elif not tag.startswith(("?", "!")) and not tag.endswith("/"):
            depth += 1
            deepest = max(deepest, depth)
        pos = text.find("<", end)
    return deepest


def _matrix(path: Path, value: Any, key: str, shape: tuple[int, int]) -> np.ndarray:
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        a = np.zeros(0)
    if a.size != shape[0] * shape[1] or not np.all(np.isfinite(a)):
        raise SlitcliError(f"{path}: '{key}' must hold {shape[0]}x{shape[1]} finite numbers; "
                           "fix the file")
    return a.reshape(shape)


def _raw_of(rig: Rig) -> RawCalibration:
    return rig.raw if rig.raw is not None else ideal_raw(rig)


def _size(path: Path, w: Any, h: Any) -> tuple[int, int]:
    if not (isinstance(w, int) and isinstance(h, int) and w >= 8 and h >= 8):
        raise SlitcliError(f"{path}: image size {w!r} x {h!r} is not valid; give whole numbers "
                           "of pixels")
    return int(w), int(h)


# ---------------------------------------------------------------------- ROS
def _ros_camera(name: str, size: tuple[int, int], K: np.ndarray, D: np.ndarray,
                Rr: np.ndarray, P: np.ndarray, lens: str = "pinhole") -> str:
    d = np.asarray(D, dtype=float).ravel()
    if lens == "pinhole" and d.size == 4:
        d = np.append(d, 0.0)
    if lens == "equidistant":
        model = "equidistant"
    elif d.size == 5:
        model = "plumb_bob"
    elif d.size == 8:
        model = "rational_polynomial"
    else:
        raise SlitcliError(f"rig: {d.size} distortion coefficients have no ROS camera_info "
                           "model (plumb_bob has 5, rational_polynomial 8)")

    def mat(a: np.ndarray, rows: int, cols: int) -> dict[str, Any]:
        return {"rows": rows, "cols": cols, "data": [float(x) for x in np.ravel(a)]}

    doc = {"image_width": int(size[0]), "image_height": int(size[1]), "camera_name": name,
           "camera_matrix": mat(K, 3, 3), "distortion_model": model,
           "distortion_coefficients": mat(d, 1, d.size), "rectification_matrix": mat(Rr, 3, 3),
           "projection_matrix": mat(P, 3, 4)}
    return yaml.safe_dump(doc, sort_keys=False, default_flow_style=None)


def _read_ros(path: Path, data: Any) -> dict[str, Any]:
    def block(key: str, shape: tuple[int, int]) -> np.ndarray:
        node = data.get(key)
        if not isinstance(node, dict) or "data" not in node:
            raise SlitcliError(f"{path}: missing '{key}' (with rows, cols, data); not a "
                               "complete ROS camera_info file")
        return _matrix(path, node["data"], f"{key}.data", shape)

    model = data.get("distortion_model")
    dist = data.get("distortion_coefficients", {})
    coeffs = np.asarray(dist.get("data", []) if isinstance(dist, dict) else [], dtype=float)
    if model not in _ROS_MODELS:
        raise SlitcliError(f"{path}: distortion_model '{model}' is not supported; slitcli reads "
                           "plumb_bob, rational_polynomial and equidistant only, recalibrate with "
                           "one of those")
    if coeffs.size not in _ROS_MODELS[model] or not np.all(np.isfinite(coeffs)):
        raise SlitcliError(f"{path}: {model} needs {' or '.join(map(str, _ROS_MODELS[model]))} "
                           f"distortion coefficients, found {coeffs.size}; fix the file")
    return {"size": _size(path, data.get("image_width"), data.get("image_height")),
            "model": "equidistant" if model == "equidistant" else "pinhole",
            "K": block("camera_matrix", (3, 3)), "D": coeffs,
            "R": block("rectification_matrix", (3, 3)), "P": block("projection_matrix", (3, 4))}


def import_ros(paths: list[Path], docs: list[Any]) -> RawCalibration:
    """Two camera_info files (any order) to a raw calibration."""
    if len(paths) != 2:
        raise SlitcliError(f"{paths[0]}: ROS camera_info needs two files, the left and the "
                           "right camera's; give both")
    cams = [_read_ros(p, d) for p, d in zip(paths, docs, strict=True)]
    if cams[0]["P"][0, 3] < cams[1]["P"][0, 3]:
        cams.reverse()
        paths = paths[::-1]
    left, right = cams
    if right["P"][0, 3] >= 0 or abs(left["P"][0, 3]) > 1e-6 * abs(right["P"][0, 3]):
        raise SlitcliError(f"{paths[1]}: projection_matrix[0,3] must be -fx * baseline < 0 for "
                           "the right camera and 0 for the left; these files are not a "
                           "rectified stereo pair")
    if left["size"] != right["size"]:
        raise SlitcliError(f"{paths[1]}: image size {right['size']} differs from the left "
                           f"camera's {left['size']}")
    if left["model"] != right["model"]:
        raise SlitcliError(f"{paths[1]}: its distortion_model differs from {paths[0]}'s; "
                           "slitcli needs one lens model for both cameras")
    R1, R2, P1, P2 = left["R"], right["R"], left["P"], right["P"]
    R = R2.T @ R1
    T = R2.T @ np.array([P2[0, 3] / P2[0, 0], 0.0, 0.0])
    f = rectify_raw(left["K"], left["D"], right["K"], right["D"], left["size"], R, T,
                    source=str(paths[0]), model=left["model"])
    return RawCalibration(image_size_px=f.image_size_px, K1=f.K1, D1=f.D1, K2=f.K2, D2=f.D2,
                          R=f.R, T=f.T, R1=_tup(R1), R2=_tup(R2), P1=_tup(P1), P2=_tup(P2),
                          model=f.model)


def _tup(a: np.ndarray) -> tuple:
    return tuple(tuple(float(x) for x in row) for row in np.asarray(a, dtype=float))


# ---------------------------------------------------------------------- OpenCV
def _fs_text(entries: dict[str, Any]) -> str:
    fs = cv2.FileStorage("out.yml", cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY)
    for k, v in entries.items():
        fs.write(k, v)
    return fs.releaseAndGetString()


def _q_matrix(P1: np.ndarray, P2: np.ndarray) -> np.ndarray:
    tx = P2[0, 3] / P2[0, 0]
    return np.array([[1.0, 0.0, 0.0, -P1[0, 2]], [0.0, 1.0, 0.0, -P1[1, 2]],
                     [0.0, 0.0, 0.0, P1[0, 0]], [0.0, 0.0, -1.0 / tx, (P1[0, 2] - P2[0, 2]) / tx]])


def _fs_array(node: Any) -> np.ndarray | None:
    """A FileStorage node as an array: ``!!opencv-matrix``, a plain list (YAML 1.2 files
    written by other tools) or a plain ``{rows, cols, data}`` mapping; None otherwise."""
    if node.isMap() and not node.getNode("dt").empty():
        try:
            m = node.mat()
        except cv2.error:
            m = None
        return None if m is None else np.asarray(m, dtype=float)
    if node.isSeq():
        vals = [node.at(i) for i in range(node.size())]
        if all(v.isReal() or v.isInt() for v in vals):
            return np.array([v.real() for v in vals], dtype=float)
        if all(v.isSeq() for v in vals):
            return np.array([[v.at(j).real() for j in range(v.size())] for v in vals])
    if node.isMap() and not node.getNode("data").empty():
        data = _fs_array(node.getNode("data"))
        rows, cols = node.getNode("rows"), node.getNode("cols")
        if data is not None and not rows.empty() and not cols.empty() and \
                data.size == int(rows.real()) * int(cols.real()):
            return data.reshape(int(rows.real()), int(cols.real()))
    return None


def _read_filestorage(p: Path, values: dict[str, np.ndarray], size: dict[str, int]) -> None:
    """Matrices and image size of one FileStorage file, into ``values`` and ``size``.

    The file is bounded in size and nesting before OpenCV parses it, and every OpenCV
    failure (cv2.error, SystemError from its bindings) becomes one line naming the file.
    """
    text = _read_text(p)
    depth = _nesting_depth(text)
    if depth > MAX_DEPTH:
        raise SlitcliError(f"{p}: nests {depth} levels deep; an OpenCV calibration file nests "
                           "at most 3, give the .yml/.xml files written by cv2.FileStorage")
    fix = "give the .yml/.xml files written by cv2.FileStorage"
    try:
        fs = cv2.FileStorage(text, cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY)
        opened = fs.isOpened()
    except (cv2.error, SystemError):
        opened = False
    if not opened:
        raise SlitcliError(f"{p}: OpenCV FileStorage cannot parse it; {fix}")
    try:
        for key in ("M1", "D1", "M2", "D2", "R", "T", "R1", "R2", "P1", "P2"):
            node = fs.getNode(key)
            if not node.empty():
                m = _fs_array(node)
                if m is None:
                    raise SlitcliError(f"{p}: '{key}' is not a matrix; fix the file")
                values[key] = m
        for key in ("image_width", "image_height"):
            node = fs.getNode(key)
            if not node.empty():
                v = float(node.real()) if node.isReal() or node.isInt() else float("nan")
                if not (np.isfinite(v) and v == int(v) and 0 < v <= 1e6):
                    raise SlitcliError(f"{p}: '{key}' is not a whole number of pixels; fix "
                                       "the file")
                size[key] = int(v)
    except (cv2.error, SystemError, TypeError, ValueError, OverflowError) as e:
        what = "OpenCV error" if isinstance(e, cv2.error) else e.__class__.__name__
        raise SlitcliError(f"{p}: OpenCV FileStorage cannot read it ({what}: a key holds "
                           f"malformed data); {fix}") from None
    finally:
        fs.release()


def import_opencv(paths: list[Path],
                  image_size_px: tuple[int, int] | None = None) -> RawCalibration:
    """OpenCV FileStorage stereo files (keys M1 D1 M2 D2 R T [R1 R2 P1 P2], image size)."""
    values: dict[str, np.ndarray] = {}
    size: dict[str, int] = {}
    for p in paths:
        _read_filestorage(p, values, size)
    missing = [k for k in ("M1", "D1", "M2", "D2", "R", "T") if k not in values]
    if missing:
        raise SlitcliError(f"{paths[0]}: missing {', '.join(missing)}; OpenCV stereo files need "
                           "M1 D1 M2 D2 (intrinsics) and R T (extrinsics)")
    src = Path(paths[0])
    if len(size) == 2:
        wh = _size(src, size["image_width"], size["image_height"])
        if image_size_px is not None and tuple(image_size_px) != wh:
            raise SlitcliError(f"{src}: the file says {wh[0]}x{wh[1]} px but `image_size_px` "
                               f"is {image_size_px[0]}x{image_size_px[1]}; drop "
                               "`image_size_px`", param="image_size_px")
    elif image_size_px is not None:
        wh = _size(src, *image_size_px)
    else:
        raise SlitcliError(f"{paths[0]}: no image_width / image_height; give `image_size_px` "
                           "W,H (the raw image size in pixels)", param="image_size_px")
    for k in ("D1", "D2"):
        n = values[k].size
        if n not in (4, 5, 8):
            raise SlitcliError(f"{src}: {k} has {n} coefficients; slitcli supports the pinhole "
                               "models with 4, 5 or 8 (k1 k2 p1 p2 [k3 [k4 k5 k6]])")
    M1, M2 = (_matrix(src, values[k], k, (3, 3)) for k in ("M1", "M2"))
    R, T = _matrix(src, values["R"], "R", (3, 3)), _matrix(src, values["T"], "T", (3, 1))
    f = rectify_raw(M1, values["D1"].ravel(), M2, values["D2"].ravel(), wh, R, T.ravel(),
                    source=str(src))
    if all(k in values for k in ("R1", "R2", "P1", "P2")):
        return RawCalibration(image_size_px=f.image_size_px, K1=f.K1, D1=f.D1, K2=f.K2,
                              D2=f.D2, R=f.R, T=f.T,
                              R1=_tup(_matrix(src, values["R1"], "R1", (3, 3))),
                              R2=_tup(_matrix(src, values["R2"], "R2", (3, 3))),
                              P1=_tup(_matrix(src, values["P1"], "P1", (3, 4))),
                              P2=_tup(_matrix(src, values["P2"], "P2", (3, 4))))
    return f


# ---------------------------------------------------------------------- Kalibr
_KALIBR_MODELS = {"radtan": "pinhole", "none": "pinhole", "equidistant": "equidistant"}


def _kalibr_camera(path: Path, cam: Any, name: str,
                   image_size_px: tuple[int, int] | None) -> dict[str, Any]:
    if not isinstance(cam, dict):
        raise SlitcliError(f"{path}: '{name}' is missing or not a mapping; a Kalibr camchain "
                           "needs cam0 and cam1")
    model = cam.get("camera_model")
    if model != "pinhole":
        raise SlitcliError(f"{path}: {name}.camera_model '{model}' is not supported; slitcli "
                           "reads pinhole cameras only (recalibrate with pinhole-radtan or "
                           "pinhole-equidistant)")
    dmodel = cam.get("distortion_model")
    if dmodel not in _KALIBR_MODELS:
        raise SlitcliError(f"{path}: {name}.distortion_model '{dmodel}' is not supported; "
                           "slitcli reads radtan, equidistant (or none)")
    intr = _matrix(path, cam.get("intrinsics"), f"{name}.intrinsics", (1, 4)).ravel()
    coeffs = np.asarray(cam.get("distortion_coeffs") or [0.0, 0.0, 0.0, 0.0], dtype=float)
    if coeffs.size != 4 or not np.all(np.isfinite(coeffs)):
        names = "k1, k2, k3, k4" if dmodel == "equidistant" else "k1, k2, r1, r2"
        raise SlitcliError(f"{path}: {name}.distortion_coeffs must be 4 numbers [{names}]")
    res = cam.get("resolution")
    if res is None and image_size_px is not None:
        size = _size(path, *image_size_px)
    elif not isinstance(res, list) or len(res) != 2:
        raise SlitcliError(f"{path}: {name}.resolution must be [width, height] (or give "
                           "`image_size_px` W,H)", param="image_size_px")
    else:
        size = _size(path, res[0], res[1])
    K = np.array([[intr[0], 0.0, intr[2]], [0.0, intr[1], intr[3]], [0.0, 0.0, 1.0]])
    return {"K": K, "D": coeffs, "size": size, "model": _KALIBR_MODELS[dmodel]}


def _kalibr_pose(path: Path, c0: Any, c1: dict[str, Any]) -> np.ndarray:
    """4x4 ``[R T; 0 1]`` taking cam0 points to cam1 (module docstring)."""
    if "T_cn_cnm1" in c1:
        return _matrix(path, c1["T_cn_cnm1"], "cam1.T_cn_cnm1", (4, 4))
    for key, to_cam in (("T_cam_imu", True), ("T_imu_cam", False)):
        if key in c0 and key in c1:
            a = _matrix(path, c0[key], f"cam0.{key}", (4, 4))
            b = _matrix(path, c1[key], f"cam1.{key}", (4, 4))
            for nm, m in (("cam0", a), ("cam1", b)):
                if not np.allclose(m[3], [0.0, 0.0, 0.0, 1.0]) or \
                        not np.allclose(m[:3, :3] @ m[:3, :3].T, np.eye(3), atol=1e-6):
                    raise SlitcliError(f"{path}: {nm}.{key} is not a rigid transform "
                                       "(rotation + translation, last row 0 0 0 1)")
            return b @ _rigid_inverse(a) if to_cam else _rigid_inverse(b) @ a
    raise SlitcliError(f"{path}: no pose of cam1: give cam1.T_cn_cnm1 (cam0 to cam1), or "
                       "T_cam_imu / T_imu_cam in both cameras")


def _rigid_inverse(m: np.ndarray) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3] = m[:3, :3].T
    out[:3, 3] = -m[:3, :3].T @ m[:3, 3]
    return out


def import_kalibr(path: Path, data: Any,
                  image_size_px: tuple[int, int] | None = None) -> RawCalibration:
    """A Kalibr camchain (cam0 = left, cam1 = right; pose: module docstring)."""
    c0 = _kalibr_camera(path, data.get("cam0"), "cam0", image_size_px)
    c1 = _kalibr_camera(path, data.get("cam1"), "cam1", image_size_px)
    Tm = _kalibr_pose(path, data["cam0"], data["cam1"])
    if c0["size"] != c1["size"]:
        raise SlitcliError(f"{path}: cam1.resolution {c1['size']} differs from cam0's "
                           f"{c0['size']}; slitcli needs one image size")
    if c0["model"] != c1["model"]:
        raise SlitcliError(f"{path}: cam0 and cam1 have different distortion models; "
                           "slitcli needs one lens model for both cameras")
    return rectify_raw(c0["K"], c0["D"], c1["K"], c1["D"], c0["size"], Tm[:3, :3], Tm[:3, 3],
                       source=str(path), model=c0["model"])


# ---------------------------------------------------------------------- entry points
def detect_format(path: Path, text: str) -> str:
    """``opencv``, ``kalibr`` or ``ros`` from a file's content."""
    head = text.lstrip()[:40]
    if "!!opencv-" in text or head.startswith("<?xml"):
        return "opencv"
    # a "%YAML:1.0" header alone says nothing: Kalibr-style chains carry it too
    data = _yaml(path, text)
    if isinstance(data, dict) and "cam0" in data:
        return "kalibr"
    if isinstance(data, dict) and "camera_matrix" in data:
        return "ros"
    if isinstance(data, dict) and ({"M1", "D1"} <= set(data) or {"R", "T"} <= set(data)):
        return "opencv"
    raise SlitcliError(f"{path}: not a ROS camera_info, OpenCV FileStorage or Kalibr camchain "
                       "file; give one of those (or `fmt`)", param="fmt")


def import_raw(paths: list[str | Path], fmt: str = "auto", *,
               image_size_px: tuple[int, int] | None = None) -> RawCalibration:
    """Read calibration files (format ``auto`` detects it from the content).

    ``image_size_px`` (width, height) is used where the files give no image size.
    """
    ps = [Path(p) for p in paths]
    if not ps:
        raise SlitcliError("rig import: give at least one calibration file")
    texts = [_read_text(p) for p in ps]
    kinds = [detect_format(p, t) if fmt == "auto" else fmt for p, t in zip(ps, texts,
                                                                           strict=True)]
    if len(set(kinds)) != 1:
        raise SlitcliError(f"{ps[1]}: is {kinds[1]} but {ps[0]} is {kinds[0]}; give files of one "
                           "format")
    kind = kinds[0]
    if kind == "opencv":
        return import_opencv(ps, image_size_px)
    docs = [_yaml(p, t) for p, t in zip(ps, texts, strict=True)]
    for p, d in zip(ps, docs, strict=True):
        if not isinstance(d, dict):
            raise SlitcliError(f"{p}: not a YAML mapping; give a {kind} calibration file")
    if kind == "ros":
        return import_ros(ps, docs)
    if kind == "kalibr":
        if len(ps) != 1:
            raise SlitcliError(f"{ps[1]}: a Kalibr camchain is one file; give only it")
        return import_kalibr(ps[0], docs[0], image_size_px)
    raise SlitcliError(f"`fmt` {kind}: unknown; use one of {', '.join(FORMATS)}",
                       param="fmt")


def run_rig_import(paths: list[str | Path], out_rig: str | Path, *, fmt: str = "auto",
                   base_rig: str | Path | None = None, name: str | None = None,
                   image_size_px: tuple[int, int] | None = None,
                   overwrite: bool = False) -> Rig:
    """``slitcli rig import``: calibration files to a rig file (written atomically).

    ``out_rig`` must be none of the inputs and must not exist unless ``overwrite``.
    """
    from slitcli.io.atomic import check_output_file
    from slitcli.rig import save_rig

    check_output_file(out_rig, inputs=[*paths, base_rig], overwrite=overwrite)
    raw = import_raw(paths, fmt, image_size_px=image_size_px)
    base = load_rig(base_rig) if base_rig is not None else None
    rig = rig_with_raw(raw, base, name=name or (base.name if base else "imported"),
                       source=str(paths[0]))
    save_rig(rig, out_rig)
    return rig


def export_texts(rig: Rig, fmt: str) -> dict[str, str]:
    """File name -> content of a rig exported in ``fmt`` (nothing is written here)."""
    raw = _raw_of(rig)
    K1, K2, D1, D2 = raw.array("K1"), raw.array("K2"), raw.array("D1"), raw.array("D2")
    R, T = raw.array("R"), raw.array("T")
    R1, R2, P1, P2 = raw.array("R1"), raw.array("R2"), raw.array("P1"), raw.array("P2")
    size = raw.image_size_px
    if fmt == "ros":
        return {"left.yaml": _ros_camera("left", size, K1, D1, R1, P1, raw.model),
                "right.yaml": _ros_camera("right", size, K2, D2, R2, P2, raw.model)}
    if fmt == "opencv":
        if raw.model != "pinhole":
            raise SlitcliError(f"rig: OpenCV stereo files have no key for the {raw.model} "
                               "lens model; export to kalibr or ros instead")
        intr = _fs_text({"image_width": int(size[0]), "image_height": int(size[1]),
                         "M1": K1, "D1": D1.reshape(1, -1), "M2": K2, "D2": D2.reshape(1, -1)})
        extr = _fs_text({"R": R, "T": T.reshape(3, 1), "R1": R1, "R2": R2, "P1": P1, "P2": P2,
                         "Q": _q_matrix(P1, P2)})
        return {"intrinsics.yml": intr, "extrinsics.yml": extr}
    if fmt == "kalibr":
        cams = {}
        for i, (K, D) in enumerate(((K1, D1), (K2, D2))):
            if raw.model == "pinhole" and D.size > 4 and np.any(D[4:] != 0):
                raise SlitcliError(f"rig: camera {i} has distortion beyond k1 k2 p1 p2 "
                                   f"({np.round(D[4:], 6).tolist()}); Kalibr's radtan cannot "
                                   "hold it, export to ros or opencv instead")
            if K[0, 1] != 0:
                raise SlitcliError(f"rig: camera {i} has skew K[0,1] = {K[0, 1]:g}; Kalibr's "
                                   "pinhole has none, export to ros or opencv instead")
            cam: dict[str, Any] = {}
            if i == 1:
                Tm = np.eye(4)
                Tm[:3, :3], Tm[:3, 3] = R, T
                cam["T_cn_cnm1"] = [[float(x) for x in row] for row in Tm]
            cam.update({"camera_model": "pinhole",
                        "intrinsics": [float(K[0, 0]), float(K[1, 1]), float(K[0, 2]),
                                       float(K[1, 2])],
                        "distortion_model": "radtan" if raw.model == "pinhole"
                        else raw.model,
                        "distortion_coeffs": [float(x) for x in np.append(D, [0.0] * 4)[:4]],
                        "resolution": [int(size[0]), int(size[1])],
                        "rostopic": f"/cam{i}/image_raw", "cam_overlaps": [1 - i]})
            cams[f"cam{i}"] = cam
        return {"camchain.yaml": yaml.safe_dump(cams, sort_keys=False, default_flow_style=None)}
    raise SlitcliError(f"`fmt` {fmt}: unknown; use one of {', '.join(FORMATS)}", param="fmt")


def run_rig_export(rig_path: str | Path, fmt: str, out_dir: str | Path) -> list[Path]:
    """``slitcli rig export``: write the rig's calibration files into ``out_dir``.

    All contents are built (and checked) before the first file is written; each file is
    written atomically.
    """
    rig = load_rig(rig_path)
    texts = export_texts(rig, fmt)
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise SlitcliError(f"{out}: exists and is not a folder; give an output folder")
    from slitcli.io.atomic import check_output_file

    for name in texts:  # existing exports are replaced, the rig file itself never
        check_output_file(out / name, inputs=[rig_path], overwrite=True)
    written = []
    for name, text in texts.items():
        write_text_atomic(out / name, text)
        written.append(out / name)
    return written
