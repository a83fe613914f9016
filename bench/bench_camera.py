"""Camera model speed: ``apply_camera`` on one 320x240 view, beside rendering that view.

The light (``linear_radiance``) of fig4's left camera is rendered once; each preset is
then applied to it (speckle, sensor, demosaicing, JPEG). The ratio is the camera model's
share of the time a camera's rendering already takes.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from slitcli.rig import paper_rig
from slitcli.sim.camera import apply_camera, camera_preset
from slitcli.sim.render import camera_poses, linear_radiance
from slitcli.sim.scene import load_scene

SAMPLE = Path(__file__).resolve().parent.parent / "sample_data"


def bench(timer) -> list[dict]:
    rig = paper_rig()
    scene = load_scene(SAMPLE / "fig4.yaml")
    pose = scene.poses()[0]
    left, _ = camera_poses(rig, pose)
    light = timer(lambda: linear_radiance(scene, rig, pose, left), runs=5)
    scene_rgb, laser_rgb = linear_radiance(scene, rig, pose, left)
    rng = np.random.default_rng(0)
    rows = [{"name": "linear light of one camera 320x240 (fig4)", **light}]
    for name in ("webcam", "robot"):
        model = camera_preset(name)
        t = timer(lambda m=model: apply_camera(scene_rgb, m, rng, laser_rgb_dn=laser_rgb),
                  runs=21)
        rows.append({"name": f"camera model '{name}' on 320x240", **t,
                     "ratio": t["median_s"] / light["median_s"],
                     "note": f"{100 * t['median_s'] / light['median_s']:.1f} % of the light"})
    return rows
