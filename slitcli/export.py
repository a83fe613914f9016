"""A detection run as ROS messages: ``sensor_msgs/LaserScan`` per frame (and images).

A per-bearing range table is a laser scan: bins ascend from right to left, which is
the counter-clockwise order of REP 103 (x forward, y left, z up) that
``sensor_msgs/LaserScan`` uses. Each frame of ``ranges.csv`` becomes three scans in the
sensor frame (docs/export.md):

- ``/slitcli/scan``: the fused range (Eq. 11), ``fused_range_m``;
- ``/slitcli/scan/laser``: ``laser_range_m``;
- ``/slitcli/scan/stereo``: ``stereo_range_m``;

with ``angle_min`` the first bin's bearing and ``angle_increment`` the bin width (rad),
ranges in metres as float32, and ``+inf`` where a bin has no return (REP 117: nothing
within the sensor's range). The bag is written with the ``rosbags`` package: a ROS 2
MCAP file (``.mcap``), a ROS 1 bag (``.bag``), or a ROS 2 sqlite3 bag folder (no suffix).
"""

from __future__ import annotations

import math
import os
import shutil
import tempfile
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from slitcli.errors import SlitcliError
from slitcli.report.run import (
    DetectRun,
    bag_stamps_ns,
    frame_times_s,
    left_images,
    load_run,
    stereo_min_range_m,
)

TOPIC_FUSED = "/slitcli/scan"
TOPIC_LASER = "/slitcli/scan/laser"
TOPIC_STEREO = "/slitcli/scan/stereo"
TOPIC_LEFT = "/slitcli/left/image_rect"
TOPIC_DISTANCE = "/slitcli/distance/image"
TOPIC_CAMERA_INFO = "/slitcli/left/camera_info"
TOPIC_TF_STATIC = "/tf_static"
LASER_SCAN = "sensor_msgs/msg/LaserScan"
IMAGE = "sensor_msgs/msg/Image"
CAMERA_INFO = "sensor_msgs/msg/CameraInfo"
TF_MESSAGE = "tf2_msgs/msg/TFMessage"
FORMATS = {".mcap": "ROS 2 MCAP", ".bag": "ROS 1", "": "ROS 2 sqlite3"}


@dataclass(frozen=True, kw_only=True)
class ExportParams:
    """How a run becomes messages.

    Attributes
    ----------
    frame_id : str
        ``header.frame_id`` of the scans (the sensor frame: x forward, y left, z up,
        origin on the floor below the left camera).
    camera_frame_id : str
        ``header.frame_id`` of the images (the left camera's optical frame).
    period_s : float
        Frame period, seconds, for runs whose frames have no times: frame ``i`` is
        stamped ``i * period_s``; also each scan's ``scan_time`` when the times do not
        give one.
    images : bool
        Also write the rectified left image (``bgr8``), where the run saved it the
        distance image (``16UC1``, millimetres, 0 = invalid, REP 118), the camera's
        ``CameraInfo`` and its pose in the scans' frame on ``/tf_static``.
    """

    frame_id: str = "slitcli_sensor"
    camera_frame_id: str = "slitcli_camera_optical"
    period_s: float = 0.1
    images: bool = False

    def __post_init__(self) -> None:
        if not (math.isfinite(self.period_s) and self.period_s > 0):
            raise SlitcliError(f"`period_s` {self.period_s} must be a positive number of "
                               "seconds", param="period_s")
        for name, value in (("frame_id", self.frame_id),
                            ("camera_frame_id", self.camera_frame_id)):
            if not value or any(c.isspace() for c in value):
                raise SlitcliError(f"`{name}` {value!r} must be a non-empty name without "
                                   "spaces", param=name)


@dataclass(frozen=True)
class ExportSummary:
    path: Path
    kind: str
    frames: int
    messages: int
    times: str
    outside_limits: int

    def line(self) -> str:
        note = (f"; {self.outside_limits} ranges lie outside their scan's range_min/max "
                "(viewers hide them)" if self.outside_limits else "")
        return (f"export: {self.frames} frames, {self.messages} messages ({self.kind}, "
                f"stamps from {self.times}){note} -> {self.path}")


def output_kind(path: str | Path) -> str:
    """The bag format an output name asks for: ``.mcap``, ``.bag`` or ``""`` (a folder)."""
    suffix = Path(path).suffix.lower()
    if suffix in (".mcap", ".bag"):
        return suffix
    if suffix:
        raise SlitcliError(f"{path}: unknown bag format {suffix!r}; name the output .mcap "
                           "(ROS 2 MCAP), .bag (ROS 1) or a folder without a suffix (ROS 2 "
                           "sqlite3)")
    return ""


@dataclass(frozen=True)
class ScanLayout:
    """The fixed fields of the run's scans (radians, metres)."""

    angle_min_rad: float
    angle_max_rad: float
    angle_increment_rad: float
    scan_time_s: float
    limits_m: dict[str, tuple[float, float]]


def scan_layout(run: DetectRun, times_s: np.ndarray) -> ScanLayout:
    """Angles from the bins and each topic's range limits from the rig.

    The laser's limits are its band (``laser.min_range_m``-``laser.max_range_m``);
    stereo's run from the nearest range its disparity search reaches (Eq. 8) to
    ``stereo.max_range_m``; the fused scan spans both.
    """
    rig = run.rig
    st_min = stereo_min_range_m(run)
    laser = (rig.laser.min_range_m, rig.laser.max_range_m)
    stereo = (st_min, rig.stereo.max_range_m)
    fused = (min(laser[0], stereo[0]), max(laser[1], stereo[1]))
    dt = np.diff(times_s)
    scan_time = float(np.median(dt)) if dt.size else 0.0
    b = np.radians(run.bearing_deg)
    return ScanLayout(float(b[0]), float(b[-1]), math.radians(run.bin_deg), scan_time,
                      {TOPIC_FUSED: fused, TOPIC_LASER: laser, TOPIC_STEREO: stereo})


def scan_ranges(range_m: np.ndarray) -> np.ndarray:
    """Ranges as a LaserScan holds them: float32 metres, ``+inf`` for no return (REP 117)."""
    r = np.asarray(range_m, dtype=np.float32)
    return np.where(np.isfinite(r), r, np.float32(np.inf)).astype(np.float32)


class _Bag:
    """A rosbags writer for one of the three formats, with its typestore."""

    def __init__(self, path: Path, kind: str) -> None:
        from rosbags.typesys import Stores, get_typestore

        if kind == ".bag":
            from rosbags.rosbag1 import Writer as Writer1

            self.ts = get_typestore(Stores.ROS1_NOETIC)
            self.writer: Any = Writer1(path)
            self.serialize = self.ts.serialize_ros1
        else:
            from rosbags.rosbag2 import StoragePlugin
            from rosbags.rosbag2 import Writer as Writer2

            self.ts = get_typestore(Stores.ROS2_HUMBLE)
            plugin = StoragePlugin.MCAP if kind == ".mcap" else StoragePlugin.SQLITE3
            self.writer = Writer2(path, version=9, storage_plugin=plugin)
            self.serialize = self.ts.serialize_cdr
        self.ros1 = kind == ".bag"
        self.conns: dict[str, Any] = {}

    def connect(self, topic: str, msgtype: str, *, latched: bool = False) -> None:
        """Add a topic; ``latched``: a late subscriber still gets the last message
        (ROS 1 latching, ROS 2 transient-local durability), as ``/tf_static`` needs."""
        extra: dict[str, Any] = {}
        if latched and self.ros1:
            extra["latching"] = 1
        elif latched:
            from rosbags.interfaces import (
                Qos,
                QosDurability,
                QosHistory,
                QosLiveliness,
                QosReliability,
                QosTime,
            )

            zero = QosTime(0, 0)
            extra["offered_qos_profiles"] = [Qos(
                QosHistory.KEEP_LAST, 1, QosReliability.RELIABLE,
                QosDurability.TRANSIENT_LOCAL, zero, zero, QosLiveliness.AUTOMATIC, zero,
                False)]
        if msgtype not in self.ts.types and msgtype == TF_MESSAGE:
            # the ROS 1 store lacks tf2_msgs; register it on this (private) store
            from rosbags.typesys import get_types_from_msg

            self.ts.register(get_types_from_msg(
                "geometry_msgs/TransformStamped[] transforms", TF_MESSAGE))
        self.conns[topic] = self.writer.add_connection(topic, msgtype, typestore=self.ts,
                                                       **extra)

    def header(self, stamp_ns: int, frame_id: str, seq: int) -> Any:
        types = self.ts.types
        stamp = types["builtin_interfaces/msg/Time"](sec=int(stamp_ns // 10**9),
                                                     nanosec=int(stamp_ns % 10**9))
        extra = {"seq": seq} if self.ros1 else {}
        return types["std_msgs/msg/Header"](stamp=stamp, frame_id=frame_id, **extra)

    def write(self, topic: str, stamp_ns: int, msg: Any) -> None:
        self.writer.write(self.conns[topic], stamp_ns, self.serialize(msg, msg.__msgtype__))


def _scan_msg(bag: _Bag, layout: ScanLayout, topic: str, header: Any,
              ranges_m: np.ndarray) -> Any:
    lo, hi = layout.limits_m[topic]
    return bag.ts.types[LASER_SCAN](
        header=header, angle_min=layout.angle_min_rad, angle_max=layout.angle_max_rad,
        angle_increment=layout.angle_increment_rad, time_increment=0.0,
        scan_time=layout.scan_time_s, range_min=float(lo), range_max=float(hi),
        ranges=scan_ranges(ranges_m), intensities=np.zeros(0, dtype=np.float32))


def _image_msg(bag: _Bag, header: Any, image: np.ndarray, encoding: str) -> Any:
    img = np.ascontiguousarray(image)
    if img.dtype == np.uint16:
        img = img.astype("<u2")  # little endian, is_bigendian = 0
    return bag.ts.types[IMAGE](
        header=header, height=img.shape[0], width=img.shape[1], encoding=encoding,
        is_bigendian=0, step=img.shape[1] * img.itemsize * (img.shape[2] if img.ndim == 3
                                                            else 1),
        data=img.reshape(-1).view(np.uint8))


def quaternion_xyzw(rotation: np.ndarray) -> np.ndarray:
    """Unit quaternion (x, y, z, w), w >= 0, of a 3 x 3 rotation matrix.

    Uses the largest of the four ``|q_i|`` candidates (Shepperd's method), so it is
    accurate for every rotation.
    """
    m = np.asarray(rotation, dtype=np.float64)
    t = np.trace(m)
    cand = np.array([1 + 2 * m[0, 0] - t, 1 + 2 * m[1, 1] - t, 1 + 2 * m[2, 2] - t, 1 + t])
    k = int(np.argmax(cand))
    q = np.empty(4)
    q[k] = 0.5 * math.sqrt(max(cand[k], 0.0))
    f = 0.25 / q[k]
    # off-diagonal sums and differences give the other three components
    if k == 3:
        q[:3] = f * np.array([m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1]])
    else:
        i, j, l = k, (k + 1) % 3, (k + 2) % 3
        q[j] = f * (m[j, i] + m[i, j])
        q[l] = f * (m[l, i] + m[i, l])
        q[3] = f * (m[l, j] - m[j, l])
    q /= np.linalg.norm(q)
    return -q if q[3] < 0 else q


def _camera_msgs(bag: _Bag, run: DetectRun, p: ExportParams, stamp_ns: int
                 ) -> tuple[Any, Any]:
    """The left camera's CameraInfo and the sensor -> camera transform (from the rig).

    The images are rectified, so the model is the rectified pinhole (no distortion,
    R = I, P = [K | 0]). The transform places the camera's optical frame (x right,
    y down, z forward) in the scans' frame: rotation ``R_sensor_from_cam``, translation
    the optical centre (DESIGN §2).
    """
    types, rig = bag.ts.types, run.rig
    k = np.array([rig.left.fx_px, 0.0, rig.left.cx_px, 0.0, rig.left.fy_px, rig.left.cy_px,
                  0.0, 0.0, 1.0])
    proj = np.array([rig.left.fx_px, 0.0, rig.left.cx_px, 0.0, 0.0, rig.left.fy_px,
                     rig.left.cy_px, 0.0, 0.0, 0.0, 1.0, 0.0])
    arrays = {"d": np.zeros(5), "k": k, "r": np.eye(3).ravel(), "p": proj}
    if bag.ros1:
        arrays = {key.upper(): v for key, v in arrays.items()}
    roi = types["sensor_msgs/msg/RegionOfInterest"](x_offset=0, y_offset=0, height=0,
                                                   width=0, do_rectify=False)
    info = types[CAMERA_INFO](
        header=bag.header(stamp_ns, p.camera_frame_id, 0), height=rig.height_px,
        width=rig.width_px, distortion_model="plumb_bob", binning_x=0, binning_y=0, roi=roi,
        **arrays)
    qx, qy, qz, qw = quaternion_xyzw(rig.R_sensor_from_cam)
    tx, ty, tz = (float(v) for v in rig.cam_origin_sensor_xyz)
    tf = types["geometry_msgs/msg/TransformStamped"](
        header=bag.header(stamp_ns, p.frame_id, 0), child_frame_id=p.camera_frame_id,
        transform=types["geometry_msgs/msg/Transform"](
            translation=types["geometry_msgs/msg/Vector3"](x=tx, y=ty, z=tz),
            rotation=types["geometry_msgs/msg/Quaternion"](x=qx, y=qy, z=qz, w=qw)))
    return info, types[TF_MESSAGE](transforms=[tf])


def stamps_ns(run: DetectRun, params: ExportParams, source: str | Path | None
              ) -> tuple[np.ndarray, str]:
    """Each frame's stamp in nanoseconds, and where it came from.

    A bag run takes the bag's own left stamps when the bag is at hand (exact), else the
    table's ``time_s``; frames without a time get ``index x period_s``.
    """
    exact = bag_stamps_ns(run, source)
    if exact is not None:
        return exact.astype(np.int64), "the input bag"
    t, own = frame_times_s(run, params.period_s)
    if own and t[0] < 0:
        t, own = run.frames.astype(np.float64) * params.period_s, False
    what = "time_s" if own else f"frame index x {params.period_s:g} s"
    return np.rint(t * 1e9).astype(np.int64), what


def export_run(run_dir: str | Path, out: str | Path, *,
               params: ExportParams | None = None, source: str | Path | None = None,
               overwrite: bool = False, on_total: Callable[[int], None] | None = None,
               on_frame: Callable[[], None] | None = None) -> ExportSummary:
    """Write a detection run as a ROS bag (module docstring; docs/export.md).

    Parameters
    ----------
    run_dir : path
        The output folder of ``slitcli detect``.
    out : path
        ``*.mcap``, ``*.bag`` or a folder name (ROS 2 sqlite3). Written under a
        temporary name and renamed when complete.
    params : ExportParams
    source : path, optional
        The run's input (sequence folder or bag), for the images and a bag's exact
        stamps; default: the path the manifest records.
    overwrite : bool
        Replace an existing ``out``.

    Raises
    ------
    SlitcliError
        Not a detect run, an existing output without ``overwrite``, a bad name.
    """
    p = ExportParams() if params is None else params
    final = Path(out)
    kind = output_kind(final)
    if final.exists() and not overwrite:
        raise SlitcliError(f"{final}: already exists; choose another name or set `overwrite`",
                           param="overwrite")
    if final.exists() and (final.is_dir() != (kind == "")):
        raise SlitcliError(f"{final}: exists and is a {'folder' if final.is_dir() else 'file'}"
                           "; choose another name")
    run = load_run(run_dir)
    stamps, what = stamps_ns(run, p, source)
    layout = scan_layout(run, stamps * 1e-9)
    images = _image_frames(run, p, source) if p.images else None
    if on_total is not None:
        on_total(run.n_frames)
    try:
        final.parent.mkdir(parents=True, exist_ok=True)
        tmp_dir = Path(tempfile.mkdtemp(prefix=f".{final.name}.", suffix=".tmp",
                                        dir=final.parent))
    except OSError as e:
        raise SlitcliError(f"{final.parent}: cannot write there ({e.strerror}); check the path "
                           "and permissions") from None
    try:
        inner = tmp_dir / (final.stem if kind == ".mcap" else final.name)
        n_msgs = _write(inner, kind, run, p, layout, stamps, images, on_frame)
        made = inner / f"{inner.name}.mcap" if kind == ".mcap" else inner
        _replace(made, final, tmp_dir)
    finally:
        shutil.rmtree(tmp_dir, ignore_errors=True)
    outside = _outside(run, layout)
    return ExportSummary(final, FORMATS[kind], run.n_frames, n_msgs, what, outside)


def _outside(run: DetectRun, layout: ScanLayout) -> int:
    n = 0
    for topic, r in ((TOPIC_FUSED, run.fused_range_m), (TOPIC_LASER, run.laser_range_m),
                     (TOPIC_STEREO, run.stereo_range_m)):
        lo, hi = layout.limits_m[topic]
        f = np.isfinite(r)
        n += int(np.count_nonzero(f & ((r < lo) | (r > hi))))
    return n


def _write(path: Path, kind: str, run: DetectRun, p: ExportParams, layout: ScanLayout,
           stamps: np.ndarray, images: Iterator[tuple[np.ndarray, np.ndarray | None]] | None,
           on_frame: Callable[[], None] | None) -> int:
    bag = _Bag(path, kind)
    scans = ((TOPIC_FUSED, run.fused_range_m), (TOPIC_LASER, run.laser_range_m),
             (TOPIC_STEREO, run.stereo_range_m))
    n = 0
    with bag.writer:
        for topic, _ in scans:
            bag.connect(topic, LASER_SCAN)
        if images is not None:
            bag.connect(TOPIC_LEFT, IMAGE)
            bag.connect(TOPIC_DISTANCE, IMAGE)
            bag.connect(TOPIC_CAMERA_INFO, CAMERA_INFO)
            bag.connect(TOPIC_TF_STATIC, TF_MESSAGE, latched=True)
            bag.write(TOPIC_TF_STATIC, int(stamps[0]), _camera_msgs(bag, run, p,
                                                                  int(stamps[0]))[1])
            n += 1
        for i in range(run.n_frames):
            stamp = int(stamps[i])
            for topic, r in scans:
                hdr = bag.header(stamp, p.frame_id, int(run.frames[i]))
                bag.write(topic, stamp, _scan_msg(bag, layout, topic, hdr, r[i]))
                n += 1
            if images is not None:
                left, dist = next(images)
                hdr = bag.header(stamp, p.camera_frame_id, int(run.frames[i]))
                bag.write(TOPIC_LEFT, stamp, _image_msg(bag, hdr, left, "bgr8"))
                info = _camera_msgs(bag, run, p, stamp)[0]
                bag.write(TOPIC_CAMERA_INFO, stamp, info)
                n += 2
                if dist is not None:
                    bag.write(TOPIC_DISTANCE, stamp, _image_msg(bag, hdr, dist, "16UC1"))
                    n += 1
            if on_frame is not None:
                on_frame()
    return n


def _image_frames(run: DetectRun, p: ExportParams, source: str | Path | None
                  ) -> Iterator[tuple[np.ndarray, np.ndarray | None]]:
    """Per frame: the rectified left image and the saved distance image (or None)."""
    import cv2

    names = run.frame_names()
    frames = left_images(run, source)
    # resolve the source now, so a missing input fails before anything is written
    first = next(frames)

    def gen() -> Iterator[tuple[np.ndarray, np.ndarray | None]]:
        for k, (_, left) in enumerate(_chain(first, frames)):
            path = run.folder / "distance" / f"{names[k]}.png"
            dist = cv2.imread(str(path), cv2.IMREAD_UNCHANGED) if path.exists() else None
            yield left, dist if dist is not None and dist.dtype == np.uint16 else None

    return gen()


def _chain(first: tuple[int, np.ndarray], rest: Iterator[tuple[int, np.ndarray]]
           ) -> Iterator[tuple[int, np.ndarray]]:
    yield first
    yield from rest


def _replace(made: Path, final: Path, tmp_dir: Path) -> None:
    """Move the finished bag onto ``final`` (an existing one is replaced only now)."""
    if final.is_dir():
        old = tmp_dir / ".old"
        os.replace(final, old)
        os.replace(made, final)
    else:
        os.replace(made, final)


__all__ = ["TOPIC_FUSED", "TOPIC_LASER", "TOPIC_STEREO", "ExportParams", "ExportSummary",
           "export_run", "scan_ranges"]
