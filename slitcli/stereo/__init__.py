"""Stereo: the paper's Eq. 10 matcher, distance image, obstacle mask and ranges per bearing.

Public API (see docs/stereo.md):

- :func:`process_stereo_pair` — one frame: left/right BGR images + rig + params ->
  :class:`StereoFrameResult` (disparity, depth, obstacle mask, nearest range per bearing);
- :func:`compute_disparity` — the matcher alone (``nssd``, ``bm``, ``sgbm``);
- :func:`slitcli.stereo.run.run_stereo` — a whole sequence folder to the
  ``disparity/``, ``distance/`` and ``mask/`` folders of DESIGN §12 (``slitcli stereo``).
"""

from slitcli.stereo.matcher import DisparityResult, MatcherParams, compute_disparity
from slitcli.stereo.obstacles import ObstacleParams
from slitcli.stereo.pipeline import StereoFrameResult, StereoParams, process_stereo_pair

__all__ = ["DisparityResult", "MatcherParams", "ObstacleParams", "StereoFrameResult",
           "StereoParams", "compute_disparity", "process_stereo_pair"]
