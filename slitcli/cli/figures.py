"""Command ``figures``: the paper's Figs. 4, 7, 8, 9 and a range-accuracy figure."""

from __future__ import annotations

from pathlib import Path

import click

from slitcli.cli.main import cli


@cli.command("figures", short_help="Draw Figs. 4, 7, 8, 9 and range accuracy.")
@click.argument("work", type=click.Path(file_okay=False, path_type=Path))
@click.option("-o", "--out", type=click.Path(file_okay=False, path_type=Path),
              default=Path("figures"), show_default=True, help="Folder for the figures.")
@click.option("--format", "fmt", type=click.Choice(["png", "svg", "pdf"]), default="png",
              show_default=True, help="File format.")
@click.option("--dpi", type=click.IntRange(20, 1200), default=150, show_default=True,
              help="Resolution of raster output, dots per inch.")
def figures_cmd(work: Path, out: Path, fmt: str, dpi: int) -> None:
    """Draw the paper's figures from a work folder of rendered, detected and simulated
    results (the layout `make reproduce-figures` writes into out/: sequences/<scene>/,
    detect/<scene>/, dwa/).

    Writes fig4 (laser stripe and ranges), fig7 (left, right, obstacle and distance
    images), fig8 (trajectories, m), fig9 (robot-obstacle distance over time, s and m)
    and accuracy (range error against the true distance, cm and m).

    Example: slitcli figures out -o figures --format svg
    """
    from slitcli.figures import make_figures

    for path in make_figures(work, out, fmt=fmt, dpi=dpi):
        click.echo(f"wrote {path}")
