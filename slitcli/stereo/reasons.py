"""Why a pixel has no disparity: the one set of rejection codes of every stereo matcher.

The codes are stored per pixel in ``DisparityResult.invalid_reason`` (uint8) and in the
``invalid_reason`` of a :class:`slitcli.stereo.pipeline.StereoFrameResult`. A pixel
carries the code of the first step that rejected it (docs/stereo.md lists the steps in
the order they run). The compiled kernels write the integer values; they read them from
this enum (``int(Reason.X)``), so the numbers are defined here only.
"""

from __future__ import annotations

from enum import IntEnum


class Reason(IntEnum):
    """Rejection code of a disparity pixel (0 = valid)."""

    VALID = 0
    NO_CANDIDATE = 1
    TEXTURE = 2
    UNIQUENESS = 3
    LEFT_RIGHT = 4
    SPECKLE = 5
    OPENCV = 6
    SUPPORT = 7
    BOUNDARY = 8

    @property
    def description(self) -> str:
        """One line for users (docs/stereo.md's table)."""
        return _DESCRIPTIONS[self]


_DESCRIPTIONS = {
    Reason.VALID: "valid",
    Reason.NO_CANDIDATE: "no candidate (disparity range or empty window)",
    Reason.TEXTURE: "texture",
    Reason.UNIQUENESS: "uniqueness",
    Reason.LEFT_RIGHT: "left-right",
    Reason.SPECKLE: "speckle",
    Reason.OPENCV: "rejected by the OpenCV matcher",
    Reason.SUPPORT: "local support",
    Reason.BOUNDARY: "depth edge (the farther surface explains the pixel better)",
}

__all__ = ["Reason"]
