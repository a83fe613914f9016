"""The command line's shared machinery (slitcli.cli.main): --config, parameter names."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pandas as pd
from click.testing import CliRunner

from slitcli.cli import cli
from slitcli.cli.main import user_message
from slitcli.errors import SlitcliError

ROOT = Path(__file__).resolve().parent.parent
BUNDLED = ROOT / "sample_data" / "sequences" / "corridor"


def _one_frame(tmp: Path) -> Path:
    seq = tmp / "seq"
    for side in ("left", "right"):
        (seq / side).mkdir(parents=True)
        shutil.copy(BUNDLED / side / "000000.png", seq / side / "000000.png")
    shutil.copy(BUNDLED / "rig.yaml", seq / "rig.yaml")
    return seq


def test_config_file_sets_options_and_flags_win(tmp_path):
    seq = _one_frame(tmp_path)
    cfg = tmp_path / "detect.yaml"
    cfg.write_text("bin-deg: 2\nfusion: conservative\n")
    runner = CliRunner()
    res = runner.invoke(cli, ["detect", str(seq), "-o", str(tmp_path / "a"), "--config",
                              str(cfg)])
    assert res.exit_code == 0, res.stderr
    b = pd.read_csv(tmp_path / "a" / "ranges.csv")["bearing_deg"].to_numpy()
    assert np.all(np.diff(b) == 2.0)
    res = runner.invoke(cli, ["detect", str(seq), "-o", str(tmp_path / "b"), "--config",
                              str(cfg), "--bin-deg", "4"])
    assert res.exit_code == 0, res.stderr
    b = pd.read_csv(tmp_path / "b" / "ranges.csv")["bearing_deg"].to_numpy()
    assert np.all(np.diff(b) == 4.0)


def test_config_file_with_an_unknown_option_is_refused(tmp_path):
    cfg = tmp_path / "c.yaml"
    cfg.write_text("bin-degree: 2\n")
    res = CliRunner().invoke(cli, ["detect", str(BUNDLED), "-o", str(tmp_path / "o"),
                                   "--config", str(cfg)])
    assert res.exit_code == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "'bin-degree' is not an option" in lines[0]
    assert "bin-deg" in lines[0] and not (tmp_path / "o").exists()


def test_parameter_names_become_flags():
    e = SlitcliError("`bin_deg` 20 is out of range; give 0.05-10 degrees", param="bin_deg")
    assert user_message(e) == "--bin-deg 20 is out of range; give 0.05-10 degrees"
    e = SlitcliError("`left_bgr` is 3x2; give the rig of this camera (`rig`)",
                     param=("left_bgr", "rig"))
    assert user_message(e) == "left_bgr is 3x2; give the rig of this camera (--rig)"
    # a word that happens to be a parameter's name is left alone
    e = SlitcliError("the rig's images are 320x240 (`rig`)", param="rig")
    assert user_message(e) == "the rig's images are 320x240 (--rig)"
    # through the command line: a bound only the library checks comes back as the flag
    table = BUNDLED.parent.parent / "missing_ranges.csv"
    res = CliRunner().invoke(cli, ["dwa", str(table), "--goal", "4,0", "-o", "x.csv",
                                   "--memory-cell-m", "1e9"])
    assert res.exit_code == 2 and "--memory-cell-m 1000000000.0 must be in" in res.stderr
    assert "`" not in res.stderr
