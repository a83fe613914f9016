"""Whether a laser candidate sits on an edge between two surfaces (colour tests).

A candidate whose flanks, just above and just below it, show two different surface
colours lies on an edge between two surfaces (an object's border, a crease between the
floor and a wall): a step there can pass for a weak stripe, and it never is one.
"""

from __future__ import annotations

import math

from numba import njit

#: a step of this much in red chromaticity r = R / (R + G + B) between the surface just
#: above and just below a candidate counts as much as the colour angle MAX_EDGE_REF
RED_STEP = 0.04
MAX_EDGE_REF = 0.02
#: the red step is judged between surfaces of at most this red share; on a red surface
#: the stripe's own tails and clipped neighbours move the red share of its flanks
MAX_GREY_RED = 0.5


@njit(cache=True, nogil=True, inline="always")
def edge_measure(ur: float, ug: float, ub: float, lr: float, lg: float, lb: float,
                 both: bool) -> float:  # pragma: no cover
    """How clearly the colours just above (u) and just below (l) are two surfaces.

    One minus the cosine between the two colours, or, where larger, the step in red
    chromaticity in units of ``RED_STEP`` squared, times ``MAX_EDGE_REF``: a crease
    between a redder and a greyer surface changes the red share (the stripe's own
    colour) more than it turns the colour (between surfaces of red share up to
    ``MAX_GREY_RED``). ``both``: rows on both sides were seen (not
    at the image's border); otherwise only the angle counts.
    """
    one_cos = 1.0 - (ur * lr + ug * lg + ub * lb) / math.sqrt(
        (ur * ur + ug * ug + ub * ub) * (lr * lr + lg * lg + lb * lb))
    if not both:
        return one_cos
    r_u = ur / (ur + ug + ub)
    r_l = lr / (lr + lg + lb)
    if max(r_u, r_l) > MAX_GREY_RED:
        return one_cos
    step = (r_u - r_l) / RED_STEP
    return max(one_cos, MAX_EDGE_REF * step * step)
