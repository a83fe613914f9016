"""Calibration hand-offs: rig set keeps the laser sheet in the world, factory rigs, rig show
flags, the placeholder notes."""

from __future__ import annotations

import math

import numpy as np
import pytest
from click.testing import CliRunner

from slitcli.cli import cli
from slitcli.rig import load_rig, paper_rig, save_rig
from slitcli.rig_tools import factory_rig, laser_height_m, rig_warnings, rig_with_mount


def _sheet_points_sensor(rig, n=50):
    """Points of the laser sheet in the sensor frame, found from the camera frame plane."""
    u = np.linspace(0, rig.width_px - 1, n)
    v = np.linspace(rig.height_px * 0.55, rig.height_px - 1, n)
    pts = rig.intersect_laser_plane(rig.pixel_rays_cam(u, v))
    return rig.cam_to_sensor(pts[np.all(np.isfinite(pts), axis=1)])


@pytest.mark.parametrize("seed", range(6))
def test_mount_edit_keeps_the_sheet_in_the_world(seed):
    rng = np.random.default_rng(seed)
    rig = paper_rig()
    new = rig_with_mount(rig, height_m=float(rng.uniform(0.3, 1.2)),
                         tilt_deg=float(rng.uniform(-5, 45)),
                         roll_deg=float(rng.uniform(-5, 5)))
    n0, d0 = rig.laser_plane_sensor()
    n1, d1 = new.laser_plane_sensor()
    assert np.allclose(n0, n1, atol=1e-12) and d1 == pytest.approx(d0, abs=1e-12)
    # points of the old sheet lie on the new sheet (sensor frame)
    pts = _sheet_points_sensor(rig)
    assert np.max(np.abs(pts @ n1 - d1)) < 1e-12
    assert new.laser.offset_m > 0 and np.linalg.norm(new.laser.normal) == pytest.approx(1.0)
    assert laser_height_m(new) == pytest.approx(0.05, abs=1e-12)  # paper: 0.65 - 0.60
    # a laser height edit: a horizontal sheet at that height, in the new mount's frame
    z = float(rng.uniform(0.0, 0.25))
    low = rig_with_mount(new, laser_height_m=z)
    n2, _ = low.laser_plane_sensor()
    assert abs(abs(n2[2]) - 1.0) < 1e-12 and laser_height_m(low) == pytest.approx(z, abs=1e-12)
    assert low.mount == new.mount


def test_cli_rig_set(tmp_path):
    rig_path = tmp_path / "rig.yaml"
    save_rig(paper_rig(), rig_path)
    res = CliRunner().invoke(cli, ["rig", "set", str(rig_path), "--mount-height-m", "0.42",
                                   "--tilt-deg", "18.5"])
    assert res.exit_code == 0, res.output
    rig = load_rig(rig_path)
    assert (rig.mount.height_m, rig.mount.tilt_deg) == (0.42, 18.5)
    n, d = rig.laser_plane_sensor()
    n0, d0 = paper_rig().laser_plane_sensor()
    assert np.allclose(n, n0, atol=1e-12) and d == pytest.approx(d0, abs=1e-12)
    assert "laser sheet 0.0500 m above the floor" in res.output
    out = tmp_path / "low.yaml"
    res = CliRunner().invoke(cli, ["rig", "set", str(rig_path), "--laser-height-m", "0.1",
                                   "-o", str(out)])
    assert res.exit_code == 0 and laser_height_m(load_rig(out)) == pytest.approx(0.1)
    # a laser sheet above the camera: exit 2, one line, nothing written
    before = rig_path.read_text()
    for args in (["--laser-height-m", "0.5"], ["--tilt-deg", "95"], []):
        res = CliRunner().invoke(cli, ["rig", "set", str(rig_path), *args,
                                       "-o", str(tmp_path / "bad.yaml")])
        assert res.exit_code == 2 and len(res.output.strip().splitlines()) == 1, res.output
        assert not (tmp_path / "bad.yaml").exists() and rig_path.read_text() == before
        if args:
            assert args[0] in res.output and "`" not in res.output  # the option, by name


def test_factory_rig_and_rig_init(tmp_path):
    rig = factory_rig((640, 400), 402.5, 0.075)
    assert rig.left.cx_px == 319.5 and rig.left.cy_px == 199.5 and rig.left.fy_px == 402.5
    assert rig.raw is None and rig.mount == paper_rig().mount
    assert laser_height_m(rig) == pytest.approx(laser_height_m(paper_rig()), abs=1e-12)
    out = tmp_path / "oak.yaml"
    res = CliRunner().invoke(cli, ["rig", "init", "-o", str(out), "--image-size", "640,400",
                                   "--fx-px", "402.5", "--baseline-m", "0.075"])
    assert res.exit_code == 0, res.output
    assert "placeholders" in res.output  # the stderr note (CliRunner mixes the streams)
    text = out.read_text()
    assert text.startswith("# mount and laser were NOT calibrated")
    back = load_rig(out)
    assert back.image_size_px == (640, 400) and back.baseline_m == 0.075
    assert back.left.fx_px == 402.5
    res = CliRunner().invoke(cli, ["rig", "init", "-o", str(tmp_path / "x.yaml"),
                                   "--image-size", "640,400"])
    assert res.exit_code == 2 and "--fx-px" in res.output
    assert not (tmp_path / "x.yaml").exists()


@pytest.mark.parametrize("tilt_deg", [0.0, 2.0, 5.0, 8.0, 60.0])
def test_rig_show_flags_stripe_rows_outside_the_image(tmp_path, tilt_deg):
    rig = rig_with_mount(factory_rig((640, 480), 500.0, 0.075), tilt_deg=tilt_deg)
    # hand-derived row of the stripe on a wall d ahead: the sheet is 0.60 m below the
    # camera, so the ray to (d, 0, -0.6) makes angle atan(0.6 / d) - tilt below the axis
    rows = {d: 239.5 + 500.0 * math.tan(math.atan(0.6 / d) - math.radians(tilt_deg))
            for d in (0.6, 0.8, 1.0)}
    for d, row in rows.items():
        assert rig.stripe_row_on_wall(d) == pytest.approx(row, abs=1e-6)
    flagged = {d for d, row in rows.items() if not -0.5 <= row <= 479.5}
    warnings = rig_warnings(rig)
    for d in (0.6, 0.8, 1.0):
        hit = any(f"wall {d:g} m ahead: row" in w for w in warnings)
        assert hit == (d in flagged), (d, warnings)
    path = tmp_path / "r.yaml"
    save_rig(rig, path)
    res = CliRunner().invoke(cli, ["rig", "show", str(path)])
    assert res.exit_code == 0 and res.output.count("# WARNING") == len(warnings)
    assert not rig_warnings(paper_rig())
