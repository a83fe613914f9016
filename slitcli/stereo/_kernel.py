"""Compiled kernels of the stereo pipeline besides the matcher itself
(slitcli.stereo._nssd) and its support and depth-edge tests (slitcli.stereo._boundary).

- :func:`clip_quantise`: the prefilter's clip and quantisation;
- :func:`reproject`, :func:`bin_percentile`: depth, sensor-frame points, obstacle
  tests and the per-bearing range percentile;
- :func:`trim_silhouettes`: obstacle runs cut back to their last intensity step where
  they end on a plain (unmatched) background;
- :func:`floor_check`: obstacle pixels that the floor explains better than their match;
- :func:`speckle_finish`: speckle removal and the NaN of invalid pixels.

They are compiled ahead of time (Cython, :mod:`slitcli.stereo._c.kernel`) and re-exported
here; all release the GIL, so bands of rows can run on plain threads.
"""

from __future__ import annotations

from slitcli.stereo._c.kernel import (
    bin_percentile,
    clip_quantise,
    floor_check,
    reproject,
    speckle_finish,
    trim_silhouettes,
)

__all__ = ["bin_percentile", "clip_quantise", "floor_check", "reproject", "speckle_finish",
           "trim_silhouettes"]
