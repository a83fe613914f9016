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


def _pattern_tables(seed: int, octaves: int) -> np.ndarray:
    """The lattice tables of one pattern, (octaves, TILE+1, TILE+1)."""
    return np.stack([_lattice_table(abs(seed) * 16 + o) for o in range(octaves)])


class TextureTables:
    """The lattice tables of the patterns drawn so far, kept for the next frames.

    Drawing a pattern's tables (three 513 x 513 tables of random values) takes a few
    milliseconds, and a frame draws them again for each textured surface and camera:
    about a quarter of a closed-loop vision step (at 2 x 2 rays a pixel), a few percent
    of a frame at 3 x 3. A caller that renders many frames of one scene cheaply (the
    closed loop) holds one of these and passes it to every render (``textures=``); the
    values are those drawn without it, to the bit. About 6 MB per textured surface; not
    for sharing between threads; pickled empty (a worker draws its own).
    """

    def __init__(self) -> None:
        self._by_pattern: dict[tuple[int, int], np.ndarray] = {}

    def tables(self, seed: int, octaves: int) -> np.ndarray:
        """The lattice tables of pattern ``seed`` with ``octaves`` octaves, drawn on the
        first call."""
        key = (seed, octaves)
        if key not in self._by_pattern:
            self._by_pattern[key] = _pattern_tables(seed, octaves)
        return self._by_pattern[key]

    def __getstate__(self) -> dict:
        return {}

    def __setstate__(self, _state: dict) -> None:
        self._by_pattern = {}


def value_noise(s_m: np.ndarray, t_m: np.ndarray, *, seed: int, scale_m: float,
                octaves: int = 3, textures: TextureTables | None = None) -> np.ndarray:
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
    textures : TextureTables, optional
        The caller's tables, kept from earlier frames; default: drawn for this call.

    Returns
    -------
    ndarray, same shape, values in [0, 1] with mean about 0.5.
    """
    freqs = (2.0 ** np.arange(octaves)) / scale_m
    amps = 0.5 ** np.arange(octaves)
    tables = (_pattern_tables(seed, octaves) if textures is None
              else textures.tables(seed, octaves))
    s_flat = np.ascontiguousarray(np.ravel(s_m), dtype=np.float64)
    t_flat = np.ascontiguousarray(np.ravel(t_m), dtype=np.float64)
    out = _octaves(s_flat, t_flat, tables, freqs, amps) / amps.sum()
    return out.reshape(np.shape(s_m))
