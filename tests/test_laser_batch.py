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


def _sequence(folder: Path, laser_dn: float, seeds: range) -> list[np.ndarray]:
    imgs = []
    for side in ("left", "right"):
        (folder / side).mkdir(parents=True)
    for i, seed in enumerate(seeds):
        img = make_frame(RIG, forward_m=0.8, seed=seed, laser_dn=laser_dn).bgr
        for side in ("left", "right"):
            cv2.imwrite(str(folder / side / f"{i:06d}.png"), img)
        imgs.append(img)
    return imgs


@pytest.mark.parametrize("seed", range(5))
def test_a_run_without_any_stripe_says_so(tmp_path, seed):
    dark = tmp_path / "dark"
    _sequence(dark, 0.0, range(seed, seed + 2))
    res = CliRunner().invoke(cli, ["laser", str(dark), "-o", str(tmp_path / "o")])
    assert res.exit_code == 0, res.stderr
    assert "found in none of the 2 frames" in res.stderr
    lit = tmp_path / "lit"
    _sequence(lit, 110.0, range(seed, seed + 2))
    res = CliRunner().invoke(cli, ["laser", str(lit), "-o", str(tmp_path / "o2")])
    assert res.exit_code == 0 and "found in none" not in res.stderr
    assert "stripe columns" in res.output


def test_bag_gives_the_folder_table(tmp_path):
    """The same frames from a bag and from a folder: the same laser.csv."""
    imgs = _sequence(tmp_path / "seq", 110.0, range(3))
    bag = write_bag(tmp_path / "b", [(i, i) for i in imgs], ros=2)
    save_rig(RIG, tmp_path / "rig.yaml")
    a = run_laser(tmp_path / "seq", tmp_path / "a").outputs[0]
    b = run_laser(bag, tmp_path / "b_out", rig_path=tmp_path / "rig.yaml").outputs[0]
    assert a.read_bytes() == b.read_bytes()
    assert pd.read_csv(a)["frame"].nunique() == 3
