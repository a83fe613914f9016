"""Compiled kernel of :mod:`slitcli.prediction` (numba; imported on first use so that
the planner's module and ``--help`` load no compiler)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def contact_kernel(robot: np.ndarray, disc: np.ndarray, reach: np.ndarray, t: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover - compiled
    # pairs x instants x discs with an early exit at the first contact: the (P, K, T)
    # arrays of the numpy form (about 1e6 elements for a person) are never built
    n_p, n_k = robot.shape[0], robot.shape[1]
    n_t = disc.shape[1]
    t_c = np.full(n_p, np.inf)
    free = np.full(n_p, np.inf)
    prev = np.empty(n_t)
    for i in range(n_p):
        for j in range(n_t):
            dx = robot[i, 0, 0] - disc[0, j, 0]
            dy = robot[i, 0, 1] - disc[0, j, 1]
            prev[j] = math.sqrt(dx * dx + dy * dy)
        for k in range(1, n_k):
            for j in range(n_t):
                dx = robot[i, k, 0] - disc[k, j, 0]
                dy = robot[i, k, 1] - disc[k, j, 1]
                gap = math.sqrt(dx * dx + dy * dy)
                f = gap - reach[i, j]
                if f < free[i]:
                    free[i] = f
                if f < 0.0 and gap < prev[j] and t_c[i] == np.inf:
                    t_c[i] = t[k]
                prev[j] = gap
    return t_c, free
