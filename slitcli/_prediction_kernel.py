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
    """First contact time and smallest free distance of each pair against moving discs:
    :func:`slitcli._c.prediction.contact_kernel` (shapes, frames and units there) on
    C-ordered float64 copies of any float arrays."""
    def c(a: np.ndarray) -> np.ndarray:
        return np.ascontiguousarray(a, dtype=np.float64)

    return _contact_kernel(c(robot), c(disc), c(reach), c(t))
