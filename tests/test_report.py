"""The report of a detection run: its files, the overlay video, the colour previews."""

from __future__ import annotations

import os
import re
import shutil
from pathlib import Path

import cv2
import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner
from detect_runs import folder_run

from slitcli.cli import cli
from slitcli.errors import SlitcliError
from slitcli.report import ReportParams, run_report
from slitcli.report.overlay import (
    arc_pixels,
    count_video_frames,
    draw_overlay,
    label_runs,
    write_video,
)
from slitcli.report.preview import colour_bar, colour_preview, nice_ticks, turbo_bgr
from slitcli.report.run import load_run
from slitcli.rig import paper_rig

FIGURES = ("heatmap.png", "birdseye.png", "sources.png", "preview_disparity.png",
           "preview_distance.png")


@pytest.fixture(scope="module")
def run6(tmp_path_factory):
    """A real 6-frame detect run of the corridor with --save-images, and its report."""
    seq, det = folder_run(tmp_path_factory.mktemp("rep"), 6)
    summary = run_report(det, source=seq)
    return seq, det, summary


def test_report_writes_the_page_the_figures_and_a_decodable_video(run6):
    _, det, summary = run6
    rep = det / "report"
    assert count_video_frames(rep / "overlay.mp4") >= 6
    assert summary.video_frames == 6
    page = (rep / "index.html").read_text()
    # self-contained: every image inline, nothing fetched but the video link
    srcs = re.findall(r'src="([^"]*)"', page)
    assert len(srcs) >= 8 and all(s.startswith("data:image/") for s in srcs)
    assert 'href="overlay.mp4"' in page
    for name in FIGURES:
        img = cv2.imread(str(rep / name))
        assert img is not None, name
        # not blank: many colours, and far from one flat tone
        packed = (img[..., 0].astype(np.uint32) << 16) | (img[..., 1].astype(np.uint32) << 8) \
            | img[..., 2]
        assert np.unique(packed).size > 50, name
        assert img.std() > 20, name
    share = summary.share
    assert sum(share.values()) == pytest.approx(1.0)
    table = pd.read_csv(det / "ranges.csv")
    assert share["laser"] == pytest.approx((table["fused_source"] == "laser").mean())


def test_video_frames_show_the_images_and_the_drawing(run6):
    seq, det, _ = run6
    cap = cv2.VideoCapture(str(det / "report" / "overlay.mp4"))
    ok, frame = cap.read()
    cap.release()
    assert ok and frame.shape == (720, 960, 3)  # 320 x 240 enlarged 3 times
    left = cv2.imread(str(seq / "left" / "000000.png"))
    big = cv2.resize(left, (960, 720), interpolation=cv2.INTER_LINEAR)
    # away from the drawing (the floor's middle band) the video is the image (mp4 loss)
    band = (slice(450, 520), slice(300, 560))
    assert np.abs(frame[band].astype(int) - big[band].astype(int)).mean() < 12
    # the legend's black box and the frame time are drawn in the corners
    assert frame[5:20, 930:955].mean() < 60


def test_resume_skips_what_is_made_and_redoes_after_a_change(run6):
    seq, det, _ = run6
    rep = det / "report"
    before = (rep / "overlay.mp4").stat().st_mtime_ns
    again = run_report(det, source=seq)
    assert "overlay.mp4" in again.skipped and "heatmap.png" in again.skipped
    assert (rep / "overlay.mp4").stat().st_mtime_ns == before
    t = pd.read_csv(det / "ranges.csv")
    t.to_csv(det / "ranges.csv", index=False, float_format="%.6g", na_rep="")
    os.utime(det / "ranges.csv", ns=(before + 10**9, before + 10**9))
    third = run_report(det, source=seq)
    assert "overlay.mp4" in third.made and not third.skipped


def test_arcs_lie_on_the_stripe_of_a_wall():
    """DESIGN §2: a wall 1.0 m ahead puts the stripe at v = 167.93 on the centre column,
    0.6 m at v = 236.08; a bin's arc at that range, in the laser plane, passes there."""
    rig = paper_rig()
    for r_m, v in ((1.0, 167.93), (0.6, 236.08)):
        # the wall is the plane x = r: at bearing 0 its horizontal range is r
        uv = arc_pixels(rig, np.array([0.0]), 1.0, np.array([r_m]), n_points=3)
        assert uv[0, 1, 0] == pytest.approx(rig.left.cx_px, abs=1e-9)
        assert uv[0, 1, 1] == pytest.approx(v, abs=0.01)
    assert np.isnan(arc_pixels(rig, np.array([0.0]), 1.0, np.array([np.nan]))).all()


def test_arcs_of_laser_bins_meet_the_detected_stripe(run6):
    """On the real run every laser-ranged bin's arc runs within 1.5 px of its stripe."""
    _, det, _ = run6
    run = load_run(det)
    las = pd.read_csv(det / "laser.csv")
    gaps = []
    for k in range(run.n_frames):
        uv = arc_pixels(run.rig, run.bearing_deg, run.bin_deg, run.fused_range_m[k], 41)
        pts = las[las["frame"] == k][["u_px", "v_px"]].to_numpy()
        for b in np.flatnonzero(run.fused_source[k] == 0):
            # the stripe's nearest point in this bin lies on the arc's row at its column
            inb = (np.abs(pts[:, 0][:, None] - uv[b, :, 0][None, :]) < 0.5).any(axis=1)
            if inb.sum() < 2:
                continue
            near_v = pts[inb, 1].max()  # nearest point = lowest in the image
            col = np.argmin(np.abs(uv[b, :, 0][None, :] - pts[inb][np.argmax(pts[inb, 1]),
                                                                   0]), axis=1)[0]
            gaps.append(abs(uv[b, col, 1] - near_v))
    assert len(gaps) > 30
    assert np.max(gaps) < 1.5


def test_label_runs_group_similar_neighbours_nearest_first():
    r = np.array([1.0, 1.05, 1.5, np.nan, 0.8, 0.82, 0.85])
    src = np.array([1, 1, 1, 2, 0, 0, 1])
    assert label_runs(r, src, 0.1) == [(4, 5, 4), (6, 6, 6), (0, 1, 0), (2, 2, 2)]
    assert label_runs(np.full(3, np.nan), np.full(3, 2), 0.1) == []


@pytest.mark.parametrize("seed", range(5))
def test_write_video_decodes_every_frame(tmp_path, seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(6, 12))
    frames = [np.full((48, 64, 3), rng.integers(0, 256, 3), np.uint8) for _ in range(n)]
    path = tmp_path / "v.mp4"
    assert write_video(path, iter(frames), fps=5.0) == n
    assert count_video_frames(path) == n
    cap = cv2.VideoCapture(str(path))
    for f in frames:
        ok, got = cap.read()
        assert ok and np.abs(got.astype(int) - f.astype(int)).mean() < 6  # flat colour
    cap.release()
    assert [p.name for p in tmp_path.iterdir()] == ["v.mp4"]  # no temporary file left


@pytest.mark.parametrize("seed", range(5))
def test_colour_preview_follows_its_bar(seed):
    rng = np.random.default_rng(seed)
    vmax = float(rng.uniform(1, 60))
    values = rng.uniform(-0.2 * vmax, 1.2 * vmax, (60, 80))
    values[rng.random(values.shape) < 0.2] = np.nan
    img = colour_preview(values, vmin=0.0, vmax=vmax, unit="px", label="disparity")
    assert img.shape == (60, 80 + 72, 3) and img.dtype == np.uint8
    ok = np.isfinite(values) & (values > 0)
    assert (img[:, :80][~ok] == 0).all()  # invalid = black
    # each valid pixel has the colour of the bar's row for its (clipped) value
    bar = colour_bar(60, vmin=0.0, vmax=vmax, unit="px")
    from slitcli.report.preview import bar_rows

    top, bottom = bar_rows(60)
    rows = np.rint(top + (vmax - np.clip(values[ok], 0, vmax)) / vmax * (bottom - top))
    want = bar[rows.astype(int), 5]
    # one bar row spans (vmax / (bottom - top)) in value: up to ~6 LUT steps for 60 rows
    diff = np.abs(img[:, :80][ok].astype(int) - want.astype(int)).max(axis=1)
    assert np.percentile(diff, 99) < 60
    assert (turbo_bgr(np.array([0.0, vmax]), 0, vmax) ==
            turbo_bgr(np.array([-5.0, 2 * vmax]), 0, vmax)).all()  # clipped at the ends


def test_nice_ticks():
    # step: the smallest 1, 2 or 5 x 10^k at least a quarter of the span
    np.testing.assert_allclose(nice_ticks(0, 3), [0, 1, 2, 3])
    np.testing.assert_allclose(nice_ticks(0, 48), [0, 20, 40])
    np.testing.assert_allclose(nice_ticks(0.5, 1.0), [0.6, 0.8, 1.0])  # step 0.2 >= 0.125


def test_overlay_tints_the_mask_and_keeps_the_rest():
    rig = paper_rig()
    left = np.full((240, 320, 3), 100, np.uint8)
    mask = np.zeros((240, 320), bool)
    mask[20:60, 200:260] = True
    img = draw_overlay(left, rig=rig, bearing_deg=np.array([0.0]), bin_deg=1.0,
                       fused_range_m=np.array([np.nan]), fused_source=np.array([2]),
                       stripe_uv=None, mask=mask, time_s=float("nan"), frame=0)
    tinted = img[3 * 40, 3 * 230]
    # 35 % magenta (255, 0, 255) over grey 100: (154, 65, 154)
    np.testing.assert_allclose(tinted, [154, 65, 154], atol=1)
    np.testing.assert_array_equal(img[600, 300], [100, 100, 100])


def test_report_needs_the_input_for_the_video(tmp_path, run6):
    _, det, _ = run6
    # a run whose input path is not recorded (detect writes it beside the manifest)
    bare = tmp_path / "bare"
    shutil.copytree(det, bare)
    (bare / ".slitcli" / "detect" / "source.json").unlink()
    with pytest.raises(SlitcliError, match="does not record the input's path"):
        run_report(bare, params=ReportParams())
    res = CliRunner().invoke(cli, ["report", str(det), "--source", str(tmp_path / "gone")])
    assert res.exit_code == 2
    assert len(res.stderr.strip().splitlines()) == 1 and "gone" in res.stderr


def test_cli_report_without_video(tmp_path, run6):
    _, det, _ = run6
    res = CliRunner().invoke(cli, ["report", str(det), "--no-video"])
    assert res.exit_code == 0, res.output
    assert "report: 6 frames" in res.stdout
    assert Path(det / "report" / "index.html").is_file()


def test_a_bag_run_reports_on_the_bags_clock(tmp_path):
    from detect_runs import bag_run

    from slitcli.report.build import time_axis, video_fps

    bag, det, stamps = bag_run(tmp_path, 3)
    run = load_run(det)
    # ranges.csv holds 1.7e+09 s for every frame; the bag's stamps are 0.2 s apart
    t, own, label = time_axis(run, ReportParams(), bag)
    assert own and label == "time since the first frame (s)"
    np.testing.assert_allclose(t, (stamps - stamps[0]) * 1e-9, atol=1e-12)
    assert video_fps(run, ReportParams(), bag) == pytest.approx(5.0)
    summary = run_report(det, source=bag)
    assert count_video_frames(det / "report" / "overlay.mp4") == summary.video_frames == 3
