"""`make reproduce-figures`: the main job on the bundled sample data.

Runs each stage on ``sample_data/`` and prints it with its time. Stages whose outputs
already exist are skipped, so a second run is quick and gives the same files.
Run as ``python -m slitcli.reproduce [--out OUT]``.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path

from slitcli.errors import SlitcliError

ROOT = Path(__file__).resolve().parent.parent
SAMPLE_SCENES = ("fig4", "corridor", "distractors")


def _stage(name: str, done: bool, fn: Callable[[], str]) -> None:
    t0 = time.perf_counter()
    if done:
        print(f"[skip] {name}: already done", flush=True)
        return
    summary = fn()
    print(f"[{time.perf_counter() - t0:6.1f} s] {name}: {summary}", flush=True)


def run(out: Path) -> None:
    """Render the sample scenes into ``out/sequences/`` and summarise them."""
    from slitcli.rig import paper_rig
    from slitcli.sim.scene import load_scene
    from slitcli.sim.sequence import render_sequence

    rig = paper_rig()
    for name in SAMPLE_SCENES:
        scene = load_scene(ROOT / "sample_data" / f"{name}.yaml")
        target = out / "sequences" / name

        def render(scene=scene, target=target) -> str:
            s = render_sequence(scene, rig, target)
            return (f"{s['frames']} frames -> {target} ({s['stripe_columns']} stripe columns, "
                    f"{s['obstacle_bins']} obstacle bins in the truth)")

        _stage(f"render {name}", (target / "gt" / "ranges.csv").exists(), render)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m slitcli.reproduce", description=__doc__)
    ap.add_argument("--out", type=Path, default=ROOT / "out", help="work folder [out/]")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    try:
        run(args.out)
    except SlitcliError as e:
        print(f"reproduce: error: {e}", file=sys.stderr)
        return 2
    print(f"done in {time.perf_counter() - t0:.1f} s", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
