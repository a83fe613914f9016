"""`slitcli laser` over a frame source (slitcli.laser.batch): bags, raw rigs, notes."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pandas as pd
import pytest
from bagwriter import write_bag
from click.testing import CliRunner
from laser_synth import make_frame

from slitcli.cli import cli
from slitcli.laser.batch import run_laser
from slitcli.rig import paper_rig, save_rig

RIG = paper_rig()


def _sequence(folder: Path, laser_dn: float | list[float], seeds: range, *,
              grey: bool = False) -> list[np.ndarray]:
    imgs = []
    for side in ("left", "right"):
        (folder / side).mkdir(parents=True)
    dn = [laser_dn] * len(seeds) if np.isscalar(laser_dn) else laser_dn
    for i, seed in enumerate(seeds):
        img = make_frame(RIG, forward_m=0.8, seed=seed, laser_dn=dn[i]).bgr
        if grey:  # a grey stream: the camera's luma in all three channels
            img = np.repeat(cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)[..., None], 3, axis=2)
        for side in ("left", "right"):
            cv2.imwrite(str(folder / side / f"{i:06d}.png"), img)
        imgs.append(img)
    return imgs


@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize("command", ["laser", "detect"])
def test_a_run_mostly_without_a_stripe_says_so_and_why(tmp_path, seed, command):
    # two of three frames without laser light: the warning (stderr, exit 0) counts them
    # and says the laser may be off
    dark = tmp_path / "dark"
    _sequence(dark, [0.0, 110.0, 0.0], range(seed, seed + 3))
    res = CliRunner().invoke(cli, [command, str(dark), "-o", str(tmp_path / "o")])
    assert res.exit_code == 0, res.stderr
    assert "no laser stripe in 2 of 3 frames" in res.stderr
    assert "laser may be off" in res.stderr and "grey" not in res.stderr
    assert "--search full searches every row" in res.stderr  # the flag, not the field
    # the same frames as a grey stream: the stripe cannot be there, and it says why
    grey = tmp_path / "grey"
    _sequence(grey, 110.0, range(seed, seed + 3), grey=True)
    res = CliRunner().invoke(cli, [command, str(grey), "-o", str(tmp_path / "o3")])
    assert res.exit_code == 0, res.stderr
    assert "no laser stripe in 3 of 3 frames" in res.stderr
    assert "3 of them are grey images" in res.stderr
    # the laser in every frame (or in two of three): no warning
    lit = tmp_path / "lit"
    _sequence(lit, [110.0, 0.0, 110.0], range(seed, seed + 3))
    res = CliRunner().invoke(cli, [command, str(lit), "-o", str(tmp_path / "o2")])
    assert res.exit_code == 0 and "no laser stripe" not in res.stderr


def test_bag_gives_the_folder_table(tmp_path):
    """The same frames from a bag and from a folder: the same laser.csv."""
    imgs = _sequence(tmp_path / "seq", 110.0, range(3))
    bag = write_bag(tmp_path / "b", [(i, i) for i in imgs], ros=2)
    save_rig(RIG, tmp_path / "rig.yaml")
    a = run_laser(tmp_path / "seq", tmp_path / "a").outputs[0]
    b = run_laser(bag, tmp_path / "b_out", rig_path=tmp_path / "rig.yaml").outputs[0]
    assert a.read_bytes() == b.read_bytes()
    assert pd.read_csv(a)["frame"].nunique() == 3
