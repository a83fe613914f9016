"""Command ``render``: generated scenes to stereo sequences with ground truth."""

from __future__ import annotations

from pathlib import Path

import click

from slitcli.cli.main import cli


@cli.command("render")
@click.argument("scene_file", metavar="SCENE.yaml",
                type=click.Path(dir_okay=False, path_type=Path))
@click.argument("out", type=click.Path(file_okay=False, path_type=Path))
@click.option("--frames", type=click.IntRange(1, 100_000), default=None,
              help="Frames to render, 1-100000 [default: the scene's robot.frames].")
@click.option("--seed", type=click.IntRange(0, 2**63 - 1), default=None,
              help="Replace the scene's seed (textures and sensor noise), a whole number >= 0 "
              "[default: the scene file's seed]. Example: --seed 9")
@click.option("--rig", "rig_path", type=click.Path(dir_okay=False, path_type=Path),
              default=None, help="Rig file [default: the paper rig].")
@click.option("--overwrite", is_flag=True,
              help="Replace what an earlier render wrote in OUT (other files are kept).")
def render_cmd(scene_file: Path, out: Path, frames: int | None, seed: int | None,
               rig_path: Path | None, overwrite: bool) -> None:
    """Render a generated scene into a stereo sequence with ground truth.

    Writes OUT/left/, OUT/right/ (colour PNG pairs), OUT/times.csv, OUT/rig.yaml,
    OUT/scene.yaml and OUT/gt/ (true disparity, depth in mm, obstacle mask, stripe rows,
    ranges per 1-degree bearing bin in metres, poses, lossless .npz). See docs/sequence.md
    and docs/ground-truth.md.

    Example: slitcli render sample_data/corridor.yaml out/corridor --frames 10
    """
    from slitcli.io.progress import progress_bar
    from slitcli.rig import load_rig, paper_rig
    from slitcli.sim.scene import load_scene
    from slitcli.sim.sequence import render_sequence

    scene = load_scene(scene_file)
    rig = load_rig(rig_path) if rig_path is not None else paper_rig()
    with progress_bar(scene.robot.frames if frames is None else frames, "render") as bar:
        summary = render_sequence(scene, rig, out, frames=frames, seed=seed,
                                  overwrite=overwrite, on_frame=lambda i, n: bar.update(1),
                                  inputs=(scene_file, rig_path))
    click.echo(f"rendered {summary['frames']} frames of '{scene.name}' to {out}: "
               f"{summary['stripe_columns']} stripe columns, "
               f"{summary['obstacle_bins']} obstacle bearing bins in the truth")


