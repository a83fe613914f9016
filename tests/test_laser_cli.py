"""`slitcli laser` end to end, and its bad-input behaviour (exit 2, nothing written)."""

from pathlib import Path

import cv2
import numpy as np
import pandas as pd
import pytest
import yaml
from click.testing import CliRunner

from slitcli.cli import cli
from slitcli.laser import TABLE_COLUMNS
from slitcli.rig import paper_rig
from slitcli.sim.scene import load_scene
from slitcli.sim.sequence import render_sequence

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def seq(tmp_path_factory):
    out = tmp_path_factory.mktemp("seq") / "distractors"
    render_sequence(load_scene(ROOT / "sample_data" / "distractors.yaml"), paper_rig(), out,
                    frames=2)
    return out


def test_laser_cli_matches_ground_truth(seq, tmp_path):
    out = tmp_path / "out"
    res = CliRunner().invoke(cli, ["laser", str(seq), "-o", str(out), "--overlay"])
    assert res.exit_code == 0, res.output
    table = pd.read_csv(out / "laser.csv")
    assert tuple(table.columns) == TABLE_COLUMNS
    gt = pd.read_csv(seq / "gt" / "laser.csv")
    m = gt.merge(table, on=["frame", "u_px"], suffixes=("_gt", ""))
    assert len(m) >= 0.99 * len(gt)
    assert len(table) == len(m)  # every reported column has a true stripe
    err = m["v_px"] - m["v_px_gt"]
    assert np.sqrt(np.mean(err**2)) <= 0.20
    assert np.median(np.abs(m["x_m"] - m["x_m_gt"]) / m["x_m_gt"]) <= 0.005
    np.testing.assert_allclose(table["range_m"], np.hypot(table["x_m"], table["y_m"]),
                               rtol=1e-5)
    band = (table["range_m"] >= 0.6) & (table["range_m"] <= 1.0)
    assert (table["in_band"] == band.astype(int)).mean() >= 0.99  # 6-digit rounding at edges
    pngs = sorted((out / "laser_overlay").glob("*.png"))
    assert [p.stem for p in pngs] == sorted(p.stem for p in (seq / "left").glob("*.png"))
    img = cv2.imread(str(pngs[0]))
    assert img.shape == (480, 640, 3)
    # the stripe is drawn in green (in band) where the detector found it
    green = (img[..., 1] == 255) & (img[..., 0] < 80) & (img[..., 2] < 80)
    assert green.sum() > 100


def _one_line_error(res):
    assert res.exit_code == 2, res.output
    lines = [x for x in res.output.strip().splitlines() if x]
    assert len(lines) == 1 and lines[0].startswith("slitcli: error:")
    return lines[0]


def test_laser_cli_missing_sequence(tmp_path):
    out = tmp_path / "out"
    msg = _one_line_error(CliRunner().invoke(cli, ["laser", str(tmp_path / "nope"), "-o",
                                                  str(out)]))
    assert "nope" in msg
    assert not out.exists()


def test_laser_cli_unreadable_image(seq, tmp_path):
    bad = tmp_path / "bad"
    for sub in ("left", "right"):
        (bad / sub).mkdir(parents=True)
        for p in sorted((seq / sub).glob("*.png")):
            (bad / sub / p.name).write_bytes(p.read_bytes())
    last = sorted((bad / "left").glob("*.png"))[-1]
    last.write_bytes(b"not a png")
    out = tmp_path / "out"
    msg = _one_line_error(CliRunner().invoke(cli, ["laser", str(bad), "-o", str(out),
                                                  "--overlay"]))
    assert last.name in msg
    assert not out.exists()


def test_laser_cli_wrong_rig(seq, tmp_path):
    rig = paper_rig().to_dict()
    rig["image_size_px"] = [640, 480]
    rig["left"].update(cx_px=319.5, cy_px=239.5)
    path = tmp_path / "rig.yaml"
    path.write_text(yaml.safe_dump(rig))
    out = tmp_path / "out"
    msg = _one_line_error(CliRunner().invoke(cli, ["laser", str(seq), "-o", str(out),
                                                  "--rig", str(path)]))
    assert "image_size_px" in msg
    assert not out.exists()
    path.write_text("slitcli_rig: 1\nname: x\n")
    msg = _one_line_error(CliRunner().invoke(cli, ["laser", str(seq), "-o", str(out),
                                                  "--rig", str(path)]))
    assert str(path) in msg
    assert not out.exists()


def test_laser_cli_bad_option(seq, tmp_path):
    out = tmp_path / "out"
    msg = _one_line_error(CliRunner().invoke(cli, ["laser", str(seq), "-o", str(out),
                                                  "--alpha", "2"]))
    assert "alpha" in msg
    assert not out.exists()


def test_every_laser_parameter_is_an_option_with_units_and_default():
    from dataclasses import fields

    from slitcli.laser import LaserParams

    cmd = cli.commands["laser"]
    options = {p.name: p for p in cmd.params}
    for f in fields(LaserParams):
        assert f.name in options, f"LaserParams.{f.name} has no `slitcli laser` option"
        opt = options[f.name]
        assert opt.default == f.default and opt.show_default
        assert opt.help and len(opt.help) > 20
