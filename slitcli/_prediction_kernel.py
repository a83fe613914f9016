"""Compiled kernel of :mod:`slitcli.prediction`: the pairs x instants x discs contact loop.

The loops run in the Cython extension :mod:`slitcli._c.prediction` (built with the
package); this module only makes its inputs the C-ordered float64 arrays the extension
takes.
"""

from __future__ import annotations

import numpy as np

from slitcli._c.prediction import contact_kernel as _contact_kernel


def contact_kernel(robot: np.ndarray, disc: np.ndarray, reach: np.ndarray, t: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray]:
    """First contact time and smallest free distance of each pair against moving discs.

    Parameters
    ----------
    robot : (P, K, 2) float
        Robot centre of each pair at each instant, robot frame, m.
    disc : (K, T, 2) float
        Centre of each disc at each instant, robot frame, m.
    reach : (P, T) float
        Centre distance below which pair p touches disc j, m.
    t : (K,) float
        The instants, s.

    Returns
    -------
    t_contact_s : (P,) float
        First instant t_k (k >= 1) at which a centre distance is below ``reach`` and
        shrinking since t_(k-1); inf where there is none.
    min_gap_m : (P,) float
        Smallest centre distance minus ``reach`` over t_1.. and all discs, m.
    """
    def c(a: np.ndarray) -> np.ndarray:
        return np.ascontiguousarray(a, dtype=np.float64)

    return _contact_kernel(c(robot), c(disc), c(reach), c(t))
