"""Score the laser stripe extractor on a folder of real photographs with per-column truth.

Usage::

    .venv/bin/python bench/laser_real_eval.py FOLDER [--method laser|paper|all]
        [--search full|rig] [--json OUT.json]

``FOLDER`` holds ``images/`` and ``truth/<name>.json`` and a ``truthlib.py`` with
``load_spec`` and ``compute_truth`` (per column: state 0 no stripe, 1 stripe with its row,
2 don't care), as the development set ``../shared/real_laser_dev/`` does. Photographs
are third-party data: they never enter the project; this script only reads them.

Measures, per image and pooled over the folder:

* found: share of stripe columns (state 1) with an estimate within 2 px of the truth row;
* false: estimates in no-stripe columns (state 0) plus estimates more than 3 px off in
  stripe columns, over all judged columns (state 0 or 1);
* median |row error| (px) of the found columns;
* columns reported on laser-off images (no segment in the truth).

Beside the extractor, the two baselines the folder's README describes: per column the
argmax of the blurred red excess ``r - (g + b) / 2`` kept above 0.8 times the mean column
maximum ("argmax"), and per column the brightest 1-20 px run of red excess above a
threshold, centred by its centre of gravity ("run-cog").

The photographs come without a rig: the extractor searches every row (``--search full``,
the default here) with the paper rig's parameters otherwise.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import sys
import time
from pathlib import Path

import cv2
import numpy as np

FOUND_PX = 2.0
FALSE_PX = 3.0


def _truthlib(folder: Path):
    path = folder / "truthlib.py"
    if not path.is_file():
        sys.exit(f"laser_real_eval: {path} is missing; give a folder with truthlib.py, "
                 "images/ and truth/")
    spec = importlib.util.spec_from_file_location("truthlib", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def baseline_argmax(bgr: np.ndarray) -> np.ndarray:
    """Per column the argmax of the blurred red excess, kept above 0.8 x the mean column
    maximum (the README's first baseline)."""
    f = bgr.astype(np.float32)
    e = f[..., 2] - 0.5 * (f[..., 0] + f[..., 1])
    e = cv2.GaussianBlur(e, (0, 0), 1.5)
    arg = np.argmax(e, axis=0)
    peak = e[arg, np.arange(e.shape[1])]
    keep = peak > 0.8 * float(np.mean(peak))
    return np.where(keep, arg.astype(float), np.nan)


def baseline_run_cog(bgr: np.ndarray, thr_dn: float = 30.0, max_run: int = 20) -> np.ndarray:
    """Per column the brightest run (1-``max_run`` px) of red excess above ``thr_dn``,
    its centre of gravity (the README's second baseline)."""
    f = bgr.astype(np.float64)
    e = f[..., 2] - 0.5 * (f[..., 0] + f[..., 1])
    h, w = e.shape
    above = e > thr_dn
    out = np.full(w, np.nan)
    # runs per column: label run starts along the rows (array code, no pixel loop)
    pad = np.zeros((1, w), bool)
    a = np.vstack([pad, above, pad])
    d = np.diff(a.astype(np.int8), axis=0)
    starts_r, starts_c = np.nonzero(d == 1)
    ends_r, ends_c = np.nonzero(d == -1)
    o1 = np.lexsort((starts_r, starts_c))
    o2 = np.lexsort((ends_r, ends_c))
    sr, sc, er = starts_r[o1], starts_c[o1], ends_r[o2]
    length = er - sr
    ok = (length >= 1) & (length <= max_run)
    sr, sc, er = sr[ok], sc[ok], er[ok]
    if sr.size == 0:
        return out
    cs = np.vstack([np.zeros((1, w)), np.cumsum(np.where(above, e, 0.0), axis=0)])
    rows = np.arange(h, dtype=float)[:, None]
    csv = np.vstack([np.zeros((1, w)), np.cumsum(np.where(above, e * rows, 0.0), axis=0)])
    mass = cs[er, sc] - cs[sr, sc]
    mom = csv[er, sc] - csv[sr, sc]
    peak = np.zeros(sr.size)
    # brightest run: the one of largest mass per column
    order = np.lexsort((mass, sc))
    last = np.r_[sc[order][1:] != sc[order][:-1], True]
    best = order[last]
    del peak
    out[sc[best]] = mom[best] / mass[best]
    return out


def score(est: np.ndarray, truth: dict) -> dict:
    """Counts of one image (see the module notes)."""
    st, row = truth["state"], truth["row"]
    has = np.isfinite(est)
    stripe = st == 1
    none = st == 0
    err = np.abs(est - row)
    found = stripe & has & (err <= FOUND_PX)
    false = (none & has).sum() + (stripe & has & (err > FALSE_PX)).sum()
    return {"stripe": int(stripe.sum()), "judged": int((stripe | none).sum()),
            "found": int(found.sum()), "false": int(false),
            "reported": int(has.sum()), "abs_err": err[found].tolist()}


def _summary(c: dict) -> dict:
    e = np.asarray(c["abs_err"])
    return {"found_share": c["found"] / c["stripe"] if c["stripe"] else float("nan"),
            "false_share": c["false"] / c["judged"] if c["judged"] else float("nan"),
            "median_err_px": float(np.median(e)) if e.size else float("nan"),
            "reported": c["reported"], "stripe": c["stripe"], "judged": c["judged"]}


def _pool(cs: list[dict]) -> dict:
    out = {"stripe": 0, "judged": 0, "found": 0, "false": 0, "reported": 0, "abs_err": []}
    for c in cs:
        for k in ("stripe", "judged", "found", "false", "reported"):
            out[k] += c[k]
        out["abs_err"] += c["abs_err"]
    return out


def make_extractors(names: list[str], search: str) -> dict:
    from slitcli.laser import LaserParams, extract_stripe

    ex = {}
    for name in names:
        if name in ("laser", "paper"):
            try:
                params = LaserParams(method="paper" if name == "paper" else "model")
            except TypeError:  # an extractor without the method option
                params = LaserParams()

            def run(bgr, p=params):
                return extract_stripe(bgr, p).v_px
            ex[name] = run
        elif name == "argmax":
            ex[name] = baseline_argmax
        elif name == "run-cog":
            ex[name] = baseline_run_cog
    del search
    return ex


def evaluate(folder: Path, extractors: dict) -> dict:
    tl = _truthlib(folder)
    specs = sorted((folder / "truth").glob("*.json"))
    if not specs:
        sys.exit(f"laser_real_eval: no truth/*.json in {folder}")
    per: dict[str, dict[str, dict]] = {k: {} for k in extractors}
    times: dict[str, list[float]] = {k: [] for k in extractors}
    off_images = []
    for sp in specs:
        spec = tl.load_spec(sp)
        bgr = cv2.imread(str(folder / "images" / spec["image"]), cv2.IMREAD_COLOR)
        if bgr is None:
            sys.exit(f"laser_real_eval: cannot read {folder / 'images' / spec['image']}")
        truth = tl.compute_truth(bgr, spec)
        name = sp.stem
        if not spec.get("segments"):
            off_images.append(name)
        for k, fn in extractors.items():
            t0 = time.perf_counter()
            est = np.asarray(fn(bgr), dtype=float)
            times[k].append(time.perf_counter() - t0)
            per[k][name] = score(est, truth)
    return {"per": per, "off": off_images, "times": times}


def report(res: dict) -> dict:
    per, off = res["per"], res["off"]
    names = list(per)
    images = list(next(iter(per.values())))
    out: dict = {"images": {}, "pooled": {}, "laser_off_columns": {}}
    hdr = f"{'image':<24}" + "".join(f"{n:>26}" for n in names)
    print("found % / false % / median px  (laser-off images: columns reported)")
    print(hdr)
    for im in images:
        cells = []
        for n in names:
            c = per[n][im]
            s = _summary(c)
            out["images"].setdefault(im, {})[n] = s
            if im in off:
                cells.append(f"{c['reported']:>20d} cols")
            else:
                cells.append(f"{100 * s['found_share']:6.1f} {100 * s['false_share']:6.2f} "
                             f"{s['median_err_px']:6.3f}".rjust(26))
        print(f"{im:<24}" + "".join(cells))
    for n in names:
        pooled = _summary(_pool([per[n][im] for im in images if im not in off]))
        out["pooled"][n] = pooled
        out["laser_off_columns"][n] = {im: per[n][im]["reported"] for im in off}
    print(f"{'pooled':<24}" + "".join(
        f"{100 * out['pooled'][n]['found_share']:6.1f} "
        f"{100 * out['pooled'][n]['false_share']:6.2f} "
        f"{out['pooled'][n]['median_err_px']:6.3f}".rjust(26) for n in names))
    print(f"{'max off-image cols':<24}" + "".join(
        f"{max(out['laser_off_columns'][n].values(), default=0):>26d}" for n in names))
    print(f"{'median time s':<24}" + "".join(
        f"{np.median(res['times'][n]):>26.4f}" for n in names))
    return out


#: rules switched off one at a time (``--ablate``): name -> LaserParams overrides
#: (``max_width_share`` None: 8 px at any image height)
ABLATIONS = {
    "default": {},
    "texture ratio fixed at 5 (min_texture_ratio 5)": {"min_texture_ratio": 5.0},
    "texture ratio as measured (min_texture_ratio 0)": {"min_texture_ratio": 0.0},
    "no one-sheet rule (min_stripe_share 0)": {"min_stripe_share": 0.0},
    "no segment length (min_segment_share 0)": {"min_segment_share": 0.0},
    "no shape test / flat tops (max_chi2 1e9)": {"max_chi2": 1e9},
    "laser-colour plane test on (colour_error 0.2)": {"colour_error": 0.2},
    "no hue test (max_hue_deg 90)": {"max_hue_deg": 90.0},
    "no frame width test (width_spread inf)": {"width_spread": float("inf")},
    "one choice, no re-choice (choice_rounds 1)": {"choice_rounds": 1},
    "no own-light test (own_z inf)": {"own_z": float("inf")},
    "no laser-share test (laser_share_z 0)": {"laser_share_z": 0.0},
    "overlapping fits both kept (one_crossing false)": {"one_crossing": False},
    "no surface test (surface_step inf)": {"surface_step": float("inf")},
    "fixed width limit 8 px (max_width_share 8/H)": {"max_width_share": None},
    "rows on the evidence alone (luma_rows false)": {"luma_rows": False},
    "no luma test under 4:2:0 (luma_min_z 0)": {"luma_min_z": 0.0},
    "widths on the evidence alone (luma_widths false)": {"luma_widths": False},
    "paper method": {"method": "paper"},
}


def ablation_extractors(search: str = "full", rig=None) -> dict:
    """One extractor per entry of ``ABLATIONS``: ``extract_stripe`` over the whole
    image, or with ``rig`` ``detect_laser`` with that rig's geometry (``search`` 'rig':
    its laser band and sheet test)."""
    from slitcli.laser import LaserGeometry, LaserParams, detect_laser, extract_stripe

    ex = {}
    for name, over in ABLATIONS.items():
        def run(bgr, over=over):
            kw = dict(over)
            if "max_width_share" in kw:
                kw["max_width_share"] = 8.0 / bgr.shape[0]
            p = LaserParams(search=search, **kw)
            if rig is None:
                return extract_stripe(bgr, p).v_px
            return detect_laser(bgr, rig, p, geometry=LaserGeometry.from_rig(rig, p)).v_px
        ex[name] = run
    return ex


def ablation_report(res: dict) -> None:
    """One line per ablation: pooled found, false, median, and laser-off columns."""
    print(f"{'rule switched off':<46}{'found %':>9}{'false %':>9}{'median px':>11}"
          f"{'off cols':>10}")
    imgs = list(next(iter(res["per"].values())))
    for n, per in res["per"].items():
        p = _summary(_pool([per[i] for i in imgs if i not in res["off"]]))
        off = max([per[i]["reported"] for i in res["off"]], default=0)
        print(f"{n:<46}{100 * p['found_share']:9.1f}{100 * p['false_share']:9.2f}"
              f"{p['median_err_px']:11.3f}{off:10d}")


#: on-minus-off red (DN) at a reported row counts as laser light above this many robust
#: noise sigmas of the difference image (the two views differ by sensor noise alone)
OFF_LIGHT_SIGMAS = 5.0


def audit_false_columns(folder: Path, params=None) -> list[dict]:
    """Every false column of the extractor, grouped in runs of neighbouring columns per
    image: reported rows, truth state (0 no stripe, 1 stripe more than 3 px off), the
    fitted peak, clipped, and, where the folder holds the same view with the laser off
    (``<name>_nolaser``), whether laser light is there: the red of the on-minus-off
    difference within a row of the reported row, less the column's median difference,
    above ``OFF_LIGHT_SIGMAS`` robust noise sigmas of the difference."""
    from slitcli.laser import LaserParams, extract_stripe

    tl = _truthlib(folder)
    params = params if params is not None else LaserParams()
    out = []
    for sp in sorted((folder / "truth").glob("*.json")):
        spec = tl.load_spec(sp)
        if not spec.get("segments"):
            continue
        bgr = cv2.imread(str(folder / "images" / spec["image"]), cv2.IMREAD_COLOR)
        truth = tl.compute_truth(bgr, spec)
        fr = extract_stripe(bgr, params)
        st, row, v = truth["state"], truth["row"], fr.v_px
        has = np.isfinite(v)
        bad = (has & (st == 0)) | (has & (st == 1) & (np.abs(v - row) > FALSE_PX))
        off = None
        off_spec = folder / "truth" / f"{sp.stem}_nolaser.json"
        if off_spec.is_file():
            obgr = cv2.imread(str(folder / "images" / tl.load_spec(off_spec)["image"]))
            if obgr is not None and obgr.shape == bgr.shape:
                off = bgr[..., 2].astype(float) - obgr[..., 2].astype(float)
        cols = np.flatnonzero(bad)
        light = np.full(cols.size, np.nan)
        if off is not None and cols.size:
            med = np.median(off, axis=0)
            sig = 1.4826 * float(np.median(np.abs(off - np.median(off))))
            r = np.clip(np.rint(v[cols]).astype(int)[:, None] + np.arange(-1, 2),
                        0, off.shape[0] - 1)
            light = (off[r, cols[:, None]].max(axis=1) - med[cols]) / max(sig, 0.5)
        for run in np.split(np.arange(cols.size), np.flatnonzero(np.diff(cols) > 1) + 1):
            if run.size == 0:
                continue
            u = cols[run]
            out.append({"image": sp.stem, "u0": int(u[0]), "u1": int(u[-1]),
                        "n": int(u.size), "state": int(st[u[0]]),
                        "v": [float(np.nanmin(v[u])), float(np.nanmax(v[u]))],
                        "truth": float(np.nanmedian(row[u])) if (st[u] == 1).any()
                        else None,
                        "peak_dn": float(np.nanmedian(fr.strength_dn[u])),
                        "clipped": int(fr.saturated[u].sum()),
                        "laser_off_sigmas": None if off is None
                        else float(np.nanmin(light[run])),
                        "laser_light": None if off is None
                        else int((light[run] >= OFF_LIGHT_SIGMAS).sum())})
    return out


def audit_report(runs: list[dict]) -> None:
    print(f"{'image':<16}{'columns':>12}{'n':>4}{'st':>4}{'rows':>16}{'truth':>8}"
          f"{'peak DN':>9}{'clip':>5}{'laser-off: lit cols (min sigmas)':>34}")
    for r in runs:
        lit = "-" if r["laser_light"] is None else \
            f"{r['laser_light']} ({r['laser_off_sigmas']:.0f})"
        tr = "-" if r["truth"] is None else f"{r['truth']:.1f}"
        print(f"{r['image']:<16}{r['u0']:>6}-{r['u1']:<5}{r['n']:>4}{r['state']:>4}"
              f"{r['v'][0]:>8.1f}{r['v'][1]:>8.1f}{tr:>8}{r['peak_dn']:>9.1f}"
              f"{r['clipped']:>5}{lit:>34}")
    n = sum(r["n"] for r in runs)
    lit = sum(r["laser_light"] or 0 for r in runs if r["state"] == 0)
    print(f"false columns {n}; of those in no-stripe columns, laser light by the "
          f"laser-off view: {lit}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("folder", type=Path, help="folder with images/, truth/ and truthlib.py")
    ap.add_argument("--method", default="all",
                    choices=["laser", "paper", "all"],
                    help="extractor to score beside the two baselines (default: all)")
    ap.add_argument("--search", default="full", choices=["full"],
                    help="rows searched: every row (no rig is known for photographs)")
    ap.add_argument("--json", type=Path, help="also write the numbers here")
    ap.add_argument("--ablate", action="store_true",
                    help="score the extractor with each rule switched off in turn")
    ap.add_argument("--false-columns", action="store_true",
                    help="list every false column of the extractor, in runs, with what it "
                         "reported and, where a laser-off view exists, the laser light there")
    a = ap.parse_args(argv)
    if not a.folder.is_dir():
        print(f"laser_real_eval: {a.folder} is not a folder; give the folder of "
              "photographs with truth", file=sys.stderr)
        return 2
    if a.false_columns:
        audit_report(audit_false_columns(a.folder))
        return 0
    if a.ablate:
        ablation_report(evaluate(a.folder, ablation_extractors(a.search)))
        return 0
    names = ["laser", "paper"] if a.method == "all" else [a.method]
    ex = make_extractors([*names, "argmax", "run-cog"], a.search)
    out = report(evaluate(a.folder, ex))
    if a.json:
        a.json.write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
