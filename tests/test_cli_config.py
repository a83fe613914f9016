"""--config FILE on every command, -o/--out everywhere, detect's laser options."""

from __future__ import annotations

import click
import pytest
from click.testing import CliRunner

from slitcli.cli import cli


def _commands(group: click.Group, prefix: tuple[str, ...] = ()):
    for name, cmd in sorted(group.commands.items()):
        if isinstance(cmd, click.Group):
            yield from _commands(cmd, (*prefix, name))
        else:
            yield (*prefix, name), cmd


ALL = list(_commands(cli))
# commands that write a file or folder they are told; report writes into DETECT_OUT/report
WRITERS = {c for c, cmd in ALL if any(p.name in ("out", "out_opt") for p in cmd.params
                                      if isinstance(p, click.Option))}


def test_every_command_takes_config_and_writers_take_o_out():
    assert len(ALL) >= 15
    for path, cmd in ALL:
        assert any("--config" in getattr(p, "opts", ()) for p in cmd.params), path
    expected = {("calibrate", "stereo"), ("calibrate", "laser"), ("calibrate", "mount"),
                ("rig", "import"), ("rig", "export"), ("detect",), ("laser",), ("stereo",),
                ("dwa",), ("simulate-dwa",), ("export",), ("figures",),
                ("rig", "init"), ("rig", "set")}
    assert expected <= WRITERS
    for path, cmd in ALL:
        if path in WRITERS:
            opts = [o for p in cmd.params if p.name in ("out", "out_opt")
                    and isinstance(p, click.Option) for o in p.opts]
            assert "-o" in opts and "--out" in opts, path


def _ctx(path: tuple[str, ...], args: list[str]) -> click.Context:
    cmd = cli
    for name in path:
        cmd = cmd.commands[name]
    return cmd.make_context(" ".join(("slitcli", *path)), args)


def test_config_sets_defaults_and_the_command_line_overrides(tmp_path):
    cfg = tmp_path / "detect.yaml"
    cfg.write_text("max-dt: 0.05\nbin_deg: 2.0\nmin-th: 0.41\nfusion: conservative\n"
                   "save-images: true\n")
    ctx = _ctx(("detect",), ["seq", "-o", "out", "--config", str(cfg)])
    assert ctx.params["max_dt"] == 0.05 and ctx.params["bin_deg"] == 2.0
    assert ctx.params["min_th"] == 0.41 and ctx.params["fusion"] == "conservative"
    assert ctx.params["save_images"] is True
    # flags win over the file wherever they stand
    ctx = _ctx(("detect",), ["--max-dt", "0.02", "seq", "-o", "out", "--config", str(cfg),
                             "--min-th", "0.38"])
    assert ctx.params["max_dt"] == 0.02 and ctx.params["min_th"] == 0.38
    assert ctx.params["bin_deg"] == 2.0
    # a required option may come from the file
    cfg2 = tmp_path / "mount.yaml"
    cfg2.write_text("rig: r.yaml\nframes: 3\n")
    ctx = _ctx(("calibrate", "mount"), ["seq", "--config", str(cfg2)])
    assert str(ctx.params["rig_path"]) == "r.yaml" and ctx.params["frames"] == 3


@pytest.mark.parametrize("text, word", [
    ("max-dt: 0.05\nbogus-option: 3\n", "'bogus-option'"),
    ("min-thh: 0.4\n", "did you mean 'min-th'"),
    ("rig: r.yaml\nrig_path: s.yaml\n", "same option"),
    ("bin-deg: many\n", "'bin-deg'"),
    ("- 1\n- 2\n", "mapping"),
    ("a: [1\n", "not valid YAML"),
])
def test_bad_config_exit_2_one_line_naming_file_and_key(tmp_path, text, word):
    cfg = tmp_path / "bad.yaml"
    cfg.write_text(text)
    out = tmp_path / "out"
    res = CliRunner().invoke(cli, ["detect", str(tmp_path), "-o", str(out), "--config",
                                   str(cfg)])
    assert res.exit_code == 2, res.output
    lines = res.output.strip().splitlines()
    assert len(lines) == 1 and str(cfg) in lines[0] and word in lines[0], lines
    assert not out.exists()


def test_missing_config_file(tmp_path):
    res = CliRunner().invoke(cli, ["rig", "show", "--config", str(tmp_path / "none.yaml")])
    assert res.exit_code == 2 and "none.yaml" in res.output
    assert len(res.output.strip().splitlines()) == 1


def test_detect_takes_every_laser_option():
    laser = {o for p in cli.commands["laser"].params for o in getattr(p, "opts", ())
             if p.name not in ("out", "rig_path", "overlay", "seq")}
    detect = {o for p in cli.commands["detect"].params for o in getattr(p, "opts", ())}
    assert laser <= detect
    ctx = _ctx(("detect",), ["seq", "-o", "o", "--sheet-sigma-mm", "0", "--alpha", "0.3"])
    assert ctx.params["sheet_sigma_mm"] == 0 and ctx.params["alpha"] == 0.3


def test_old_output_spelling_still_works(tmp_path):
    from slitcli.rig import load_rig, paper_rig, save_rig

    rig = tmp_path / "rig.yaml"
    save_rig(paper_rig(), rig)
    res = CliRunner().invoke(cli, ["rig", "export", str(rig), "--format", "kalibr",
                                   "--output", str(tmp_path / "k")])
    assert res.exit_code == 0, res.output
    res = CliRunner().invoke(cli, ["rig", "import", str(tmp_path / "k" / "camchain.yaml"),
                                   "--out", str(tmp_path / "r2.yaml")])
    assert res.exit_code == 0, res.output
    assert load_rig(tmp_path / "r2.yaml").baseline_m == pytest.approx(0.088, abs=1e-9)
