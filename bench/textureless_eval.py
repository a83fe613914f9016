"""Textureless study behind docs/stereo.md: issue 5's "invalid, not guessed" on random scenes.

Renders (once, into a cache folder) random scenes of 1-3 plain (textureless) boxes and
cylinders, 0.1-0.5 m across, at 0.7-3 m in a corridor with textured walls and floor
(laser on, 2-3 DN sensor noise), runs the Eq. 10 matcher with its default filters on
each frame and scores every plain object against the renderer's truth: the share of its
plain pixels (truth ``textured`` false, which also counts the laser stripe as texture)
that are invalid, and the share that carry a disparity more than 1 px wrong. The valid
pixels are split by where their 9 x 9 window finds texture: within 1.5 px of the
object's silhouette, within half a window (4.5 px) of it, within half a window of the
stripe, or elsewhere (shading, a crease between two faces).

Not part of `make bench` (about a minute).

    .venv/bin/python bench/textureless_eval.py [--cache out/textureless_eval] [--scenes 16]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np

from slitcli.rig import paper_rig
from slitcli.sim.render import render_frame
from slitcli.sim.scene import scene_from_dict
from slitcli.stereo.matcher import MatcherParams, compute_disparity

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


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cache", default=str(ROOT / "out" / "textureless_eval"),
                    help="folder for the rendered frames (reused when present)")
    ap.add_argument("--scenes", type=int, default=16, help="number of random scenes")
    args = ap.parse_args()
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
