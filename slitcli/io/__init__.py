"""Input and output.

- :mod:`slitcli.io.frames`: the one frame source (:func:`~slitcli.io.frames.open_frames`)
  over sequence folders (:mod:`slitcli.io.layouts`, :mod:`slitcli.io.sequence`) and ROS
  bags (:mod:`slitcli.io.bags`);
- :mod:`slitcli.io.batch`: resumable, parallel batches over frames;
- :mod:`slitcli.io.progress`: the progress callback convention and :class:`RunSummary`;
- :mod:`slitcli.io.png`: the disparity, distance and mask image encodings;
- :mod:`slitcli.io.atomic`: writes that never leave half a file.
"""
