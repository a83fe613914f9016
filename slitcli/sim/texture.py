"""Seeded procedural texture: smooth multi-octave value noise over surface coordinates.

The texture is a function of a surface's own 2-D coordinates in metres, so every camera
(and every supersample) sees the same pattern at the same surface point: stereo pairs
rendered from it are exact views of one textured world.
"""

from __future__ import annotations

import numpy as np

from slitcli.sim._c.texture import octaves as _octaves

# Lattice values repeat every TILE cells; at the default 2 cm feature size the coarsest
# octave repeats every 10 m, farther than any generated scene reaches.
TILE = 512


def _lattice_table(seed: int) -> np.ndarray:
    """Random lattice values in [0, 1), one (TILE+1, TILE+1) table per seed (wrapped)."""
    t = np.random.default_rng(seed).random((TILE, TILE))
    return np.pad(t, ((0, 1), (0, 1)), mode="wrap")

def value_noise(s_m: np.ndarray, t_m: np.ndarray, *, seed: int, scale_m: float,
                octaves: int = 3) -> np.ndarray:
    """Band-limited noise in [0, 1] at surface coordinates (metres).

    Parameters
    ----------
    s_m, t_m : ndarray, same shape
        Surface coordinates, metres.
    seed : int
        Pattern seed.
    scale_m : float
        Lattice spacing of the coarsest octave (feature size), metres.
    octaves : int
        Octaves at half the spacing each, with half the amplitude each.

    Returns
    -------
    ndarray, same shape, values in [0, 1] with mean about 0.5.
    """
    freqs = (2.0 ** np.arange(octaves)) / scale_m
    amps = 0.5 ** np.arange(octaves)
    tables = np.stack([_lattice_table(abs(seed) * 16 + o) for o in range(octaves)])
    s_flat = np.ascontiguousarray(np.ravel(s_m), dtype=np.float64)
    t_flat = np.ascontiguousarray(np.ravel(t_m), dtype=np.float64)
    out = _octaves(s_flat, t_flat, tables, freqs, amps) / amps.sum()
    return out.reshape(np.shape(s_m))
