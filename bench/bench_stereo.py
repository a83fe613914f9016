"""Stereo speed (ratios to OpenCV's StereoBM measured in the same run) and accuracy.

Rows:
- matcher speed at 320x240 / 64 disparities / 9x9 and 640x480 / 128 disparities:
  StereoBM (defaults), the Eq. 10 matcher with its default filters and with all
  filters off, StereoSGBM; ``ratio`` = median time / StereoBM's median time, all
  measured in alternation (21 rounds) so that they share the machine's load; the
  1-minute load average before and after is in the note;
- the same 320x240 comparison while a competing busy loop (a second Python process)
  holds a core, as on a machine shared with another job;
- sgm against StereoSGBM on one core (thread CPU time, interleaved) at both sizes;
- end to end: ``slitcli stereo`` (through click, in process) over a 60-frame sequence
  against a plain read -> StereoBM -> write-PNG loop over the same frames;
- first call: import and first ``compute_disparity`` in a fresh interpreter (the
  kernels are compiled ahead of time: nothing to compile or load from a cache);
- accuracy (no timing): Middlebury motorcycle bad2 / density for each filter setting
  (protocol of issue 5), and the rendered scene of tests/test_stereo_rendered.py.
"""

from __future__ import annotations

import importlib.util
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def interleaved(fns: dict, runs: int = 21) -> dict:
    """Median and minimum wall time of each function, measured in alternation.

    One warm-up call each, then ``runs`` rounds that call every function once, so all
    of them see the same machine load (this 2-core machine is shared); ratios of
    these medians are what the issue's speed limits are checked against.
    """
    for fn in fns.values():
        fn()
    times: dict = {k: [] for k in fns}
    for _ in range(runs):
        for k, fn in fns.items():
            t0 = time.perf_counter()
            fn()
            times[k].append(time.perf_counter() - t0)
    return {k: {"median_s": float(np.median(v)), "min_s": float(np.min(v)), "runs": runs}
            for k, v in times.items()}


def _motorcycle(size: tuple[int, int]):
    from skimage import data

    left, right, gt = data.stereo_motorcycle()
    lg = cv2.resize(cv2.cvtColor(left, cv2.COLOR_RGB2GRAY), size, interpolation=cv2.INTER_AREA)
    rg = cv2.resize(cv2.cvtColor(right, cv2.COLOR_RGB2GRAY), size,
                    interpolation=cv2.INTER_AREA)
    g = cv2.resize(gt, size, interpolation=cv2.INTER_NEAREST) * (size[0] / 741.0)
    bgr = [cv2.resize(cv2.cvtColor(im, cv2.COLOR_RGB2BGR), size, interpolation=cv2.INTER_AREA)
           for im in (left, right)]
    return lg, rg, g, bgr


def _bad2(disp: np.ndarray, gt: np.ndarray) -> tuple[float, float, float]:
    has = np.isfinite(gt)
    valid = has & np.isfinite(disp)
    bad = valid & (np.abs(disp - gt) > 2.0)
    return (bad.sum() / max(valid.sum(), 1), valid.sum() / has.sum(),
            (bad.sum() + (has & ~valid).sum()) / has.sum())


def _load() -> str:
    """1-minute load average and the number of runnable tasks right now."""
    with open("/proc/loadavg", encoding="ascii") as fh:
        fields = fh.read().split()
    return f"load {fields[0]}, {fields[3].split('/')[0]} running"


def _speed_rows(timer, size, num, label: str = "") -> list[dict]:
    from slitcli.stereo.bands import kernel_threads
    from slitcli.stereo.matcher import MatcherParams, compute_disparity
    from slitcli.stereo.sgm import SgmWorkspace

    lg, rg, _, _ = _motorcycle(size)
    tag = f"{size[0]}x{size[1]}/{num}d/9x9{label}"
    bm = cv2.StereoBM_create(numDisparities=num, blockSize=9)
    sgbm = cv2.StereoSGBM_create(0, num, 9, P1=8 * 81, P2=32 * 81,
                                 mode=cv2.STEREO_SGBM_MODE_SGBM)
    nssd = MatcherParams(num_disparities=num)
    sgm = MatcherParams(num_disparities=num, aggregation="sgm")
    sgm_off = MatcherParams(num_disparities=num, aggregation="sgm", sgm_ground="off")
    plain = MatcherParams(num_disparities=num, prefilter="none", texture_min_dn=0.0,
                          uniqueness_ratio=0.0, lr_max_diff_px=-1, support_min_zncc=0.0,
                          boundary_ratio=0.0, speckle_window_px=0, subpixel="none")
    threads = []
    workspace = SgmWorkspace()

    def nssd_default() -> None:
        threads.append(kernel_threads())
        compute_disparity(lg, rg, nssd)

    before = _load()
    # a sequence's caller holds one pool for all its frames (slitcli.stereo.run)
    with ThreadPoolExecutor(max_workers=1) as pool:
        t = interleaved({
            "bm": lambda: bm.compute(lg, rg),
            "nssd default filters": nssd_default,
            "nssd plain WTA": lambda: compute_disparity(lg, rg, plain),
            "nssd sgm": lambda: compute_disparity(lg, rg, sgm),
            "nssd sgm, caller's pool": lambda: compute_disparity(lg, rg, sgm, pool=pool),
            "nssd sgm, sequence": lambda: compute_disparity(lg, rg, sgm, pool=pool,
                                                            workspace=workspace),
            "nssd sgm, ground off": lambda: compute_disparity(lg, rg, sgm_off),
            "sgbm": lambda: sgbm.compute(lg, rg),
        })
    load = f"{before} before, {_load()} after; matcher threads {min(threads)}-{max(threads)}"
    notes = {
        "nssd default filters": "Eq. 10 + prefilter, texture, uniqueness, left-right, "
                                "support (centred, one-sided, cross), depth edges, speckle; "
                                "limit 3x at 320x240",
        "nssd plain WTA": "Eq. 10, no filters",
        "nssd sgm": "Eq. 10 + 4-path semi-global aggregation + the default filters and "
                    "the bracket test, its ground estimated from the pair (no rig: "
                    "sgm_ground auto; none found on this pair); issue 23: <= sgbm at 320x240",
        "nssd sgm, caller's pool": "the same with a helper thread held for the sequence "
                                   "(no pool started and joined per frame)",
        "nssd sgm, sequence": "as `slitcli stereo` and `detect` match a sequence: the "
                              "helper thread and the cost volumes' memory (SgmWorkspace) "
                              "held for all frames",
        "nssd sgm, ground off": "the same without the ground estimate (as with a rig "
                                "whose ground shifts no window row, e.g. the paper rig)",
        "sgbm": "OpenCV StereoSGBM, P1=8w^2, P2=32w^2",
    }
    rows = [{"name": f"stereo bm defaults {tag}", **t["bm"], "ratio": 1.0, "note": load}]
    for name, note in notes.items():
        ratio = t[name]["median_s"] / t["bm"]["median_s"]
        rows.append({"name": f"stereo {name} {tag}", **t[name], "ratio": ratio,
                     "note": f"{ratio:.2f}x bm; {note}"})
    return rows


def _cpu_rows(size, num) -> list[dict]:
    """sgm against StereoSGBM on one core: thread CPU time of each call (the matcher on
    one thread, ``SLITCLI_THREADS=1``; OpenCV's SGBM mode runs on the calling thread),
    medians of 21 interleaved calls. CPU time is what a busy machine leaves comparable:
    other processes lengthen a call's wall time, not the CPU time it takes."""
    import os

    from slitcli.stereo.bands import THREADS_ENV
    from slitcli.stereo.matcher import MatcherParams, compute_disparity
    from slitcli.stereo.sgm import SgmWorkspace

    lg, rg, _, _ = _motorcycle(size)
    tag = f"{size[0]}x{size[1]}/{num}d/9x9"
    sgbm = cv2.StereoSGBM_create(0, num, 9, P1=8 * 81, P2=32 * 81,
                                 mode=cv2.STEREO_SGBM_MODE_SGBM)
    sgm = MatcherParams(num_disparities=num, aggregation="sgm")
    workspace = SgmWorkspace()
    fns = {"sgm": lambda: compute_disparity(lg, rg, sgm),
           "sgm, sequence": lambda: compute_disparity(lg, rg, sgm, workspace=workspace),
           "sgbm": lambda: sgbm.compute(lg, rg)}
    saved = os.environ.get(THREADS_ENV)
    os.environ[THREADS_ENV] = "1"
    try:
        for fn in fns.values():
            fn()
        cpu: dict = {k: [] for k in fns}
        for _ in range(21):
            for k, fn in fns.items():
                t0 = time.thread_time()
                fn()
                cpu[k].append(time.thread_time() - t0)
    finally:
        if saved is None:
            del os.environ[THREADS_ENV]
        else:
            os.environ[THREADS_ENV] = saved
    med = {k: float(np.median(v)) for k, v in cpu.items()}
    rows = []
    for name, what in (("sgm", "a frame on its own"),
                       ("sgm, sequence", "the cost volumes' memory held for a sequence")):
        ratio = float(np.median(np.array(cpu[name]) / np.array(cpu["sgbm"])))
        rows.append({"name": f"stereo {name} one thread, CPU {tag}", "median_s": med[name],
                     "min_s": float(np.min(cpu[name])), "runs": 21, "ratio": ratio,
                     "note": f"{ratio:.2f}x StereoSGBM's thread CPU time "
                             f"({med['sgbm'] * 1e3:.1f} ms; median of the 21 per-round "
                             f"ratios); {what}; issue 23: <= 1 at 320x240"})
    return rows


def _loaded_rows(timer) -> list[dict]:
    """The 320x240 comparison while another process keeps one core busy."""
    busy = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        time.sleep(1.0)
        return _speed_rows(timer, (320, 240), 64, label=", competing busy loop")
    finally:
        busy.terminate()
        busy.wait()


def _e2e_rows(timer) -> list[dict]:
    from click.testing import CliRunner

    from slitcli.cli import cli

    _, _, _, (left, right) = _motorcycle((320, 240))
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        seq = Path(tmp) / "seq"
        (seq / "left").mkdir(parents=True)
        (seq / "right").mkdir()
        rng = np.random.default_rng(0)
        names = []
        for i in range(60):
            name = f"{i:06d}.png"
            noise = rng.integers(-2, 3, left.shape)
            cv2.imwrite(str(seq / "left" / name), np.clip(left + noise, 0, 255).astype(np.uint8))
            cv2.imwrite(str(seq / "right" / name),
                        np.clip(right + noise, 0, 255).astype(np.uint8))
            names.append(name)
        count = [0]

        def plain_loop() -> None:
            out = Path(tmp) / f"bm{count[0]}"
            count[0] += 1
            out.mkdir()
            bm = cv2.StereoBM_create(numDisparities=64, blockSize=9)
            for name in names:
                lg = cv2.cvtColor(cv2.imread(str(seq / "left" / name)), cv2.COLOR_BGR2GRAY)
                rg = cv2.cvtColor(cv2.imread(str(seq / "right" / name)), cv2.COLOR_BGR2GRAY)
                d = bm.compute(lg, rg)
                cv2.imwrite(str(out / name), np.where(d > 0, d * 16, 0).astype(np.uint16))

        def slitcli_stereo() -> None:
            out = Path(tmp) / f"st{count[0]}"
            count[0] += 1
            res = CliRunner().invoke(cli, ["stereo", str(seq), "-o", str(out),
                                           "--num-disparities", "64"])
            if res.exit_code != 0:
                raise RuntimeError(res.output)

        t = interleaved({"plain": plain_loop, "cli": slitcli_stereo})
        t_plain, t_cli = t["plain"], t["cli"]
        ratio = t_cli["median_s"] / t_plain["median_s"]
        rows.append({"name": "stereo e2e plain read-bm-write loop, 60 frames", **t_plain,
                     "ratio": 1.0})
        rows.append({"name": "stereo e2e slitcli stereo, 60 frames", **t_cli, "ratio": ratio,
                     "note": f"{ratio:.2f}x the plain loop (<= 3x); 3 PNGs + ranges table "
                             "per frame, in process through click"})
    return rows


def _first_call_rows() -> list[dict]:
    code = ("import time, numpy as np\n"
            "t = time.perf_counter()\n"
            "from slitcli.stereo.matcher import MatcherParams, compute_disparity\n"
            "a = np.random.default_rng(0).integers(0, 255, (240, 320)).astype(np.uint8)\n"
            "compute_disparity(a, np.roll(a, -5, 1), MatcherParams())\n"
            "print(time.perf_counter() - t)\n")
    t0 = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True,
                         text=True, cwd=ROOT).stdout
    wall = time.perf_counter() - t0
    return [{"name": "stereo first call in a fresh process",
             "note": f"import + first compute_disparity {float(out):.2f} s "
                     f"(process {wall:.2f} s)"}]


def _accuracy_rows() -> list[dict]:
    from slitcli.stereo.matcher import MatcherParams, compute_disparity

    lg, rg, gt, _ = _motorcycle((320, 240))
    base = MatcherParams(num_disparities=64)
    settings = {
        "plain WTA (filters off)": replace(base, prefilter="none", texture_min_dn=0.0,
                                           uniqueness_ratio=0.0, lr_max_diff_px=-1,
                                           support_min_zncc=0.0, boundary_ratio=0.0,
                                           speckle_window_px=0, subpixel="none"),
        "default filters": base,
        "default, prefilter none": replace(base, prefilter="none"),
        "default, prefilter xsobel": replace(base, prefilter="xsobel"),
        "default, prefilter log": replace(base, prefilter="log"),
        "default, speckle off": replace(base, speckle_window_px=0),
        "default, support off": replace(base, support_min_zncc=0.0),
        "default, one-sided support off": replace(base, support_side_min_zncc=0.0),
        "default, cross support off": replace(base, support_cross_min_zncc=0.0),
        "default, depth-edge test off": replace(base, boundary_ratio=0.0),
        "default, left-right off": replace(base, lr_max_diff_px=-1),
        "default, uniqueness off": replace(base, uniqueness_ratio=0.0),
        "sgm (aggregation sgm)": replace(base, aggregation="sgm"),
    }
    rows = []
    for label, p in settings.items():
        b, dens, ball = _bad2(compute_disparity(lg, rg, p).disparity_px, gt)
        rows.append({"name": f"middlebury nssd {label}",
                     "note": f"bad2 valid {b:.4f}, density {dens:.4f}, bad2 all {ball:.4f}"})
    bm = cv2.StereoBM_create(numDisparities=64, blockSize=9).compute(lg, rg) / 16.0
    sgbm = cv2.StereoSGBM_create(0, 64, 9, P1=8 * 81, P2=32 * 81,
                                 mode=cv2.STEREO_SGBM_MODE_SGBM).compute(lg, rg) / 16.0
    for label, d in (("bm defaults", bm), ("sgbm", sgbm)):
        b, dens, ball = _bad2(np.where(d >= 0, d, np.nan), gt)
        rows.append({"name": f"middlebury {label}",
                     "note": f"bad2 valid {b:.4f}, density {dens:.4f}, bad2 all {ball:.4f}"})
    rows.append(_rendered_row())
    return rows


def _rendered_row() -> dict:
    from slitcli.rig import paper_rig
    from slitcli.sim.render import render_frame
    from slitcli.sim.scene import scene_from_dict
    from slitcli.stereo.pipeline import process_stereo_pair

    spec = importlib.util.spec_from_file_location(
        "stereo_rendered_test", ROOT / "tests" / "test_stereo_rendered.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    scene = scene_from_dict(module.SCENE, "stereo-test scene")
    rig = paper_rig()
    fr = render_frame(scene, rig, scene.poses(1)[0], frame_index=0)
    res = process_stereo_pair(fr.left_bgr, fr.right_bgr, rig)
    t = fr.truth
    valid = np.isfinite(res.disparity_px)
    near = t.textured & (t.depth_m <= 3.0) & np.isfinite(t.disparity_px)
    err = np.abs(res.disparity_px - t.disparity_px)
    plain = ~t.textured & np.isfinite(t.disparity_px)
    inner = cv2.erode(plain.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
    return {"name": "rendered test corridor (tests/test_stereo_rendered.py), nssd defaults",
            "note": f"textured <=3 m: valid {valid[near].mean():.3f}, median |err| "
                    f"{np.median(err[near & valid]):.3f} px; textureless invalid "
                    f"{(~valid[plain]).mean():.3f} (1 px inside: {(~valid[inner]).mean():.3f}),"
                    f" guessed (|err|>1 px) {(plain & valid & (err > 1)).sum() / plain.sum():.3f}"}


# ------------------------------------------------------------------ folders of pairs
#: Names tried, in order, for the left image, the right image and the ground truth.
LEFT_NAMES = ("im0.png", "view1.png", "left.png")
RIGHT_NAMES = ("im1.png", "view5.png", "right.png")
GT_NAMES = ("disp0GT.pfm", "disp0.pfm", "disp1.png", "disp.pfm", "disp.png")


def read_pfm(path: Path) -> np.ndarray:
    """A PFM image (grey), rows top to bottom, float32; inf stays inf."""
    with open(path, "rb") as fh:
        kind = fh.readline().strip()
        if kind != b"Pf":
            raise ValueError(f"{path}: not a grey PFM")
        w, h = (int(v) for v in fh.readline().split())
        scale = float(fh.readline())
        data = np.fromfile(fh, dtype="<f4" if scale < 0 else ">f4", count=w * h)
    return np.flipud(data.reshape(h, w)).astype(np.float32)


def read_gt(path: Path, png_scale: float) -> np.ndarray:
    """Ground-truth disparity, px, NaN = unknown. 16-bit PNG: value / 256 (KITTI);
    8-bit PNG: value / ``png_scale`` (Middlebury 2001-2006: 4 for quarter size, 3 for
    third size); PFM: as stored (inf = unknown). 0 is unknown in PNGs."""
    if path.suffix == ".pfm":
        d = read_pfm(path)
    else:
        raw = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        d = raw.astype(np.float32) / (256.0 if raw.dtype == np.uint16 else png_scale)
        d[raw == 0] = np.nan
    d[~np.isfinite(d)] = np.nan
    return d


def find_pairs(folder: Path) -> list[tuple[str, Path, Path, Path]]:
    """(name, left, right, gt) of every pair below ``folder``: subfolders holding one
    of LEFT_NAMES / RIGHT_NAMES / GT_NAMES each (Middlebury, or any pair saved so), and
    KITTI folders (image_2/, image_3/, disp_occ_0/: NAME_10.png)."""
    pairs = []
    for d in sorted(p for p in [folder, *folder.rglob("*")] if p.is_dir()):
        pick = [next((d / n for n in names if (d / n).exists()), None)
                for names in (LEFT_NAMES, RIGHT_NAMES, GT_NAMES)]
        if all(pick):
            pairs.append((str(d.relative_to(folder)) or d.name, *pick))
        if (d / "image_2").is_dir() and (d / "disp_occ_0").is_dir():
            for gt in sorted((d / "disp_occ_0").glob("*_10.png")):
                left, right = d / "image_2" / gt.name, d / "image_3" / gt.name
                if left.exists() and right.exists():
                    pairs.append((f"kitti/{gt.stem}", left, right, gt))
    return pairs


def score(disp: np.ndarray, gt: np.ndarray) -> dict:
    """Counts for bad2: GT pixels, valid GT pixels, bad valid pixels (|err| > 2 px)."""
    has = np.isfinite(gt)
    valid = has & np.isfinite(disp)
    bad = valid & (np.abs(disp - gt) > 2.0)
    return {"gt": int(has.sum()), "valid": int(valid.sum()), "bad": int(bad.sum())}


#: Matchers scored by :func:`score_folder`: MatcherParams keywords, or None for
#: OpenCV's StereoSGBM (5 x 5, P1 = 8 w^2, P2 = 32 w^2, with its own uniqueness (15 %),
#: left-right (1 px) and speckle checks, i.e. tightened as ours are).
FOLDER_METHODS: dict[str, dict | None] = {
    "none": {},
    "sgm": {"aggregation": "sgm"},
    "sgm-nobracket": {"aggregation": "sgm", "sgm_bracket_px": 0},
    "sgbm": None,
}


def run_method(kw: dict | None, left: np.ndarray, right: np.ndarray, num: int) -> np.ndarray:
    """Disparity (px, NaN = invalid) of one method of :data:`FOLDER_METHODS`."""
    from slitcli.stereo.matcher import MatcherParams, compute_disparity

    if kw is None:
        sgbm = cv2.StereoSGBM_create(0, num, 5, P1=8 * 25, P2=32 * 25, uniquenessRatio=15,
                                     disp12MaxDiff=1, speckleWindowSize=100, speckleRange=2,
                                     preFilterCap=15, mode=cv2.STEREO_SGBM_MODE_SGBM)
        d = sgbm.compute(left, right)
        return np.where(d >= 0, d / 16.0, np.nan).astype(np.float32)
    return compute_disparity(left, right, MatcherParams(num_disparities=num,
                                                        **kw)).disparity_px


def score_folder(folder: Path, *, max_width: int = 800, png_scale: float = 4.0,
                 ground: tuple[float, float, float | None] | str | None = None) -> None:
    """Score the local Eq. 10 matcher, SGM over Eq. 10 and StereoSGBM on every pair of
    ``folder`` (:func:`find_pairs`) and print bad2 over all GT pixels, bad2 on valid
    pixels, density and time per pair, then pooled over all pairs (KITTI apart).

    ``sgm`` runs as ``compute_disparity`` does without a rig: its ground from the pair
    (``sgm_ground`` 'auto'). ``ground``: (px per row, horizon row px, band px or None)
    of the pairs' rig at their full size: SGM with its window sheared by that ground is
    scored too (``sgm-ground``; horizon and band scaled with the pair); ``"auto"``:
    SGM without a ground (``sgm-off``) is scored too, and each pair's ground estimate
    (slitcli.stereo.ground.estimate_ground) is printed."""
    pairs = find_pairs(folder)
    if not pairs:
        raise SystemExit(f"{folder}: no pairs found (see find_pairs)")
    methods = dict(FOLDER_METHODS)
    pooled: dict[tuple[str, str], dict] = {}
    for name, lp, rp, gp in pairs:
        left = cv2.imread(str(lp), cv2.IMREAD_GRAYSCALE)
        right = cv2.imread(str(rp), cv2.IMREAD_GRAYSCALE)
        gt = read_gt(gp, png_scale)
        f = min(1.0, max_width / left.shape[1])
        if f < 1.0:
            size = (round(left.shape[1] * f), round(left.shape[0] * f))
            left = cv2.resize(left, size, interpolation=cv2.INTER_AREA)
            right = cv2.resize(right, size, interpolation=cv2.INTER_AREA)
            gt = cv2.resize(gt, size, interpolation=cv2.INTER_NEAREST) * f
        if ground == "auto":
            methods["sgm-off"] = {"aggregation": "sgm", "sgm_ground": "off"}
        elif ground is not None:
            # a gradient in px per row is the same at any scale; rows and bands scale
            methods["sgm-ground"] = {
                "aggregation": "sgm", "sgm_ground_px_per_row": ground[0],
                "sgm_ground_horizon_row_px": ground[1] * f,
                "sgm_ground_band_px": None if ground[2] is None else ground[2] * f}
        num = int(16 * np.ceil((np.nanmax(gt) + 2) / 16))
        num = min(num, (left.shape[1] // 2) // 16 * 16)
        group = "kitti" if name.startswith("kitti/") else "all"
        line = [f"{name:28s} {left.shape[1]}x{left.shape[0]}/{num}d"]
        if ground == "auto":
            line.append(_ground_note(left, right, num))
        for m in methods:
            run_method(methods[m], left, right, num)   # warm-up: compile / load kernels
            t0 = time.perf_counter()
            disp = run_method(methods[m], left, right, num)
            dt = time.perf_counter() - t0
            sc = score(disp, gt)
            acc = pooled.setdefault((group, m), {"gt": 0, "valid": 0, "bad": 0, "s": 0.0})
            for k in ("gt", "valid", "bad"):
                acc[k] += sc[k]
            acc["s"] += dt
            line.append(f"{m}: all {(sc['bad'] + sc['gt'] - sc['valid']) / sc['gt']:.3f} "
                        f"valid {sc['bad'] / max(sc['valid'], 1):.3f} dens "
                        f"{sc['valid'] / sc['gt']:.3f} {dt * 1000:.0f} ms")
        print(" | ".join(line), flush=True)
    for (group, m), acc in pooled.items():
        print(f"pooled {group:5s} {m:5s}: bad2 all "
              f"{(acc['bad'] + acc['gt'] - acc['valid']) / acc['gt']:.3f}, bad2 valid "
              f"{acc['bad'] / max(acc['valid'], 1):.3f}, density {acc['valid'] / acc['gt']:.3f}"
              f", time {acc['s']:.2f} s")


def _ground_note(left: np.ndarray, right: np.ndarray, num: int) -> str:
    """The pair's ground estimate (what ``sgm_ground`` 'auto' shears by), one line."""
    from slitcli.stereo.ground import estimate_ground
    from slitcli.stereo.matcher import MatcherParams

    e = estimate_ground(left, right, MatcherParams(num_disparities=num, aggregation="sgm"))
    if not e.found:
        return (f"ground: none ({e.why}; share {e.share:.2f}, rows {e.row_share:.2f}, "
                f"{e.px_per_row:.3f} px/row)")
    return (f"ground: {e.px_per_row:.3f} px/row, horizon {e.horizon_row_px:.1f}, band "
            f"{e.band_px:.2f} px (share {e.share:.2f}, rows {e.row_share:.2f}, residual "
            f"{e.residual_px:.2f} px)")


def export_motorcycle(folder: Path) -> None:
    """Write scikit-image's Middlebury motorcycle pair as folder/motorcycle/{im0,im1}.png
    + disp0GT.pfm (for :func:`score_folder`; third-party data: keep it out of the repo)."""
    from skimage import data

    left, right, gt = data.stereo_motorcycle()
    out = folder / "motorcycle"
    out.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(out / "im0.png"), cv2.cvtColor(left, cv2.COLOR_RGB2BGR))
    cv2.imwrite(str(out / "im1.png"), cv2.cvtColor(right, cv2.COLOR_RGB2BGR))
    g = np.where(np.isfinite(gt) & (gt > 0), gt, np.inf).astype("<f4")
    with open(out / "disp0GT.pfm", "wb") as fh:
        fh.write(f"Pf\n{g.shape[1]} {g.shape[0]}\n-1.0\n".encode())
        np.flipud(g).tofile(fh)


def main() -> int:
    import argparse

    ap = argparse.ArgumentParser(description="Score stereo matchers on a folder of pairs "
                                 "with ground truth (not part of make bench).")
    ap.add_argument("folder", type=Path, help="folder of pairs (see find_pairs)")
    ap.add_argument("--max-width", type=int, default=800,
                    help="pairs wider than this are scaled down (px; GT scaled too)")
    ap.add_argument("--png-scale", type=float, default=4.0,
                    help="8-bit PNG ground truth: disparity = value / this")
    ap.add_argument("--export-motorcycle", action="store_true",
                    help="first write scikit-image's motorcycle pair into FOLDER")
    ap.add_argument("--ground", nargs="+", metavar="auto | PX_PER_ROW HORIZON_ROW_PX",
                    help="'auto': also score sgm without a ground (sgm-off) and print each "
                    "pair's ground estimate (sgm itself takes its ground from the pair); "
                    "two numbers: also score sgm with its window sheared by this ground "
                    "(the rig's disparity gradient and horizon row at full size; KITTI "
                    "about 0.33 and the principal point's row)")
    ap.add_argument("--ground-band-px", type=float, default=None,
                    help="--ground: disparities within this of the ground's take the "
                    "sheared window (px at full size; default every disparity; KITTI, "
                    "1 deg of pitch: f W / h x 0.0175 = 4.1)")
    args = ap.parse_args()
    if args.export_motorcycle:
        export_motorcycle(args.folder)
    ground: tuple[float, float, float | None] | str | None = None
    if args.ground == ["auto"]:
        ground = "auto"
    elif args.ground is not None:
        try:
            if len(args.ground) != 2:
                raise ValueError
            ground = (float(args.ground[0]), float(args.ground[1]), args.ground_band_px)
        except ValueError:
            ap.error("--ground takes 'auto' or two numbers: PX_PER_ROW HORIZON_ROW_PX")
    score_folder(args.folder, max_width=args.max_width, png_scale=args.png_scale,
                 ground=ground)
    return 0


def bench(timer) -> list[dict]:
    rows = _speed_rows(timer, (320, 240), 64)
    rows += _cpu_rows((320, 240), 64)
    rows += _loaded_rows(timer)
    rows += _speed_rows(timer, (640, 480), 128)
    rows += _cpu_rows((640, 480), 128)
    rows += _e2e_rows(timer)
    rows += _first_call_rows()
    rows += _accuracy_rows()
    return rows


if __name__ == "__main__":
    raise SystemExit(main())
