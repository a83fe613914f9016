"""`slitcli detect`: accuracy against rendered truth, resume, parallel runs, bags, bad input."""

from __future__ import annotations

import math
import os
import shutil
import signal
import subprocess
import sys
import time
from functools import cache
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml
from bagwriter import write_bag
from click.testing import CliRunner
from laser_synth import wall_stripe_rows

from slitcli.cli import cli
from slitcli.detect import Detector, DetectParams
from slitcli.evaluate import range_errors
from slitcli.io.sequence import StereoSequence
from slitcli.laser import (
    LaserFrame,
    bearing_bin_centres_deg,
    detect_laser,
    nearest_range_per_bin,
)
from slitcli.laser.frame import EdgeParams, edge_reach_px, segment_edges, triangulate_stripe
from slitcli.rig import paper_rig
from slitcli.sim.render import render_left
from slitcli.sim.scene import load_scene, scene_from_dict
from slitcli.sim.sequence import render_sequence

ROOT = Path(__file__).resolve().parent.parent
BUNDLED = ROOT / "sample_data" / "sequences" / "corridor"


def _detect_table(seq_dir: Path, mode: str = "paper") -> pd.DataFrame:
    seq = StereoSequence(seq_dir)
    rig = seq.rig()
    det = Detector(rig, DetectParams(fusion_mode=mode))
    rows = []
    for f in seq.frames(rig):
        rows.append(det(f.left_bgr, f.right_bgr).table(f.index,
                                                                                f.time_s))
    return pd.concat(rows, ignore_index=True)


def _scores(seq_dir: Path, mode: str = "paper") -> dict:
    table = _detect_table(seq_dir, mode)
    truth = pd.read_csv(seq_dir / "gt" / "ranges.csv")
    err = range_errors(table, truth)
    err["bearing_deg"] = table.merge(truth, on=["frame", "bearing_deg"])[
        "bearing_deg"].to_numpy()[truth.merge(table, on=["frame", "bearing_deg"])[
            "range_m"].notna().to_numpy()]
    band = err[(err["true_m"] >= 0.6) & (err["true_m"] <= 3.0)]
    ok = band["fused_err_m"].abs() <= np.maximum(0.05, 0.05 * band["true_m"])
    j = table.merge(truth, on=["frame", "bearing_deg"])
    free = j[j["range_m"].isna() | (j["range_m"] > 3.0)]
    limit = np.where(free["range_m"].isna(), np.inf, free["range_m"]) - 0.2
    phantom = free["fused_range_m"] < limit
    return {"detected": float(ok.mean()), "bins": len(band), "phantom": float(phantom.mean()),
            "free": len(free), "errors": err}


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    base = tmp_path_factory.mktemp("scenes")
    rig = paper_rig()
    out = {}
    for name, frames in (("distractors", 2), ("overhang", 3)):
        out[name] = base / name
        render_sequence(load_scene(ROOT / "sample_data" / f"{name}.yaml"), rig, out[name],
                        frames=frames)
    return out


@pytest.mark.parametrize("name", ["corridor", "distractors"])
def test_fused_ranges_against_truth(rendered, name):
    seq = BUNDLED if name == "corridor" else rendered[name]
    s = _scores(seq)
    assert s["bins"] > 50
    assert s["detected"] >= 0.99, s["errors"]
    # the floor is a phantom rate of at most 1 %; one sequence has only ~80 free bins, so
    # bound the count by what a true 1 % rate exceeds with < 1 % probability (binomial)
    assert round(s["phantom"] * s["free"]) <= _binomial_p99(s["free"], 0.01)


def _binomial_p99(n: int, p: float) -> int:
    """Smallest k with P(X <= k) >= 0.99 for X ~ Binomial(n, p)."""
    total = 0.0
    for k in range(n + 1):
        total += math.comb(n, k) * p**k * (1 - p) ** (n - k)
        if total >= 0.99:
            return k
    return n


@pytest.mark.parametrize("seed", [2, 3, 4, 6, 7])
@pytest.mark.parametrize("centre_x_m, yaw_deg", [(0.95, 0.0), (0.82, 10.0)])
def test_textureless_obstacle_within_1m_is_ranged_by_the_laser(tmp_path, centre_x_m, yaw_deg,
                                                               seed):
    # at 0.82 m (front face about 0.7 m) the box's top edge and the laser stripe give
    # stereo a few hundred matches a fraction of a pixel short of the face: the laser's
    # range must still be the one reported
    scene = scene_from_dict({"slitcli_scene": 1, "seed": seed, "objects": [
        {"type": "box", "centre_xy_m": [centre_x_m, 0.0], "size_m": [0.3, 0.6, 0.5],
         "yaw_deg": yaw_deg, "surface": {"colour_rgb": [0.7, 0.7, 0.68], "texture": "plain"}},
        {"type": "wall", "from_xy_m": [3.0, -3], "to_xy_m": [3.0, 3], "height_m": 2.0}]})
    render_sequence(scene, paper_rig(), tmp_path / "s", frames=1)
    table = _detect_table(tmp_path / "s")
    truth = pd.read_csv(tmp_path / "s" / "gt" / "ranges.csv")
    j = table.merge(truth, on=["frame", "bearing_deg"])
    box = j[j["range_m"] < 1.0]  # the bins whose nearest obstacle is the plain box
    assert len(box) >= 20
    assert (box["fused_source"] == "laser").mean() >= 0.95
    rel = (box["fused_range_m"] - box["range_m"]).abs() / box["range_m"]
    assert rel.max() <= 0.01


def test_overhang_paper_mode_trusts_the_missing_laser_return(rendered):
    paper = _scores(rendered["overhang"], "paper")["errors"]
    cons = _scores(rendered["overhang"], "conservative")["errors"]
    # the shelf (true 0.8 m) is seen by stereo only; paper fusion pushes it out to the
    # laser's 1.0 m reach, the conservative minimum keeps it
    def shelf(e: pd.DataFrame) -> pd.DataFrame:  # the shelf spans bearings -26..7 degrees
        return e[((e["true_m"] - 0.8).abs() < 0.03) & (e["bearing_deg"] < 5)]

    shelf_p, shelf_c = shelf(paper), shelf(cons)
    assert len(shelf_p) >= 5
    assert (shelf_p["fused_range_m"] >= 0.99).mean() >= 0.8
    assert (shelf_c["fused_err_m"].abs() <= 0.05).mean() >= 0.8


def test_table_top_past_its_edge_is_ranged_from_its_own_points(tmp_path):
    # The overhang scene seen from 6 cm further on: at 12 deg the table top's side face
    # (4 cm thick, 0.45 m up, above the laser sheet) spans 1.39-1.50 m across the bin at
    # a grazing angle and holds about a third of the bin's obstacle points, the wall at
    # 3 m behind it the rest. The bin's 10th percentile lands on the face's far part
    # (1.48 m, 7 % long); the face's own points give its near edge.
    d = yaml.safe_load((ROOT / "sample_data" / "overhang.yaml").read_text())
    d["robot"] = {**d["robot"], "start": [0.06, 0.0, 0.0]}
    render_sequence(scene_from_dict(d, "overhang"), paper_rig(), tmp_path / "s", frames=1)
    table = _detect_table(tmp_path / "s", "conservative")
    truth = pd.read_csv(tmp_path / "s" / "gt" / "ranges.csv")
    j = table.merge(truth, on=["frame", "bearing_deg"])
    top = j[(j["bearing_deg"] >= 12) & (j["bearing_deg"] <= 17)]  # true 1.28-1.39 m
    assert len(top) == 6
    assert top["range_m"].between(1.25, 1.4).all()
    assert top["laser_range_m"].isna().all()          # the laser passes under it
    err = (top["fused_range_m"] - top["range_m"]).abs()
    assert (err <= np.maximum(0.05, 0.05 * top["range_m"])).all(), top


def _run(args, **kw):
    return CliRunner().invoke(cli, [str(a) for a in args], **kw)


def test_cli_detect_jobs_and_resume_are_byte_identical(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    res = _run(["detect", BUNDLED, "-o", a])
    assert res.exit_code == 0, res.stderr
    assert "8 frames (0 already done)" in res.output
    res = _run(["detect", BUNDLED, "-o", b, "--jobs", "2"])
    assert res.exit_code == 0, res.stderr
    assert (a / "ranges.csv").read_bytes() == (b / "ranges.csv").read_bytes()
    table = pd.read_csv(a / "ranges.csv")
    assert list(table.columns) == ["frame", "time_s", "bearing_deg", "laser_range_m",
                                   "stereo_range_m", "stereo_has_features", "fused_range_m",
                                   "fused_source", "laser_free_m"]
    assert len(table) == 8 * 65 and set(table["fused_source"]) <= {"laser", "stereo", "none"}
    # every corridor frame shows the stripe: the laser certifies free space in every bin,
    # never beyond its band (the rig's laser.max_range_m, 1 m)
    assert table["laser_free_m"].notna().all() and table["laser_free_m"].max() <= 1.0
    # a re-run with the same arguments does nothing new; other arguments are refused
    res = _run(["detect", BUNDLED, "-o", a])
    assert "8 already done" in res.output
    res = _run(["detect", BUNDLED, "-o", a, "--fusion", "conservative"])
    assert res.exit_code == 2 and "--overwrite" in res.stderr
    res = _run(["detect", BUNDLED, "-o", a, "--fusion", "conservative", "--overwrite"])
    assert res.exit_code == 0 and "0 already done" in res.output


def test_kill_9_then_rerun_gives_the_same_table(tmp_path):
    seq = tmp_path / "seq"
    names = sorted(p.name for p in (BUNDLED / "left").iterdir())
    for side in ("left", "right"):
        (seq / side).mkdir(parents=True)
        for i in range(40):
            os.link(BUNDLED / side / names[i % len(names)], seq / side / f"{i:04d}.png")
    shutil.copy(BUNDLED / "rig.yaml", seq / "rig.yaml")
    full = tmp_path / "full"
    assert _run(["detect", seq, "-o", full]).exit_code == 0
    out = tmp_path / "killed"
    cmd = [sys.executable, "-m", "slitcli", "detect", str(seq), "-o", str(out)]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    parts = out / ".slitcli" / "detect" / "parts"
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and len(list(parts.glob("*.rows.csv"))
                                              if parts.exists() else []) < 10:
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    done = len(list(parts.glob("*.rows.csv")))
    assert 10 <= done < 40 and not (out / "ranges.csv").exists()
    res = _run(["detect", seq, "-o", out])
    assert res.exit_code == 0
    assert f"({done} already done)" in res.output
    assert (out / "ranges.csv").read_bytes() == (full / "ranges.csv").read_bytes()


@pytest.mark.parametrize("ros,storage", [(1, ""), (2, "sqlite3"), (2, "mcap")])
def test_bags_give_the_folder_table(tmp_path, ros, storage):
    seq = tmp_path / "seq"
    shutil.copytree(BUNDLED, seq, ignore=shutil.ignore_patterns("gt"))
    frames = list(StereoSequence(seq).frames())[:3]
    for p in (seq / "left").iterdir():
        if p.name not in {f.name + ".png" for f in frames}:
            p.unlink()
            (seq / "right" / p.name).unlink()
    t0 = 1_700_000_000
    (seq / "times.csv").write_text("frame,time_s\n" + "".join(
        f"{i},{t0 + 0.2 * i}\n" for i in range(3)))
    bag = write_bag(tmp_path / ("run.bag" if ros == 1 else "run"),
                    [(f.left_bgr, f.right_bgr) for f in frames], ros=ros, storage=storage,
                    t0_ns=t0 * 10**9, right_offset_ns=1_000_000)
    assert _run(["detect", seq, "-o", tmp_path / "f"]).exit_code == 0
    res = _run(["detect", bag, "-o", tmp_path / "b", "--rig", seq / "rig.yaml"])
    assert res.exit_code == 0, res.stderr
    assert (tmp_path / "f" / "ranges.csv").read_text() == \
        (tmp_path / "b" / "ranges.csv").read_text()


def test_bad_input_exits_2_with_one_line_and_writes_nothing(tmp_path):
    empty = tmp_path / "empty"
    (empty / "left").mkdir(parents=True)
    (empty / "right").mkdir()
    unpaired = tmp_path / "unpaired"
    shutil.copytree(BUNDLED, unpaired, ignore=shutil.ignore_patterns("gt"))
    next((unpaired / "right").iterdir()).unlink()
    bag = write_bag(tmp_path / "bag", [(np.zeros((240, 320, 3), np.uint8),) * 2], ros=2)
    cases = [
        ([empty], "no images"),
        ([unpaired], "missing right frame"),
        ([BUNDLED, "--fusion", "best"], "--fusion"),
        ([bag, "--rig", BUNDLED / "rig.yaml", "--left-topic", "/nope"], "no topic '/nope'"),
        ([BUNDLED, "--window", "8"], "window"),
    ]
    for i, (args, text) in enumerate(cases):
        out = tmp_path / f"out{i}"
        res = _run(["detect", *args[:1], "-o", out, *args[1:]])
        assert res.exit_code == 2, (args, res.output, res.stderr)
        lines = res.stderr.strip().splitlines()
        assert len(lines) == 1 and text in lines[0], lines
        assert not out.exists()


# ------------------------------------------------------------ sub-pixel laser segment ends
def _ends(rows: list[list[float]], sat: list[list[bool]] | None = None):
    s = np.array(rows, dtype=float)
    return edge_reach_px(s, np.zeros(s.shape, bool) if sat is None else np.array(sat))


@pytest.mark.parametrize("cover", [0.2, 0.5, 0.8])
def test_edge_reach_of_a_partly_covered_end_column(cover):
    # a face of constant brightness 100 DN covering the share `cover` of the end column
    # ends cover - 1/2 pixels past that column's centre
    reach, fading = _ends([[100.0 * cover, 100.0, 100.0, 100.0]])
    np.testing.assert_allclose(reach, [cover - 0.5], atol=1e-12)
    assert not fading[0]


def test_edge_reach_of_a_fully_covered_end_column_is_its_border():
    # as bright as the inner columns (or brighter, by noise): covered; the unseen next
    # column says only that its share is below detection
    reach, fading = _ends([[100.0, 100.0, 100.0, 100.0], [104.0, 100.0, 99.0, 101.0]])
    np.testing.assert_allclose(reach, [0.5, 0.5])
    assert not fading.any()


@pytest.mark.parametrize("limb_px", [0.3, 0.6, 0.9])
def test_edge_reach_of_a_fading_stripe_is_where_its_square_reaches_zero(limb_px):
    # near a limb the cosine of incidence goes as sqrt(distance to the limb): with the
    # limb `limb_px` past the end column, column k in from the end has s**2 = G (limb + k)
    g = 900.0
    s = np.sqrt(g * (limb_px + np.arange(4.0)))
    reach, fading = _ends([list(s)])
    assert fading[0]
    np.testing.assert_allclose(reach, [limb_px], atol=1e-9)


def test_edge_reach_of_a_fading_stripe_stops_at_the_next_column():
    s = np.sqrt(400.0 * (2.5 + np.arange(4.0)))  # limb 2.5 px out: s1/s3 = 0.80 fades
    reach, fading = edge_reach_px(s[None, :], np.zeros((1, 4), bool),
                                  EdgeParams(fade_ratio=0.85, max_reach_px=1.0))
    assert fading[0]
    assert reach[0] == 1.0


def test_edge_reach_with_saturation_and_short_segments():
    reach, fading = _ends(
        [[50.0, 100.0, 100.0, 100.0],     # end column clipped: no coverage information
         [50.0, 70.0, 100.0, 100.0],      # an inner column clipped (its strength is unreliable)
         [50.0, 100.0, 100.0, np.nan]],   # only two inner columns: no estimate
        [[True, True, False, False],
         [False, True, False, False],
         [False, False, False, False]])
    assert reach[0] == 0.0
    np.testing.assert_allclose(reach[1], 0.0)  # 50 / median(100, 100) - 1/2, not a fade
    assert not fading[1]
    assert np.isnan(reach[2])


def _wall_frame(first: int, last: int, strength: np.ndarray, *, forward_m: float = 0.8,
                far: tuple[int, int, float] | None = None) -> LaserFrame:
    """A stripe on a wall ``forward_m`` ahead over columns first..last (inclusive), with
    the given strength per column; optionally a farther wall (x = far[2]) over far[0..1]."""
    rig = paper_rig()
    w = rig.width_px
    u = np.arange(w, dtype=float)
    v = np.full(w, np.nan)
    v[first:last + 1] = wall_stripe_rows(rig, forward_m)[first:last + 1]
    if far is not None:
        v[far[0]:far[1] + 1] = wall_stripe_rows(rig, far[2])[far[0]:far[1] + 1]
    x, y, rng, bearing = triangulate_stripe(rig, u, v)
    found = np.isfinite(v)
    with np.errstate(invalid="ignore"):
        band = found & (rng >= rig.laser.min_range_m) & (rng <= rig.laser.max_range_m)
    return LaserFrame(u_px=u, v_px=v, strength_dn=np.where(found, strength, np.nan),
                      saturated=np.zeros(w, bool), x_m=x, y_m=y, range_m=rng,
                      bearing_deg=bearing, in_band=band, noise_sigma_dn=2.0, threshold_dn=19.0)


def test_segment_edge_points_lie_on_the_surface_at_the_covered_share():
    rig = paper_rig()
    s = np.full(rig.width_px, 120.0)
    s[100], s[170] = 0.3 * 120.0, 0.9 * 120.0   # left end 30 % covered, right end 90 %
    f = _wall_frame(100, 170, s)
    e = segment_edges(f, rig)
    # the 30 % end ends inside its column (reach -0.2): not listed; the 90 % end 0.4 px out
    assert e.u_px.tolist() == [170.0]
    assert e.direction.tolist() == [1]
    np.testing.assert_allclose(e.reach_px, [0.4])
    # on the wall (x = 0.8 m), at the bearing 0.4 of the way from column 170 to 171
    x = e.range_m * np.cos(np.radians(e.bearing_deg))
    np.testing.assert_allclose(x, [0.8], atol=1e-9)
    b170, b171 = f.bearing_deg[170], triangulate_stripe(
        rig, np.array([171.0]), wall_stripe_rows(rig, 0.8)[171:172])[3][0]
    np.testing.assert_allclose(e.bearing_deg, [b170 + 0.4 * (b171 - b170)], atol=2e-4)


def test_edge_counts_in_the_next_bin_only_when_it_crosses_the_boundary():
    rig = paper_rig()
    f0 = _wall_frame(100, 260, np.full(rig.width_px, 120.0))
    b = f0.bearing_deg
    # a column whose right neighbour (bearing falls with u) lies in the next bin, with
    # the half-degree boundary between their bearings well inside the pair
    k = np.floor(b + 0.5)
    frac = (b[:-1] - (k[:-1] - 0.5)) / (b[:-1] - b[1:])  # boundary past column u, px
    cand = np.flatnonzero((k[1:] == k[:-1] - 1) & (frac > 0.2) & (frac < 0.4))
    end = int(cand[(cand > 110) & (cand < 250)][0])
    boundary, frac = k[end] - 0.5, frac[end]
    nxt = int(np.flatnonzero(bearing_bin_centres_deg(rig) == k[end] - 1)[0])
    for cover in (frac + 0.5 - 0.1, frac + 0.5 + 0.1):
        s = np.full(rig.width_px, 120.0)
        s[end] = 120.0 * cover
        s[100] = 60.0  # the left end covered by half: it ends at its column's centre
        f = _wall_frame(100, end, s)
        plain = nearest_range_per_bin(f, rig)
        edged = nearest_range_per_bin(f, rig, edges=segment_edges(f, rig))
        assert np.isnan(plain.range_m[nxt])
        crosses = cover - 0.5 > frac
        assert np.isfinite(edged.range_m[nxt]) == crosses
        if crosses:  # the wall's range just past the boundary bearing
            np.testing.assert_allclose(edged.range_m[nxt],
                                       0.8 / np.cos(np.radians(boundary)), atol=2e-3)
        # the end column's own bin may get the slightly nearer wall point at the edge
        # (bearing nearer 0); the other bins are untouched; the count stays the columns'
        own = nxt + 1
        assert 0.0 <= plain.range_m[own] - edged.range_m[own] < 1e-3
        others = (np.arange(plain.range_m.size) != nxt) & (np.arange(plain.range_m.size) != own)
        np.testing.assert_array_equal(edged.range_m[others], plain.range_m[others])
        np.testing.assert_array_equal(edged.count, plain.count)


def test_only_the_near_side_of_a_range_jump_is_an_edge():
    rig = paper_rig()
    s = np.full(rig.width_px, 120.0)
    s[150] = 0.8 * 120.0
    # near wall 0.7 m over 100..150, far wall 0.95 m over 151..200 (an occlusion boundary)
    f = _wall_frame(100, 150, s, forward_m=0.7, far=(151, 200, 0.95))
    e = segment_edges(f, rig)
    ends = dict(zip(e.u_px.tolist(), e.reach_px.tolist(), strict=True))
    # the near wall's right end (80 % covered) and the outer ends of both walls (fully
    # covered, reach to their borders); the far wall's left end at 151 is no edge
    assert ends.keys() == {100.0, 150.0, 200.0}
    np.testing.assert_allclose([ends[100.0], ends[150.0], ends[200.0]], [0.5, 0.3, 0.5])


@cache
def _plain_objects_bins(seed: int) -> tuple[int, dict, dict]:
    """Plain (laser-only) cylinders and a yawed box at 0.8-1 m, approached over 10
    frames so that their limbs and corners sweep across bin boundaries at sub-pixel
    offsets; per frame the laser's bins without and with the segment edges against the
    renderer's truth. Returns the obstacle bins (truth 0.6-1 m), those ranged within
    max(5 cm, 5 %) and the bins ranged more than 5 cm too near, without (False) and
    with (True) the edges; rendered once per seed for the two tests below."""
    plain = {"colour_rgb": [0.7, 0.7, 0.68], "texture": "plain"}
    scene = scene_from_dict({"slitcli_scene": 1, "seed": seed, "objects": [
        {"type": "cylinder", "centre_xy_m": [0.95, -0.25], "radius_m": 0.1, "height_m": 0.5,
         "surface": plain},
        {"type": "cylinder", "centre_xy_m": [0.9, 0.3], "radius_m": 0.06, "height_m": 0.5,
         "surface": plain},
        {"type": "box", "centre_xy_m": [0.95, 0.02], "size_m": [0.2, 0.12, 0.4],
         "yaw_deg": 20.0, "surface": plain},
        {"type": "wall", "from_xy_m": [3.0, -3], "to_xy_m": [3.0, 3], "height_m": 2.0}],
        "robot": {"start": [0.0, 0.0, 0.0], "motion": "straight", "speed_mps": 0.05,
                  "frames": 10, "frame_rate_hz": 5.0}})
    rig = paper_rig()
    obstacle_bins, ranged, too_near = 0, {False: 0, True: 0}, {False: 0, True: 0}
    for i, pose in enumerate(scene.poses(10)):
        r = render_left(scene, rig, pose, frame_index=i)
        las = detect_laser(r.left_bgr, rig)
        t = r.truth.range_m
        obj = (t >= 0.6) & (t <= 1.0)
        obstacle_bins += int(obj.sum())
        for on in (False, True):
            b = nearest_range_per_bin(las, rig, edges=segment_edges(las, rig) if on else None)
            ok = np.abs(b.range_m - t) <= np.maximum(0.05, 0.05 * t)
            ranged[on] += int((obj & ok).sum())
            too_near[on] += int((b.range_m < np.where(np.isfinite(t), t, np.inf)
                                 - 0.05).sum())
    return obstacle_bins, ranged, too_near


@pytest.mark.parametrize("seed", [5, 6, 7, 8, 9])
def test_edges_range_more_obstacle_bins(seed):
    # measured (seeds 5-9): 321-327 of 344 bins without the edges, 327-336 with; the
    # edges never lose a bin (what they add is bounded by the bins the extractor leaves)
    obstacle_bins, ranged, _ = _plain_objects_bins(seed)
    assert obstacle_bins >= 300
    assert ranged[True] >= ranged[False]
    assert ranged[True] >= 0.95 * obstacle_bins


_TOO_NEAR = pytest.mark.xfail(
    reason="docs/laser.md Limits: one bin ranged too near with the segment edges, none "
           "without them (seeds 6, 7, 9 not traced)", strict=True)


@pytest.mark.parametrize("seed", [pytest.param(s, marks=_TOO_NEAR) for s in (6, 7, 9)]
                         + [5, 8])
def test_edges_range_no_bin_too_near(seed):
    _, _, too_near = _plain_objects_bins(seed)
    assert too_near[True] == too_near[False] == 0
