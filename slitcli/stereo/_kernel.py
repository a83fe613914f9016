"""Compiled kernels of the stereo pipeline besides the matcher itself
(slitcli.stereo._nssd) and its support and depth-edge tests (slitcli.stereo._boundary):
the prefilter's clip, reprojection and obstacle tests, per-bearing percentiles,
silhouette trimming, the floor check and speckle removal. Compiled ahead of time
(Cython, :mod:`slitcli.stereo._c.kernel` and :mod:`slitcli.stereo._c.speckle`, whose
docstrings list them) and re-exported
here; all release the GIL, so bands of rows can run on plain threads.
"""

from __future__ import annotations

from slitcli.stereo._c.kernel import (
    bin_percentile,
    clip_quantise,
    floor_check,
    reproject,
    trim_silhouettes,
)
from slitcli.stereo._c.speckle import speckle_finish, speckle_small

__all__ = ["bin_percentile", "clip_quantise", "floor_check", "reproject", "speckle_finish",
           "speckle_small", "trim_silhouettes"]
