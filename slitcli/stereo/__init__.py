"""Stereo: the paper's Eq. 10 matcher, distance image, obstacle mask and ranges per bearing.

Public API (see docs/stereo.md):

- :func:`process_stereo_pair` — one frame: left/right BGR images + rig + params ->
  :class:`StereoFrameResult` (disparity, depth, obstacle mask, nearest range per bearing);
- :class:`StereoGeometry` — everything that depends on the rig only, built once per rig
  and passed to every frame;
- :func:`compute_disparity` — the matcher alone (``nssd`` with ``aggregation`` ``none``
  or ``sgm``, ``bm``, ``sgbm``); :class:`Reason` — why a pixel has no disparity;
- :func:`slitcli.stereo.run.run_stereo` — a whole sequence folder to the
  ``disparity/``, ``distance/`` and ``mask/`` folders (``slitcli stereo``).
"""

from slitcli.stereo.geometry import StereoGeometry
from slitcli.stereo.matcher import DisparityResult, MatcherParams, compute_disparity
from slitcli.stereo.obstacles import ObstacleParams
from slitcli.stereo.pipeline import StereoFrameResult, StereoParams, process_stereo_pair
from slitcli.stereo.reasons import Reason

__all__ = ["DisparityResult", "MatcherParams", "ObstacleParams", "Reason", "StereoFrameResult",
           "StereoGeometry", "StereoParams", "compute_disparity", "process_stereo_pair"]
