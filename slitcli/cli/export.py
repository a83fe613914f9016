"""Command ``export``: a detection run as ROS LaserScan messages in a bag."""

from __future__ import annotations

from pathlib import Path

import click

from slitcli.cli.main import cli


@cli.command("export", short_help="Write a detect run as ROS LaserScan messages (bag).")
@click.argument("run", metavar="DETECT_OUT", type=click.Path(path_type=Path))
@click.option("-o", "--out", required=True, type=click.Path(path_type=Path),
              help="Output bag: NAME.mcap = ROS 2 MCAP, NAME.bag = ROS 1, NAME (no suffix) "
              "= ROS 2 sqlite3 bag folder.")
@click.option("--frame-id", default="slitcli_sensor", show_default=True,
              help="header.frame_id of the scans (sensor frame: x forward, y left, z up).")
@click.option("--camera-frame-id", default="slitcli_camera_optical", show_default=True,
              help="header.frame_id of the images (with --images).")
@click.option("--period-s", type=float, default=0.1, show_default=True,
              help="Frame period, seconds, for runs without frame times (frame i is "
              "stamped i x period).")
@click.option("--images", is_flag=True, help="Also write the rectified left image (bgr8) on "
              "/slitcli/left/image_rect, the distance image (16UC1, mm; needs detect "
              "--save-images) on /slitcli/distance/image, the camera on "
              "/slitcli/left/camera_info and its pose on /tf_static.")
@click.option("--source", type=click.Path(path_type=Path), default=None,
              help="The run's input (sequence folder or bag) for --images and a bag's exact "
              "stamps [default: the path the run's manifest records].")
@click.option("--overwrite", is_flag=True, help="Replace an existing output.")
def export_cmd(run: Path, out: Path, frame_id: str, camera_frame_id: str, period_s: float,
               images: bool, source: Path | None, overwrite: bool) -> None:
    """Write the range table of a `slitcli detect` run as sensor_msgs/LaserScan messages,
    one per frame on each of /slitcli/scan (fused), /slitcli/scan/laser and
    /slitcli/scan/stereo.

    Scans: angle_min = the first bin's bearing (rad, counter-clockwise from x forward),
    angle_increment = the bin width, ranges float32 metres, +inf = no return (REP 117),
    range_min/max from the rig. Stamps: the frames' times (a bag run's own stamps when
    the bag is at hand), else frame index x --period-s. See docs/export.md for viewing
    the bag in Foxglove or RViz.

    \b
    Examples:
      slitcli export out/det -o out/det.mcap
      slitcli export out/det -o out/det.bag --frame-id base_scan --images
    """
    from slitcli.export import ExportParams, export_run
    from slitcli.io.progress import progress_bar

    params = ExportParams(frame_id=frame_id, camera_frame_id=camera_frame_id,
                          period_s=period_s, images=images)
    with progress_bar(0, "export") as bar:
        def total(n: int) -> None:
            bar.total = n
            bar.refresh()

        summary = export_run(run, out, params=params, source=source, overwrite=overwrite,
                             on_total=total, on_frame=lambda: bar.update(1))
    click.echo(summary.line())
