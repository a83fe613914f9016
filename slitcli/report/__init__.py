"""Reports of a detection run: figures, an overlay video, colour previews (DESIGN §12).

:func:`run_report` (``slitcli report``) reads only the files ``slitcli detect`` writes;
:mod:`~slitcli.report.preview` makes the colour previews of disparity and distance;
:mod:`~slitcli.report.overlay` draws the overlay frames and writes the video.
matplotlib is imported only by :mod:`~slitcli.report.plots`, when figures are drawn.
"""

from slitcli.report.build import ReportParams, ReportSummary, run_report
from slitcli.report.preview import colour_preview, disparity_preview, distance_preview

__all__ = ["ReportParams", "ReportSummary", "colour_preview", "disparity_preview",
           "distance_preview", "run_report"]
