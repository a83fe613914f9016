"""Compiled kernel of the procedural texture (slitcli.sim.texture): value-noise octaves.

:func:`octaves` replaces the numba kernel of the same sum, operation for operation (no
fast-math, no contraction), so it gives the same bits. It releases the GIL.
"""

import numpy as np

from libc.math cimport floor


def octaves(const double[::1] s, const double[::1] t, const double[:, :, ::1] tables,
            const double[::1] freqs, const double[::1] amps):
    """Sum of bilinearly interpolated lattice octaves with a quintic fade.

    The quintic fade ``6 f^5 - 15 f^4 + 10 f^3`` is C2-continuous, so the texture has no
    creases along lattice lines. Octave ``o`` samples lattice ``tables[o]`` at
    ``(s freqs[o], t freqs[o])`` (lattice cells), wrapped to the tile.

    Parameters
    ----------
    s, t : (N,) float64
        Surface coordinates, metres.
    tables : (O, TILE + 1, TILE + 1) float64
        Lattice values per octave, the last row and column repeating the first (wrapped);
        TILE a power of two.
    freqs : (O,) float64
        Lattice cells per metre of each octave.
    amps : (O,) float64
        Amplitude of each octave.

    Returns
    -------
    (N,) float64: sum over octaves of ``amps[o]`` x the interpolated lattice value.
    """
    cdef Py_ssize_t n = s.shape[0], n_o = freqs.shape[0]
    cdef Py_ssize_t side = tables.shape[1], tile = side - 1
    if t.shape[0] != n or amps.shape[0] != n_o or tables.shape[0] < n_o:
        raise ValueError("s and t, and freqs, amps and tables, must have matching lengths")
    if tables.shape[2] != side or tile < 1 or (tile & (tile - 1)) != 0:
        raise ValueError("tables must be (O, TILE + 1, TILE + 1) with TILE a power of two")
    out_arr = np.empty(n, dtype=np.float64)
    cdef double[::1] out = out_arr
    cdef Py_ssize_t mask = tile - 1
    cdef const double* tb
    cdef Py_ssize_t i, o, ix, iy
    cdef double x, y, fx0, fy0, fx, fy, sx, sy, a, b, t00, t10, t01, t11
    if n == 0 or n_o == 0:
        out_arr[:] = 0.0
        return out_arr
    cdef double* res = &out[0]
    cdef const double* sp = &s[0]
    cdef const double* tp = &t[0]
    cdef double freq, amp
    with nogil:
        for i in range(n):
            res[i] = 0.0
        # octave by octave: one lattice table at a time stays in cache; each point still
        # sums its octaves in order from 0.0, as the numba kernel did, so the bits agree
        for o in range(n_o):
            freq = freqs[o]
            amp = amps[o]
            tb = &tables[o, 0, 0]
            for i in range(n):
                x = sp[i] * freq
                y = tp[i] * freq
                fx0 = floor(x)
                fy0 = floor(y)
                # int() then a mask, as numba: two's complement wraps negative cells
                ix = (<Py_ssize_t>fx0) & mask
                iy = (<Py_ssize_t>fy0) & mask
                fx = x - fx0
                fy = y - fy0
                sx = fx * fx * fx * (fx * (fx * 6.0 - 15.0) + 10.0)
                sy = fy * fy * fy * (fy * (fy * 6.0 - 15.0) + 10.0)
                t00 = tb[ix * side + iy]
                t10 = tb[(ix + 1) * side + iy]
                t01 = tb[ix * side + iy + 1]
                t11 = tb[(ix + 1) * side + iy + 1]
                a = t00 + sx * (t10 - t00)
                b = t01 + sx * (t11 - t01)
                res[i] += amp * (a + sy * (b - a))
    return out_arr
