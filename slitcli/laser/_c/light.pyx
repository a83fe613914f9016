"""The own-light test of every candidate, compiled (:func:`slitcli.laser.judge.
own_light_candidates` calls :func:`own_light_table`; the test itself is ``light.pxd``'s
:func:`own_light`)."""

import numpy as np

from libc.math cimport isfinite, isnan

from slitcli.laser._c.fields cimport F_GNOISE, F_POS, F_SAT, F_WIDTH, N_FIELDS


def own_light_table(const double[:, :, ::1] cand, const float[:, ::1] y,
                    const float[:, ::1] y_avg, clipped, mask, Py_ssize_t row0,
                    double sigma_y, double shape_error, double z, need, ok):
    """:func:`own_light` of every candidate into ``ok`` (W, K) bool.

    Parameters
    ----------
    cand : ndarray, shape (W, K, N_FIELDS), float64
        The candidate table (:mod:`slitcli.laser.profile`'s fields; rows from the image's
        top).
    y, y_avg : ndarray, shape (W, H'), float32
        The laser evidence and its average along the stripe, rows from ``row0``, DN.
    clipped, mask : ndarray, shape (W, H'), bool
        Clipped red, searched pixels.
    row0 : int
        Image row of the evidence's first row.
    sigma_y : float
        Noise of ``y``, DN; a candidate whose ``F_GNOISE`` is it was fitted on ``y``.
    shape_error : float
        The profile's model error (share of the profile).
    z : float
        Shortfall allowed, in standard errors of the own peak.
    need : ndarray, shape (W, K), bool
        Candidates to judge; the others (and clipped cores, fits of the column's own
        evidence, NaN rows) get True.
    ok : ndarray, shape (W, K), bool
        Output.
    """
    cdef const unsigned char[:, ::1] ci = np.ascontiguousarray(clipped).view(np.uint8)
    cdef const unsigned char[:, ::1] mi = np.ascontiguousarray(mask).view(np.uint8)
    cdef const unsigned char[:, ::1] nd = np.ascontiguousarray(need).view(np.uint8)
    cdef unsigned char[:, ::1] res = ok.view(np.uint8)
    cdef Py_ssize_t n_cols = cand.shape[0], k = cand.shape[1], n = y.shape[1], u, q
    cdef const double* c
    cdef double pos, wid
    if cand.shape[2] != N_FIELDS or res.shape[0] != n_cols or res.shape[1] != k \
            or nd.shape[0] != n_cols or nd.shape[1] != k:
        raise ValueError("own_light_table: cand must be (W, K, N_FIELDS), need and ok (W, K)")
    if y_avg.shape[0] < n_cols or y.shape[0] < n_cols or ci.shape[0] < n_cols \
            or mi.shape[0] < n_cols or y_avg.shape[1] != n or ci.shape[1] != n \
            or mi.shape[1] != n:
        raise ValueError("own_light_table: y, y_avg, clipped and mask must be (W, H')")
    with nogil:
        for u in range(n_cols):
            for q in range(k):
                c = &cand[u, q, 0]
                res[u, q] = True
                pos = c[F_POS] - row0
                if nd[u, q] and c[F_SAT] == 0 and c[F_GNOISE] != sigma_y and isfinite(pos):
                    wid = 1.0 if isnan(c[F_WIDTH]) else c[F_WIDTH]
                    res[u, q] = own_light(&y[u, 0], &y_avg[u, 0], &ci[u, 0], &mi[u, 0], n,
                                          pos, wid, sigma_y, shape_error, z)
