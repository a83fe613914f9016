"""Commands ``calibrate stereo``, ``calibrate laser``, ``calibrate mount``."""

from __future__ import annotations

from pathlib import Path

import click

from slitcli.cli.main import cli

_BOARD_HELP = "Chessboard inner corners COLSxROWS (points where four squares meet), e.g. 9x6."
_SQUARE_HELP = "Side of one chessboard square in metres, e.g. 0.025."


@cli.group("calibrate")
def calibrate_group() -> None:
    """Calibrate the rig: stereo from chessboards, the laser plane, the camera mount.

    \b
    Usual order (docs/calibration.md):
      slitcli calibrate stereo calib/left calib/right --board 9x6 --square-m 0.025 -o rig.yaml
      slitcli calibrate laser --rig rig.yaml laser_views/ --board 9x6 --square-m 0.025
      slitcli calibrate mount --rig rig.yaml floor_seq/
    """


@calibrate_group.command("stereo")
@click.argument("left_dir", type=click.Path(path_type=Path))
@click.argument("right_dir", type=click.Path(path_type=Path))
@click.option("--board", required=True, help=_BOARD_HELP)
@click.option("--square-m", type=float, required=True, help=_SQUARE_HELP)
@click.option("-o", "--out", "--output", "out", required=True,
              type=click.Path(dir_okay=False, path_type=Path), help="Rig file to write (YAML).")
@click.option("--base", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Rig whose name, mount, laser plane and range limits are kept "
                   "[default: the paper rig's].")
@click.option("--min-views", type=click.IntRange(min=3), default=5, show_default=True,
              help="Views with the board in both cameras required.")
@click.option("--k3/--no-k3", default=False, show_default=True,
              help="Also estimate the third radial distortion coefficient (wide lenses).")
@click.option("--alpha", type=click.FloatRange(0.0, 1.0), default=0.0, show_default=True,
              help="Rectification scaling: 0 keeps only valid pixels, 1 keeps every raw pixel.")
def calibrate_stereo_cmd(left_dir: Path, right_dir: Path, board: str, square_m: float,
                         out: Path, base: Path | None, min_views: int, k3: bool,
                         alpha: float) -> None:
    """Stereo calibration from chessboard views: intrinsics, R, T, rectification.

    LEFT_DIR and RIGHT_DIR hold the raw images of the two cameras (PNG/JPEG), paired in
    name order. Views where either camera misses the board are named and skipped.
    Prints the RMS reprojection error (px) overall and per view and the rectified
    epipolar error (|dy| of the board corners, median / p95 / max, px), and writes a rig
    whose `raw` holds K1 D1 K2 D2 R T R1 R2 P1 P2 and whose `left` / `baseline_m` are the
    rectified camera, plus OUT_rectified.png (the first view rectified, side by side,
    with horizontal lines). Mount and laser plane are placeholders (a note says so):
    calibrate them next, or set them with `slitcli rig set`.

    Example: slitcli calibrate stereo calib/left calib/right --board 9x6 --square-m 0.025
    -o rig.yaml
    """
    from slitcli.calibrate.board import BoardSpec
    from slitcli.calibrate.stereo import StereoCalibrationParams, run_calibrate_stereo

    params = StereoCalibrationParams(board=BoardSpec.parse(board, square_m),
                                     min_views=min_views, k3=k3, alpha=alpha)
    from slitcli.calibrate.stereo import preview_path
    from slitcli.cli.main import echo_notes

    result = run_calibrate_stereo(left_dir, right_dir, out, params, base_rig=base)
    for line in result.report_lines():
        click.echo(line)
    echo_notes(result.notes)
    click.echo(f"wrote {out}")
    click.echo(f"wrote {preview_path(out)} (rectified first view, lines every 24 rows)")


@calibrate_group.command("laser")
@click.argument("images_dir", type=click.Path(path_type=Path))
@click.option("--rig", "rig_path", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="Stereo-calibrated rig; its laser plane is replaced.")
@click.option("--board", required=True, help=_BOARD_HELP)
@click.option("--square-m", type=float, required=True, help=_SQUARE_HELP)
@click.option("-o", "--out", "--output", "out", type=click.Path(dir_okay=False, path_type=Path),
              default=None, help="Rig file to write [default: update --rig in place].")
@click.option("--min-views", type=click.IntRange(min=2), default=2, show_default=True,
              help="Board poses with the stripe on the board required.")
@click.option("--left-only", is_flag=True, default=False,
              help="Ignore IMAGES_DIR/right/: board poses from the left camera alone "
                   "(less accurate in depth and tilt).")
def calibrate_laser_cmd(images_dir: Path, rig_path: Path, board: str, square_m: float,
                        out: Path | None, min_views: int, left_only: bool) -> None:
    """Laser plane from views of a chessboard crossed by the laser stripe.

    IMAGES_DIR has left/ and right/ subfolders (images paired by file name), raw if the
    rig has a `raw` calibration; the stripe is read in the left image and each board
    pose is measured by both cameras. A folder of left images alone (or a left/ without
    right/) also works, with board poses from the left camera only: less accurate, the
    board's tilt and distance then come from perspective alone. Use at least 3 board
    poses at different distances (0.6-1.2 m); a single pose is refused (its stripe is a
    line). Prints the plane (n . X = offset_m, metres, rectified left camera frame), the
    residual std (mm) and per view how the pose was found.

    Example: slitcli calibrate laser --rig rig.yaml laser_views/ --board 9x6 --square-m 0.025
    """
    from slitcli.calibrate.board import BoardSpec
    from slitcli.calibrate.laser_plane import LaserPlaneParams, run_calibrate_laser

    params = LaserPlaneParams(board=BoardSpec.parse(board, square_m), min_views=min_views)
    result = run_calibrate_laser(rig_path, images_dir, params, out_rig=out,
                                 use_right=not left_only)
    for line in result.report_lines():
        click.echo(line)
    click.echo(f"wrote {out or rig_path}")


@calibrate_group.command("mount")
@click.argument("seq", type=click.Path(path_type=Path))
@click.option("--rig", "rig_path", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="Stereo-calibrated rig; its mount height, tilt and roll are replaced.")
@click.option("-o", "--out", "--output", "out", type=click.Path(dir_okay=False, path_type=Path),
              default=None, help="Rig file to write [default: update --rig in place].")
@click.option("--frames", type=click.IntRange(min=1), default=5, show_default=True,
              help="Frames used, spread over the sequence.")
@click.option("--max-depth-m", type=click.FloatRange(min=0.5), default=3.0, show_default=True,
              help="Floor points farther than this (metres) are ignored.")
def calibrate_mount_cmd(seq: Path, rig_path: Path, out: Path | None, frames: int,
                        max_depth_m: float) -> None:
    """Camera height (m), tilt and roll (deg) from a textured floor seen in stereo.

    SEQ is a stereo sequence folder (left/, right/) looking at a flat floor. The floor
    plane is found by RANSAC on StereoSGBM points and polished by aligning the two
    images through the plane; `mount.forward_m` is kept. Views that show no floor are
    refused (exit 2, nothing written): fewer than 50 % of the stereo points on the
    plane, a residual RMS above 1.36 x the stereo depth noise, a plane tilted over
    75 deg or above the camera; the message names the numbers (docs/calibration.md).

    Example: slitcli calibrate mount --rig rig.yaml floor_seq/
    """
    from slitcli.calibrate.mount import MountParams, run_calibrate_mount

    params = MountParams(max_frames=frames, max_depth_m=max_depth_m)
    result = run_calibrate_mount(rig_path, seq, params, out_rig=out)
    for line in result.report_lines():
        click.echo(line)
    click.echo(f"wrote {out or rig_path}")


