"""One frame source for sequence folders and bags (slitcli.io.frames)."""

from __future__ import annotations

import math
import shutil
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest
from bagwriter import write_bag

from slitcli.errors import SlitcliError
from slitcli.io.frames import BagFrames, FolderFrames, open_frames
from slitcli.io.sequence import natural_key
from slitcli.rig import paper_rig

ROOT = Path(__file__).resolve().parent.parent
BUNDLED = ROOT / "sample_data" / "sequences" / "corridor"


def _folder(tmp: Path, names: list[str], size=(16, 12), seed=0) -> list[np.ndarray]:
    """Random pairs under the given names. Where a test uses one seed, the pixels only
    tell the frames apart (any content would do), so one seed suffices."""
    rng = np.random.default_rng(seed)
    imgs = []
    for side in ("left", "right"):
        (tmp / side).mkdir(parents=True, exist_ok=True)
    for n in names:
        pair = [rng.integers(0, 256, (size[1], size[0], 3), dtype=np.uint8) for _ in range(2)]
        for side, img in zip(("left", "right"), pair, strict=True):
            cv2.imwrite(str(tmp / side / f"{n}.png"), img)
        imgs.append(pair[0])
    return imgs


@pytest.mark.parametrize("seed", range(5))
def test_natural_order_frames_2_before_10(tmp_path, seed):
    rng = np.random.default_rng(seed)
    k = rng.permutation(np.arange(1, 27))
    names = [f"frame_{i}" for i in k]
    imgs = _folder(tmp_path, names, seed=seed)
    src = open_frames(tmp_path)
    assert isinstance(src, FolderFrames)
    assert [i.name for i in src.info] == [f"frame_{i}" for i in range(1, 27)]
    by_name = dict(zip(names, imgs, strict=True))
    for f in src.frames():
        np.testing.assert_array_equal(f.left_bgr, by_name[f.name])
    # zero-padded names keep their order
    assert sorted(["000010", "000002", "000001"], key=natural_key) == \
        ["000001", "000002", "000010"]


def test_skipped_frames_are_not_decoded(tmp_path):
    _folder(tmp_path, ["a1", "a2", "a3"])
    (tmp_path / "left" / "a2.png").write_bytes(b"not a png")  # would fail if decoded
    src = open_frames(tmp_path)
    assert [f.index for f in src.frames(skip={1})] == [0, 2]
    with pytest.raises(SlitcliError, match=r"a2\.png: unreadable"):
        list(src.frames())


def test_sizes_are_checked_against_the_rig(tmp_path):
    _folder(tmp_path, ["x"])
    src = open_frames(tmp_path)
    with pytest.raises(SlitcliError, match="does not match the rig") as e:
        list(src.frames(paper_rig()))
    assert e.value.param == "rig"
    with pytest.raises(SlitcliError, match="does not match the rig"):
        src.check_sizes(paper_rig())


def test_frame_digest_follows_the_bytes(tmp_path):
    """A changed image changes its frame's digest only (a resumed batch recomputes that
    frame and keeps the others); the manifest names the frames."""
    _folder(tmp_path, ["p", "q"])
    src = open_frames(tmp_path)
    before = [src.frame_digest(i) for i in range(2)]
    assert src.manifest()["names"] == ["p", "q"]
    img = cv2.imread(str(tmp_path / "right" / "q.png"))
    img[0, 0] ^= 1
    cv2.imwrite(str(tmp_path / "right" / "q.png"), img)
    after = [open_frames(tmp_path).frame_digest(i) for i in range(2)]
    assert after[0] == before[0] and after[1] != before[1]


@pytest.mark.parametrize("ros,storage", [(1, ""), (2, "sqlite3"), (2, "mcap")])
def test_bag_source_matches_the_folder(tmp_path, ros, storage):
    """The same pairs as a bag and as a folder: same images, bag times from the stamps
    at full precision (0.2 s apart near 1.7e9 s)."""
    folder = open_frames(BUNDLED)
    pairs = [(f.left_bgr, f.right_bgr) for f in folder.frames()][:3]
    bag = write_bag(tmp_path / ("b.bag" if ros == 1 else "b"), pairs, ros=ros,
                    storage=storage)
    src = open_frames(bag)
    assert isinstance(src, BagFrames) and len(src) == 3
    t = np.array([i.time_s for i in src.info])
    np.testing.assert_allclose(np.diff(t), 0.2, atol=1e-6)
    assert t[0] > 1.6e9
    with pytest.raises(SlitcliError, match="carries no rig") as e:
        src.rig()
    assert e.value.param == "rig"
    rig = src.rig(BUNDLED / "rig.yaml")
    got = list(src.frames(rig, skip={1}))
    assert [f.index for f in got] == [0, 2]
    for f in got:
        np.testing.assert_array_equal(f.left_bgr, pairs[f.index][0])
        np.testing.assert_array_equal(f.right_bgr, pairs[f.index][1])


def _raw_rig():
    """Paper rig whose raw cameras have radial distortion and a slight relative yaw."""
    from slitcli.rig import RawCalibration

    rig = paper_rig()
    size = rig.image_size_px
    k = rig.left.K
    dist = np.array([-0.12, 0.03, 0.0005, -0.0004, 0.0])
    yaw = math.radians(0.8)
    r = np.array([[math.cos(yaw), 0, math.sin(yaw)], [0, 1, 0],
                  [-math.sin(yaw), 0, math.cos(yaw)]])
    t = np.array([-rig.baseline_m, 0.0, 0.0])
    r1, r2, p1, p2, *_ = cv2.stereoRectify(k, dist, k, dist, size, r, t.reshape(3, 1),
                                           alpha=0, flags=cv2.CALIB_ZERO_DISPARITY)

    def freeze(a):
        a = np.asarray(a, float)
        return tuple(map(freeze, a)) if a.ndim > 1 else tuple(float(v) for v in a)

    raw = RawCalibration(image_size_px=size, K1=freeze(k), D1=freeze(dist), K2=freeze(k),
                         D2=freeze(dist), R=freeze(r), T=freeze(t), R1=freeze(r1),
                         R2=freeze(r2), P1=freeze(p1), P2=freeze(p2))
    return replace(rig, raw=raw)


def test_raw_pairs_are_rectified_once_with_the_rig(tmp_path):
    """rectify=True gives what the rectification module gives for the raw pair."""
    from slitcli.calibrate.rectify import rectify_pair

    raw_rig = _raw_rig()
    shutil.copytree(BUNDLED / "left", tmp_path / "left")
    shutil.copytree(BUNDLED / "right", tmp_path / "right")
    src = open_frames(tmp_path)
    skip = set(range(2, 8))
    raw_frames = list(src.frames(raw_rig, skip=skip))
    rect = list(src.frames(raw_rig, rectify=True, skip=skip))
    assert len(rect) == 2
    for a, b in zip(raw_frames, rect, strict=True):
        want = rectify_pair(raw_rig, a.left_bgr, a.right_bgr)
        np.testing.assert_array_equal(b.left_bgr, want[0])
        np.testing.assert_array_equal(b.right_bgr, want[1])
        assert not np.array_equal(b.left_bgr, a.left_bgr)


def test_unpaired_bag_images_are_reported(tmp_path):
    """Free-running cameras: every other right image 30 ms late. With max_dt_s 0.01 half
    the pairs are dropped, and the source says so with the numbers and a fix (half the
    0.2 s frame period)."""
    rng = np.random.default_rng(0)  # pairing reads stamps only: the pixels do not matter
    frames = [(rng.integers(0, 256, (12, 16, 3), dtype=np.uint8),) * 2 for _ in range(6)]
    offsets = [2_000_000, 30_000_000] * 3
    bag = write_bag(tmp_path / "b", frames, ros=2, right_offsets_ns=offsets)
    src = open_frames(bag, max_dt_s=0.01)
    assert len(src) == 3
    (note,) = src.notes()
    assert "3 of 6 left and 3 of 6 right images found no partner within `max_dt_s` 0.01" \
        in note
    assert "2 ms apart median" in note and "up to 30 ms" in note
    assert "try `max_dt_s` 0.1 " in note
    assert open_frames(bag, max_dt_s=0.1).notes() == ()
    assert len(open_frames(bag, max_dt_s=0.1)) == 6


def test_bad_frames_stop_or_are_skipped(tmp_path):
    _folder(tmp_path, ["a1", "a2", "a3"])
    (tmp_path / "right" / "a2.png").write_bytes(b"broken")
    src = open_frames(tmp_path)
    with pytest.raises(SlitcliError, match=r"a2\.png: unreadable"):
        list(src.frames())
    got = list(src.frames(on_bad="skip"))
    assert [type(f).__name__ for f in got] == ["StereoFrame", "BadFrame", "StereoFrame"]
    assert got[1].index == 1 and "a2.png: unreadable" in got[1].reason
    with pytest.raises(SlitcliError) as e:
        list(src.frames(on_bad="ignore"))
    assert e.value.param == "on_bad"


def test_detect_skips_a_bad_frame_and_retries_it(tmp_path):
    """`detect --on-bad-frame skip`: the other frames' rows, the bad one listed; after the
    file is fixed a re-run computes it, and the table equals a clean run's."""
    from click.testing import CliRunner

    from slitcli.cli import cli

    seq = tmp_path / "seq"
    for side in ("left", "right"):
        (seq / side).mkdir(parents=True)
        for p in sorted((BUNDLED / side).iterdir())[:3]:
            shutil.copy(p, seq / side / p.name)
    good = (seq / "left" / "000001.png").read_bytes()
    (seq / "left" / "000001.png").write_bytes(b"broken")
    runner = CliRunner()
    args = ["detect", str(seq), "--rig", str(BUNDLED / "rig.yaml"), "-o", str(tmp_path / "o")]
    res = runner.invoke(cli, args)
    assert res.exit_code == 2 and "000001.png: unreadable" in res.stderr
    res = runner.invoke(cli, [*args, "--on-bad-frame", "skip"])
    assert res.exit_code == 0, res.stderr
    assert "1 frame(s) could not be read" in res.stderr
    import pandas as pd

    table = pd.read_csv(tmp_path / "o" / "ranges.csv")
    assert sorted(set(table["frame"])) == [0, 2]
    skipped = pd.read_csv(tmp_path / "o" / "skipped_frames.csv")
    assert skipped["frame"].tolist() == [1] and "unreadable" in skipped["reason"][0]
    (seq / "left" / "000001.png").write_bytes(good)
    res = runner.invoke(cli, [*args, "--on-bad-frame", "skip"])
    assert res.exit_code == 0 and "(2 already done)" in res.output
    assert not (tmp_path / "o" / "skipped_frames.csv").exists()
    clean = tmp_path / "clean"
    assert runner.invoke(cli, [*args[:-1], str(clean)]).exit_code == 0
    assert (tmp_path / "o" / "ranges.csv").read_bytes() == (clean / "ranges.csv").read_bytes()


def test_frame_source_is_abstract():
    """A frame source that leaves out a reader method cannot be made (no stub that raises
    only when called)."""
    from slitcli.io.frames import FrameSource

    with pytest.raises(TypeError):
        FrameSource()

    class Partial(FrameSource):
        def rig(self, rig_path=None):
            return paper_rig()

    with pytest.raises(TypeError, match=r"frames|manifest"):
        Partial()
    assert issubclass(FolderFrames, FrameSource) and issubclass(BagFrames, FrameSource)
