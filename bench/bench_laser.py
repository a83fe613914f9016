"""Laser extraction speed per 320x240 frame, against cv2.StereoBM on the same frame.

Both run side by side in this one process on rendered frames (fig4 and distractors):
the laser side is ``detect_laser`` (Eqs. 1-4, sub-pixel fit, triangulation) with the
per-rig geometry computed once, as in a sequence; the reference is OpenCV's block
matcher with 64 disparities and a 9x9 window on the grey left/right pair (OpenCV's
thread pool: all cores; the laser's candidate fits run on the cores that are free,
``SLITCLI_THREADS`` at most, the rest of the laser serially).
The two calls alternate (laser, StereoBM, laser, ...), so that a change of the
machine's load during the run reaches both alike; the ratio is that of the medians.
Goal: ratio <= 0.5. A second pass runs StereoBM on one OpenCV thread and the laser on one
thread (``SLITCLI_THREADS=1``), and times both by the thread's CPU clock: the ratio of the
work done, steady on a busy machine where the wall times of the first pass are not.
"""

from __future__ import annotations

import os
import statistics
import time
from collections.abc import Callable
from pathlib import Path

import cv2

from slitcli.laser import LaserGeometry, LaserParams, detect_laser
from slitcli.rig import paper_rig
from slitcli.sim.render import render_frame
from slitcli.sim.scene import load_scene

SAMPLE = Path(__file__).resolve().parent.parent / "sample_data"
RUNS = 41


def interleaved(fn_a: Callable[[], object], fn_b: Callable[[], object],
                runs: int = RUNS,
                clock: Callable[[], float] = time.perf_counter) -> tuple[dict, dict]:
    """Median and minimum times (s, by ``clock``: wall time by default) of ``fn_a`` and
    ``fn_b`` called alternately ``runs`` times each (after one warm-up call each), in
    ``run.timer``'s format."""
    fn_a()
    fn_b()
    ta, tb = [], []
    for _ in range(runs):
        t0 = clock()
        fn_a()
        t1 = clock()
        fn_b()
        t2 = clock()
        ta.append(t1 - t0)
        tb.append(t2 - t1)
    return tuple({"median_s": statistics.median(t), "min_s": min(t), "runs": runs}
                 for t in (ta, tb))


def bench(timer) -> list[dict]:
    # (run.py's interface; ``timer`` is not used: the two calls are timed alternately)
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
        laser, stereo = interleaved(
            lambda im=left: detect_laser(im, rig, params, geometry=geometry),
            lambda a=grey_l, b=grey_r: bm.compute(a, b))
        ratio = laser["median_s"] / stereo["median_s"]
        rows.append({"name": f"laser detect_laser 320x240 ({name})", **laser, "ratio": ratio,
                     "note": f"{ratio:.2f} x StereoBM (goal <= 0.5), compiled kernels, "
                             "interleaved"})
        rows.append({"name": f"cv2.StereoBM 64 disp 9x9 320x240 ({name})", **stereo,
                     "note": f"{cv2.getNumThreads()} OpenCV threads"})
        # the same on one OpenCV thread, timed by the calling thread's CPU clock (both
        # then run on it alone): the ratio of the work done, which the load of a shared
        # machine leaves alone, beside the wall-time ratio above
        # (the laser on one thread too: a helper thread's CPU time is not this thread's)
        threads = cv2.getNumThreads()
        laser_threads = os.environ.get("SLITCLI_THREADS")
        cv2.setNumThreads(1)
        os.environ["SLITCLI_THREADS"] = "1"
        try:
            laser1, stereo1 = interleaved(
                lambda im=left: detect_laser(im, rig, params, geometry=geometry),
                lambda a=grey_l, b=grey_r: bm.compute(a, b), clock=time.thread_time)
        finally:
            cv2.setNumThreads(threads)
            if laser_threads is None:
                os.environ.pop("SLITCLI_THREADS", None)
            else:
                os.environ["SLITCLI_THREADS"] = laser_threads
        ratio1 = laser1["median_s"] / stereo1["median_s"]
        rows.append({"name": f"cv2.StereoBM 64 disp 9x9 320x240, 1 thread, CPU ({name})",
                     **stereo1, "ratio": ratio1,
                     "note": f"laser CPU {laser1['median_s'] * 1e3:.2f} ms: "
                             f"{ratio1:.2f} x StereoBM's CPU time"})
    return rows
