"""Laser extraction speed per 320x240 frame, against cv2.StereoBM on the same frame.

Both run side by side in this one process on rendered frames (fig4 and distractors):
the laser side is ``detect_laser`` (Eqs. 1-4, sub-pixel fit, triangulation) with the
per-rig geometry computed once, as in a sequence; the reference is OpenCV's block
matcher with 64 disparities and a 9x9 window on the grey left/right pair (OpenCV's
thread pool: all cores; the laser kernels are serial, which a busy machine slows less).
Goal: ratio <= 0.5.
"""

from __future__ import annotations

from pathlib import Path

import cv2

from slitcli.laser import LaserGeometry, LaserParams, detect_laser
from slitcli.rig import paper_rig
from slitcli.sim.render import render_frame
from slitcli.sim.scene import load_scene

SAMPLE = Path(__file__).resolve().parent.parent / "sample_data"


def bench(timer) -> list[dict]:
    rig = paper_rig()
    params = LaserParams()
    geometry = LaserGeometry.from_rig(rig, params)
    bm = cv2.StereoBM_create(numDisparities=64, blockSize=9)
    rows = []
    for name in ("fig4", "distractors"):
        scene = load_scene(SAMPLE / f"{name}.yaml")
        frame = render_frame(scene, rig, scene.poses(1)[0])
        left, right = frame.left_bgr, frame.right_bgr
        grey_l = cv2.cvtColor(left, cv2.COLOR_BGR2GRAY)
        grey_r = cv2.cvtColor(right, cv2.COLOR_BGR2GRAY)
        laser = timer(lambda im=left: detect_laser(im, rig, params, geometry=geometry), runs=41)
        stereo = timer(lambda a=grey_l, b=grey_r: bm.compute(a, b), runs=41)
        ratio = laser["median_s"] / stereo["median_s"]
        rows.append({"name": f"laser detect_laser 320x240 ({name})", **laser, "ratio": ratio,
                     "note": f"{ratio:.2f} x StereoBM (goal <= 0.5), serial numba"})
        rows.append({"name": f"cv2.StereoBM 64 disp 9x9 320x240 ({name})", **stereo,
                     "note": f"{cv2.getNumThreads()} OpenCV threads"})
    return rows
