"""Calibration of the rig (DESIGN §9): stereo from chessboards, laser plane, camera mount,
and import/export of ROS, OpenCV and Kalibr calibration files.

Modules: :mod:`.board` (views and chessboard corners), :mod:`.rectify` (raw calibration
to the rectified rig, image rectification), :mod:`.stereo`, :mod:`.laser_plane`,
:mod:`.mount`, :mod:`.formats`. The file formats are documented in docs/calibration.md.
"""
