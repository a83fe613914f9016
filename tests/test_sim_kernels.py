"""The compiled (Cython) kernels of the renderer and the planner's prediction
(slitcli.sim._c, slitcli._c): values at hand-derived points, the inputs they refuse, and
that rendering and planning load no numba."""

from __future__ import annotations

import json
import pickle
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from slitcli._prediction_kernel import contact_kernel
from slitcli.sim.camera import bloom
from slitcli.sim.texture import TILE, TextureTables, _lattice_table, value_noise
from slitcli.sim.texture import _octaves as octaves

ROOT = Path(__file__).resolve().parent.parent
SEEDS = [0, 1, 2, 3, 4]


@pytest.mark.parametrize("seed", SEEDS)
def test_value_noise_at_lattice_points_is_the_lattice_value(seed):
    """At a lattice point the fade weights are 0, so one octave is the table's value
    there, wrapped to the tile (negative cells too). Spacing 0.25 m keeps s / spacing an
    exact integer."""
    rng = np.random.default_rng(seed)
    i, j = rng.integers(-3 * TILE, 3 * TILE, (2, 200))
    got = value_noise(0.25 * i, 0.25 * j, seed=seed, scale_m=0.25, octaves=1)
    table = _lattice_table(seed * 16)
    assert np.array_equal(got, table[i % TILE, j % TILE])


@pytest.mark.parametrize("seed", SEEDS)
def test_value_noise_midway_is_the_mean_of_the_corners(seed):
    """Midway between lattice points the quintic fade is exactly 1/2 both ways: the
    value is the mean of the four corners."""
    rng = np.random.default_rng(seed)
    i, j = rng.integers(-TILE, TILE, (2, 100))
    got = value_noise(0.25 * (i + 0.5), 0.25 * (j + 0.5), seed=seed, scale_m=0.25,
                      octaves=1)
    tb = _lattice_table(seed * 16)
    want = [tb[i % TILE, j % TILE], tb[(i + 1) % TILE, j % TILE],
            tb[i % TILE, (j + 1) % TILE], tb[(i + 1) % TILE, (j + 1) % TILE]]
    np.testing.assert_allclose(got, np.mean(want, axis=0), rtol=0, atol=1e-15)


@pytest.mark.parametrize("seed", SEEDS)
def test_kept_texture_tables_give_the_same_noise(seed):
    """Tables kept across calls (a sequence's TextureTables) give the values drawn
    without them, to the bit, for several patterns and octave counts; each pattern's
    tables are drawn once; a pickled copy holds none and draws them again."""
    rng = np.random.default_rng(seed)
    s, t = rng.uniform(-20.0, 20.0, (2, 500))
    kept = TextureTables()
    for pattern, n_oct in ((seed, 3), (seed + 7, 3), (seed, 2), (seed, 3)):
        want = value_noise(s, t, seed=pattern, scale_m=0.03, octaves=n_oct)
        got = value_noise(s, t, seed=pattern, scale_m=0.03, octaves=n_oct, textures=kept)
        assert np.array_equal(got, want)
    assert kept.tables(seed, 3) is kept.tables(seed, 3)
    assert len(kept._by_pattern) == 3
    copy = pickle.loads(pickle.dumps(kept))
    assert copy._by_pattern == {}
    assert np.array_equal(copy.tables(seed, 2), kept.tables(seed, 2))


def test_octaves_refuse_mismatched_inputs():
    s = np.zeros(4)
    with pytest.raises(ValueError, match="matching lengths"):
        octaves(s, np.zeros(3), np.zeros((1, 9, 9)), np.ones(1), np.ones(1))
    with pytest.raises(ValueError, match="power of two"):
        octaves(s, s, np.zeros((1, 7, 7)), np.ones(1), np.ones(1))


def test_contact_kernel_refuses_mismatched_inputs():
    with pytest.raises(ValueError, match="do not match"):
        contact_kernel(np.zeros((3, 4, 2)), np.zeros((2, 5, 2)), np.zeros((3, 5)),
                       np.zeros(4))


def test_bloom_keeps_a_nan_pixel_and_spills_nothing_from_it():
    """np.minimum's semantics: a NaN pixel stays NaN, its neighbours are untouched."""
    e = np.full((5, 5), 100.0)
    e[2, 2] = np.nan
    out = bloom(e, 1000.0, 1.0, 0.5)
    assert np.isnan(out[2, 2])
    assert np.array_equal(np.delete(out.ravel(), 12), np.full(24, 100.0))


def test_rendering_and_planning_load_no_numba():
    """Render a camera-modelled frame and plan against a moving disc: no numba."""
    code = textwrap.dedent("""
        import json, sys
        import numpy as np
        from slitcli.prediction import MovingDiscs, moving_contact_time
        from slitcli.sim.camera import bloom
        from slitcli.sim.texture import value_noise
        import slitcli.sim.render, slitcli.sim.loop, slitcli.dwa
        value_noise(np.zeros(3), np.ones(3), seed=1, scale_m=0.02)
        bloom(np.full((4, 4), 2000.0), 1000.0, 0.5, 0.9)
        moving = MovingDiscs(np.array([[1.0, 0.0]]), np.array([[-0.5, 0.0]]), np.zeros(1))
        t_c, _ = moving_contact_time(np.array([0.2]), np.array([0.0]), moving,
                                     radius_m=0.3, horizon_s=3.0, step_s=0.1)
        print(json.dumps({"numba": "numba" in sys.modules, "t_c": float(t_c[0])}))
        """)
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         cwd=ROOT, timeout=300)
    assert res.returncode == 0, res.stderr[-2000:]
    out = json.loads(res.stdout.strip().splitlines()[-1])
    assert not out["numba"]
    # the gap 1 - 0.7 t m falls below reach 0.3 + 0.05 (0.2 + 0.5) = 0.335 m after
    # 0.95 s: the first instant on the 0.1 s grid is 1.0 s
    assert out["t_c"] == pytest.approx(1.0, abs=1e-9)
