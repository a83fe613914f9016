"""Renderer speed: one stereo frame (both cameras and the truth) at 320x240."""

from __future__ import annotations

from pathlib import Path

from slitcli.rig import paper_rig
from slitcli.sim.render import frame_truth, render_frame
from slitcli.sim.scene import load_scene

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
    return rows
