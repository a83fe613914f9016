"""Compiled kernel of the renderer's sensor model (slitcli.sim.camera): blooming.

:func:`bloom_kernel` moves the excess charge of full pixels into their neighbours, in
place of the numba kernel it replaces (same operations in the same order, so the same
bits: no fast-math, no contraction). It releases the GIL.
"""

import numpy as np


def bloom_kernel(const double[:, ::1] e, double full_well_e, double share,
                 double column_share):
    """Clip charge at the full well and spill ``share`` of each full pixel's excess.

    Pixels are visited row by row, left to right; each one's excess flows up, down, left
    and right (``column_share / 2`` of the spilled charge up and down each,
    ``(1 - column_share) / 2`` left and right each). Flowing away it fills the next pixel;
    once that is full it passes on ``share`` of the rest, its drain takes the remainder,
    and charge that leaves the image is lost (slitcli.sim.camera.bloom states the model).

    Parameters
    ----------
    e : (H, W) float64, C order
        Collected charge per raw pixel, electrons (not changed).
    full_well_e : float
        Charge a pixel holds, electrons.
    share : float
        Share 0-1 of a full pixel's excess that spills over.
    column_share : float
        Share 0-1 of the spilled charge that flows along the column.

    Returns
    -------
    (H, W) float64, electrons, every value <= ``full_well_e`` (NaN stays NaN).
    """
    cdef Py_ssize_t h = e.shape[0], w = e.shape[1]
    out_arr = np.empty((h, w), dtype=np.float64)
    if h == 0 or w == 0:
        return out_arr
    cdef double[:, ::1] out_v = out_arr
    cdef double* out = &out_v[0, 0]
    cdef const double* src = &e[0, 0]
    cdef double fracs[4]
    cdef Py_ssize_t step[4]
    cdef Py_ssize_t room_px[4]
    fracs[0] = 0.5 * column_share
    fracs[1] = 0.5 * column_share
    fracs[2] = 0.5 * (1.0 - column_share)
    fracs[3] = 0.5 * (1.0 - column_share)
    # up, down, left, right, as pointer steps
    step[0] = -w
    step[1] = w
    step[2] = -1
    step[3] = 1
    cdef Py_ssize_t y, x, k, n
    cdef unsigned char over
    row_over_arr = np.empty(h, dtype=np.uint8)
    cdef unsigned char[::1] row_over = row_over_arr
    cdef double v, excess, q, room
    cdef double* p
    with nogil:
        for y in range(h):
            over = 0
            for x in range(y * w, y * w + w):
                # np.minimum's semantics: a NaN stays NaN
                v = src[x]
                out[x] = full_well_e if v > full_well_e else v
                over |= v > full_well_e
            row_over[y] = over
        for y in range(h):
            # a row with no pixel over the well spills nothing (a NaN pixel spills NaN
            # charge, which the loop below drops: `q > 0` is false)
            if not row_over[y]:
                continue
            for x in range(w):
                excess = src[y * w + x] - full_well_e
                if excess <= 0.0:
                    continue
                # pixels between this one and the border, in each direction
                room_px[0] = y
                room_px[1] = h - 1 - y
                room_px[2] = x
                room_px[3] = w - 1 - x
                for k in range(4):
                    q = share * excess * fracs[k]
                    p = out + y * w + x
                    n = room_px[k]
                    if not q > 0.0:
                        continue
                    while n > 0:
                        p += step[k]
                        n -= 1
                        room = full_well_e - p[0]
                        if room >= q:
                            p[0] += q
                            break
                        # fill it; it passes on `share` of the rest, drains the remainder
                        p[0] = full_well_e
                        q = share * (q - room)
                        if not q > 0.0:
                            break
    return out_arr
