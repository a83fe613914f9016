"""Command ``report``: figures, an overlay video and an HTML page of a detect run."""

from __future__ import annotations

from pathlib import Path

import click

from slitcli.cli.main import cli


@cli.command("report", short_help="HTML report and overlay video of a detect run.")
@click.argument("run", metavar="DETECT_OUT", type=click.Path(path_type=Path))
@click.option("--source", type=click.Path(path_type=Path), default=None,
              help="The run's input (sequence folder or bag) for the video [default: the "
              "path the run's manifest records].")
@click.option("--no-video", is_flag=True, help="Skip overlay.mp4 (no input images needed).")
@click.option("--fps", type=float, default=None,
              help="Video frame rate, frames/s [default: from the frame times, 1-30; else 5].")
@click.option("--period-s", type=float, default=0.1, show_default=True,
              help="Frame period, seconds, for runs without frame times (time axes).")
@click.option("--dpi", type=int, default=110, show_default=True,
              help="Resolution of the PNG figures, dots per inch.")
def report_cmd(run: Path, source: Path | None, no_video: bool, fps: float | None,
               period_s: float, dpi: int) -> None:
    """Write DETECT_OUT/report/: index.html (self-contained, opens from disk),
    heatmap.png (fused range per bearing over time, m), birdseye.png (the fused points
    of all frames from above, m), sources.png (share of bins ranged by laser / stereo /
    neither, %), overlay.mp4 (left images with the laser stripe, the obstacle mask and
    each bin's fused range as an arc labelled in m; frame time in the corner) and
    colour previews of one frame's disparity (px) and distance (m).

    Stripe and mask need `slitcli detect --save-images`. A re-run with the same inputs
    skips the files already made. See docs/report.md.

    \b
    Examples:
      slitcli report out/det
      slitcli report out/bagrun --source run.bag --fps 10
    """
    from slitcli.io.progress import progress_bar
    from slitcli.report import ReportParams, run_report

    params = ReportParams(video=not no_video, fps=fps, period_s=period_s, dpi=dpi)
    with progress_bar(0, "report") as bar:
        def total(n: int) -> None:
            bar.total = n
            bar.refresh()

        summary = run_report(run, params=params, source=source,
                             on_stage=lambda s: click.echo(f"report: {s}", err=True),
                             on_total=total, on_frame=lambda: bar.update(1))
    click.echo(summary.line())
