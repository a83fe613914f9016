"""Stereo pairs from ROS 1 and ROS 2 bags (``.bag``, ``.db3``, ``.mcap``) via rosbags.

Left and right images come from two topics (``sensor_msgs/Image`` or
``sensor_msgs/CompressedImage``) and are paired by their header stamps: each left image
takes the nearest right image within ``max_dt_s``, one to one, in time order. Frames are
numbered 0, 1, ... in the order of the left stamps; ``time_s`` is the left stamp.
Pairing needs only the stamps (a first pass); images are decoded in a second pass, one
pair at a time, so memory does not grow with the bag.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from slitcli.errors import SlitcliError
from slitcli.io.sequence import StereoFrame

BAG_SUFFIXES = (".bag", ".db3", ".mcap")
IMAGE_TYPES = ("sensor_msgs/msg/Image", "sensor_msgs/msg/CompressedImage")


def is_bag(path: str | Path) -> bool:
    """A ROS 1 ``.bag`` file, a ROS 2 storage file, or a ROS 2 bag folder."""
    p = Path(path)
    return p.suffix in BAG_SUFFIXES or (p.is_dir() and (p / "metadata.yaml").exists())


def _bag_root(path: Path) -> Path:
    # rosbags opens a ROS 2 bag by its folder (metadata.yaml beside the storage files)
    if path.suffix in (".db3", ".mcap") and path.is_file():
        return path.parent
    return path


@dataclass(frozen=True)
class BagPairs:
    """The pairing of one bag: per frame, the left and right message stamps (ns).

    ``all_left_ns`` and ``all_right_ns`` are every stamp of each topic (sorted), so the
    images that found no partner within ``max_dt_s`` can be reported
    (:meth:`pairing_report`).
    """

    path: Path
    left_topic: str
    right_topic: str
    left_ns: np.ndarray
    right_ns: np.ndarray
    all_left_ns: np.ndarray
    all_right_ns: np.ndarray
    max_dt_s: float

    def __len__(self) -> int:
        return len(self.left_ns)

    @property
    def unpaired(self) -> tuple[int, int]:
        """Left and right images without a partner."""
        return len(self.all_left_ns) - len(self), len(self.all_right_ns) - len(self)

    def suggested_max_dt_s(self) -> float:
        """Half the left camera's median frame period: the largest tolerance that still
        cannot pair an image with its neighbour's partner (free-running cameras at one
        rate are at most half a period apart)."""
        if len(self.all_left_ns) < 2:
            return self.max_dt_s
        return 0.5 * float(np.median(np.diff(self.all_left_ns))) * 1e-9

    def pairing_report(self) -> str | None:
        """One line when images were left unpaired (None when every image has a
        partner): how many of each camera, the stamp differences seen, the fix."""
        n_l, n_r = self.unpaired
        if n_l == 0 and n_r == 0:
            return None
        paired_ms = np.abs(self.right_ns - self.left_ns) * 1e-6
        j = np.clip(np.searchsorted(self.all_right_ns, self.all_left_ns), 1,
                    max(len(self.all_right_ns) - 1, 1))
        near = np.minimum(np.abs(self.all_right_ns[j] - self.all_left_ns),
                          np.abs(self.all_right_ns[j - 1] - self.all_left_ns)) * 1e-6
        suggest = self.suggested_max_dt_s()
        fix = (f"; for free-running cameras try `max_dt_s` {suggest:.3g} (half the frame "
               "period)" if suggest > self.max_dt_s else "")
        return (f"{self.path}: {n_l} of {len(self.all_left_ns)} left and {n_r} of "
                f"{len(self.all_right_ns)} right images found no partner within `max_dt_s` "
                f"{self.max_dt_s:g} s (paired: {np.median(paired_ms):.3g} ms apart median, "
                f"{paired_ms.max():.3g} ms max; nearest partner of every left image: up to "
                f"{near.max():.3g} ms){fix}")


def _stamp_ns(msg: object, log_ns: int) -> int:
    st = getattr(getattr(msg, "header", None), "stamp", None)
    if st is None:
        return log_ns
    ns = int(st.sec) * 1_000_000_000 + int(st.nanosec)
    return ns if ns > 0 else log_ns


def _open(path: Path):  # returns rosbags' AnyReader, opened
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    if not path.exists():
        raise SlitcliError(f"{path}: bag not found; give a .bag file or a ROS 2 bag folder")
    try:
        reader = AnyReader([_bag_root(path)],
                           default_typestore=get_typestore(Stores.ROS2_HUMBLE))
        reader.open()
    except Exception as e:  # rosbags raises several types for unreadable bags
        raise SlitcliError(f"{path}: cannot open the bag ({e.__class__.__name__}: "
                           f"{str(e).splitlines()[0] if str(e) else 'unreadable'}); check that "
                           "it is a ROS 1 .bag or a ROS 2 bag folder") from None
    return reader


def pair_bag(path: str | Path, left_topic: str, right_topic: str, max_dt_s: float) -> BagPairs:
    """Read the stamps of both topics and pair them (first pass, no image decoding)."""
    if not max_dt_s > 0:
        raise SlitcliError(f"`max_dt_s` {max_dt_s} must be positive (seconds)", param="max_dt_s")
    p = Path(path)
    reader = _open(p)
    try:
        topics = {c.topic: c.msgtype for c in reader.connections}
        images = sorted(t for t, ty in topics.items() if ty in IMAGE_TYPES)
        for opt, topic in (("left_topic", left_topic), ("right_topic", right_topic)):
            if topic not in topics:
                raise SlitcliError(f"{p}: no topic {topic!r} (`{opt}`); image topics in this bag: "
                                   f"{', '.join(images) or 'none'}", param=opt)
            if topics[topic] not in IMAGE_TYPES:
                raise SlitcliError(f"{p}: topic {topic!r} (`{opt}`) carries {topics[topic]}, not "
                                   "images; choose one of " + (", ".join(images) or "none"),
                                   param=opt)
        stamps: dict[str, list[int]] = {left_topic: [], right_topic: []}
        conns = [c for c in reader.connections if c.topic in stamps]
        for conn, log_ns, raw in reader.messages(connections=conns):
            msg = _deserialize(reader, raw, conn, p)
            stamps[conn.topic].append(_stamp_ns(msg, log_ns))
    finally:
        reader.close()
    left = np.sort(np.array(stamps[left_topic], dtype=np.int64))
    right = np.sort(np.array(stamps[right_topic], dtype=np.int64))
    for topic, t in ((left_topic, left), (right_topic, right)):
        repeated = int((np.diff(t) == 0).sum())
        if repeated:
            # frames are told apart by their stamps: two images with one stamp cannot both
            # be paired, and dropping one silently would lose data
            raise SlitcliError(f"{p}: topic {topic!r} has {repeated} image(s) whose header "
                               "stamp repeats an earlier one; fix the driver's stamps (or "
                               "re-stamp the bag with the recording time)")
    if len(left) == 0 or len(right) == 0:
        empty = left_topic if len(left) == 0 else right_topic
        raise SlitcliError(f"{p}: topic {empty!r} has no messages; the sequence is empty")
    li, ri = _pair(left, right, round(max_dt_s * 1e9))
    if len(li) == 0:
        raise SlitcliError(f"{p}: no left/right pairs within `max_dt_s` {max_dt_s:g} s; "
                           + _why_unpaired(left, right, max_dt_s), param="max_dt_s")
    return BagPairs(p, left_topic, right_topic, left[li], right[ri], left, right,
                    float(max_dt_s))


def _pair(left: np.ndarray, right: np.ndarray, max_dt_ns: int) -> tuple[np.ndarray, np.ndarray]:
    """One-to-one nearest pairing of sorted stamps within ``max_dt_ns``."""
    j = np.clip(np.searchsorted(right, left), 1, len(right) - 1) if len(right) > 1 else \
        np.zeros(len(left), dtype=np.int64)
    if len(right) > 1:
        prev_better = np.abs(left - right[j - 1]) <= np.abs(right[j] - left)
        j = np.where(prev_better, j - 1, j)
    ok = np.abs(right[j] - left) <= max_dt_ns
    li, ri = np.nonzero(ok)[0], j[ok]
    # one right image may be nearest to two left images: keep the closer one
    order = np.lexsort((np.abs(right[ri] - left[li]), ri))
    li, ri = li[order], ri[order]
    first = np.r_[True, ri[1:] != ri[:-1]][: len(ri)]
    li, ri = li[first], ri[first]
    keep = np.argsort(li)
    return li[keep], ri[keep]


def _why_unpaired(left: np.ndarray, right: np.ndarray, max_dt_s: float) -> str:
    j = np.clip(np.searchsorted(right, left), 0, len(right) - 1)
    gap_s = float(np.median(np.abs(right[j] - left))) * 1e-9
    med_l, med_r = float(np.median(left)), float(np.median(right))
    if med_l > 0 and med_r > 0:
        decades = math.log10(med_l / med_r)
        for k in (3, 6, 9):
            if abs(abs(decades) - k) < 0.5:
                return (f"the left and right stamps differ by a factor of about 10^{k}: one "
                        "camera seems to stamp in another time unit (s, ms, us, ns); fix its "
                        "stamps or driver")
    hint = ""
    if gap_s > max_dt_s:
        hint = (f"; if the cameras are not synchronised, try `max_dt_s` {gap_s * 1.5:.3g} "
                "(seconds, not milliseconds)")
    return f"the nearest left/right stamps are {gap_s:.3g} s apart (median){hint}"


_BYTES_PER_PIXEL = {"bgr8": 3, "rgb8": 3, "bgra8": 4, "rgba8": 4, "mono8": 1,
                    "bayer_rggb8": 1, "bayer_bggr8": 1, "bayer_gbrg8": 1, "bayer_grbg8": 1,
                    "8UC1": 1, "8UC3": 3, "8UC4": 4}


def _deserialize(reader, raw: bytes, conn, path: Path) -> object:  # rosbags types
    try:
        return reader.deserialize(raw, conn.msgtype)
    except Exception as e:  # rosbags raises several types for a corrupt message
        raise SlitcliError(f"{path}: a message on topic {conn.topic!r} cannot be decoded "
                           f"({e.__class__.__name__}); the bag is corrupt there: cut it before "
                           "that message or record it again") from None


def decode_image(msg: object, msgtype: str, where: str) -> np.ndarray:
    """One ``sensor_msgs/Image`` or ``CompressedImage`` as a BGR uint8 array (H, W, 3).

    The message is checked before its bytes are trusted: an 8-bit encoding, ``step`` at
    least ``width x bytes per pixel`` (rows padded beyond that are cropped, as drivers
    that align rows write them), data at least ``height x step`` bytes; grey images become
    three equal channels. ``where`` names the bag, topic and frame in errors.
    """
    import cv2

    if msgtype.endswith("CompressedImage"):
        data = np.frombuffer(bytes(msg.data), dtype=np.uint8)
        img = cv2.imdecode(data, cv2.IMREAD_COLOR) if data.size else None
        if img is None:
            raise SlitcliError(f"{where}: the compressed image ({msg.format!r}) cannot be "
                               "decoded; the message is corrupt")
        return np.ascontiguousarray(img)
    enc = str(msg.encoding)
    bpp = _BYTES_PER_PIXEL.get(enc)
    if bpp is None:
        raise SlitcliError(f"{where}: image encoding {enc!r} is not an 8-bit colour or grey "
                           "image (bgr8, rgb8, mono8, bayer_*8...); convert the topic to bgr8")
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    data = np.frombuffer(bytes(msg.data), dtype=np.uint8)
    if h <= 0 or w <= 0 or step < w * bpp or data.size < h * step:
        raise SlitcliError(f"{where}: image header says {w}x{h} {enc} with step {step} but "
                           f"carries {data.size} bytes (needs step >= {w * bpp} and "
                           f"{h} x step bytes); the message is corrupt")
    px = data[: h * step].reshape(h, step)[:, : w * bpp].reshape(h, w, bpp)
    if enc in ("mono8", "8UC1"):
        return np.ascontiguousarray(np.repeat(px, 3, axis=2))
    if enc.startswith("bayer_"):
        # OpenCV names a Bayer pattern by its second row's second and third pixels, so
        # ROS' (and cv_bridge's) bayer_rggb8 is OpenCV's BayerBG
        code = {"bayer_rggb8": cv2.COLOR_BayerBG2BGR, "bayer_bggr8": cv2.COLOR_BayerRG2BGR,
                "bayer_gbrg8": cv2.COLOR_BayerGR2BGR, "bayer_grbg8": cv2.COLOR_BayerGB2BGR}[enc]
        return np.ascontiguousarray(cv2.cvtColor(np.ascontiguousarray(px[..., 0]), code))
    if enc in ("rgb8", "rgba8"):
        px = px[..., 2::-1] if enc == "rgb8" else px[..., [2, 1, 0]]
    return np.ascontiguousarray(px[..., :3])


def bag_frames(pairs: BagPairs, *, skip: set[int] | frozenset[int] = frozenset()
               ) -> Iterator[StereoFrame | int]:
    """Decode the paired images (second pass), yielding frames in left-stamp order.

    Frames whose index is in ``skip`` are not decoded: their index is yielded instead
    (a resumed batch does not pay for finished frames).
    """
    left_idx = {int(t): i for i, t in enumerate(pairs.left_ns)}
    right_idx = {int(t): i for i, t in enumerate(pairs.right_ns)}
    reader = _open(pairs.path)
    pending: dict[int, dict[str, np.ndarray]] = {}
    next_out = 0
    done: dict[int, StereoFrame | int] = {}
    try:
        conns = [c for c in reader.connections if c.topic in (pairs.left_topic,
                                                                 pairs.right_topic)]
        for conn, log_ns, raw in reader.messages(connections=conns):
            msg = _deserialize(reader, raw, conn, pairs.path)
            stamp = _stamp_ns(msg, log_ns)
            side = "left" if conn.topic == pairs.left_topic else "right"
            idx = (left_idx if side == "left" else right_idx).get(stamp)
            if idx is None or (side in pending.get(idx, {})):
                continue
            if idx in skip:
                pending.setdefault(idx, {})[side] = np.empty(0)
            else:
                img = decode_image(msg, conn.msgtype, f"{pairs.path}: topic {conn.topic!r}, "
                                   f"frame {idx}")
                pending.setdefault(idx, {})[side] = img
            slot = pending[idx]
            if len(slot) == 2:
                del pending[idx]
                done[idx] = idx if idx in skip else StereoFrame(
                    idx, f"{idx:06d}", pairs.left_ns[idx] * 1e-9, slot["left"], slot["right"])
            while next_out in done:  # emit in frame order; only out-of-order pairs wait
                yield done.pop(next_out)
                next_out += 1
    finally:
        reader.close()
    if next_out != len(pairs):
        raise SlitcliError(f"{pairs.path}: {len(pairs) - next_out} paired images could not be "
                           "read back; the bag may be truncated")
