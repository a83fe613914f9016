"""The ROS export: read every bag back with rosbags and compare it to ranges.csv."""

from __future__ import annotations

import csv
import math
import shutil
from pathlib import Path

import cv2
import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner
from detect_runs import CORRIDOR, bag_run, folder_run
from rosbags.highlevel import AnyReader

from slitcli.cli import cli
from slitcli.errors import SlitcliError
from slitcli.export import (
    TOPIC_FUSED,
    TOPIC_LASER,
    TOPIC_STEREO,
    ExportParams,
    export_run,
    scan_ranges,
)

COLUMNS = {TOPIC_FUSED: "fused_range_m", TOPIC_LASER: "laser_range_m",
           TOPIC_STEREO: "stereo_range_m"}
NAMES = {".mcap": "out.mcap", ".bag": "out.bag", "": "outbag"}


@pytest.fixture(scope="module")
def run6(tmp_path_factory):
    """A real 6-frame detect run of the corridor, with --save-images."""
    return folder_run(tmp_path_factory.mktemp("exp"), 6)


def read_bag(path: Path) -> dict[str, list[tuple[int, object]]]:
    """Every message per topic: (log time ns, message)."""
    got: dict[str, list[tuple[int, object]]] = {}
    with AnyReader([path]) as r:
        for conn, t, raw in r.messages():
            got.setdefault(conn.topic, []).append((t, r.deserialize(raw, conn.msgtype)))
    return got


def expected(table: pd.DataFrame, column: str, frame: int) -> np.ndarray:
    """The scan a frame's column must give: float32 m, +inf for an empty cell.

    The cells are parsed from the CSV text with Python's float() (``table.attrs``
    holds the path), independently of the exporter's reader.
    """
    with open(table.attrs["path"], newline="") as f:
        rows = [r for r in csv.DictReader(f) if int(r["frame"]) == frame]
    return np.array([float(r[column]) if r[column] != "" else np.inf for r in rows],
                    dtype=np.float32)


def read_table(path: Path) -> pd.DataFrame:
    t = pd.read_csv(path)
    t.attrs["path"] = str(path)
    return t


def random_table(run: Path, dst: Path, seed: int) -> pd.DataFrame:
    """A copy of ``run`` whose ranges are random, a third of them empty (no return)."""
    shutil.copytree(run, dst)
    t = pd.read_csv(run / "ranges.csv")
    rng = np.random.default_rng(seed)
    for c in COLUMNS.values():
        v = rng.uniform(0.3, 3.5, len(t))
        v[rng.random(len(t)) < 1 / 3] = np.nan
        t[c] = v
    t.to_csv(dst / "ranges.csv", index=False, float_format="%.6g", na_rep="")
    return read_table(dst / "ranges.csv")


@pytest.mark.parametrize("kind", [".mcap", ".bag", ""])
def test_one_scan_per_frame_equal_to_the_table(run6, tmp_path, kind):
    _, det = run6
    out = tmp_path / NAMES[kind]
    summary = export_run(det, out)
    table = read_table(det / "ranges.csv")
    frames = sorted(table["frame"].unique())
    got = read_bag(out)
    assert set(got) == set(COLUMNS)
    bearings = table.loc[table["frame"] == 0, "bearing_deg"].to_numpy()
    for topic, column in COLUMNS.items():
        msgs = got[topic]
        assert len(msgs) == len(frames) == 6
        for frame, (_, m) in zip(frames, msgs, strict=True):
            np.testing.assert_array_equal(m.ranges, expected(table, column, frame))
            assert m.ranges.dtype == np.float32
            assert m.angle_min == pytest.approx(math.radians(bearings[0]), abs=1e-7)
            assert m.angle_max == pytest.approx(math.radians(bearings[-1]), abs=1e-7)
            assert m.angle_increment == pytest.approx(math.radians(1.0), abs=1e-7)
            assert m.header.frame_id == "slitcli_sensor"
            # len(ranges) == (angle_max - angle_min) / increment + 1, as viewers assume
            assert round((m.angle_max - m.angle_min) / m.angle_increment) + 1 == len(m.ranges)
    # the paper rig: laser band 0.6-1 m; stereo from f B / 48 px = 0.458 m to 3 m
    fused = got[TOPIC_FUSED][0][1]
    assert (fused.range_min, fused.range_max) == pytest.approx((22 / 48, 3.0), rel=1e-6)
    laser = got[TOPIC_LASER][0][1]
    assert (laser.range_min, laser.range_max) == pytest.approx((0.6, 1.0), rel=1e-6)
    # the corridor's times.csv: 0.2 s per frame
    stamps = [t for t, _ in got[TOPIC_FUSED]]
    assert stamps == [200_000_000 * f for f in frames]
    assert [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec
            for _, m in got[TOPIC_FUSED]] == stamps
    assert summary.frames == 6 and summary.messages == 18


@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize("kind", [".mcap", ".bag"])
def test_random_tables_round_trip_exactly(run6, tmp_path, seed, kind):
    _, det = run6
    table = random_table(det, tmp_path / "run", seed)
    out = tmp_path / NAMES[kind]
    export_run(tmp_path / "run", out)
    got = read_bag(out)
    for topic, column in COLUMNS.items():
        for frame, (_, m) in enumerate(got[topic]):
            want = expected(table, column, frame)
            np.testing.assert_array_equal(m.ranges, want)
            assert np.isposinf(m.ranges).sum() == table.loc[table["frame"] == frame,
                                                            column].isna().sum()


def test_scan_ranges_inf_for_no_return():
    r = scan_ranges(np.array([0.5, np.nan, 2.25, np.inf]))
    assert r.dtype == np.float32
    np.testing.assert_array_equal(r, np.array([0.5, np.inf, 2.25, np.inf], np.float32))


def test_frames_without_times_are_stamped_by_the_period(tmp_path):
    _, det = folder_run(tmp_path, 2, save_images=False, times=False)
    out = tmp_path / "p.mcap"
    summary = export_run(det, out, params=ExportParams(period_s=0.25, frame_id="base_scan"))
    msgs = read_bag(out)[TOPIC_FUSED]
    assert [t for t, _ in msgs] == [0, 250_000_000]
    assert msgs[0][1].header.frame_id == "base_scan"
    assert "frame index x 0.25 s" in summary.line()


@pytest.mark.parametrize("ros", [1, 2])
def test_a_bag_run_keeps_the_bags_own_stamps(tmp_path, ros):
    bag, det, stamps = bag_run(tmp_path, 3, ros=ros)
    out = tmp_path / "scan.mcap"
    summary = export_run(det, out, source=bag)
    msgs = read_bag(out)[TOPIC_FUSED]
    assert [t for t, _ in msgs] == stamps.tolist()
    assert [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for _, m in msgs] == \
        stamps.tolist()
    assert "the input bag" in summary.line()
    # without the bag, ranges.csv's full-precision time_s stamps the scans: a float64
    # of 1.7e9 s resolves 2.4e-7 s, so each stamp is within 1 us of the bag's
    out2 = tmp_path / "nobag.mcap"
    export_run(det, out2, params=ExportParams(period_s=0.2))
    got = np.array([t for t, _ in read_bag(out2)[TOPIC_FUSED]], dtype=np.int64)
    assert np.all(np.abs(got - stamps) < 1_000)


def test_images_are_the_left_image_and_the_saved_distance(run6, tmp_path):
    seq, det = run6
    out = tmp_path / "img.bag"
    export_run(det, out, params=ExportParams(images=True), source=seq)
    got = read_bag(out)
    left, dist = got["/slitcli/left/image_rect"], got["/slitcli/distance/image"]
    assert len(left) == len(dist) == 6
    for k in (0, 5):
        m = left[k][1]
        img = np.frombuffer(m.data, np.uint8).reshape(m.height, m.width, 3)
        np.testing.assert_array_equal(img, cv2.imread(str(CORRIDOR / "left" / f"{k:06d}.png")))
        d = dist[k][1]
        assert d.encoding == "16UC1" and d.step == 2 * d.width
        mm = np.frombuffer(d.data, "<u2").reshape(d.height, d.width)
        np.testing.assert_array_equal(mm, cv2.imread(str(det / "distance" / f"{k:06d}.png"),
                                                     cv2.IMREAD_UNCHANGED))


def test_refuses_an_existing_output_and_replaces_it_on_request(run6, tmp_path):
    _, det = run6
    out = tmp_path / "x.mcap"
    out.write_bytes(b"keep me")
    with pytest.raises(SlitcliError, match="already exists"):
        export_run(det, out)
    assert out.read_bytes() == b"keep me"
    export_run(det, out, overwrite=True)
    assert len(read_bag(out)[TOPIC_FUSED]) == 6
    folder = tmp_path / "dirbag"
    export_run(det, folder)
    export_run(det, folder, overwrite=True)
    assert len(read_bag(folder)[TOPIC_FUSED]) == 6
    assert sorted(p.name for p in tmp_path.iterdir()) == ["dirbag", "x.mcap"]  # no leftovers


def _cli(*args: str):
    return CliRunner().invoke(cli, list(args))


@pytest.mark.parametrize("args,match", [
    (["nowhere", "-o", "{t}/a.mcap"], "nowhere: not found"),
    (["{det}", "-o", "{t}/a.db3"], "unknown bag format '.db3'"),
    (["{det}", "-o", "{t}/a.mcap", "--period-s", "0"], "--period-s 0"),
    (["{t}", "-o", "{t}/a.mcap"], "ranges.csv: not found"),
])
def test_bad_input_is_one_line_and_exit_2(run6, tmp_path, args, match):
    _, det = run6
    res = _cli("export", *[a.format(t=tmp_path, det=det) for a in args])
    assert res.exit_code == 2, res.output
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and match in lines[0] and "Traceback" not in res.output
    assert not (tmp_path / "a.mcap").exists() and not (tmp_path / "a.db3").exists()


def test_cli_writes_the_bag_and_prints_a_summary(run6, tmp_path):
    _, det = run6
    res = _cli("export", str(det), "-o", str(tmp_path / "c.mcap"))
    assert res.exit_code == 0, res.output
    assert "6 frames, 18 messages (ROS 2 MCAP" in res.stdout
    assert len(read_bag(tmp_path / "c.mcap")[TOPIC_FUSED]) == 6


def _matrix(q):
    x, y, z, w = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


@pytest.mark.parametrize("seed", range(5))
def test_quaternion_of_a_rotation(seed):
    from slitcli.export import quaternion_xyzw

    rng = np.random.default_rng(seed)
    for _ in range(50):
        # random rotations, and near-half-turns where the trace is close to -1
        q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        q *= np.sign(np.linalg.det(q))
        got = quaternion_xyzw(q)
        assert np.linalg.norm(got) == pytest.approx(1.0) and got[3] >= 0
        np.testing.assert_allclose(_matrix(got), q, atol=1e-12)
    half = np.diag([1.0, -1.0, -1.0])  # a half turn about x: q = (1, 0, 0, 0)
    np.testing.assert_allclose(quaternion_xyzw(half), [1, 0, 0, 0], atol=1e-15)


@pytest.mark.parametrize("kind", [".mcap", ".bag"])
def test_images_come_with_camera_info_and_the_camera_pose(run6, tmp_path, kind):
    seq, det = run6
    out = tmp_path / NAMES[kind]
    export_run(det, out, params=ExportParams(images=True), source=seq)
    got = read_bag(out)
    from slitcli.rig import load_rig

    rig = load_rig(seq / "rig.yaml")
    (_, tfm), = got["/tf_static"]
    tf = tfm.transforms[0]
    assert (tf.header.frame_id, tf.child_frame_id) == ("slitcli_sensor",
                                                       "slitcli_camera_optical")
    r = tf.transform.rotation
    t = tf.transform.translation
    # a camera point taken to the sensor frame by the transform and by the rig agree
    p_cam = np.array([0.3, -0.2, 1.7])
    via_tf = _matrix((r.x, r.y, r.z, r.w)) @ p_cam + np.array([t.x, t.y, t.z])
    np.testing.assert_allclose(via_tf, rig.cam_to_sensor(p_cam), atol=1e-12)
    infos = got["/slitcli/left/camera_info"]
    assert len(infos) == 6
    info = infos[0][1]
    k = info.K if kind == ".bag" else info.k
    np.testing.assert_allclose(k, [250, 0, 159.5, 0, 250, 119.5, 0, 0, 1])
    assert (info.width, info.height) == (320, 240)
