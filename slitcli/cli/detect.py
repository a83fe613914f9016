"""Command ``detect``: laser + stereo + fusion over a sequence folder or a ROS bag."""

from __future__ import annotations

from pathlib import Path

import click

from slitcli.cli.laser import LASER_OPTION_NAMES, laser_options
from slitcli.cli.main import bad_frame_option, bag_options, cli, echo_notes
from slitcli.cli.stereo import matcher_options, stereo_params


@cli.command("detect", short_help="Per-bearing obstacle ranges of a sequence or bag.")
@click.argument("source", metavar="SEQ|BAG", type=click.Path(path_type=Path))
@click.option("-o", "--out", "out", required=True,
              type=click.Path(file_okay=False, path_type=Path),
              help="Output folder for ranges.csv (and the images with --save-images).")
@click.option("--rig", "rig_path", type=click.Path(dir_okay=False, path_type=Path),
              default=None, help="Rig file [default: SEQ/rig.yaml, else the paper rig; "
              "required for bags].")
@click.option("--fusion", type=click.Choice(["paper", "conservative"]), default="paper",
              show_default=True, help="paper = Eq. 11 (trusts a laser 'no return' up to the "
              "laser's max range; keeps the laser's range where stereo sees the same "
              "surface, within 2 px); conservative = the nearer of laser and stereo.")
@click.option("--bin-deg", type=click.FloatRange(0.05, 10.0), default=1.0, show_default=True,
              help="Bearing bin width, degrees (0.05-10).")
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
def detect_cmd(source: Path, out: Path, rig_path: Path | None, fusion: str, bin_deg: float,
               jobs: int, save_images: bool, left_topic: str, right_topic: str, max_dt: float,
               on_bad_frame: str, overwrite: bool, **tuning: object) -> None:
    """Range obstacles per bearing bin: laser stripe (Eqs. 1-7), Eq. 10 stereo (Eqs. 8-10)
    and their fusion (Eq. 11), for a sequence folder or a ROS 1/2 bag.

    Writes OUT/ranges.csv: one row per frame and bin (frame, time_s, bearing_deg,
    laser_range_m, stereo_range_m, stereo_has_features, fused_range_m, fused_source),
    metres, sensor frame, empty = no return. A re-run resumes where it stopped. See
    docs/detect.md.

    \b
    Examples:
      slitcli detect sample_data/sequences/corridor -o out/det --jobs 2
      slitcli detect run.bag --rig rig.yaml -o out/bag --left-topic /cam/left/image_raw \\
          --right-topic /cam/right/image_raw
    """
    from slitcli.detect import DetectParams, run_detect, summary_line
    from slitcli.io.progress import progress
    from slitcli.laser.params import LaserParams

    laser = {k: tuning.pop(k) for k in LASER_OPTION_NAMES}
    params = DetectParams(stereo=stereo_params(**tuning), laser=LaserParams(**laser),
                          fusion_mode=fusion, bin_deg=bin_deg)
    with progress("detect") as on_progress:
        summary = run_detect(source, out, rig_path=rig_path, params=params, jobs=jobs,
                             save_images=save_images, overwrite=overwrite,
                             left_topic=left_topic, right_topic=right_topic, max_dt_s=max_dt,
                             on_bad_frame=on_bad_frame, on_progress=on_progress)
    echo_notes(summary.notes)
    click.echo(summary_line(summary))
