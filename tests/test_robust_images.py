"""io/images.py: headers checked before decoding, one line naming the file, no libpng lines."""

from __future__ import annotations

import os
import struct
import subprocess
import sys
import zlib

import cv2
import numpy as np
import pytest

from slitcli.errors import SlitcliError
from slitcli.io.images import MAX_PIXELS, image_size_px, read_image_bgr


def _chunk(kind: bytes, data: bytes, crc: int | None = None) -> bytes:
    crc = zlib.crc32(kind + data) if crc is None else crc
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", crc)


def _png_claiming(width: int, height: int) -> bytes:
    """A tiny PNG whose IHDR claims ``width x height`` RGB pixels."""
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + _chunk(b"IHDR", ihdr)
            + _chunk(b"IDAT", zlib.compress(b"\0" * 64)) + _chunk(b"IEND", b""))


def _image(seed: int) -> np.ndarray:
    """A random colour image of random size. Tests of the file handling (channels,
    limits, corrupt data, messages) use one: no pixel value changes how a file is read
    or refused, so one seed suffices."""
    rng = np.random.default_rng(seed)
    h, w = rng.integers(8, 64, size=2)
    return rng.integers(0, 256, size=(h, w, 3), dtype=np.uint8)


@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize("ext", [".png", ".jpg"])
def test_valid_images_read_as_opencv_reads_them(tmp_path, seed, ext):
    img = _image(seed)
    path = tmp_path / f"a{ext}"
    cv2.imwrite(str(path), img)
    got = read_image_bgr(path)
    np.testing.assert_array_equal(got, cv2.imread(str(path), cv2.IMREAD_COLOR))
    assert image_size_px(path) == (img.shape[1], img.shape[0])
    if ext == ".png":  # lossless: the exact pixels
        np.testing.assert_array_equal(got, img)


def test_grey_png_becomes_three_channels(tmp_path):
    grey = _image(7)[..., 0]
    cv2.imwrite(str(tmp_path / "g.png"), grey)
    got = read_image_bgr(tmp_path / "g.png")
    assert got.shape == (*grey.shape, 3)
    np.testing.assert_array_equal(got[..., 1], grey)


@pytest.mark.parametrize("width, height", [(30000, 30000), (MAX_PIXELS // 1000 + 1, 1000),
                                           (2**31 - 1, 2**31 - 1)])
def test_huge_claimed_size_is_refused_before_decoding(tmp_path, width, height):
    path = tmp_path / "bomb.png"
    path.write_bytes(_png_claiming(width, height))
    with pytest.raises(SlitcliError, match=r"bomb\.png: the header claims"):
        read_image_bgr(path)


def test_pixel_limit_is_a_parameter(tmp_path):
    path = tmp_path / "a.png"
    cv2.imwrite(str(path), _image(1))
    with pytest.raises(SlitcliError, match="more than the 10 pixels"):
        read_image_bgr(path, max_pixels=10)


def test_sparse_giant_file_is_refused_by_its_size(tmp_path):
    path = tmp_path / "giant.png"
    cv2.imwrite(str(path), _image(2))
    with path.open("r+b") as f:
        f.truncate(20 * 10**9)  # sparse: no disk used
    with pytest.raises(SlitcliError, match=r"giant\.png: \d+ bytes is far more"):
        read_image_bgr(path)


def test_non_files_are_refused(tmp_path):
    (tmp_path / "dir.png").mkdir()
    with pytest.raises(SlitcliError, match=r"dir\.png: is not a regular file"):
        read_image_bgr(tmp_path / "dir.png")
    with pytest.raises(SlitcliError, match=r"missing\.png: image not found"):
        read_image_bgr(tmp_path / "missing.png")
    (tmp_path / "empty.png").write_bytes(b"")
    with pytest.raises(SlitcliError, match=r"empty\.png: empty file"):
        read_image_bgr(tmp_path / "empty.png")
    (tmp_path / "text.png").write_text("not an image\n")
    with pytest.raises(SlitcliError, match=r"text\.png: unreadable image"):
        read_image_bgr(tmp_path / "text.png")


@pytest.mark.parametrize("damage", ["flip_idat", "truncate", "flip_jpeg"])
def test_corrupt_data_is_one_line(tmp_path, damage):
    ext = ".jpg" if damage == "flip_jpeg" else ".png"
    path = tmp_path / f"c{ext}"
    cv2.imwrite(str(path), _image(3))
    data = bytearray(path.read_bytes())
    if damage == "truncate":
        data = data[: len(data) // 3]
    elif damage == "flip_idat":
        data[-20] ^= 0xFF
    else:
        data = data[: len(data) // 2]
    path.write_bytes(bytes(data))
    with pytest.raises(SlitcliError, match=r"c\.(png|jpg): unreadable image"):
        read_image_bgr(path)


def test_libpng_lines_do_not_reach_stderr(tmp_path):
    """libpng prints 'libpng warning/error' itself; only slitcli's own line may appear."""
    ok = tmp_path / "ok.png"
    cv2.imwrite(str(ok), _image(4))
    raw = ok.read_bytes()
    warn = tmp_path / "warn.png"  # a tEXt chunk with a wrong CRC: libpng warns, decodes
    warn.write_bytes(raw[:33] + _chunk(b"tEXt", b"k\x00v", crc=1) + raw[33:])
    bad = tmp_path / "bad.png"  # damaged pixel data: libpng reports an error
    damaged = bytearray(raw)
    damaged[-20] ^= 0xFF
    bad.write_bytes(bytes(damaged))
    code = ("import sys\n"
            "from slitcli.errors import SlitcliError\n"
            "from slitcli.io.images import read_image_bgr\n"
            "print(read_image_bgr(sys.argv[1]).shape)\n"
            "try:\n    read_image_bgr(sys.argv[2])\n"
            "except SlitcliError as e:\n    print(f'slitcli: error: {e}', file=sys.stderr)\n")
    proc = subprocess.run([sys.executable, "-c", code, str(warn), str(bad)], capture_output=True,
                          text=True, timeout=60, env={**os.environ, "OPENCV_LOG_LEVEL": "INFO"})
    assert proc.returncode == 0, proc.stderr
    assert "libpng warning" not in proc.stderr and "libpng error" not in proc.stderr
    assert "[ WARN" not in proc.stderr
    lines = [x for x in proc.stderr.splitlines() if x.strip()]
    assert len(lines) == 1 and "bad.png: unreadable image" in lines[0]
