"""Bag images are checked before their bytes are trusted (padded rows, encodings, sizes,
repeated stamps): a wrong table with exit status 0 is the failure to avoid."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from bagwriter import padded_rows, write_bag
from click.testing import CliRunner

from slitcli.cli import cli
from slitcli.errors import SlitcliError
from slitcli.io.bags import decode_image
from slitcli.io.frames import open_frames
from slitcli.io.sequence import read_image

ROOT = Path(__file__).resolve().parent.parent
BUNDLED = ROOT / "sample_data" / "sequences" / "corridor"
IMAGE = "sensor_msgs/msg/Image"


def _msg(img: np.ndarray, enc: str, pad: int = 0, data: np.ndarray | None = None):
    h, w = img.shape[:2]
    ch = 1 if img.ndim == 2 else img.shape[2]
    rows = np.full((h, w * ch + pad), 7, np.uint8)
    rows[:, : w * ch] = img.reshape(h, -1)
    return SimpleNamespace(height=h, width=w, step=w * ch + pad, encoding=enc,
                           data=rows.reshape(-1) if data is None else data)


@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize("pad", [0, 1, 4, 64])
def test_padded_rows_decode_to_the_image(seed, pad):
    rng = np.random.default_rng(seed)
    bgr = rng.integers(0, 256, (13, 17, 3), dtype=np.uint8)
    np.testing.assert_array_equal(decode_image(_msg(bgr, "bgr8", pad), IMAGE, "x"), bgr)
    rgb = bgr[..., ::-1].copy()
    np.testing.assert_array_equal(decode_image(_msg(rgb, "rgb8", pad), IMAGE, "x"), bgr)
    grey = bgr[..., 0].copy()
    out = decode_image(_msg(grey, "mono8", pad), IMAGE, "x")
    assert out.shape == (13, 17, 3) and all(np.array_equal(out[..., c], grey) for c in range(3))


@pytest.mark.parametrize(("enc", "step_delta", "cut", "what"), [
    ("16UC1", 0, 0, "not an 8-bit"), ("32FC1", 0, 0, "not an 8-bit"),
    ("yuv422_weird", 0, 0, "not an 8-bit"), ("bgr8", -1, 0, "needs step >="),
    ("bgr8", 0, 10, "needs step >=")])
def test_bad_image_messages_name_bag_topic_and_frame(enc, step_delta, cut, what):
    bgr = np.zeros((4, 5, 3), np.uint8)
    m = _msg(bgr, "bgr8")
    m.encoding, m.step = enc, m.step + step_delta
    if cut:
        m.data = m.data[:-cut]
    with pytest.raises(SlitcliError, match=what) as e:
        decode_image(m, IMAGE, "run.bag: topic '/l', frame 3")
    assert "run.bag: topic '/l', frame 3" in str(e.value)


def test_corrupt_compressed_image_is_refused():
    m = SimpleNamespace(format="jpeg", data=np.frombuffer(b"not a jpeg", np.uint8))
    with pytest.raises(SlitcliError, match="cannot be decoded"):
        decode_image(m, "sensor_msgs/msg/CompressedImage", "b: topic '/l', frame 0")


@pytest.mark.parametrize("ros", [1, 2])
def test_a_bag_with_padded_rows_gives_the_folders_table(tmp_path, ros):
    names = sorted(p.name for p in (BUNDLED / "left").iterdir())[:2]
    frames = [(read_image(BUNDLED / "left" / n), read_image(BUNDLED / "right" / n))
              for n in names]
    bag = write_bag(tmp_path / ("p.bag" if ros == 1 else "p"), frames, ros=ros, pad=32)
    assert padded_rows(frames[0][0], 32).shape[1] == 320 * 3 + 32
    src = open_frames(bag)
    got = list(src.frames())
    for f, (left, right) in zip(got, frames, strict=True):
        np.testing.assert_array_equal(f.left_bgr, left)
        np.testing.assert_array_equal(f.right_bgr, right)


def test_repeated_stamps_are_refused_not_dropped(tmp_path):
    img = read_image(BUNDLED / "left" / sorted(p.name for p in (BUNDLED / "left").iterdir())[0])
    bag = write_bag(tmp_path / "same.bag", [(img, img)] * 3, ros=1,
                    left_stamps_ns=[1_700_000_000 * 10**9] * 3)
    res = CliRunner().invoke(cli, ["detect", str(bag), "--rig", str(BUNDLED / "rig.yaml"),
                                   "-o", str(tmp_path / "out")])
    assert res.exit_code == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "repeats an earlier one" in lines[0] and "same.bag" in lines[0]
    assert not (tmp_path / "out" / "ranges.csv").exists()
