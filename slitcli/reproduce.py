"""`make reproduce-figures`: the main job on the bundled sample data.

Stages (each printed with its time; a stage whose outputs exist is skipped, so a second
run is quick and gives the same files):

1. render the sample scenes (``sample_data/*.yaml``) into ``out/sequences/<scene>/``;
2. detect each sequence (laser + Eq. 10 stereo + Eq. 11 fusion) into
   ``out/detect/<scene>/`` (and the overhang scene also with the conservative fusion);
3. simulate the modified DWA on the paper scenario into ``out/dwa/``;
4. draw ``figures/fig4.png``, ``fig7.png``, ``fig8.png``, ``fig9.png``, ``accuracy.png``;
5. write ``docs/reproduction.md``: the paper's claims against what this run measured.

Run as ``python -m slitcli.reproduce [--out OUT] [--figures DIR] [--report FILE]``.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pandas as pd

from slitcli.errors import SlitcliError

ROOT = Path(__file__).resolve().parent.parent
SCENES = {"fig4": 1, "corridor": 12, "distractors": 3, "overhang": 4}
DWA_RANGES_M = (0.6, 1.0, 1.5, 2.0, 2.5, 3.0)


class _Stages:
    """Prints each stage with its time; remembers whether anything was recomputed."""

    def __init__(self) -> None:
        self.changed = False

    def run(self, name: str, done: bool, fn: Callable[[], str]) -> None:
        if done and not self.changed:
            print(f"[  skip  ] {name}: already done", flush=True)
            return
        t0 = time.perf_counter()
        summary = fn()
        self.changed = True
        print(f"[{time.perf_counter() - t0:6.1f} s] {name}: {summary}", flush=True)


def run(out: Path, figures: Path, report: Path) -> None:
    """Run every stage; see the module docstring."""
    from slitcli.detect import DetectParams, run_detect, summary_line
    from slitcli.dwa import DwaParams
    from slitcli.rig import paper_rig
    from slitcli.sim.loop import SimParams, simulate_dwa
    from slitcli.sim.scene import load_scene
    from slitcli.sim.sequence import render_sequence

    rig = paper_rig()
    stages = _Stages()
    for name, frames in SCENES.items():
        target = out / "sequences" / name

        def render(name: str = name, frames: int = frames, target: Path = target) -> str:
            scene = load_scene(ROOT / "sample_data" / f"{name}.yaml")
            s = render_sequence(scene, rig, target, frames=frames, overwrite=True)
            return f"{s['frames']} frames -> {target}"

        stages.run(f"render {name}", (target / "gt" / "ranges.csv").exists(), render)
    runs = [(name, name, "paper") for name in SCENES]
    runs.append(("overhang", "overhang-conservative", "conservative"))
    for scene, label, mode in runs:
        target = out / "detect" / label

        def detect(scene: str = scene, mode: str = mode, target: Path = target) -> str:
            s = run_detect(out / "sequences" / scene, target,
                           params=DetectParams(fusion_mode=mode), save_images=True, jobs=2)
            return summary_line(s)

        stages.run(f"detect {label}", (target / "ranges.csv").exists(), detect)
    dwa_out = out / "dwa"

    def dwa() -> str:
        m = simulate_dwa(dwa_out, rig, DwaParams(), SimParams(), scenario="paper",
                         sensing_ranges_m=DWA_RANGES_M, overwrite=True)
        return (f"{len(m)} runs, reached {int(m['reached_goal'].sum())}, collided "
                f"{int(m['collided'].sum())} -> {dwa_out}")

    stages.run("simulate-dwa paper", (dwa_out / "metrics.csv").exists(), dwa)

    def draw() -> str:
        from slitcli.figures import make_figures

        return ", ".join(str(p) for p in make_figures(out, figures))

    stages.run("figures", (figures / "fig9.png").exists(), draw)
    stages.run("report", report.exists(), lambda: write_report(out, report))


def write_report(out: Path, report: Path) -> str:
    """``docs/reproduction.md`` from the detect, truth and DWA tables under ``out``."""
    from slitcli.evaluate import (
        dwa_claim,
        laser_range_claim,
        markdown_table,
        range_errors,
        stereo_range_claim,
    )
    from slitcli.io.atomic import write_text_atomic

    errors = pd.concat([
        range_errors(pd.read_csv(out / "detect" / s / "ranges.csv"),
                     pd.read_csv(out / "sequences" / s / "gt" / "ranges.csv"))
        for s in SCENES], ignore_index=True)
    ranges_all = pd.concat([pd.read_csv(out / "detect" / s / "ranges.csv").assign(scene=s)
                            for s in SCENES], ignore_index=True)
    laser_truth = pd.concat([pd.read_csv(out / "sequences" / s / "gt" / "laser_ranges.csv")
                             .assign(scene=s) for s in SCENES], ignore_index=True)
    laser_claim, laser_table = laser_range_claim(
        ranges_all.assign(frame=ranges_all["scene"] + ":" + ranges_all["frame"].astype(str)),
        laser_truth.assign(frame=laser_truth["scene"] + ":" + laser_truth["frame"].astype(str)))
    stereo_claim, stereo_table = stereo_range_claim(errors)
    metrics = pd.read_csv(out / "dwa" / "metrics.csv")
    dwa = dwa_claim(metrics)
    fusion_rows = _overhang_fusion_rows(out)
    text = f"""# Reproduction report

Written by `make reproduce-figures` from this run's own outputs (paper rig, generated
scenes `{"`, `".join(SCENES)}` from `sample_data/`, ground truth from the renderer). Numbers
change only when the code or the sample data change.

## The paper's claims

| claim | measured here | holds? |
|---|---|---|
{laser_claim.row()}
{stereo_claim.row()}
{dwa.row()}

## Laser (active) range, per true distance

{markdown_table(laser_table)}

Scored on the bins where the laser sheet truly lights an obstacle (render's
`gt/laser_ranges.csv`: the nearest lit point per bin, from the scene's geometry).
`within_tol`: laser range within 1 % of the truth; `returned`: any
laser return in the bin.

## Stereo (passive) range, per true distance

{markdown_table(stereo_table)}

All bins with a true obstacle, textureless ones included (stereo cannot range those:
that is the laser's job within 1 m). `within_tol`: stereo range within max(5 cm, 5 %)
of the truth; `returned`: any stereo return in the bin.

## Fusion on the overhang scene (shelf and table top above the laser sheet)

{markdown_table(pd.DataFrame(fusion_rows))}

Eq. 11 trusts a laser "no return" up to the laser's reach (1 m): an obstacle that
overhangs the laser sheet is pushed out to 1 m; the conservative minimum keeps it.

## Modified DWA, paper scenario (obstacle first sensed at each range)

{markdown_table(metrics)}

Figures: `figures/fig4.png`, `fig7.png`, `fig8.png`, `fig9.png`, `accuracy.png`.
"""
    write_text_atomic(report, text)
    return f"{report}"


def _overhang_fusion_rows(out: Path) -> list[dict[str, object]]:
    """Fused-range accuracy on the overhang scene, paper (Eq. 11) and conservative
    fusion: one row each, over the bins whose true obstacle lies 0.6-3 m away."""
    from slitcli.evaluate import range_errors

    truth = pd.read_csv(out / "sequences" / "overhang" / "gt" / "ranges.csv")
    rows = []
    for mode, label in (("paper", "overhang"), ("conservative", "overhang-conservative")):
        e = range_errors(pd.read_csv(out / "detect" / label / "ranges.csv"), truth)
        band = e[(e["true_m"] >= 0.6) & (e["true_m"] <= 3.0)]
        err = band["fused_err_m"]
        rows.append({
            "fusion": mode, "bins 0.6-3 m": len(band),
            "within max(5 cm, 5 %)":
                f"{(err.abs() <= (0.05 * band['true_m']).clip(0.05)).mean():.3f}",
            "too far by > 10 cm (unsafe)": f"{(err > 0.10).mean():.3f}",
            "worst overestimate m": f"{err.max():.3f}",
            "median abs error m": f"{err.abs().median():.3f}"})
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m slitcli.reproduce", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=ROOT / "out", help="work folder [out/]")
    ap.add_argument("--figures", type=Path, default=ROOT / "figures",
                    help="figure folder [figures/]")
    ap.add_argument("--report", type=Path, default=ROOT / "docs" / "reproduction.md",
                    help="report file [docs/reproduction.md]")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    try:
        run(args.out, args.figures, args.report)
    except SlitcliError as e:
        print(f"reproduce: error: {e}", file=sys.stderr)
        return 2
    print(f"done in {time.perf_counter() - t0:.1f} s", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
