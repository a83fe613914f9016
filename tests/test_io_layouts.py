"""Folder layouts (slitcli.io.layouts): EuRoC, KITTI raw, flat left*/right*, natural order."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from slitcli.detect import run_detect
from slitcli.errors import SlitcliError
from slitcli.io.frames import open_frames
from slitcli.io.layouts import detect_layout

ROOT = Path(__file__).resolve().parent.parent
BUNDLED = ROOT / "sample_data" / "sequences" / "corridor"
RIG = BUNDLED / "rig.yaml"
T0_NS = 1_403_636_579_763_555_584  # an EuRoC-like wall-clock stamp
DT_NS = 50_000_000


def _frames(n: int = 3) -> list[tuple[Path, Path]]:
    lefts = sorted((BUNDLED / "left").iterdir())[:n]
    return [(p, BUNDLED / "right" / p.name) for p in lefts]


def _euroc(tmp: Path, n: int = 3) -> Path:
    root = tmp / "euroc" / "mav0"
    for cam in ("cam0", "cam1"):
        (root / cam / "data").mkdir(parents=True)
    rows = ["#timestamp [ns],filename"]
    for i, (left, right) in enumerate(_frames(n)):
        t = T0_NS + i * DT_NS
        shutil.copy(left, root / "cam0" / "data" / f"{t}.png")
        shutil.copy(right, root / "cam1" / "data" / f"{t}.png")
        rows.append(f"{t},{t}.png")
    for cam in ("cam0", "cam1"):
        (root / cam / "data.csv").write_text("\n".join(rows) + "\n")
    return tmp / "euroc"


def _kitti(tmp: Path, n: int = 3) -> Path:
    root = tmp / "kitti"
    stamps = []
    for cam in ("image_02", "image_03"):
        (root / cam / "data").mkdir(parents=True)
    for i, (left, right) in enumerate(_frames(n)):
        shutil.copy(left, root / "image_02" / "data" / f"{i:010d}.png")
        shutil.copy(right, root / "image_03" / "data" / f"{i:010d}.png")
        t = np.datetime64("2011-09-26T13:02:25.964389445") + np.timedelta64(i * 103_702_000,
                                                                             "ns")
        stamps.append(str(t).replace("T", " "))
    for cam in ("image_02", "image_03"):
        (root / cam / "timestamps.txt").write_text("\n".join(stamps) + "\n")
    return root


def _flat(tmp: Path, n: int = 3) -> Path:
    root = tmp / "flat"
    root.mkdir()
    for i, (left, right) in enumerate(_frames(n)):
        shutil.copy(left, root / f"left_{i + 1}.png")
        shutil.copy(right, root / f"right_{i + 1}.png")
    return root


@pytest.mark.parametrize("make,layout", [(_euroc, "euroc"), (_kitti, "kitti"),
                                         (_flat, "flat")])
def test_layouts_read_the_same_pairs(tmp_path, make, layout):
    folder = make(tmp_path)
    assert detect_layout(folder) == layout
    src = open_frames(folder)
    ref = open_frames(BUNDLED)
    assert len(src) == 3
    mine = list(src.frames())
    theirs = list(ref.frames(skip=set(range(3, len(ref)))))
    for a, b in zip(mine, theirs, strict=True):
        np.testing.assert_array_equal(a.left_bgr, b.left_bgr)
        np.testing.assert_array_equal(a.right_bgr, b.right_bgr)
    with pytest.raises(SlitcliError, match="carries no slitcli rig"):
        src.rig()


def test_euroc_and_kitti_times_are_their_stamps(tmp_path):
    t = np.array([i.time_s for i in open_frames(_euroc(tmp_path)).info])
    np.testing.assert_allclose(np.diff(t), DT_NS * 1e-9, atol=1e-6)
    assert abs(t[0] - T0_NS * 1e-9) < 1e-6
    t = np.array([i.time_s for i in open_frames(_kitti(tmp_path)).info])
    np.testing.assert_allclose(np.diff(t), 0.103702, atol=1e-6)
    # datetime(2011, 9, 26, 13, 2, 25, tzinfo=timezone.utc).timestamp() == 1317042145
    assert abs(t[0] - (1317042145 + 0.964389445)) < 1e-6


def test_euroc_gives_the_same_range_columns_as_the_slitcli_layout(tmp_path):
    """The must-show: the same frames in another layout give the same ranges.csv range
    columns (frame numbers, bearings and every range), only the times differ."""
    euroc = _euroc(tmp_path, n=2)
    slit = tmp_path / "slit"
    for side in ("left", "right"):
        (slit / side).mkdir(parents=True)
        for p in sorted((BUNDLED / side).iterdir())[:2]:
            shutil.copy(p, slit / side / p.name)
    a = pd.read_csv(run_detect(euroc, tmp_path / "a", rig_path=RIG).outputs[0])
    b = pd.read_csv(run_detect(slit, tmp_path / "b", rig_path=RIG).outputs[0])
    cols = ["frame", "bearing_deg", "laser_range_m", "stereo_range_m", "stereo_has_features",
            "fused_range_m", "fused_source"]
    pd.testing.assert_frame_equal(a[cols], b[cols])
    assert a["time_s"].iloc[-1] - a["time_s"].iloc[0] == pytest.approx(DT_NS * 1e-9, abs=1e-6)
    # wall-clock stamps survive the table: the offline planner takes it (issue: %.6g
    # made every time 1.4e+09 and `dwa` refused the table)
    from slitcli.dwa import DwaParams
    from slitcli.dwa_table import dwa_offline

    cmds = dwa_offline(tmp_path / "a" / "ranges.csv", (3.0, 0.0), tmp_path / "cmds.csv",
                       DwaParams())
    assert len(cmds) == 2
    back = pd.read_csv(tmp_path / "cmds.csv")["time_s"].to_numpy()
    assert np.diff(back)[0] == pytest.approx(DT_NS * 1e-9, abs=1e-6)


def test_unknown_and_ambiguous_folders_are_refused(tmp_path):
    (tmp_path / "empty").mkdir()
    with pytest.raises(SlitcliError, match=r"no stereo images in a known layout.*euroc"):
        open_frames(tmp_path / "empty")
    both = _flat(tmp_path)
    (both / "left").mkdir()
    with pytest.raises(SlitcliError, match=r"several layouts \(slitcli, flat\)"):
        open_frames(both)


def test_flat_folder_needs_partners(tmp_path):
    root = _flat(tmp_path)
    (root / "right_2.png").unlink()
    with pytest.raises(SlitcliError, match=r"left_2\.png: no right image"):
        open_frames(root)
