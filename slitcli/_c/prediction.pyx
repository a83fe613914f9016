# cflags: -fno-math-errno -fno-trapping-math
# (sqrt of a sum of squares sets no errno and nothing traps; numba's sqrt is the bare
# instruction as well. Changes no value.)
"""Compiled kernel of the moving-obstacle prediction (slitcli.prediction, docs/dwa.md §1
step 3b): first contact of each (v, w) pair's arc with the predicted discs.

:func:`contact_kernel` replaces the numba kernel of the same loops, operation for
operation, so it gives the same bits. It releases the GIL.
"""

import numpy as np

from libc.math cimport INFINITY, sqrt


def contact_kernel(const double[:, :, ::1] robot, const double[:, :, ::1] disc,
                   const double[:, ::1] reach, const double[::1] t):
    """First contact time and smallest free distance of each pair against moving discs.

    Pairs x instants x discs: the (P, K, T) arrays of a numpy form (about 1e6 elements
    for a person) are never built. Contact at instant k (k >= 1): the centre distance
    minus ``reach`` is negative and the distance shrinks since instant k - 1.

    Parameters
    ----------
    robot : (P, K, 2) float64
        Robot centre of each pair at each instant t_k, robot frame, metres.
    disc : (K, T, 2) float64
        Centre of each disc at each instant, robot frame, metres.
    reach : (P, T) float64
        Centre distance below which pair p touches disc j, metres.
    t : (K,) float64
        The instants, seconds.

    Returns
    -------
    t_contact_s : (P,) float64
        First t_k of a contact, inf where there is none.
    min_gap_m : (P,) float64
        Smallest centre distance minus reach over instants 1..K-1 and all discs, metres
        (inf when K < 2).
    """
    cdef Py_ssize_t n_p = robot.shape[0], n_k = robot.shape[1], n_t = disc.shape[1]
    if (robot.shape[2] < 2 or disc.shape[2] < 2 or disc.shape[0] < n_k
            or reach.shape[0] < n_p or reach.shape[1] < n_t or t.shape[0] < n_k):
        raise ValueError("robot (P, K, 2), disc (K, T, 2), reach (P, T) and t (K,) "
                         "do not match")
    t_c_arr = np.full(n_p, np.inf)
    free_arr = np.full(n_p, np.inf)
    prev_arr = np.empty(n_t)
    cdef double[::1] t_c = t_c_arr
    cdef double[::1] free = free_arr
    cdef double[::1] prev_v = prev_arr
    if n_p == 0 or n_k == 0 or n_t == 0:
        return t_c_arr, free_arr
    cdef double* prev = &prev_v[0]
    # raw pointers: the loops keep the pair's running minimum and contact time in
    # registers instead of storing them at every disc
    cdef const double* rob = &robot[0, 0, 0]
    cdef const double* dis = &disc[0, 0, 0]
    cdef const double* rea = &reach[0, 0]
    cdef Py_ssize_t rs = robot.shape[1] * robot.shape[2], ds = disc.shape[1] * disc.shape[2]
    cdef Py_ssize_t dc = disc.shape[2], rc = robot.shape[2], es = reach.shape[1]
    cdef Py_ssize_t i, j, k
    cdef double dx, dy, gap, f, rx, ry, free_i, tc_i
    cdef const double* dk
    cdef const double* re
    with nogil:
        for i in range(n_p):
            rx = rob[i * rs]
            ry = rob[i * rs + 1]
            for j in range(n_t):
                dx = rx - dis[j * dc]
                dy = ry - dis[j * dc + 1]
                prev[j] = sqrt(dx * dx + dy * dy)
            free_i = INFINITY
            tc_i = INFINITY
            re = rea + i * es
            for k in range(1, n_k):
                rx = rob[i * rs + k * rc]
                ry = rob[i * rs + k * rc + 1]
                dk = dis + k * ds
                for j in range(n_t):
                    dx = rx - dk[j * dc]
                    dy = ry - dk[j * dc + 1]
                    gap = sqrt(dx * dx + dy * dy)
                    f = gap - re[j]
                    if f < free_i:
                        free_i = f
                    if f < 0.0 and gap < prev[j] and tc_i == INFINITY:
                        tc_i = t[k]
                    prev[j] = gap
            free[i] = free_i
            t_c[i] = tc_i
    return t_c_arr, free_arr
