"""Renderer speed: one stereo frame (both cameras and the truth) at 320x240; and the
closed loop's vision sensing renders (the two images alone at 2 x 2 rays a pixel,
``slitcli.sim.vision``), with the textures' tables drawn per frame and kept for the run
(``TextureTables``)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from slitcli.rig import paper_rig
from slitcli.sim.render import frame_truth, render_frame, render_pair
from slitcli.sim.scene import load_scene
from slitcli.sim.texture import TextureTables
from slitcli.sim.vision import VISION_SUPERSAMPLE

SAMPLE = Path(__file__).resolve().parent.parent / "sample_data"


def bench(timer) -> list[dict]:
    rig = paper_rig()
    rows = []
    for name in ("fig4", "corridor"):
        scene = load_scene(SAMPLE / f"{name}.yaml")
        pose = scene.poses()[0]
        full = timer(lambda s=scene, p=pose: render_frame(s, rig, p), runs=21)
        truth = timer(lambda s=scene, p=pose: frame_truth(s, rig, p), runs=21)
        rows.append({"name": f"render stereo frame 320x240 ({name}, supersample "
                             f"{scene.image.supersample})", **full,
                     "note": f"{1 / full['median_s']:.2f} frames/s"})
        rows.append({"name": f"ground truth only ({name})", **truth,
                     "ratio": truth["median_s"] / full["median_s"],
                     "note": f"{100 * truth['median_s'] / full['median_s']:.0f} % of a frame"})
        fast = replace(scene, image=replace(scene.image, supersample=VISION_SUPERSAMPLE))
        kept = TextureTables()
        drawn = timer(lambda s=fast, p=pose: render_pair(s, rig, p), runs=21)
        held = timer(lambda s=fast, p=pose, k=kept: render_pair(s, rig, p, textures=k), runs=21)
        rows.append({"name": f"vision step images ({name}, supersample {VISION_SUPERSAMPLE})",
                     **drawn, "note": "render_pair, textures drawn every frame"})
        rows.append({"name": f"vision step images, textures kept ({name})", **held,
                     "ratio": held["median_s"] / drawn["median_s"],
                     "note": "render_pair with the run's TextureTables (simulate-dwa "
                             "--sensing vision)"})
    return rows
