"""Detection study behind docs/detect.md: issue 6's floors on rendered sequences.

Renders (once, into a cache folder) the sample corridor with several seeds, the
distractors and overhang samples, and random scenes of 2-4 textured or plain boxes and
cylinders at 0.7-2.8 m (half of them before a back wall), runs the per-frame detector
(slitcli.detect.Detector) on each and scores its table against the renderer's truth:

- **detected**: a bin whose true nearest obstacle lies at 0.6-3 m, ranged within
  max(5 cm, 5 %) of it;
- **phantom**: a free bin (nothing within 3 m) whose fused range is nearer than the
  truth minus 0.2 m.

With ``--reseed N`` it adds the three sample scenes again with N new texture and noise
seeds each (seeds the tuning never saw). With ``--overhang N`` it adds N random overhang
scenes: 1-2 slabs 4-40 cm thick whose underside is 0.15-0.6 m up (above the laser
sheet), at 0.8-2.4 m, four in five textured, before a back wall. ``--coverage`` prints,
for each missed bin, the share of its 1-degree wedge in which the true obstacle lies
within tolerance of the bin's true range (20 sub-wedges): a share of 0.05-0.2 is an
object edge that reaches 1-4 tenths of a degree (a pixel or less) into the bin.

With ``--plain N`` it also renders N scenes of 1-3 textureless boxes and cylinders at
0.7-1 m and reports which sensor ranges their bins and the laser's error there.

Not part of `make bench` (a few minutes).

    .venv/bin/python bench/detect_eval.py [--cache out/detect_eval] [--random 24]
        [--overhang 0] [--reseed 0] [--plain 0] [--fusion paper] [--camera PRESET]
        [--laser-power DN] [--no-sheet-check] [--no-depth-check] [--details] [--coverage]

Prints one line per sequence and the totals per group (markdown table).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from slitcli.detect import Detector, DetectParams
from slitcli.io.sequence import StereoSequence
from slitcli.rig import paper_rig
from slitcli.sim.scene import scene_from_dict
from slitcli.sim.sequence import render_sequence
from slitcli.sim.truth import true_ranges

ROOT = Path(__file__).resolve().parent.parent
CORRIDOR_SEEDS = (21, 22, 23, 24)
# --reseed: the same sample scenes with new texture and noise seeds, never used in tuning
RESEED_FIRST = {"corridor": 25, "distractors": 41, "overhang": 51}


def _textured(rng: np.random.Generator) -> dict:
    return {"colour_rgb": [float(c) for c in rng.uniform(0.35, 0.8, 3).round(2)],
            "texture": "noise", "scale_m": 0.02,
            "contrast": round(float(rng.uniform(0.4, 0.8)), 2)}


def _plain(rng: np.random.Generator) -> dict:
    return {"colour_rgb": [float(c) for c in rng.uniform(0.4, 0.8, 3).round(2)],
            "texture": "plain"}


def _back_wall(distance_m: float) -> dict:
    return {"type": "wall", "from_xy_m": [distance_m, -4], "to_xy_m": [distance_m, 4],
            "height_m": 2.0, "surface": {"colour_rgb": [0.7, 0.68, 0.62], "texture": "noise",
                                         "scale_m": 0.04, "contrast": 0.5}}


def _scene(name: str, seed: int, objs: list[dict]) -> dict:
    """A scene of ``objs`` on the textured floor, 3 frames driving ahead at 0.1 m/s."""
    return {"slitcli_scene": 1, "name": name, "seed": int(seed),
            "floor": {"colour_rgb": [0.55, 0.5, 0.45], "texture": "noise", "scale_m": 0.03,
                      "contrast": 0.5},
            "objects": objs,
            "robot": {"start": [0, 0, 0], "motion": "straight", "speed_mps": 0.1,
                      "frames": 3, "frame_rate_hz": 5.0}}


def random_scene(seed: int) -> dict:
    """2-4 boxes or cylinders at 0.7-2.8 m (a fifth of those nearer than 1 m plain),
    a back wall at 3.5-6 m in half of the scenes; 3 frames at 0.1 m/s."""
    rng = np.random.default_rng(seed)
    objs = []
    for _ in range(rng.integers(2, 5)):
        x = rng.uniform(0.7, 2.8)
        y = rng.uniform(-0.45, 0.45) * x
        surface = _textured(rng)
        if rng.random() < 0.2 and x < 1.0:
            surface = _plain(rng)
        if rng.random() < 0.5:
            objs.append({"type": "box", "centre_xy_m": [float(x), float(y)],
                         "size_m": [float(rng.uniform(0.15, 0.4)),
                                    float(rng.uniform(0.15, 0.5)),
                                    float(rng.uniform(0.2, 0.9))],
                         "yaw_deg": float(rng.uniform(-40, 40)), "surface": surface})
        else:
            objs.append({"type": "cylinder", "centre_xy_m": [float(x), float(y)],
                         "radius_m": float(rng.uniform(0.04, 0.2)),
                         "height_m": float(rng.uniform(0.2, 1.0)), "surface": surface})
    if rng.random() < 0.5:
        d = float(rng.uniform(3.5, 6))
        objs.append(_back_wall(d))
    return _scene(f"random-{seed}", seed, objs)


def overhang_scene(seed: int) -> dict:
    """1-2 slabs (boxes lifted above the laser sheet) at 0.8-2.4 m before a back wall."""
    rng = np.random.default_rng(500 + seed)
    objs = []
    for _ in range(rng.integers(1, 3)):
        x = rng.uniform(0.8, 2.4)
        y = rng.uniform(-0.4, 0.4) * x
        thickness = float(rng.choice([0.04, 0.08, 0.2, 0.4]))
        z_min = float(rng.uniform(0.15, 0.6))
        surface = _textured(rng) if rng.random() < 0.8 else _plain(rng)
        objs.append({"type": "box", "centre_xy_m": [float(x), float(y)],
                     "size_m": [float(rng.uniform(0.3, 0.6)), float(rng.uniform(0.3, 0.8)),
                                thickness],
                     "z_min_m": z_min, "yaw_deg": float(rng.uniform(-30, 30)),
                     "surface": surface})
    d = float(rng.uniform(3.2, 5))
    objs.append(_back_wall(d))
    return _scene(f"overhang-{seed}", seed, objs)


def plain_near_scene(seed: int) -> dict:
    """1-3 plain (textureless) boxes or cylinders at 0.7-1 m before a textured wall."""
    rng = np.random.default_rng(900 + seed)
    objs = []
    for _ in range(rng.integers(1, 4)):
        x = float(rng.uniform(0.7, 1.0))
        y = float(rng.uniform(-0.5, 0.5)) * x
        surface = {"colour_rgb": [float(c) for c in rng.uniform(0.35, 0.8, 3).round(2)],
                   "texture": "plain"}
        if rng.random() < 0.5:
            objs.append({"type": "box", "centre_xy_m": [x, y],
                         "size_m": [float(rng.uniform(0.1, 0.3)), float(rng.uniform(0.15, 0.4)),
                                    float(rng.uniform(0.2, 0.7))],
                         "yaw_deg": float(rng.uniform(-40, 40)), "surface": surface})
        else:
            objs.append({"type": "cylinder", "centre_xy_m": [x, y],
                         "radius_m": float(rng.uniform(0.04, 0.15)),
                         "height_m": float(rng.uniform(0.2, 0.8)), "surface": surface})
    objs.append(_back_wall(float(rng.uniform(3.2, 5))))
    return _scene(f"plain-{seed}", seed, objs)


def plain_near_report(cache: Path, n: int, fusion: str) -> None:
    """Which sensor ranges the bins of near textureless obstacles (truth 0.6-0.98 m),
    and the laser's relative error there."""
    rig = paper_rig()
    rows = []
    for s in range(n):
        d = plain_near_scene(s)
        out = cache / d["name"]
        if not (out / "gt" / "ranges.csv").exists():
            render_sequence(scene_from_dict(d, d["name"]), rig, out, overwrite=True)
        j = detect_table(out, fusion).merge(pd.read_csv(out / "gt" / "ranges.csv"),
                                            on=["frame", "bearing_deg"])
        rows.append(j[(j.range_m >= 0.6) & (j.range_m < 0.98)])
    j = pd.concat(rows)
    rel = ((j.fused_range_m - j.range_m).abs() / j.range_m)[j.fused_source == "laser"]
    print(f"\nplain obstacles at 0.6-0.98 m ({n} scenes, {fusion} fusion): {len(j)} bins; "
          f"source {j.fused_source.value_counts().to_dict()}; laser bins: relative error "
          f"median {rel.median():.2%}, 95th percentile {rel.quantile(0.95):.2%}, "
          f"within 1 % {(rel <= 0.01).mean():.1%}")


def wedge_coverage(d: dict, name: str, seq_dir: Path, wrong: pd.DataFrame) -> np.ndarray:
    """Per missed bin, the share of its wedge where the truth is within tolerance of
    the bin's true range (20 sub-wedges; 1 = the obstacle fills the bin)."""
    scene = scene_from_dict(d, name)
    poses = scene.poses(scene.robot.frames)
    forward_m = StereoSequence(seq_dir).rig().mount.forward_m
    out = []
    for frame, b, r in zip(wrong.frame, wrong.bearing_deg, wrong.range_m,
                               strict=True):
        edges = np.linspace(b - 0.5, b + 0.5, 21)
        sub = true_ranges(scene, poses[frame], edges[:-1], edges[1:], forward_m=forward_m)
        out.append(float(np.mean(np.abs(sub - r) <= max(0.05, 0.05 * r))))
    return np.array(out)


def sequences(n_random: int, n_overhang: int = 0,
              n_reseed: int = 0) -> list[tuple[str, str, dict]]:
    """(group, name, scene dict) of every evaluation sequence."""
    out = []
    corridor = yaml.safe_load((ROOT / "sample_data" / "corridor.yaml").read_text())
    for s in CORRIDOR_SEEDS:
        out.append(("corridor", f"corridor-{s}", {**corridor, "seed": s}))
    for name in ("distractors", "overhang"):
        out.append((name, name, yaml.safe_load((ROOT / "sample_data" / f"{name}.yaml")
                                               .read_text())))
    for name, first in RESEED_FIRST.items():
        d = yaml.safe_load((ROOT / "sample_data" / f"{name}.yaml").read_text())
        for s in range(first, first + n_reseed):
            out.append((f"{name}, new textures", f"{name}-{s}", {**d, "seed": s}))
    for s in range(n_random):
        d = random_scene(s)
        wall = any(o["type"] == "wall" for o in d["objects"])
        out.append(("random, back wall" if wall else "random, open", d["name"], d))
    for s in range(n_overhang):
        d = overhang_scene(s)
        out.append(("random overhangs", d["name"], d))
    return out


def detect_table(seq_dir: Path, fusion: str, sheet_check: bool = True,
                 depth_check: bool = True) -> pd.DataFrame:
    """The detector's range table of a rendered sequence (what ranges.csv holds)."""
    seq = StereoSequence(seq_dir)
    rig = seq.rig()
    det = Detector(rig, DetectParams(fusion_mode=fusion, stereo_sheet_check=sheet_check,
                                     laser_depth_check=depth_check))
    rows = []
    for f in seq.frames(rig):
        rows.append(det(f.left_bgr, f.right_bgr).table(f.index, f.time_s))
    return pd.concat(rows, ignore_index=True)


def score(seq_dir: Path, fusion: str, sheet_check: bool = True,
          depth_check: bool = True) -> tuple[pd.DataFrame, pd.DataFrame, int, int]:
    """Wrong obstacle bins, phantom free bins, and the two bin counts of a sequence."""
    table = detect_table(seq_dir, fusion, sheet_check, depth_check)
    truth = pd.read_csv(seq_dir / "gt" / "ranges.csv")
    j = table.merge(truth, on=["frame", "bearing_deg"])
    band = j[(j.range_m >= 0.6) & (j.range_m <= 3.0)]
    ok = (band.fused_range_m - band.range_m).abs() <= np.maximum(0.05, 0.05 * band.range_m)
    free = j[j.range_m.isna() | (j.range_m > 3.0)]
    limit = np.where(free.range_m.isna(), np.inf, free.range_m) - 0.2
    return band[~ok], free[free.fused_range_m < limit], len(band), len(free)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cache", default=str(ROOT / "out" / "detect_eval"),
                    help="folder for the rendered sequences (reused when present)")
    ap.add_argument("--random", type=int, default=24, help="number of random scenes")
    ap.add_argument("--overhang", type=int, default=0, help="number of random overhang scenes")
    ap.add_argument("--reseed", type=int, default=0,
                    help="also score corridor, distractors and overhang with this many "
                         "new texture seeds each")
    ap.add_argument("--plain", type=int, default=0,
                    help="also report which sensor ranges near textureless obstacles, over "
                         "this many scenes")
    ap.add_argument("--fusion", default="paper", choices=("paper", "conservative"))
    ap.add_argument("--camera", default=None,
                    help="render every scene through this camera model (image.camera: a "
                         "preset such as webcam or robot, docs/scene.md); its sequences "
                         "are cached apart")
    ap.add_argument("--laser-power", type=float, default=None,
                    help="render every scene with this laser.power_dn (DN at the reference "
                         "range; default: each scene's own, 900); its sequences are cached "
                         "apart")
    ap.add_argument("--no-sheet-check", action="store_true",
                    help="detect without its stereo sheet check (DetectParams."
                         "stereo_sheet_check False), for comparison")
    ap.add_argument("--no-depth-check", action="store_true",
                    help="detect without the stripe's depth check (DetectParams."
                         "laser_depth_check False), for comparison")
    ap.add_argument("--details", action="store_true", help="print every wrong bin")
    ap.add_argument("--coverage", action="store_true",
                    help="print how much of each missed bin's wedge the true obstacle fills")
    args = ap.parse_args()
    rig = paper_rig()
    totals: dict[str, np.ndarray] = {}
    cols = ["frame", "bearing_deg", "range_m", "laser_range_m", "stereo_range_m",
            "fused_range_m", "fused_source"]
    coverage = []
    for group, name, d in sequences(args.random, args.overhang, args.reseed):
        if args.camera:
            d = {**d, "image": {**d.get("image", {}), "camera": args.camera}}
            name = f"{name}-{args.camera}"
        if args.laser_power is not None:
            d = {**d, "laser": {**d.get("laser", {}), "power_dn": args.laser_power}}
            name = f"{name}-p{args.laser_power:g}"
        out = Path(args.cache) / name
        if not (out / "gt" / "ranges.csv").exists():
            render_sequence(scene_from_dict(d, name), rig, out, overwrite=True)
        wrong, phantom, n_band, n_free = score(out, args.fusion, not args.no_sheet_check,
                                               not args.no_depth_check)
        totals.setdefault(group, np.zeros(4, int))
        totals[group] += [len(wrong), n_band, len(phantom), n_free]
        print(f"{name}: missed {len(wrong)}/{n_band}, phantom {len(phantom)}/{n_free}",
              flush=True)
        if args.details and len(wrong):
            print(wrong[cols].to_string(index=False))
        if args.details and len(phantom):
            print(phantom[cols].to_string(index=False))
        if args.coverage and len(wrong):
            cov = wedge_coverage(d, name, out, wrong)
            coverage.append(cov)
            print("  missed bins, wedge coverage: " + ", ".join(
                f"{b:.0f} deg {c:.2f}" for b, c in zip(wrong.bearing_deg, cov, strict=True)))
    print(f"\n| group ({args.fusion} fusion) | detected | phantom free bins |\n|---|---|---|")
    for group, (m, nb, p, nf) in totals.items():
        print(f"| {group} | {nb - m}/{nb} = {(nb - m) / max(nb, 1):.2%} | "
              f"{p}/{nf} = {p / max(nf, 1):.2%} |")
    if coverage:
        c = np.concatenate(coverage)
        print(f"\nmissed bins {c.size}: the obstacle fills < 25 % of the wedge in "
              f"{np.sum(c < 0.25)}, < 50 % in {np.sum(c < 0.5)}, all of it in "
              f"{np.sum(c >= 0.99)}")
    if args.plain:
        plain_near_report(Path(args.cache), args.plain, args.fusion)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
