"""Per-stage CPU time of ``detect_laser`` on the laser bench's frames (320x240).

The frames of ``bench/bench_laser.py`` (fig4 and distractors, first pose, the paper rig,
geometry computed once). Every stage of the extractor is wrapped by a timer of the
calling thread's CPU clock; the laser runs on one thread (``SLITCLI_THREADS=1``, OpenCV
on one thread), so a stage's time is its own work, steady on a shared machine where wall
times are not. Stages nest (``_judged_candidates`` holds ``column_candidates``, the
judge's tests and the glue between them); the rows are means per frame over ``--runs``
calls, the first line the median of the whole call.

Usage: ``.venv/bin/python bench/profile_laser.py [--runs 200]``
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from collections.abc import Callable
from pathlib import Path

import cv2

from slitcli.laser import (
    LaserGeometry,
    LaserParams,
    candidates,
    choose,
    detect_laser,
    evidence,
    judge,
)
from slitcli.laser import extract as extract_mod
from slitcli.laser import frame as frame_mod
from slitcli.rig import paper_rig
from slitcli.sim.render import render_frame
from slitcli.sim.scene import load_scene

SAMPLE = Path(__file__).resolve().parent.parent / "sample_data"
#: (module, attribute, label): the stages timed, as the extractor looks them up
STAGES = (
    (frame_mod, "extract_stripe", "extract_stripe"),
    (extract_mod, "_evidence", "_evidence (step 1)"),
    (evidence, "channel_sigma", "  channel_sigma"),
    (evidence, "vertical_opening", "  vertical_opening"),
    (evidence, "texture_share", "  texture_share"),
    (evidence, "laser_evidence", "  laser_evidence"),
    (extract_mod.cv2, "filter2D", "  filter2D (y_avg)"),
    (extract_mod.cv2, "transpose", "  cv2.transpose (image, opening)"),
    (candidates, "evidence_live", "  evidence_live"),
    (evidence, "robust_sigma", "  robust_sigma (x2)"),
    (evidence, "spread_sigma", "  spread_sigma (x2)"),
    (extract_mod.luma, "chroma_smoothness", "  chroma_smoothness"),
    (extract_mod, "_judged_candidates", "_judged_candidates (steps 3-4)"),
    (candidates, "column_candidates", "  column_candidates"),
    (judge, "valid_candidates", "  valid_candidates"),
    (judge, "surface_continues", "  surface_continues"),
    (judge, "own_light_candidates", "  own_light_candidates"),
    (judge, "one_crossing", "  one_crossing"),
    (choose, "choose_stripe", "choose_stripe"),
    (candidates, "fill_gaps", "fill_gaps"),
    (frame_mod, "triangulate_columns", "triangulate_columns"),
)


def _timed(fn: Callable, label: str, acc: dict[str, float]) -> Callable:
    """``fn`` adding its CPU time to ``acc[label]``."""
    def wrapper(*args, **kwargs):
        t0 = time.thread_time()
        try:
            return fn(*args, **kwargs)
        finally:
            acc[label] = acc.get(label, 0.0) + time.thread_time() - t0
    return wrapper


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=200)
    runs = parser.parse_args().runs
    cv2.setNumThreads(1)
    os.environ["SLITCLI_THREADS"] = "1"  # (kernel_threads reads it at every call)
    acc: dict[str, float] = {}
    for mod, attr, label in STAGES:
        setattr(mod, attr, _timed(getattr(mod, attr), label, acc))
    rig = paper_rig()
    params = LaserParams()
    geometry = LaserGeometry.from_rig(rig, params)
    for name in ("fig4", "distractors"):
        scene = load_scene(SAMPLE / f"{name}.yaml")
        left = render_frame(scene, rig, scene.poses(1)[0]).left_bgr
        for _ in range(5):  # (warm-up)
            detect_laser(left, rig, params, geometry=geometry)
        acc.clear()
        total = []
        for _ in range(runs):
            t0 = time.thread_time()
            detect_laser(left, rig, params, geometry=geometry)
            total.append(time.thread_time() - t0)
        print(f"{name}: detect_laser median {statistics.median(total) * 1e3:.3f} ms CPU "
              f"({runs} calls, one thread)")
        for _, _, label in STAGES:
            print(f"  {label:34s} {acc.get(label, 0.0) / runs * 1e3:7.3f} ms")


if __name__ == "__main__":
    main()
