"""Vision sensing for the closed loop: render the stereo pair, detect and fuse (paper §2).

The full pipeline of the paper in simulation: at every control step the rig's two
cameras are rendered at the robot's pose (:mod:`slitcli.sim.render`), the laser stripe
and the Eq. 10 matcher range the obstacles and Eq. 11 fuses them
(:class:`slitcli.detect.Detector`); the planner sees the fused range per bearing, cut
at the sensing range.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from slitcli.detect import Detector, DetectParams
from slitcli.rig import Rig
from slitcli.sim.render import render_pair
from slitcli.sim.scene import Pose2D, Scene
from slitcli.sim.sensing import RangeScan
from slitcli.sim.texture import TextureTables

# one ray per pixel-quarter is enough for the planner; rendering dominates a step
VISION_SUPERSAMPLE = 2


@dataclass(frozen=True)
class VisionSensor:
    """Rendered stereo + laser detection at each pose, fused and cut at the sensing range."""

    scene: Scene
    rig: Rig
    detector: Detector
    sensing_range_m: float
    #: the scene's texture tables, drawn at the first step and kept for the run
    textures: TextureTables

    def __call__(self, pose: Pose2D, step: int, t_s: float = 0.0) -> RangeScan:
        # moving objects are rendered where they are at t_s; a missed return (free_m 0)
        # never clears the obstacle memory
        left, right = render_pair(self.scene.at_time(t_s), self.rig, pose, frame_index=step,
                                  textures=self.textures)
        det = self.detector(left, right)
        r = det.ranges.fused_range_m
        return RangeScan(det.ranges.bearing_deg, np.where(r <= self.sensing_range_m, r, np.nan),
                         self.rig.mount.forward_m)


def vision_sensor(scene: Scene, rig: Rig, sensing_range_m: float, *,
                  bin_deg: float = 1.0) -> VisionSensor:
    """The ``vision`` sensing mode of ``simulate-dwa``."""
    fast = replace(scene, image=replace(scene.image, supersample=VISION_SUPERSAMPLE))
    # the renderer writes BGR: its channel order is checked until a frame shows the stripe
    det = Detector(rig, DetectParams(bin_deg=bin_deg), colour_check="once")
    return VisionSensor(fast, rig, det, sensing_range_m, TextureTables())
