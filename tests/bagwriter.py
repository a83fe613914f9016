"""Write small ROS 1 / ROS 2 bags of stereo frames with the rosbags Writer (test helper)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Writer2
from rosbags.typesys import Stores, get_typestore

IMAGE = "sensor_msgs/msg/Image"


def _image(ts, t_ns: int, bgr: np.ndarray, pad: int = 0):
    types = ts.types
    header_cls = types["std_msgs/msg/Header"]
    extra = {"seq": 0} if "seq" in header_cls.__dataclass_fields__ else {}
    stamp = types["builtin_interfaces/msg/Time"](sec=t_ns // 10**9, nanosec=t_ns % 10**9)
    return types[IMAGE](header=header_cls(stamp=stamp, frame_id="cam", **extra),
                        height=bgr.shape[0], width=bgr.shape[1], encoding="bgr8",
                        is_bigendian=0, step=bgr.shape[1] * 3 + pad,
                        data=padded_rows(bgr, pad).reshape(-1))


def padded_rows(bgr: np.ndarray, pad: int) -> np.ndarray:
    """The image's rows as a driver that aligns rows writes them: ``pad`` bytes more each
    (filled with 255, so an unpadded read shifts visibly)."""
    h, w = bgr.shape[:2]
    rows = np.full((h, w * 3 + pad), 255, np.uint8)
    rows[:, : w * 3] = np.ascontiguousarray(bgr).reshape(h, -1)
    return rows


def write_bag(path: Path, frames: list[tuple[np.ndarray, np.ndarray]], *, ros: int,
              t0_ns: int = 1_700_000_000 * 10**9, dt_ns: int = 200_000_000,
              right_offset_ns: int = 2_000_000, right_divisor: int = 1,
              storage: str = "sqlite3", right_offsets_ns: list[int] | None = None,
              pad: int = 0, left_stamps_ns: list[int] | None = None) -> Path:
    """Frames as /stereo/left/image_raw and /stereo/right/image_raw; returns the bag path.

    ``right_offsets_ns`` (one per frame) replaces the constant ``right_offset_ns``;
    ``pad`` bytes pad every image row (``step`` > width x 3); ``left_stamps_ns`` replaces
    the left header stamps."""
    if ros == 1:
        ts = get_typestore(Stores.ROS1_NOETIC)
        writer, ser = Writer1(path), ts.serialize_ros1
    else:
        ts = get_typestore(Stores.ROS2_HUMBLE)
        plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
        writer, ser = Writer2(path, version=9, storage_plugin=plugin), ts.serialize_cdr
    with writer as w:
        cl = w.add_connection("/stereo/left/image_raw", IMAGE, typestore=ts)
        cr = w.add_connection("/stereo/right/image_raw", IMAGE, typestore=ts)
        for i, (left, right) in enumerate(frames):
            t = t0_ns + i * dt_ns
            off = right_offset_ns if right_offsets_ns is None else right_offsets_ns[i]
            tr = (t + off) // right_divisor
            tl = t if left_stamps_ns is None else left_stamps_ns[i]
            w.write(cl, t, ser(_image(ts, tl, left, pad), IMAGE))
            w.write(cr, t + off, ser(_image(ts, tr, right, pad), IMAGE))
    return path
