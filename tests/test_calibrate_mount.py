"""`calibrate mount`: height, tilt and roll from a rendered textured floor seen in stereo."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from click.testing import CliRunner

from slitcli.calibrate.mount import MountParams, calibrate_mount_frames, fit_floor_ransac
from slitcli.calibrate.rectify import rig_with_raw
from slitcli.cli import cli
from slitcli.rig import load_rig, save_rig
from slitcli.sim.targets import (
    TargetRenderer,
    demo_raw_calibration,
    floor_for_mount,
    stereo_cameras,
)

HEIGHT_M, TILT_DEG, ROLL_DEG = 0.65, 20.0, 1.5


@pytest.fixture(scope="module")
def cameras():
    """The demo rig's raw calibration and a renderer per camera (their per-pixel rays take
    seconds to build, so every test of the module shares them)."""
    raw = demo_raw_calibration()
    lc, rc = stereo_cameras(raw)
    return raw, TargetRenderer(lc), TargetRenderer(rc)


def _floor_view(cameras, seed: int) -> dict:
    """A rendered floor pair (floor texture seed ``3 + 10 seed``, camera noise seeds after
    it) with the truth in the rig frame."""
    raw, left_cam, right_cam = cameras
    floor = floor_for_mount(HEIGHT_M, TILT_DEG, ROLL_DEG, seed=3 + 10 * seed)
    left = left_cam.render_floor(floor, seed=1 + 10 * seed)
    right = right_cam.render_floor(floor, seed=2 + 10 * seed)
    rig = rig_with_raw(raw)
    # truth in the rig's (rectified left) frame: the floor normal rotated by R1
    n = raw.array("R1") @ -np.asarray(floor.up_left)
    truth = {"tilt_deg": math.degrees(math.asin(n[2])),
             "roll_deg": math.degrees(math.atan2(n[0], n[1])), "height_m": HEIGHT_M}
    return {"rig": rig, "left": left, "right": right, "truth": truth}


@pytest.fixture(scope="module")
def floor_view(cameras):
    return _floor_view(cameras, 0)


@pytest.mark.parametrize("seed", range(5))
def test_mount_from_rendered_floor(cameras, floor_view, seed):
    floor_view = floor_view if seed == 0 else _floor_view(cameras, seed)
    res = calibrate_mount_frames(["f0"], [(floor_view["left"], floor_view["right"])],
                                 floor_view["rig"], MountParams())
    m, t = res.rig.mount, floor_view["truth"]
    assert abs(m.tilt_deg - t["tilt_deg"]) < 0.3
    assert abs(m.roll_deg - t["roll_deg"]) < 0.3
    assert abs(m.height_m - t["height_m"]) < 0.005
    assert res.floor.inliers > 0.8 * res.floor.points
    assert "tilt_deg" in "\n".join(res.report_lines())


@pytest.mark.parametrize("seed", range(5))
def test_ransac_ignores_an_obstacle_and_far_noise(seed):
    # 60 % floor points with depth-dependent noise, 40 % on a box face and scattered
    rig = rig_with_raw(demo_raw_calibration())
    rng = np.random.default_rng(4 + 10 * seed)
    t = math.radians(25.0)
    n = np.array([0.0, math.cos(t), math.sin(t)])
    e1 = np.array([1.0, 0.0, 0.0])
    e2 = np.cross(n, e1)
    a, b = rng.uniform(-1, 1, 6000), rng.uniform(-1.5, 1.5, 6000)
    floor = 0.5 * n + a[:, None] * e1 + b[:, None] * e2
    floor = floor[(floor[:, 2] > 0.4) & (floor[:, 2] < 2.8)]
    sigma = floor[:, 2:3] ** 2 * 0.3 / (rig.focal_px * rig.baseline_m)
    floor = floor + rng.normal(size=floor.shape) * sigma * floor / floor[:, 2:3]
    box = np.column_stack([rng.uniform(-0.3, 0.3, 2500), rng.uniform(-0.2, 0.3, 2500),
                           np.full(2500, 1.2) + rng.normal(0, 0.003, 2500)])
    junk = rng.uniform([-1, -1, 0.4], [1, 1, 2.8], size=(1000, 3))
    plane = fit_floor_ransac(np.vstack([floor, box, junk]), rig, MountParams(seed=seed))
    assert math.degrees(math.acos(min(1.0, float(np.asarray(plane.normal) @ n)))) < 0.3
    assert abs(plane.height_m - 0.5) < 0.005


def test_cli_calibrate_mount(floor_view, tmp_path):
    seq = tmp_path / "seq"
    (seq / "left").mkdir(parents=True)
    (seq / "right").mkdir()
    cv2.imwrite(str(seq / "left" / "000.png"), floor_view["left"])
    cv2.imwrite(str(seq / "right" / "000.png"), floor_view["right"])
    rig_path = tmp_path / "rig.yaml"
    save_rig(floor_view["rig"], rig_path)
    res = CliRunner().invoke(cli, ["calibrate", "mount", "--rig", str(rig_path), str(seq)])
    assert res.exit_code == 0, res.output
    m = load_rig(rig_path).mount
    assert m.tilt_deg == pytest.approx(floor_view["truth"]["tilt_deg"], abs=0.3)
    assert m.height_m == pytest.approx(HEIGHT_M, abs=0.005)

    # a missing sequence: exit 2, one line, nothing written
    out = tmp_path / "new.yaml"
    res = CliRunner().invoke(cli, ["calibrate", "mount", "--rig", str(rig_path),
                                   str(tmp_path / "nope"), "-o", str(out)])
    assert res.exit_code == 2 and len(res.output.strip().splitlines()) == 1
    assert "nope" in res.output and not out.exists()


# ---------------------------------------------------------------- refusing what is not a floor
def _plane_points(noise_scale: float, seed: int, rig) -> tuple[np.ndarray, np.ndarray]:
    """Floor points 0.5 m below a 25-deg camera, depth noise ``noise_scale`` x the model's."""
    rng = np.random.default_rng(seed)
    t = math.radians(25.0)
    n = np.array([0.0, math.cos(t), math.sin(t)])
    e1, e2 = np.array([1.0, 0.0, 0.0]), np.cross(n, [1.0, 0.0, 0.0])
    p = 0.5 * n + rng.uniform(-1, 1, (8000, 1)) * e1 + rng.uniform(-1.5, 1.5, (8000, 1)) * e2
    p = p[(p[:, 2] > 0.4) & (p[:, 2] < 2.8)]
    sigma = p[:, 2] ** 2 * MountParams().disparity_sigma_px / (rig.focal_px * rig.baseline_m)
    # depth error along the ray (the stereo noise model), scaled to the point
    dz = rng.normal(size=p.shape[0]) * sigma * noise_scale
    return p * (1 + dz / p[:, 2])[:, None], n


def test_normalised_rms_threshold_is_the_midpoint_of_the_two_hypotheses():
    from statistics import NormalDist

    from slitcli.calibrate.mount import normalised_rms_threshold

    nd = NormalDist()
    for k in (2.0, 3.0, 4.0):
        rho_g = math.sqrt(1 - 2 * k * nd.pdf(k) / (2 * nd.cdf(k) - 1))
        assert normalised_rms_threshold(k) == pytest.approx(0.5 * (rho_g + k / math.sqrt(3)),
                                                            rel=1e-12)
    assert normalised_rms_threshold(3.0) == pytest.approx(1.3593, abs=1e-4)


@pytest.mark.parametrize("seed", range(5))
def test_floor_check_accepts_model_noise_and_refuses_a_scatter(seed):
    from slitcli.calibrate.mount import floor_plane_check
    from slitcli.errors import SlitcliError

    rig = rig_with_raw(demo_raw_calibration())
    pts, _ = _plane_points(1.0, seed, rig)
    plane = fit_floor_ransac(pts, rig, MountParams(seed=seed))
    # truncated standard normal at 3 sigma: RMS 0.987, share 99.7 % (a few % sampling slack)
    assert plane.normalised_rms == pytest.approx(0.987, abs=0.05)
    assert plane.inliers / plane.points > 0.98
    floor_plane_check(plane, MountParams())
    # noise 2.5 x the model: 77 % inside the band, normalised RMS 2.5 * 0.628 = 1.57 > 1.36
    pts, _ = _plane_points(2.5, seed, rig)
    plane = fit_floor_ransac(pts, rig, MountParams(seed=seed))
    assert plane.normalised_rms == pytest.approx(1.57, abs=0.08)
    with pytest.raises(SlitcliError, match=r"x the stereo depth noise \(at most 1\.36"):
        floor_plane_check(plane, MountParams())


def _render_pairs(cameras, floors, seed):
    raw, left_cam, right_cam = cameras
    return [(left_cam.render_floor(f, seed=seed + 2 * i),
             right_cam.render_floor(f, seed=seed + 2 * i + 1))
            for i, f in enumerate(floors)], rig_with_raw(raw)


def _write_seq(root, pairs):
    (root / "left").mkdir(parents=True)
    (root / "right").mkdir()
    for i, (left, right) in enumerate(pairs):
        cv2.imwrite(str(root / "left" / f"{i:03d}.png"), left)
        cv2.imwrite(str(root / "right" / f"{i:03d}.png"), right)


@pytest.mark.parametrize("seed", range(5))
def test_cli_refuses_views_without_a_floor(cameras, tmp_path, seed):
    from slitcli.sim.targets import Floor

    rng = np.random.default_rng(seed)
    # five "rooms": floors at unrelated heights and tilts, as frames of one sequence
    rooms = [floor_for_mount(float(h), float(t), seed=seed + i) for i, (h, t) in enumerate(
        zip(rng.uniform(0.3, 1.2, 5), [5.0, 40.0, 60.0, 12.0, 28.0], strict=True))]
    wall = [Floor(up_left=(0.0, 0.0, -1.0), height_m=float(rng.uniform(0.8, 1.6)), seed=seed)]
    # a wall: no floor-like RANSAC candidate at all, or a candidate that refines to the wall
    for name, floors, why in (("rooms", rooms, ("lie on the best floor plane",)),
                              ("wall", wall, ("not the floor", "no floor-like plane"))):
        pairs, rig = _render_pairs(cameras, floors, seed)
        _write_seq(tmp_path / name, pairs)
        rig_path, out = tmp_path / f"{name}_rig.yaml", tmp_path / f"{name}_out.yaml"
        save_rig(rig, rig_path)
        before = rig_path.read_text()
        res = CliRunner().invoke(cli, ["calibrate", "mount", "--rig", str(rig_path),
                                       str(tmp_path / name), "-o", str(out)])
        assert res.exit_code == 2, res.output
        assert len(res.output.strip().splitlines()) == 1
        assert any(w in res.output for w in why), res.output
        assert not out.exists() and rig_path.read_text() == before
        # in place: the rig is left as it was
        res = CliRunner().invoke(cli, ["calibrate", "mount", "--rig", str(rig_path),
                                       str(tmp_path / name)])
        assert res.exit_code == 2 and rig_path.read_text() == before


@pytest.mark.parametrize("seed", range(5))
def test_corridor_sample_still_gives_its_mount(tmp_path, seed):
    from pathlib import Path

    from slitcli.calibrate.mount import run_calibrate_mount

    seq = Path(__file__).resolve().parents[1] / "sample_data" / "sequences" / "corridor"
    truth = load_rig(seq / "rig.yaml").mount  # the rig the sample was rendered with
    out = tmp_path / "rig.yaml"
    res = run_calibrate_mount(seq / "rig.yaml", seq, MountParams(seed=seed), out_rig=out)
    m = load_rig(out).mount
    # the sample's walls take a third of the points; the floor still holds the majority
    assert res.floor.inliers / res.floor.points > 0.5
    # tolerance: a 0.25 px disparity bias of the compressed, rendered images at the floor's
    # mean disparity (~15 px) scales height by 1.7 % (11 mm) and tilts it by ~0.6 deg
    assert m.height_m == pytest.approx(truth.height_m, abs=0.015)
    assert m.tilt_deg == pytest.approx(truth.tilt_deg, abs=1.0)
    assert abs(m.roll_deg - truth.roll_deg) < 1.0


def test_remap_tables_are_built_once_per_run(floor_view, monkeypatch):
    """Three raw frames: the rig's remap tables are built once, not once per frame; the
    fit still finds the rendered mount (bounds of test_mount_from_rendered_floor)."""
    from slitcli.calibrate import rectify

    built = []
    real = rectify.RectificationMaps.for_rig.__func__

    def counting(cls, rig):
        built.append(rig)
        return real(cls, rig)

    pair = (floor_view["left"], floor_view["right"])
    params = MountParams(photometric_refinement=False)
    monkeypatch.setattr(rectify.RectificationMaps, "for_rig", classmethod(counting))
    res = calibrate_mount_frames(["f0", "f1", "f2"], [pair] * 3, floor_view["rig"], params)
    assert len(built) == 1
    t = floor_view["truth"]
    assert abs(res.rig.mount.tilt_deg - t["tilt_deg"]) < 0.3
    assert abs(res.rig.mount.height_m - t["height_m"]) < 0.005
