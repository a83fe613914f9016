"""Textureless study (docs/notes/stereo-kernels.md): issue 5's "invalid, not guessed", and SGM.

Renders (once, into a cache folder) random scenes of 1-3 plain (textureless) boxes and
cylinders, 0.1-0.5 m across, at 0.7-3 m in a corridor with textured walls and floor
(laser on, 2-3 DN sensor noise), runs the Eq. 10 matcher with its default filters on
each frame and scores every plain object against the renderer's truth: the share of its
plain pixels (truth ``textured`` false, which also counts the laser stripe as texture)
that are invalid, and the share that carry a disparity more than 1 px wrong. The valid
pixels are split by where their 9 x 9 window finds texture: within 1.5 px of the
object's silhouette, within half a window (4.5 px) of it, within half a window of the
stripe, or elsewhere (shading, a crease between two faces).

``--compare`` scores the matcher settings of :data:`SETTINGS` (the local Eq. 10
matcher and semi-global aggregation, issue 23) side by side on the same frames, by
surface (truth ``object_id``, within 3 m): textured objects and walls (density, median
|error|, share > 1 px), the slanted floor (density, share > 1 px, median signed error,
share of wrong pixels that are too near), plain surfaces (invalid, wrong > 1 px), and
per plain object at 1.2-3 m whether stereo ranges it: a bin counts as detected when
the full pipeline's range lies within max(5 cm, 5 %) of the nearest point of that
object in the bin (from the truth depth).

Not part of `make bench` (about a minute; --compare a few).

    .venv/bin/python bench/textureless_eval.py [--cache out/textureless_eval] [--scenes 16]
    .venv/bin/python bench/textureless_eval.py --compare
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np

from slitcli.rig import paper_rig
from slitcli.sim.render import render_frame
from slitcli.sim.scene import scene_from_dict
from slitcli.stereo.geometry import StereoGeometry
from slitcli.stereo.matcher import MatcherParams, compute_disparity, with_rig_ground
from slitcli.stereo.pipeline import StereoParams, process_stereo_pair

ROOT = Path(__file__).resolve().parent.parent
WALLS = 3  # the corridor's walls come first in the object list


def random_scene(seed: int) -> dict:
    """1-3 plain boxes or cylinders at 0.7-3 m in a 2.2 m wide textured corridor."""
    rng = np.random.default_rng(1000 + seed)
    textured = {"texture": "noise", "scale_m": 0.04, "contrast": 0.5}
    objs: list[dict] = [
        {"type": "wall", "from_xy_m": [0.0, 1.1], "to_xy_m": [6.0, 1.1], "height_m": 1.5,
         "surface": {"colour_rgb": [0.7, 0.66, 0.6], **textured}},
        {"type": "wall", "from_xy_m": [0.0, -1.1], "to_xy_m": [6.0, -1.1], "height_m": 1.5,
         "surface": {"colour_rgb": [0.66, 0.68, 0.7], **textured}},
        {"type": "wall", "from_xy_m": [6.0, -1.1], "to_xy_m": [6.0, 1.1], "height_m": 1.5,
         "surface": {"colour_rgb": [0.7, 0.7, 0.7], **textured}}]
    for _ in range(rng.integers(1, 4)):
        x, y = rng.uniform(0.7, 3.0), rng.uniform(-0.7, 0.7)
        grey = rng.uniform(0.35, 0.85) + rng.uniform(-0.05, 0.05, 3)
        plain = {"colour_rgb": [float(c) for c in np.round(grey, 3)], "texture": "plain"}
        if rng.random() < 0.5:
            objs.append({"type": "cylinder", "centre_xy_m": [float(x), float(y)],
                         "radius_m": float(rng.uniform(0.05, 0.25)),
                         "height_m": float(rng.uniform(0.3, 1.0)), "surface": plain})
        else:
            objs.append({"type": "box", "centre_xy_m": [float(x), float(y)],
                         "size_m": [float(rng.uniform(0.1, 0.4)), float(rng.uniform(0.1, 0.6)),
                                    float(rng.uniform(0.3, 1.0))],
                         "yaw_deg": float(rng.uniform(-40, 40)), "surface": plain})
    return {"slitcli_scene": 1, "name": f"textureless-{seed}", "seed": seed,
            "floor": {"colour_rgb": [0.55, 0.5, 0.45], "texture": "noise", "scale_m": 0.03,
                      "contrast": 0.5},
            "objects": objs, "image": {"noise_sigma_dn": float(rng.uniform(2.0, 3.0))},
            "robot": {"start": [0.0, 0.0, 0.0], "motion": "static", "frames": 1}}


def _frame(cache: Path, seed: int) -> tuple[dict, dict[str, np.ndarray]]:
    """The scene dict and its rendered frame 0 (images and truth), cached as .npz."""
    d = random_scene(seed)
    path = cache / f"{d['name']}.npz"
    if not path.exists():
        scene = scene_from_dict(d, d["name"])
        fr = render_frame(scene, paper_rig(), scene.poses(1)[0], frame_index=0)
        t = fr.truth
        cache.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp.npz")
        np.savez_compressed(tmp, left=fr.left_bgr, right=fr.right_bgr,
                            disparity_px=t.disparity_px, depth_m=t.depth_m, textured=t.textured,
                            object_id=t.object_id)
        tmp.replace(path)
    with np.load(path) as z:
        return d, {k: z[k] for k in z.files}


def score_objects(d: dict, z: dict[str, np.ndarray], params: MatcherParams) -> list[dict]:
    """One row per plain object of at least 50 plain pixels: counts and shares."""
    res = compute_disparity(z["left"], z["right"], params)
    valid = np.isfinite(res.disparity_px)
    wrong = valid & (np.abs(res.disparity_px - z["disparity_px"]) > 1.0)
    rows = []
    for k, obj in enumerate(d["objects"][WALLS:]):
        on = z["object_id"] == WALLS + k + 1
        plain = on & ~z["textured"] & np.isfinite(z["disparity_px"])
        if plain.sum() < 50:
            continue
        # distance (px) inside the silhouette, and to the nearest stripe-lit pixel
        sil = cv2.distanceTransform(on.astype(np.uint8), cv2.DIST_L2, 3)
        stripe = cv2.distanceTransform((~(on & z["textured"])).astype(np.uint8),
                                       cv2.DIST_L2, 3)
        vp = plain & valid
        rows.append({
            "scene": d["name"], "type": obj["type"],
            "depth_m": float(np.median(z["depth_m"][plain])),
            "plain_px": int(plain.sum()),
            "invalid": 1.0 - vp.sum() / plain.sum(),
            "wrong": (plain & wrong).sum() / plain.sum(),
            "valid_at_silhouette": int((vp & (sil <= 1.5)).sum()),
            "valid_half_window": int((vp & (sil > 1.5) & (sil <= 4.5)).sum()),
            "valid_near_stripe": int((vp & (sil > 4.5) & (stripe <= 4.5)).sum()),
            "valid_elsewhere": int((vp & (sil > 4.5) & (stripe > 4.5)).sum()),
        })
    return rows


#: Matcher settings compared by ``--compare`` (name -> MatcherParams keywords).
SETTINGS: dict[str, dict] = {
    "local (none)": {},
    "sgm": {"aggregation": "sgm"},
    "sgm, no bracket": {"aggregation": "sgm", "sgm_bracket_px": 0},
    "sgm, no support": {"aggregation": "sgm", "support_min_zncc": 0.0},
}


def _object_ranges(z: dict[str, np.ndarray], geo: StereoGeometry, obj: int
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Per bin: nearest horizontal range (m) of object ``obj``'s pixels (NaN: none)."""
    on = (z["object_id"] == obj) & np.isfinite(z["depth_m"])
    pts = geo.rays_sensor_xyz[on] * z["depth_m"][on][:, None]
    r = np.hypot(pts[:, 0], pts[:, 1] - 0.0)
    idx = geo.pixel_bin[on]
    out = np.full(len(geo.bins), np.inf)
    ok = idx >= 0
    np.minimum.at(out, idx[ok], r[ok])
    return np.where(np.isfinite(out), out, np.nan), np.bincount(idx[ok], minlength=len(
        geo.bins))


def compare(frames: list[tuple[dict, dict[str, np.ndarray]]]) -> None:
    """Print the surface scores of every setting of :data:`SETTINGS`."""
    rig = paper_rig()
    geo = StereoGeometry.for_rig(rig)
    for name, kw in SETTINGS.items():
        acc: dict[str, float] = dict.fromkeys(
            ("tex", "tex_valid", "tex_bad", "floor", "floor_valid", "floor_bad",
             "floor_near", "plain", "plain_valid", "plain_wrong", "bins", "bins_hit"), 0.0)
        tex_err: list[np.ndarray] = []
        floor_err: list[np.ndarray] = []
        params = StereoParams(matcher=MatcherParams(**kw))
        for d, z in frames:
            res = process_stereo_pair(z["left"], z["right"], rig, params, geometry=geo)
            disp, gt = res.disparity_px, z["disparity_px"]
            near = np.isfinite(gt) & (z["depth_m"] <= 3.0)
            valid = np.isfinite(disp)
            err = disp - gt
            tex = near & z["textured"] & (z["object_id"] > 0)
            floor = near & (z["object_id"] == 0)
            plain = near & ~z["textured"] & (z["object_id"] > 0)
            acc["tex"] += tex.sum()
            acc["tex_valid"] += (tex & valid).sum()
            acc["tex_bad"] += (tex & valid & (np.abs(err) > 1)).sum()
            tex_err.append(np.abs(err[tex & valid]))
            acc["floor"] += floor.sum()
            acc["floor_valid"] += (floor & valid).sum()
            acc["floor_bad"] += (floor & valid & (np.abs(err) > 1)).sum()
            acc["floor_near"] += (floor & valid & (err > 1)).sum()
            floor_err.append(err[floor & valid])
            acc["plain"] += plain.sum()
            acc["plain_valid"] += (plain & valid).sum()
            acc["plain_wrong"] += (plain & valid & (np.abs(err) > 1)).sum()
            for k, obj in enumerate(d["objects"][WALLS:]):
                if obj["surface"]["texture"] != "plain":
                    continue
                r_obj, npx = _object_ranges(z, geo, WALLS + k + 1)
                want = np.isfinite(r_obj) & (r_obj >= 1.2) & (r_obj <= 3.0) & (npx >= 20)
                hit = want & (np.abs(res.range_m - r_obj) <= np.maximum(0.05, 0.05 * r_obj))
                acc["bins"] += want.sum()
                acc["bins_hit"] += hit.sum()
        te = np.concatenate(tex_err)
        fe = np.concatenate(floor_err)
        print(f"{name:22s} textured: density {acc['tex_valid'] / acc['tex']:.3f} median "
              f"|err| {np.median(te):.3f} px, > 1 px {acc['tex_bad'] / acc['tex_valid']:.4f}"
              f" | floor: density {acc['floor_valid'] / acc['floor']:.3f}, > 1 px "
              f"{acc['floor_bad'] / acc['floor_valid']:.4f} (too near "
              f"{acc['floor_near'] / max(acc['floor_bad'], 1):.0%}), median signed "
              f"{np.median(fe):+.3f} px | plain: valid "
              f"{acc['plain_valid'] / acc['plain']:.3f}, wrong > 1 px "
              f"{acc['plain_wrong'] / acc['plain']:.4f} ({int(acc['plain_wrong'])} px) | "
              f"plain objects 1.2-3 m: {int(acc['bins_hit'])} of {int(acc['bins'])} bins")


def slanted_floor(cache: Path, baseline_m: float, seeds: range,
                  contrast: float = 0.25) -> None:
    """Floor-only scenes seen by the paper rig with a wider baseline (a steeper floor
    disparity gradient: ``baseline_m / height`` px per row, 0.135 for the paper rig's
    0.088 m, 0.38 for 0.25 m, KITTI's road about 0.33; ``contrast``: the floor
    texture's, 0.25 by default, lower for a weakly textured road): every setting of
    :data:`SETTINGS` scored on the floor pixels within 3 m (density, share more than
    1 px and 2 px off, share of those too near, median signed error)."""
    from dataclasses import replace

    rig = replace(paper_rig(), baseline_m=baseline_m)
    frames = []
    for seed in seeds:
        tag = "" if contrast == 0.25 else f"-c{contrast:.3f}"
        path = cache / f"slanted-{baseline_m:.3f}{tag}-{seed}.npz"
        if not path.exists():
            d = {"slitcli_scene": 1, "name": f"slanted-{seed}", "seed": seed,
                 "floor": {"colour_rgb": [0.55, 0.5, 0.45], "texture": "noise",
                           "scale_m": 0.03, "contrast": contrast},
                 "objects": [], "image": {"noise_sigma_dn": 2.0},
                 "robot": {"start": [0.0, 0.0, 0.0], "motion": "static", "frames": 1}}
            scene = scene_from_dict(d, d["name"])
            fr = render_frame(scene, rig, scene.poses(1)[0], frame_index=0)
            cache.mkdir(parents=True, exist_ok=True)
            tmp = path.with_suffix(".tmp.npz")
            np.savez_compressed(tmp, left=fr.left_bgr, right=fr.right_bgr,
                                disparity_px=fr.truth.disparity_px,
                                depth_m=fr.truth.depth_m, object_id=fr.truth.object_id)
            tmp.replace(path)
        with np.load(path) as z:
            frames.append({k: z[k] for k in z.files})
    num = int(16 * np.ceil(np.nanmax(frames[0]["disparity_px"][120:]) / 16 + 0.5))
    print(f"baseline {baseline_m} m, floor contrast {contrast}, {len(frames)} frames, "
          f"{num} disparities")
    # the matcher as the stereo pipeline runs it for this rig (SGM's ground shear)
    geo = StereoGeometry.for_rig(rig)
    settings = {**SETTINGS, "sgm, fronto-parallel": {"aggregation": "sgm",
                                                     "sgm_ground_px_per_row": 0.0},
                # the ground from the pair, the rig unused (as for a folder of pairs)
                "sgm, ground from pair": {"aggregation": "sgm", "sgm_ground": "pair"}}
    for name, kw in settings.items():
        n = valid = bad1 = bad2 = near = 0
        errs = []
        for z in frames:
            params = with_rig_ground(MatcherParams(num_disparities=num, **kw), geo)
            disp = compute_disparity(z["left"], z["right"], params).disparity_px
            gt = z["disparity_px"]
            floor = (z["object_id"] == 0) & (z["depth_m"] <= 3.0) & np.isfinite(gt)
            v = floor & np.isfinite(disp)
            e = disp - gt
            n += floor.sum()
            valid += v.sum()
            bad1 += (v & (np.abs(e) > 1)).sum()
            bad2 += (v & (np.abs(e) > 2)).sum()
            near += (v & (e > 1)).sum()
            errs.append(e[v])
        e = np.concatenate(errs)
        print(f"  {name:22s} floor density {valid / n:.3f}, > 1 px {bad1 / valid:.4f} (too "
              f"near {near / max(bad1, 1):.0%}), > 2 px {bad2 / valid:.4f}, bad2 all "
              f"{(bad2 + n - valid) / n:.3f}, median signed {np.median(e):+.3f} px, "
              f"median |err| {np.median(np.abs(e)):.3f} px")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cache", default=str(ROOT / "out" / "textureless_eval"),
                    help="folder for the rendered frames (reused when present)")
    ap.add_argument("--scenes", type=int, default=16, help="number of random scenes")
    ap.add_argument("--compare", action="store_true",
                    help="score the matcher settings of SETTINGS side by side")
    ap.add_argument("--slanted", type=float, default=None, metavar="BASELINE_M",
                    help="score the settings on floor-only scenes with this baseline (m)")
    ap.add_argument("--floor-contrast", type=float, default=0.25,
                    help="--slanted: the floor texture's contrast (0-1)")
    args = ap.parse_args()
    if args.slanted is not None:
        slanted_floor(Path(args.cache), args.slanted, range(args.scenes),
                      args.floor_contrast)
        return 0
    if args.compare:
        compare([_frame(Path(args.cache), seed) for seed in range(args.scenes)])
        return 0
    params = MatcherParams()
    rows = []
    for seed in range(args.scenes):
        d, z = _frame(Path(args.cache), seed)
        rows += score_objects(d, z, params)
    for r in rows:
        print(f"{r['scene']:15s} {r['type']:8s} {r['depth_m']:4.2f} m plain "
              f"{r['plain_px']:6d} px  invalid "
              f"{r['invalid']:7.2%}  wrong {r['wrong']:6.2%}  valid at silhouette "
              f"{r['valid_at_silhouette']:4d}, half window {r['valid_half_window']:4d}, "
              f"near stripe {r['valid_near_stripe']:4d}, elsewhere {r['valid_elsewhere']:4d}")
    plain = np.array([r["plain_px"] for r in rows], float)
    inv = np.array([r["invalid"] for r in rows])
    wr = np.array([r["wrong"] for r in rows])
    big = plain >= 5000
    print(f"\n{len(rows)} plain objects: pooled invalid {np.sum(inv * plain) / plain.sum():.2%}, "
          f"pooled wrong by > 1 px {np.sum(wr * plain) / plain.sum():.2%}; "
          f"per object median invalid {np.median(inv):.2%}, {np.sum(inv >= 0.95)} of {len(rows)} "
          f">= 95 %; objects of >= 5000 plain px: {np.sum(inv[big] >= 0.95)} of {big.sum()} "
          f">= 95 %")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
