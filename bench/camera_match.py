"""Match a camera preset to real robot photographs: noise, stripe strength, background.

Measures the same image statistics on real photographs (with per-column truth rows, the
layout of a real-laser development folder: ``images/``, ``truth/<name>.json`` and its
``truthlib.py``) and on rendered sample scenes through a camera preset, so that the
preset's physical terms (exposure, gain, read noise, crosstalk) can be set from data:

- **noise** per channel and of the red excess ``e = r - (g + b) / 2``: the robust
  standard deviation (1.4826 x MAD) of the residual of each pixel against the mean of
  its 5x5 neighbourhood, over the surface 8-40 rows from the stripe, on pixels whose
  local (smoothed) gradient is in the lower half (flat areas; texture and edges add to
  a residual);
- **background**: the median R, G, B of the surface 8-20 rows from the stripe;
- **stripe**: the median over the stripe columns of R, G, B and red-excess profiles
  down each column, aligned on the truth row (noise-free: a per-column maximum would add
  the noise's own extreme); its rise at the truth row over its median 8-14 rows away per
  channel, the stripe colour (G + B rise) / (2 x R rise), the red excess's FWHM in rows
  (interpolated at both ends) and the SNR: red-excess rise / red-excess noise.

The table shows each picture (a rendered frame with the median range of its stripe) and
the spread (min-max) of the pictures. Not part of `make bench` (seconds a scene).

    .venv/bin/python bench/camera_match.py DEV_FOLDER [--preset robot]
        [--set KEY=VALUE ...] [--scenes sample_data/corridor.yaml ...] [--frames 0 6 11]
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
from pathlib import Path

import cv2
import numpy as np
import yaml

from slitcli.rig import paper_rig
from slitcli.sim.render import render_frame
from slitcli.sim.scene import scene_from_dict

ROOT = Path(__file__).resolve().parent.parent
MAD_SIGMA = 1.4826  # std / MAD of a normal distribution


def _band_rows(rows_v: np.ndarray, lo: int, hi: int, h: int) -> tuple[np.ndarray, np.ndarray]:
    """Pixel (row, col) of the surface lo..hi rows above and below each stripe column."""
    cols = np.flatnonzero(np.isfinite(rows_v))
    off = np.r_[-np.arange(lo, hi + 1), np.arange(lo, hi + 1)]
    rr = np.rint(rows_v[cols])[:, None].astype(int) + off[None, :]
    cc = np.broadcast_to(cols[:, None], rr.shape)
    ok = (rr >= 0) & (rr < h)
    return rr[ok], cc[ok]


def measure(bgr: np.ndarray, rows_v: np.ndarray) -> dict[str, np.ndarray | float]:
    """Noise, background and stripe statistics of one image with stripe rows ``rows_v``
    (W,) (NaN: no stripe in that column)."""
    h = bgr.shape[0]
    rgb = bgr[..., ::-1].astype(np.float64)
    e = rgb[..., 0] - 0.5 * (rgb[..., 1] + rgb[..., 2])
    planes = np.dstack([rgb, e])  # (H, W, 4): R, G, B, red excess
    resid = planes - cv2.blur(planes, (5, 5), borderType=cv2.BORDER_REFLECT)
    smooth = cv2.GaussianBlur(rgb.mean(2), (0, 0), 2.0)
    grad = np.hypot(cv2.Sobel(smooth, cv2.CV_64F, 1, 0), cv2.Sobel(smooth, cv2.CV_64F, 0, 1))
    rr, cc = _band_rows(rows_v, 8, 40, h)
    flat = grad[rr, cc] <= np.median(grad[rr, cc])
    res = resid[rr[flat], cc[flat]]
    noise = MAD_SIGMA * np.median(np.abs(res - np.median(res, 0)), 0)
    rb, cb = _band_rows(rows_v, 8, 20, h)
    background = np.median(rgb[rb, cb], 0)
    cols = np.flatnonzero(np.isfinite(rows_v))
    v0 = np.rint(rows_v[cols]).astype(int)
    dv = np.arange(-14, 15)
    rows = np.clip(v0[:, None] + dv[None, :], 0, h - 1)
    # the columns' median profile, aligned on the truth row: noise-free (a per-column
    # maximum would add the noise's own extreme to the stripe)
    prof = np.median(planes[rows, cols[:, None]], 0)  # (29, 4) R, G, B, e
    rise = prof[14] - np.median(prof[np.abs(dv) >= 8], 0)  # at the truth row
    return {"noise_rgbe": noise, "background_rgb": background, "rise_rgbe": rise,
            "excess": float(rise[3]), "width": _fwhm(prof[:, 3] - prof[np.abs(dv) >= 8, 3]
                                                     .mean()),
            "whiteness": float(0.5 * (rise[1] + rise[2]) / rise[0]),
            "snr": float(rise[3] / noise[3]), "columns": cols.size}


def _fwhm(profile: np.ndarray) -> float:
    """Full width (rows) at half maximum of a background-free profile around its centre,
    interpolated linearly at both ends; NaN if it does not fall to half within it."""
    c = profile.size // 2
    half = 0.5 * profile[c - 1:c + 2].max()
    below = profile < half
    left = np.flatnonzero(below[:c])
    right = np.flatnonzero(below[c + 1:]) + c + 1
    if left.size == 0 or right.size == 0:
        return float("nan")
    i, j = left[-1], right[0]
    x_l = i + (half - profile[i]) / (profile[i + 1] - profile[i])
    x_r = j - (half - profile[j]) / (profile[j - 1] - profile[j])
    return float(x_r - x_l)


def real_images(dev: Path, prefix: str) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """(name, BGR image, truth rows) of the development folder's photographs."""
    spec_ = importlib.util.spec_from_file_location("truthlib", dev / "truthlib.py")
    if spec_ is None or spec_.loader is None or not (dev / "truth").is_dir():
        print(f"camera_match: DEV {dev} is not a real-laser dev folder (needs truthlib.py "
              f"and truth/); give the folder of the real laser photographs", file=sys.stderr)
        sys.exit(2)
    tl = importlib.util.module_from_spec(spec_)
    spec_.loader.exec_module(tl)
    out = []
    for p in sorted((dev / "truth").glob(f"{prefix}*.json")):
        spec = tl.load_spec(p)
        bgr = cv2.imread(str(dev / "images" / spec["image"]))
        if bgr is None:
            print(f"camera_match: cannot read {dev / 'images' / spec['image']} named by "
                  f"{p}; restore the image", file=sys.stderr)
            sys.exit(2)
        t = tl.compute_truth(bgr, spec)
        out.append((p.stem, bgr, np.where(t["state"] == 1, t["row"], np.nan)))
    return out


def rendered_images(scenes: list[Path], frames: list[int], camera: dict
                    ) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """(name, left BGR image, truth rows) of sample scenes rendered through ``camera``."""
    rig = paper_rig()
    out = []
    for path in scenes:
        d = yaml.safe_load(path.read_text())
        d["image"] = {**d.get("image", {}), "camera": camera}
        scene = scene_from_dict(d, path.stem)
        poses = scene.poses(scene.robot.frames)
        for k in frames:
            if k < len(poses):
                f = render_frame(scene, rig, poses[k], frame_index=k)
                r_m = np.nanmedian(np.linalg.norm(f.truth.stripe_sensor_xyz, axis=1))
                out.append((f"{path.stem}#{k} at {r_m:.2f} m", f.left_bgr,
                            f.truth.stripe_v_px))
    return out


def _table(title: str, items: list[tuple[str, np.ndarray, np.ndarray]]) -> None:
    print(f"\n{title}\n| image | cols | noise R G B e (DN) | background R G B | "
          f"stripe rise R G B | stripe excess | FWHM px | (G+B)/2R | SNR |\n"
          f"|---|---|---|---|---|---|---|---|---|")
    ms = []
    for name, bgr, rows_v in items:
        m = measure(bgr, rows_v)
        ms.append(m)
        print(f"| {name} | {m['columns']} | {np.round(m['noise_rgbe'], 1)} | "
              f"{np.round(m['background_rgb'], 0)} | {np.round(m['rise_rgbe'][:3], 1)} | "
              f"{m['excess']:.1f} | {m['width']:.1f} | "
              f"{m['whiteness']:.2f} | {m['snr']:.1f} |")
    nz = np.array([m["noise_rgbe"] for m in ms])
    bg = np.array([m["background_rgb"] for m in ms])
    rs = np.array([m["rise_rgbe"][:3] for m in ms])
    sc = {k: np.array([m[k] for m in ms]) for k in ("excess", "width", "whiteness", "snr")}
    print(f"| spread | | {np.round(nz.min(0), 1)}-{np.round(nz.max(0), 1)} | "
          f"{np.round(bg.min(0), 0)}-{np.round(bg.max(0), 0)} | "
          f"{np.round(rs.min(0), 1)}-{np.round(rs.max(0), 1)} | "
          + " | ".join(f"{v.min():.2f}-{v.max():.2f}" for v in sc.values()) + " |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("dev", type=Path, help="real-laser dev folder (images/, truth/, truthlib.py)")
    ap.add_argument("--prefix", default="neil_", help="truth files of the robot photographs")
    ap.add_argument("--preset", default="robot")
    ap.add_argument("--set", nargs="*", default=[], metavar="KEY=VALUE",
                    help="override preset fields (YAML values), e.g. exposure_scale=0.8")
    ap.add_argument("--scenes", nargs="*", type=Path,
                    default=[ROOT / "sample_data" / f"{n}.yaml"
                             for n in ("corridor", "distractors", "overhang")])
    ap.add_argument("--frames", nargs="*", type=int, default=[0, 6, 11])
    ap.add_argument("--no-real", action="store_true", help="only the rendered scenes")
    a = ap.parse_args()
    camera = {"preset": a.preset, **{k: yaml.safe_load(v) for k, v in
                                     (s.split("=", 1) for s in a.set)}}
    if not a.no_real:
        _table(f"real photographs {a.dev}/{a.prefix}*", real_images(a.dev, a.prefix))
    _table(f"rendered through {camera}", rendered_images(a.scenes, a.frames, camera))


if __name__ == "__main__":
    main()
