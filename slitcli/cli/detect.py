"""Command ``detect``: laser + stereo + fusion over a sequence folder or a ROS bag."""

from __future__ import annotations

from pathlib import Path

import click

from slitcli.cli.laser import LASER_OPTION_NAMES, laser_options
from slitcli.cli.main import bad_frame_option, bag_options, cli, echo_notes, to_flags
from slitcli.cli.stereo import matcher_options, stereo_params


@cli.command("detect", short_help="Per-bearing obstacle ranges of a sequence or bag.")
@click.argument("sources", metavar="SEQ|BAG...", nargs=-1, type=click.Path(path_type=Path))
@click.option("-o", "--out", required=True, type=click.Path(file_okay=False, path_type=Path),
              help="Output folder for ranges.csv (and the images with --save-images); with "
              "several inputs OUT/<input name>/ per input and OUT/index.csv.")
@click.option("--inputs", "inputs_file", type=click.Path(dir_okay=False, path_type=Path),
              default=None, help="Text file of inputs, one folder or bag per line (# comments; "
              "relative paths are relative to the file), added to SEQ|BAG... [default: none]. "
              "Example: --inputs runs.txt")
@click.option("--cluster", default=None, metavar="local:N|tcp://HOST:PORT",
              help="Run on a Dask cluster: local:N starts N worker processes here, "
              "tcp://HOST:PORT uses a running scheduler (paths must be the same on every "
              "worker). Needs pip install 'slitcli[cluster]'. [default: none: --jobs processes "
              "here] Example: --cluster local:4. See docs/cluster.md.")
@click.option("--chunk-frames", type=click.IntRange(1, 10_000_000), default=None,
              help="Split each input into chunks of this many frames (default: one chunk per "
              "input); the tables are byte-identical for any chunking.")
@click.option("--rig", "rig_path", type=click.Path(dir_okay=False, path_type=Path),
              default=None, help="Rig file [default: SEQ/rig.yaml, else the paper rig; "
              "required for bags].")
@click.option("--fusion", type=click.Choice(["paper", "conservative"]), default="paper",
              show_default=True, help="paper = Eq. 11 (trusts a laser 'no return' up to the "
              "laser's max range where the frame's stripe shows the laser could have seen "
              "there, column laser_free_m; keeps the laser's range where stereo sees the "
              "same surface, within 2 px); conservative = the nearer of laser and stereo.")
@click.option("--bin-deg", type=click.FloatRange(0.05, 10.0), default=1.0, show_default=True,
              help="Bearing bin width, degrees (0.05-10).")
@click.option("--laser-depth-check/--no-laser-depth-check", default=True, show_default=True,
              help="Drop pieces of laser stripe whose pixels stereo sees more than 5 % and "
              "0.5 px of disparity farther than the laser plane (reddish texture below the "
              "sheet; the frame's longest piece always stays).")
@click.option("--stereo-sheet-check/--no-stereo-sheet-check", default=True, show_default=True,
              help="--fusion paper: keep a stereo return the laser is silent about where "
              "stereo sees the obstacle reach down to the laser sheet (3 points at most 8 cm "
              "above it): the sheet falls on it, so the silence is a miss, not free "
              "space. Overhangs above the sheet are still moved out.")
@click.option("--jobs", type=click.IntRange(1, 64), default=1, show_default=True,
              help="Worker processes, 1-64, about 250 MB each (the table is byte-identical "
                   "for any number).")
@click.option("--save-images", is_flag=True, help="Also write disparity/, distance/, mask/ "
              "PNGs and laser.csv.")
@bag_options
@bad_frame_option
@matcher_options
@laser_options
@click.option("--overwrite", is_flag=True, help="Replace results made with other settings.")
def detect_cmd(sources: tuple[Path, ...], out: Path, inputs_file: Path | None,
               cluster: str | None, chunk_frames: int | None, rig_path: Path | None,
               fusion: str, bin_deg: float, laser_depth_check: bool,
               stereo_sheet_check: bool, jobs: int, save_images: bool, left_topic: str,
               right_topic: str, max_dt: float,
               on_bad_frame: str, overwrite: bool, **tuning: object) -> None:
    """Range obstacles per bearing bin: laser stripe (Eqs. 1-7), Eq. 10 stereo (Eqs. 8-10)
    and their fusion (Eq. 11), for a sequence folder or a ROS 1/2 bag.

    Writes OUT/ranges.csv: one row per frame and bin (frame, time_s, bearing_deg,
    laser_range_m, stereo_range_m, stereo_has_features, fused_range_m, fused_source,
    laser_free_m),
    metres, sensor frame, empty = no return. A re-run resumes where it stopped. See
    docs/detect.md.

    Several inputs (folders and bags, any mix, or --inputs FILE) write OUT/<input
    name>/ranges.csv each (a name given twice gets -2, -3...) and OUT/index.csv (input,
    output, frames, resumed, status, seconds, message). --cluster runs the inputs, split
    in --chunk-frames chunks, on Dask workers (docs/cluster.md).

    \b
    Examples:
      slitcli detect sample_data/sequences/corridor -o out/det --jobs 2
      slitcli detect run.bag --rig rig.yaml -o out/bag --left-topic /cam/left/image_raw \\
          --right-topic /cam/right/image_raw
      slitcli detect runs/a runs/b day1.bag -o out/all --cluster local:2
      slitcli detect --inputs runs.txt -o /shared/out --cluster tcp://head:8786 \\
          --chunk-frames 200
    """
    from slitcli.detect import DetectParams, run_detect, summary_line
    from slitcli.io.progress import progress
    from slitcli.laser.params import LaserParams

    laser = {k: tuning.pop(k) for k in LASER_OPTION_NAMES}
    params = DetectParams(stereo=stereo_params(**tuning), laser=LaserParams(**laser),
                          fusion_mode=fusion, bin_deg=bin_deg,
                          laser_depth_check=laser_depth_check,
                          stereo_sheet_check=stereo_sheet_check)
    srcs = list(sources)
    if inputs_file is not None:
        from slitcli.multi import read_inputs_file

        srcs += read_inputs_file(inputs_file)
    if not srcs:
        raise click.UsageError("give at least one input: SEQ|BAG... or --inputs FILE")
    if len(srcs) > 1 or cluster is not None or chunk_frames is not None:
        _detect_many(srcs, out, cluster, chunk_frames, rig_path=rig_path, params=params,
                     jobs=jobs, save_images=save_images, overwrite=overwrite,
                     left_topic=left_topic, right_topic=right_topic, max_dt_s=max_dt,
                     on_bad_frame=on_bad_frame)
        return
    source = srcs[0]
    with progress("detect") as on_progress:
        summary = run_detect(source, out, rig_path=rig_path, params=params, jobs=jobs,
                             save_images=save_images, overwrite=overwrite,
                             left_topic=left_topic, right_topic=right_topic, max_dt_s=max_dt,
                             on_bad_frame=on_bad_frame, on_progress=on_progress)
    echo_notes(summary.notes)
    click.echo(summary_line(summary))


def _detect_many(sources: list[Path], out: Path, cluster: str | None, chunk_frames: int | None,
                 **kwargs: object) -> None:
    """Many inputs, chunks, or a cluster: :func:`slitcli.multi.run_detect_many`."""
    import contextlib

    from slitcli.multi import ManyProgress, run_detect_many, summary_line

    last: list[tuple[int, int]] = []

    def on_progress(p: ManyProgress) -> None:
        # one line per change, on stderr: cluster runs mostly log to files, not terminals
        if last and last[-1] == (p.inputs_done, p.frames_done):
            return
        last.append((p.inputs_done, p.frames_done))
        click.echo(f"detect: {p.inputs_done}/{p.inputs} inputs, {p.frames_done}/{p.frames} "
                   "frames done", err=True)

    with contextlib.ExitStack() as stack:
        make_runner = None
        if cluster is not None:
            from slitcli.cluster import dask_client, dask_runner, parse_cluster

            client = stack.enter_context(dask_client(parse_cluster(cluster)))
            make_runner = dask_runner(client)
        summary = run_detect_many(sources, out, chunk_frames=chunk_frames,
                                  make_runner=make_runner, on_progress=on_progress, **kwargs)
    echo_notes(summary.notes)
    for src, message in summary.failed:
        click.echo(f"slitcli: error: {src}: {to_flags(message)}", err=True)
    click.echo(summary_line(summary))
    if summary.failed:
        raise SystemExit(2)
