"""Command-line behaviour: help everywhere, one-line errors, end-to-end render and rig."""

from pathlib import Path

import click
import numpy as np
import pytest
from click.testing import CliRunner

from slitcli.cli import cli
from slitcli.rig import load_rig, paper_rig

ROOT = Path(__file__).resolve().parent.parent


def _commands(group: click.Group, prefix: tuple[str, ...] = ()):
    for name, cmd in group.commands.items():
        yield (*prefix, name)
        if isinstance(cmd, click.Group):
            yield from _commands(cmd, (*prefix, name))


@pytest.mark.parametrize("path", [(), *list(_commands(cli))], ids=lambda p: " ".join(p) or "top")
def test_every_command_has_help_with_an_example(path):
    res = CliRunner().invoke(cli, [*path, "--help"])
    assert res.exit_code == 0, res.output
    assert "Usage:" in res.output
    cmd = cli
    for p in path:
        cmd = cmd.commands[p]
    if not isinstance(cmd, click.Group):
        assert "Example" in res.output
    else:
        # a group's help shows a session (its commands in use), not only a docs pointer
        assert "slitcli " in res.output.split("Options:")[0].split("Usage:")[1].split("\n", 1)[1]
    # every value option states its default in the help itself (shown by click, or
    # written out: "default: ...", "default: none: ..."), not only in docs/
    missing = [p.opts[-1] for p in cmd.params
               if isinstance(p, click.Option) and not p.is_flag and not p.required
               and not p.show_default and "default" not in (p.help or "").lower()]
    assert not missing, missing


def test_rig_init_then_show(tmp_path):
    r = CliRunner()
    res = r.invoke(cli, ["rig", "init", str(tmp_path / "rig.yaml")])
    assert res.exit_code == 0
    assert load_rig(tmp_path / "rig.yaml") == paper_rig()
    res = r.invoke(cli, ["rig", "show", str(tmp_path / "rig.yaml")])
    assert res.exit_code == 0
    assert "167.93 at 1.0 m" in res.output and "195.31 at 0.8 m" in res.output
    assert "236.08 at 0.6 m" in res.output and "22.00 at 1 m" in res.output


@pytest.mark.parametrize("edit,key", [
    (("tilt_deg: 20.0", "tilt_deg: 95.0"), "mount.tilt_deg"),
    (("fx_px: 250.0", "fx_px: 0.0"), "left.fx_px"),
    (("slitcli_rig: 1", "slitcli_rig: 7"), "slitcli_rig"),
    (("image_size_px: [320, 240]", "image_size_px: [-320, 240]"), "image_size_px"),
])
def test_bad_rig_exits_2_with_one_line(tmp_path, edit, key):
    p = tmp_path / "rig.yaml"
    p.write_text(paper_rig().to_yaml().replace(*edit))
    assert edit[1] in p.read_text()
    res = CliRunner().invoke(cli, ["rig", "show", str(p)])
    assert res.exit_code == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and key in lines[0] and str(p) in lines[0]


def test_render_end_to_end(tmp_path):
    """One seed suffices: the seed draws textures and sensor noise only, and every
    value asserted here (the file list, the columns, the nearest range and the lit
    points of the left box) comes from the scene's geometry alone (the truth tables
    are ray casts, not image measurements), so another seed gives the same values."""
    scene = tmp_path / "s.yaml"
    scene.write_text((ROOT / "sample_data" / "fig4.yaml").read_text()
                     .replace("frames: 1", "frames: 2"))
    out = tmp_path / "seq"
    res = CliRunner().invoke(cli, ["render", str(scene), str(out), "--seed", "9"])
    assert res.exit_code == 0, res.stderr
    assert "rendered 2 frames" in res.output
    for sub in ("left", "right", "gt/disparity", "gt/distance", "gt/mask"):
        assert sorted(p.name for p in (out / sub).iterdir()) == ["000000.png", "000001.png"]
    import pandas as pd

    ranges = pd.read_csv(out / "gt" / "ranges.csv")
    assert list(ranges.columns) == ["frame", "time_s", "bearing_deg", "range_m"]
    # the left box's front face is 0.6 m ahead and spans y = 0.05..0.39 m: its nearest
    # point is the corner (0.6, 0.05)
    assert ranges["range_m"].min() == pytest.approx(np.hypot(0.6, 0.05), abs=1e-6)
    laser = pd.read_csv(out / "gt" / "laser.csv")
    assert list(laser.columns) == ["frame", "u_px", "v_px", "strength", "x_m", "y_m",
                                   "range_m", "bearing_deg"]
    near = laser[(laser.frame == 0) & (laser.x_m < 0.7)]
    # lit points of the left box lie on its front face (x = 0.6) or its inner side (y = 0.05)
    on_box = np.isclose(near.x_m, 0.6, atol=1e-6) | np.isclose(near.y_m, 0.05, atol=1e-6)
    assert on_box.all() and np.isclose(near.x_m, 0.6, atol=1e-6).sum() > 80
    assert load_rig(out / "rig.yaml") == paper_rig()
    # the output exists: a second run refuses, and leaves it alone
    res = CliRunner().invoke(cli, ["render", str(scene), str(out)])
    assert res.exit_code == 2 and "--overwrite" in res.stderr


@pytest.mark.parametrize("text,key", [
    ("slitcli_scene: 1\nobjects: [{type: box, centre_xy_m: [1, 0], size_m: [0.3, 0.3, -1]}]\n",
     "objects[0].size_m"),
    ("slitcli_scene: 1\nimage: {supersample: 99}\n", "image.supersample"),
    ("slitcli_scene: [\n", "not valid YAML"),
    ("slitcli_scene: 3\n", "slitcli_scene"),
])
def test_bad_scene_exits_2_and_writes_nothing(tmp_path, text, key):
    scene = tmp_path / "bad.yaml"
    scene.write_text(text)
    out = tmp_path / "out"
    res = CliRunner().invoke(cli, ["render", str(scene), str(out)])
    assert res.exit_code == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and key in lines[0]
    assert not out.exists() and list(tmp_path.iterdir()) == [scene]


def test_missing_scene_and_bad_option_are_one_line(tmp_path):
    res = CliRunner().invoke(cli, ["render", str(tmp_path / "nope.yaml"), str(tmp_path / "o")])
    assert res.exit_code == 2 and "scene file not found" in res.stderr
    res = CliRunner().invoke(cli, ["render", "x.yaml", "o", "--frames", "0"])
    assert res.exit_code == 2 and len(res.stderr.strip().splitlines()) == 1
    assert "--frames" in res.stderr


def test_internal_error_is_one_line_and_debug_shows_traceback(tmp_path, monkeypatch):
    import slitcli.rig as rigmod

    def boom():
        raise ZeroDivisionError("kaboom")

    monkeypatch.setattr(rigmod, "paper_rig", boom)
    res = CliRunner().invoke(cli, ["rig", "show"])
    assert res.exit_code == 1
    assert res.stderr.strip().splitlines() == [
        "slitcli: internal error: ZeroDivisionError: kaboom (run with --debug for the "
        "traceback)"]
    res = CliRunner().invoke(cli, ["--debug", "rig", "show"])
    assert res.exit_code == 1 and "Traceback" in res.stderr
