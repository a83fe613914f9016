"""The laser extractor on renders through the camera model, and renders beside photographs.

Part 1 renders a scene's left view once as linear light (``linear_radiance``), then makes
images from it: ``clean`` (the renderer's look without a camera: Gaussian noise of the
scene's ``noise_sigma_dn``, rounding), the ``webcam`` and ``robot`` presets, and each
camera stage alone. For every variant and seed it runs ``detect_laser`` and scores it
against the renderer's stripe truth (and reports the extractor's own noise estimate,
``sigma``): found = truth columns with an estimate within 2 px,
false = estimates in columns without a stripe or more than 3 px off (share of the
columns the truth judges: all columns), median and RMS |row error| of the found columns.

Part 2 (``--real DIR``, e.g. ../shared/real_laser_dev) measures the same image statistics
on photographs and on the renders: per-channel noise (robust, from horizontal second
differences), the JPEG 8x8 block-edge step, and the stripe's red excess, width and core
colour along the truth. Photographs are only read, never copied.

``--ablate`` instead switches the extractor's rules off one at a time (the list of
bench/laser_real_eval.py, with the paper rig's geometry: ``--search rig``) and scores
each on the sample scenes' first and middle frames, rendered plain and through the
``webcam`` and ``robot`` presets: the rendered half of docs/laser.md's ablation.

Not part of `make bench` (about a minute each).

    .venv/bin/python bench/camera_eval.py [--scene sample_data/fig4.yaml] [--seeds 8]
        [--real ../shared/real_laser_dev] [--preview /tmp/previews]
    .venv/bin/python bench/camera_eval.py --ablate [--seeds 3]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import cv2
import numpy as np

from slitcli.laser import LaserGeometry, LaserParams, detect_laser
from slitcli.rig import paper_rig
from slitcli.sim.camera import CameraModel, apply_camera, camera_preset
from slitcli.sim.render import camera_poses, frame_truth, linear_radiance
from slitcli.sim.scene import load_scene

ROOT = Path(__file__).resolve().parent.parent

# each stage is added to the webcam's sensor noise (about 2 DN in the mid-tones, like the
# clean look's 2 DN), so that a stage is not confused with the absence of noise
_SENSOR = {"gain_dn_per_e": 0.25, "read_noise_e": 4.0, "adc_bits": 10}
STAGES: dict[str, CameraModel | None] = {
    "clean": None,
    "webcam": camera_preset("webcam"),
    "robot": camera_preset("robot"),
    "sensor noise (webcam)": CameraModel(**_SENSOR),
    "sensor noise (robot)": CameraModel(gain_dn_per_e=2.0, read_noise_e=3.0, adc_bits=10),
    "+ bayer RGGB edge-aware": CameraModel(**_SENSOR, bayer="RGGB", demosaic="edge_aware"),
    "+ bayer BGGR bilinear": CameraModel(**_SENSOR, bayer="BGGR", demosaic="bilinear"),
    "+ JPEG 85 4:2:0": CameraModel(**_SENSOR, jpeg_quality=85),
    "+ JPEG 85 4:4:4": CameraModel(**_SENSOR, jpeg_quality=85, jpeg_chroma="444"),
    "+ speckle 0.4 / 1.5 px": CameraModel(**_SENSOR, speckle_contrast=0.4,
                                          speckle_grain_px=1.5),
    "+ exposure 0.5, sRGB": CameraModel(**_SENSOR, exposure_scale=0.5, tone_curve="srgb"),
    "+ full well, blooming 0.3": CameraModel(**_SENSOR, full_well_e=3000.0,
                                             blooming_share=0.3),
    "+ vignetting 0.35": CameraModel(**_SENSOR, vignetting_corner_loss=0.35),
    "+ response [.55 1 .7]": CameraModel(**_SENSOR, channel_response_rgb=(0.55, 1.0, 0.7)),
}


def make_image(scene_rgb: np.ndarray, laser_rgb: np.ndarray, model: CameraModel | None,
               sigma_dn: float, rng: np.random.Generator) -> np.ndarray:
    """8-bit BGR image of the linear light through ``model`` (None: the plain look)."""
    if model is None:
        img = scene_rgb + laser_rgb + rng.normal(0.0, sigma_dn, scene_rgb.shape)
        return np.ascontiguousarray(np.clip(np.rint(img), 0, 255).astype(np.uint8)[..., ::-1])
    return apply_camera(scene_rgb, model, rng, laser_rgb_dn=laser_rgb)


def score(v_px: np.ndarray, truth_v_px: np.ndarray) -> dict[str, float]:
    """found / false shares and row errors of one frame's columns (NaN = none)."""
    has_t, has_e = np.isfinite(truth_v_px), np.isfinite(v_px)
    err = np.abs(v_px - truth_v_px)
    found = has_t & has_e & (err <= 2.0)
    false = (has_e & ~has_t) | (has_t & has_e & (err > 3.0))
    return {"truth_cols": int(has_t.sum()), "found": int(found.sum()),
            "false": int(false.sum()), "cols": len(v_px), "err": err[found].tolist()}


def laser_study(scene_path: Path, seeds: int, preview: Path | None) -> dict[str, dict]:
    rig = paper_rig()
    scene = load_scene(scene_path)
    pose = scene.poses()[0]
    left, _ = camera_poses(rig, pose)
    scene_rgb, laser_rgb = linear_radiance(scene, rig, pose, left)
    truth = frame_truth(scene, rig, pose)
    params = LaserParams()
    geometry = LaserGeometry.from_rig(rig, params)
    out = {}
    for name, model in STAGES.items():
        tot = {"truth_cols": 0, "found": 0, "false": 0, "cols": 0, "err": []}
        sigmas: list[float] = []
        for seed in range(seeds):
            rng = np.random.default_rng([scene.seed, seed])
            img = make_image(scene_rgb, laser_rgb, model, scene.image.noise_sigma_dn, rng)
            if preview is not None and seed == 0:
                preview.mkdir(parents=True, exist_ok=True)
                slug = "".join(c if c.isalnum() else "_" for c in name)
                cv2.imwrite(str(preview / f"{scene.name}_{slug}.png"), img)
            fr = detect_laser(img, rig, params, geometry=geometry)
            sigmas.append(fr.noise_sigma_dn)
            s = score(fr.v_px, truth.stripe_v_px)
            for k in ("truth_cols", "found", "false", "cols"):
                tot[k] += s[k]
            tot["err"] += s["err"]
        err = np.array(tot["err"])
        out[name] = {"found": tot["found"] / tot["truth_cols"], "false": tot["false"] / tot["cols"],
                     "median_err_px": float(np.median(err)) if len(err) else float("nan"),
                     "rms_err_px": float(np.sqrt(np.mean(err ** 2))) if len(err) else
                     float("nan"), "extractor_noise_dn": float(np.median(sigmas))}
    return out


ABLATE_SCENES = ("fig4", "corridor", "distractors", "overhang")
ABLATE_VARIANTS = ("clean", "webcam", "robot")


def ablation_study(seeds: int) -> dict[str, dict[str, dict]]:
    """Found / false / median row error of every ablation of bench/laser_real_eval.py
    per camera variant, pooled over :data:`ABLATE_SCENES` (first and middle frames) and
    ``seeds`` noise seeds: {ablation: {variant: scores}}."""
    from laser_real_eval import ablation_extractors

    rig = paper_rig()
    extractors = ablation_extractors("rig", rig)
    tot = {n: {v: {"truth_cols": 0, "found": 0, "false": 0, "cols": 0, "err": []}
               for v in ABLATE_VARIANTS} for n in extractors}
    for name in ABLATE_SCENES:
        scene = load_scene(ROOT / "sample_data" / f"{name}.yaml")
        poses = scene.poses()
        for pose in (poses[0], poses[len(poses) // 2]):
            left, _ = camera_poses(rig, pose)
            scene_rgb, laser_rgb = linear_radiance(scene, rig, pose, left)
            truth_v = frame_truth(scene, rig, pose).stripe_v_px
            for variant in ABLATE_VARIANTS:
                for seed in range(seeds):
                    rng = np.random.default_rng([scene.seed, seed])
                    img = make_image(scene_rgb, laser_rgb, STAGES[variant],
                                     scene.image.noise_sigma_dn, rng)
                    for n, run in extractors.items():
                        s = score(run(img), truth_v)
                        t = tot[n][variant]
                        for k in ("truth_cols", "found", "false", "cols"):
                            t[k] += s[k]
                        t["err"] += s["err"]
    return {n: {v: {"found": t["found"] / max(t["truth_cols"], 1),
                    "false": t["false"] / max(t["cols"], 1),
                    "median_err_px": float(np.median(t["err"])) if t["err"] else
                    float("nan")} for v, t in per.items()} for n, per in tot.items()}


def print_ablation(res: dict[str, dict[str, dict]]) -> None:
    """One line per ablation: found % / false % / median px per variant."""
    print(f"{'rule switched off':<50}" + "".join(f"{v:>24}" for v in ABLATE_VARIANTS))
    for n, per in res.items():
        print(f"{n:<50}" + "".join(
            f"{100 * r['found']:>10.1f}{100 * r['false']:>7.2f}{r['median_err_px']:>7.3f}"
            for r in per.values()))


# ------------------------------------------------------------------ image statistics
def noise_per_channel(bgr: np.ndarray) -> np.ndarray:
    """Robust noise sigma per channel (B, G, R), DN: MAD of the horizontal second
    difference ``x[i] - (x[i-1] + x[i+1]) / 2`` (variance 1.5 sigma^2 for white noise)."""
    x = bgr.astype(float)
    d = x[:, 1:-1] - 0.5 * (x[:, :-2] + x[:, 2:])
    d = d.reshape(-1, 3)
    mad = np.median(np.abs(d - np.median(d, axis=0)), axis=0)
    return 1.4826 * mad / np.sqrt(1.5)


def block_step(bgr: np.ndarray) -> float:
    """Mean |horizontal step| across JPEG 8x8 block edges over that inside blocks (1: no
    blocks)."""
    y = cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY).astype(float)
    g = np.abs(np.diff(y, axis=1))
    at_edge = (np.arange(g.shape[1]) % 8) == 7
    return float(g[:, at_edge].mean() / g[:, ~at_edge].mean())


def stripe_stats(bgr: np.ndarray, rows: np.ndarray) -> dict[str, float]:
    """Along the truth rows: the red excess peak r - (g + b)/2 over the local background,
    its FWHM in rows and the core's (R, G, B), medians over the columns."""
    x = bgr.astype(float)
    excess = x[..., 2] - 0.5 * (x[..., 0] + x[..., 1])
    h = bgr.shape[0]
    u = np.nonzero(np.isfinite(rows))[0]
    v = np.rint(rows[u]).astype(int)
    keep = (v >= 10) & (v <= h - 11)
    u, v = u[keep], v[keep]
    win = excess[v[:, None] + np.arange(-10, 11)[None, :], u[:, None]]  # (n, 21)
    bg = np.median(np.hstack([win[:, :4], win[:, -4:]]), axis=1)
    prof = win - bg[:, None]
    pk = prof[:, 7:14].max(axis=1)
    ok = pk > 0
    if not np.any(ok):
        return {"excess_dn": float("nan"), "fwhm_px": float("nan"), "core_rgb": [np.nan] * 3}
    width = (prof[ok] >= pk[ok, None] / 2).sum(axis=1)
    core = x[v[ok], u[ok], ::-1]
    return {"excess_dn": float(np.median(pk[ok])), "fwhm_px": float(np.median(width)),
            "core_rgb": np.median(core, axis=0).round(0).tolist()}


def real_stats(real_dir: Path) -> dict[str, dict]:
    sys.path.insert(0, str(real_dir))
    from truthlib import compute_truth, load_spec  # the dev set's own loader

    out = {}
    for spec_path in sorted((real_dir / "truth").glob("*.json")):
        spec = load_spec(str(spec_path))
        bgr = cv2.imread(str(real_dir / "images" / spec["image"]))
        t = compute_truth(bgr, spec)
        rows = np.where(t["state"] == 1, t["row"], np.nan)
        out[spec["image"]] = {"size": f"{bgr.shape[1]}x{bgr.shape[0]}",
                              "noise_bgr": noise_per_channel(bgr).round(2).tolist(),
                              "block_step": round(block_step(bgr), 2),
                              **stripe_stats(bgr, rows)}
    return out


def render_stats(scene_path: Path) -> dict[str, dict]:
    rig = paper_rig()
    scene = load_scene(scene_path)
    pose = scene.poses()[0]
    left, _ = camera_poses(rig, pose)
    scene_rgb, laser_rgb = linear_radiance(scene, rig, pose, left)
    truth = frame_truth(scene, rig, pose)
    out = {}
    for name in ("clean", "webcam", "robot"):
        img = make_image(scene_rgb, laser_rgb, STAGES[name], scene.image.noise_sigma_dn,
                         np.random.default_rng(0))
        out[f"{scene.name} {name}"] = {"noise_bgr": noise_per_channel(img).round(2).tolist(),
                                       "block_step": round(block_step(img), 2),
                                       **stripe_stats(img, truth.stripe_v_px)}
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", type=Path, default=ROOT / "sample_data" / "fig4.yaml")
    ap.add_argument("--seeds", type=int, default=8)
    ap.add_argument("--real", type=Path, default=None,
                    help="folder with images/ and truth/ (the real_laser_dev layout)")
    ap.add_argument("--preview", type=Path, default=None,
                    help="write seed 0's image of each variant here (PNG)")
    ap.add_argument("--json", type=Path, default=None, help="also write the results here")
    ap.add_argument("--ablate", action="store_true",
                    help="switch the extractor's rules off one at a time (see above)")
    a = ap.parse_args()
    if a.ablate:
        abl = ablation_study(a.seeds)
        print_ablation(abl)
        if a.json is not None:
            a.json.write_text(json.dumps(abl, indent=1))
        return
    res: dict[str, dict] = {"laser": laser_study(a.scene, a.seeds, a.preview)}
    print(f"{'variant':28s} {'found':>7s} {'false':>7s} {'median':>7s} {'rms':>7s} "
          f"{'sigma':>6s}")
    for name, r in res["laser"].items():
        print(f"{name:28s} {100 * r['found']:6.1f}% {100 * r['false']:6.2f}% "
              f"{r['median_err_px']:7.3f} {r['rms_err_px']:7.3f} "
              f"{r['extractor_noise_dn']:6.2f}")
    stats = render_stats(a.scene)
    if a.real is not None:
        stats.update(real_stats(a.real))
    res["images"] = stats
    print(f"\n{'image':28s} {'noise B,G,R DN':>20s} {'block':>6s} {'excess':>7s} {'fwhm':>5s}"
          "  core RGB")
    for name, r in stats.items():
        nb = ",".join(f"{x:.1f}" for x in r["noise_bgr"])
        print(f"{name:28s} {nb:>20s} {r['block_step']:6.2f} {r['excess_dn']:7.1f} "
              f"{r['fwhm_px']:5.1f}  {r['core_rgb']}")
    if a.json is not None:
        a.json.write_text(json.dumps(res, indent=1))


if __name__ == "__main__":
    main()
