"""The laser stripe's physical signal and noise through the camera model (docs/laser.md Limits).

Renders a scene's first left view once as linear light, then through a camera preset
(``webcam``, ``robot``) with its noise sources switched off (no shot or read noise, no
speckle, no full well) with and without the laser: the difference is the stripe's own
signal per output channel, after exposure, demosaicing, the colour matrix, the tone curve
and JPEG. The same preset with its noise, less the noiseless image, is the noise: per
channel, of the red excess ``r - (g + b) / 2``, its correlation down and across the
columns (demosaicing and JPEG spread it over the stripe's own width). It prints, over the
truth's stripe columns, the medians of the stripe's signal and of its share across the
surface colour (the part texture cannot mimic), and each camera stage's share of the
loss (the preset with one stage at a time).

Not part of `make bench` (a few seconds a scene).

    .venv/bin/python bench/camera_snr.py SCENE.yaml [--preset robot]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import yaml

from slitcli.rig import paper_rig
from slitcli.sim.camera import PRESETS, CameraModel, apply_camera
from slitcli.sim.render import camera_poses, frame_truth, linear_radiance
from slitcli.sim.scene import scene_from_dict

_QUIET = {"gain_dn_per_e": None, "read_noise_e": 0.0, "full_well_e": None,
          "blooming_share": 0.0, "speckle_contrast": 0.0}


def stripe_signal(scene_rgb: np.ndarray, laser_rgb: np.ndarray, kw: dict,
                  rows: np.ndarray, cols: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Noise-free stripe signal (n, 3) RGB at the truth pixels and the surface there."""
    m = CameraModel(**{**kw, **_QUIET})
    rng = np.random.default_rng(0)
    on = apply_camera(scene_rgb, m, rng, laser_rgb_dn=laser_rgb).astype(float)[..., ::-1]
    off = apply_camera(scene_rgb, m, rng, laser_rgb_dn=0.0 * laser_rgb).astype(float)[..., ::-1]
    return (on - off)[rows, cols], off[rows, cols]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scene", type=Path, help="scene YAML (its image.camera is ignored)")
    ap.add_argument("--preset", default="robot", choices=sorted(PRESETS))
    a = ap.parse_args()
    d = yaml.safe_load(a.scene.read_text())
    d.get("image", {}).pop("camera", None)
    scene = scene_from_dict(d)
    rig = paper_rig()
    pose = scene.poses()[0]
    left, _ = camera_poses(rig, pose)
    scene_rgb, laser_rgb = linear_radiance(scene, rig, pose, left)
    tv = frame_truth(scene, rig, pose).stripe_v_px
    cols = np.flatnonzero(np.isfinite(tv))
    rows = np.rint(tv[cols]).astype(int)
    kw = dict(PRESETS[a.preset])
    quiet = apply_camera(scene_rgb, CameraModel(**{**kw, **_QUIET}), np.random.default_rng(0),
                         laser_rgb_dn=0.0 * laser_rgb).astype(float)
    noise = np.stack([apply_camera(scene_rgb, CameraModel(**{**kw, "speckle_contrast": 0.0}),
                                   np.random.default_rng([1, s]),
                                   laser_rgb_dn=0.0 * laser_rgb).astype(float) - quiet
                      for s in range(3)])[..., ::-1]  # (3, H, W, 3) RGB
    excess = noise[..., 0] - 0.5 * (noise[..., 1] + noise[..., 2])

    def corr(x: np.ndarray, axis: int, lag: int) -> float:
        a_, b_ = np.moveaxis(x, axis, -1)[..., :-lag], np.moveaxis(x, axis, -1)[..., lag:]
        return float(np.corrcoef(a_.ravel(), b_.ravel())[0, 1])

    print(f"{scene.name} through {a.preset}: {cols.size} stripe columns")
    print(f"noise RGB {noise.reshape(-1, 3).std(0).round(2)} DN, red excess "
          f"{excess.std():.2f} DN; red-excess correlation down the columns lag 1 "
          f"{corr(excess, 1, 1):.2f}, lag 2 {corr(excess, 1, 2):.2f}, across lag 1 "
          f"{corr(excess, 2, 1):.2f}")
    stages = {"preset": {}, "no tone curve": {"tone_curve": "linear"},
              "no JPEG": {"jpeg_quality": None}, "JPEG 4:4:4": {"jpeg_chroma": "444"},
              "no Bayer": {"bayer": "none"}, "no crosstalk": {"colour_crosstalk": 0.0},
              "exposure 1": {"exposure_scale": 1.0}}
    print(f"{'variant':14s} {'signal RGB':>22s} {'excess':>7s} {'across k':>8s} "
          f"{'surface RGB':>18s}")
    for name, over in stages.items():
        sig, surf = stripe_signal(scene_rgb, laser_rgb, {**kw, **over}, rows, cols)
        k = (surf + 0.5) / np.linalg.norm(surf + 0.5, axis=1, keepdims=True)
        across = np.linalg.norm(sig - (sig * k).sum(1, keepdims=True) * k, axis=1)
        ex = sig[:, 0] - 0.5 * (sig[:, 1] + sig[:, 2])
        print(f"{name:14s} {np.median(sig, 0).round(1)!s:>22s} {np.median(ex):7.1f} "
              f"{np.median(across):8.1f} {np.median(surf, 0).round(0)!s:>18s}")


if __name__ == "__main__":
    main()
