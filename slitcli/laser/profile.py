"""Step 2 of the stripe model: the profile across one column, fitted.

A stripe crossing a column is a Gaussian of the laser evidence (:mod:`.evidence`) on a
straight background, ``y(v) = c + b (v - v_s) + A exp(-(v - v0)^2 / (2 s^2))`` (the line:
what the opening leaves of the surface's texture and shading), with noise ``sigma`` per
row and a model error proportional to the profile (speckle, demosaicing and compression
make real profiles only roughly Gaussian): the shape test allows a row variance
``sigma^2 + (shape_error A p(v))^2``. A hump that fails it (a flat or skewed top) is
centred by its upper half (``flat_top``). Clipped rows carry no shape and are left
out; a clipped core is fitted on its flanks. Rows are pixel centres at integers.

The kernels (the Gauss-Newton fit ``fit_gaussian``, ``flat_top``, ``plateau_centre``,
``gaussian_rows``) are compiled C, inlined where candidates are fitted:
``slitcli/laser/_c/profile.pxd``. This module keeps the constants and the fields of the
candidate table, which that file mirrors (a test checks that the two agree).
"""

from __future__ import annotations

MAX_ITER = 6
CONVERGED_PX = 0.005
MIN_SIGMA_PX = 0.3  # a pixel's own extent gives any profile sqrt(1/12) = 0.29 px
MIN_ROWS = 6
N_PAR = 5  # offset, peak, centre, width, background slope

#: fields of one fit (last axis of the candidate table)
(F_POS, F_AMP, F_WIDTH, F_Z, F_SE_POS, F_CHI2, F_SAT, F_NOISE, F_TR, F_TG, F_TB, F_KR, F_KG,
 F_KB, F_NCORE, F_FLAT, F_GNOISE) = range(17)
N_FIELDS = 17
