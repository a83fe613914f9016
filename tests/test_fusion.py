"""Eq. 11 fusion, case by case against hand-worked bins."""

import numpy as np
import pytest

from slitcli.errors import SlitcliError
from slitcli.fusion import FusionParams, fuse

NAN = np.nan
# bins: (laser, stereo, has_features)
CASES = [
    (0.8, NAN, False),   # 0 textureless: laser only
    (NAN, NAN, False),   # 1 textureless, no laser: nothing
    (0.8, 2.0, True),    # 2 laser in band, stereo farther -> laser
    (0.8, 0.7, True),    # 3 laser in band, stereo nearer -> stereo
    (NAN, 2.0, True),    # 4 no laser, stereo far -> stereo
    (NAN, 0.7, True),    # 5 no laser, stereo near (overhang!) -> paper clamps to 1.0
    (NAN, NAN, True),    # 6 nothing
    (1.3, 2.0, True),    # 7 laser beyond its band: treated as no laser return
    (NAN, 3.5, True),    # 8 stereo beyond its range: ignored
    (NAN, 2.0, False),   # 9 a stereo return in a bin flagged featureless: it saw features
]


def _run(mode):
    laser, stereo, feat = (np.array(c) for c in zip(*CASES, strict=True))
    return fuse(laser, stereo, feat.astype(bool), FusionParams(mode=mode))


def test_paper_mode_bins():
    f = _run("paper")
    expect = [0.8, NAN, 0.8, 0.7, 2.0, 1.0, NAN, 2.0, NAN, 2.0]
    np.testing.assert_allclose(f.range_m, expect, equal_nan=True)
    assert list(f.source) == ["laser", "none", "laser", "stereo", "stereo", "stereo", "none",
                              "stereo", "none", "stereo"]


def test_conservative_mode_is_the_plain_minimum():
    f = _run("conservative")
    expect = [0.8, NAN, 0.8, 0.7, 2.0, 0.7, NAN, 1.3, NAN, 2.0]
    np.testing.assert_allclose(f.range_m, expect, equal_nan=True)
    assert f.source[5] == "stereo" and f.source[7] == "laser"


def test_unknown_mode_is_an_input_error():
    with pytest.raises(SlitcliError, match="--fusion 'best'"):
        FusionParams(mode="best")
