"""slitcli: obstacle detection with a stereo camera and a red laser slit, and a modified DWA.

Coordinate conventions (stated once, used everywhere)
-----------------------------------------------------
Camera frame
    x right, y down, z along the optical axis (OpenCV). Metres.
Sensor frame
    x forward, y left, z up; the floor is z = 0 and the origin lies on the floor
    directly below the left camera's optical centre. Ranges, bearings and range
    tables are in this frame. Bearing is positive to the left (counter-clockwise
    seen from above). The robot's rotation centre is ``mount.forward_m`` behind
    the origin.
Pixels
    (u, v): u to the right, v down, pixel centres at integer coordinates;
    (cx, cy) is the principal point.
World frame (simulation only)
    x, y on the floor, z up. A robot pose (x, y, yaw) locates the rotation centre.
"""

__version__ = "0.2.0"
