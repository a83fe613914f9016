"""The command line: parses options, builds parameter dataclasses, calls the library.

Every command calls one library function. The library's own :class:`SlitcliError`
becomes exit status 2 with one line on stderr; click's usage errors too; any other
exception is an internal error (exit 1, one line; the traceback with ``--debug``).
"""

from __future__ import annotations

import sys
import traceback
from pathlib import Path
from typing import Any

import click

from slitcli import __version__
from slitcli.errors import SlitcliError


class _Group(click.Group):
    """A group whose errors are one line on stderr (exit 2 for bad input, 1 for bugs)."""

    def main(self, args: Any = None, prog_name: str | None = None,
             complete_var: str | None = None, standalone_mode: bool = True,
             **extra: Any) -> Any:
        argv = list(sys.argv[1:] if args is None else args)
        debug = "--debug" in argv
        try:
            rv = super().main(args=argv, prog_name=prog_name or "slitcli",
                              complete_var=complete_var, standalone_mode=False, **extra)
        except SlitcliError as e:
            if debug:
                traceback.print_exc()
            click.echo(f"slitcli: error: {e}", err=True)
            sys.exit(2)
        except click.exceptions.NoArgsIsHelpError as e:
            click.echo(e.ctx.get_help() if e.ctx else str(e), err=True)
            sys.exit(2)
        except click.UsageError as e:
            where = f" (see '{e.ctx.command_path} --help')" if e.ctx is not None else ""
            click.echo(f"slitcli: error: {e.format_message()}{where}", err=True)
            sys.exit(2)
        except click.ClickException as e:
            click.echo(f"slitcli: error: {e.format_message()}", err=True)
            sys.exit(e.exit_code)
        except click.exceptions.Abort:
            click.echo("slitcli: interrupted", err=True)
            sys.exit(130)
        except KeyboardInterrupt:
            click.echo("slitcli: interrupted", err=True)
            sys.exit(130)
        except Exception as e:
            if debug:
                traceback.print_exc()
            msg = str(e).splitlines()[0] if str(e) else ""
            click.echo(f"slitcli: internal error: {e.__class__.__name__}: {msg} "
                       "(run with --debug for the traceback)", err=True)
            sys.exit(1)
        sys.exit(rv if isinstance(rv, int) else 0)


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"],
                                           "max_content_width": 100})
@click.option("--debug", is_flag=True, help="Print the full traceback on errors.")
@click.version_option(__version__, prog_name="slitcli")
def cli(debug: bool) -> None:
    """Obstacle detection with a stereo camera and a red laser slit, and a modified DWA.

    \b
    Typical session:
      slitcli rig init rig.yaml              # the paper's rig, edit to taste
      slitcli render sample_data/corridor.yaml out/corridor
      slitcli detect out/corridor -o out/det # per-bearing range table
      slitcli simulate-dwa --scenario paper -o out/dwa

    Frames: sensor x forward, y left, z up, origin on the floor below the left camera.
    """


def main() -> None:
    """Console-script entry point (also ``python -m slitcli``)."""
    cli.main()


# ---------------------------------------------------------------------------- rig
@cli.group("rig")
def rig_group() -> None:
    """Create, inspect, import and export rig files (DESIGN §12 rig schema)."""


@rig_group.command("init")
@click.argument("file", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--force", is_flag=True, help="Overwrite FILE if it exists.")
def rig_init(file: Path, force: bool) -> None:
    """Write the paper's default rig to FILE (YAML).

    The paper rig: 320x240 px, f = 250 px, baseline 0.088 m, camera 0.65 m above the
    floor tilted 20 deg down, horizontal laser sheet 0.60 m below the camera.

    Example: slitcli rig init rig.yaml
    """
    from slitcli.rig import paper_rig, save_rig

    if file.exists() and not force:
        raise SlitcliError(f"{file}: already exists; pass --force to overwrite it")
    save_rig(paper_rig(), file)
    click.echo(f"wrote {file}")


@rig_group.command("show")
@click.argument("file", required=False, type=click.Path(dir_okay=False, path_type=Path))
def rig_show(file: Path | None) -> None:
    """Print a rig (default: the paper rig) and the numbers derived from it.

    Derived: field of view (deg), disparity at 1 m and 3 m (px), depth change per
    disparity pixel at 1 m and 3 m (m/px), and the laser stripe row on the centre
    column for walls 0.6, 0.8 and 1.0 m ahead (px).

    Example: slitcli rig show rig.yaml
    """
    from slitcli.rig import describe_rig, load_rig, paper_rig

    rig = load_rig(file) if file is not None else paper_rig()
    click.echo(rig.to_yaml().rstrip())
    d = describe_rig(rig)
    click.echo("# derived")
    click.echo(f"field_of_view_deg: {d['hfov_deg']:.2f} x {d['vfov_deg']:.2f}  "
               "# horizontal x vertical")
    click.echo(f"disparity_px: {d['disparity_at_1m_px']:.2f} at 1 m, "
               f"{d['disparity_at_3m_px']:.2f} at 3 m")
    click.echo(f"depth_per_disparity_px_m: {d['depth_per_px_at_1m_m']:.4f} at 1 m, "
               f"{d['depth_per_px_at_3m_m']:.4f} at 3 m")
    rows = ", ".join(f"{d[f'stripe_row_wall_{r:.1f}m_px']:.2f} at {r:.1f} m"
                     for r in (0.6, 0.8, 1.0))
    click.echo(f"laser_stripe_row_px (centre column, wall ahead): {rows}")


# ---------------------------------------------------------------------------- render
@cli.command("render")
@click.argument("scene_file", metavar="SCENE.yaml",
                type=click.Path(dir_okay=False, path_type=Path))
@click.argument("out", type=click.Path(file_okay=False, path_type=Path))
@click.option("--frames", type=click.IntRange(min=1), default=None,
              help="Frames to render [default: the scene's robot.frames].")
@click.option("--seed", type=int, default=None,
              help="Replace the scene's seed (textures and sensor noise).")
@click.option("--rig", "rig_path", type=click.Path(dir_okay=False, path_type=Path),
              default=None, help="Rig file [default: the paper rig].")
@click.option("--overwrite", is_flag=True, help="Replace OUT if it exists.")
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
                                  overwrite=overwrite, on_frame=lambda i, n: bar.update(1))
    click.echo(f"rendered {summary['frames']} frames of '{scene.name}' to {out}: "
               f"{summary['stripe_columns']} stripe columns, "
               f"{summary['obstacle_bins']} obstacle bearing bins in the truth")


# ---------------------------------------------------------------------------- calibrate
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
@click.option("-o", "--output", "out", required=True,
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
    Prints the RMS reprojection error (px) overall and per view, and writes a rig whose
    `raw` holds K1 D1 K2 D2 R T R1 R2 P1 P2 and whose `left` / `baseline_m` are the
    rectified camera.

    Example: slitcli calibrate stereo calib/left calib/right --board 9x6 --square-m 0.025
    -o rig.yaml
    """
    from slitcli.calibrate.board import BoardSpec
    from slitcli.calibrate.stereo import StereoCalibrationParams, run_calibrate_stereo

    params = StereoCalibrationParams(board=BoardSpec.parse(board, square_m),
                                     min_views=min_views, k3=k3, alpha=alpha)
    result = run_calibrate_stereo(left_dir, right_dir, out, params, base_rig=base)
    for line in result.report_lines():
        click.echo(line)
    click.echo(f"wrote {out}")


@calibrate_group.command("laser")
@click.argument("images_dir", type=click.Path(path_type=Path))
@click.option("--rig", "rig_path", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="Stereo-calibrated rig; its laser plane is replaced.")
@click.option("--board", required=True, help=_BOARD_HELP)
@click.option("--square-m", type=float, required=True, help=_SQUARE_HELP)
@click.option("-o", "--output", "out", type=click.Path(dir_okay=False, path_type=Path),
              default=None, help="Rig file to write [default: update --rig in place].")
@click.option("--min-views", type=click.IntRange(min=2), default=2, show_default=True,
              help="Board poses with the stripe on the board required.")
def calibrate_laser_cmd(images_dir: Path, rig_path: Path, board: str, square_m: float,
                        out: Path | None, min_views: int) -> None:
    """Laser plane from left-camera views of a chessboard crossed by the laser stripe.

    IMAGES_DIR holds the left camera's images (or has a left/ subfolder), raw if the
    rig has a `raw` calibration. Use at least 3 board poses at different distances
    (0.6-1.2 m); a single pose is refused (its stripe is a line). Prints the plane
    (n . X = offset_m, metres, rectified left camera frame) and the residual std (mm).

    Example: slitcli calibrate laser --rig rig.yaml laser_views/ --board 9x6 --square-m 0.025
    """
    from slitcli.calibrate.board import BoardSpec
    from slitcli.calibrate.laser_plane import LaserPlaneParams, run_calibrate_laser

    params = LaserPlaneParams(board=BoardSpec.parse(board, square_m), min_views=min_views)
    result = run_calibrate_laser(rig_path, images_dir, params, out_rig=out)
    for line in result.report_lines():
        click.echo(line)
    click.echo(f"wrote {out or rig_path}")


@calibrate_group.command("mount")
@click.argument("seq", type=click.Path(path_type=Path))
@click.option("--rig", "rig_path", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="Stereo-calibrated rig; its mount height, tilt and roll are replaced.")
@click.option("-o", "--output", "out", type=click.Path(dir_okay=False, path_type=Path),
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
    images through the plane; `mount.forward_m` is kept.

    Example: slitcli calibrate mount --rig rig.yaml floor_seq/
    """
    from slitcli.calibrate.mount import MountParams, run_calibrate_mount

    params = MountParams(max_frames=frames, max_depth_m=max_depth_m)
    result = run_calibrate_mount(rig_path, seq, params, out_rig=out)
    for line in result.report_lines():
        click.echo(line)
    click.echo(f"wrote {out or rig_path}")


# ---------------------------------------------------------------------------- rig import/export
@rig_group.command("import")
@click.argument("files", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option("-o", "--output", "out", required=True,
              type=click.Path(dir_okay=False, path_type=Path), help="Rig file to write (YAML).")
@click.option("--format", "fmt", type=click.Choice(["auto", "ros", "opencv", "kalibr"]),
              default="auto", show_default=True, help="Format of FILES (auto: from content).")
@click.option("--base", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Rig whose mount, laser plane and range limits are kept "
                   "[default: the paper rig's].")
@click.option("--name", default=None, help="Rig name [default: the base rig's, or 'imported'].")
def rig_import(files: tuple[Path, ...], out: Path, fmt: str, base: Path | None,
               name: str | None) -> None:
    """Build a rig from ROS, OpenCV or Kalibr stereo calibration files.

    \b
    ros:    left.yaml right.yaml   camera_info (plumb_bob / rational_polynomial)
    opencv: intrinsics.yml extrinsics.yml   cv2.FileStorage, M1 D1 M2 D2 R T [R1 R2 P1 P2]
    kalibr: camchain.yaml   cam0/cam1 pinhole-radtan, cam1.T_cn_cnm1
    Other camera models (fisheye, omni, ...) are refused.

    Example: slitcli rig import camchain.yaml -o rig.yaml
    """
    from slitcli.calibrate.formats import run_rig_import

    rig = run_rig_import(list(files), out, fmt=fmt, base_rig=base, name=name)
    click.echo(f"rectified: fx {rig.left.fx_px:.3f} px, baseline_m {rig.baseline_m:.5f}, "
               f"{rig.image_size_px[0]}x{rig.image_size_px[1]} px")
    click.echo(f"wrote {out}")


@rig_group.command("export")
@click.argument("rig_file", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--format", "fmt", required=True, type=click.Choice(["ros", "opencv", "kalibr"]),
              help="ros: left.yaml + right.yaml; opencv: intrinsics.yml + extrinsics.yml; "
                   "kalibr: camchain.yaml.")
@click.option("-o", "--output", "out", required=True,
              type=click.Path(file_okay=False, path_type=Path), help="Folder to write into.")
def rig_export(rig_file: Path, fmt: str, out: Path) -> None:
    """Write a rig's stereo calibration as ROS, OpenCV or Kalibr files.

    A rig without `raw` is exported as an ideal pair (no distortion, no rotation).
    Kalibr's radtan model holds k1 k2 p1 p2 only: rigs with k3 are refused there.

    Example: slitcli rig export rig.yaml --format ros -o calib_ros/
    """
    from slitcli.calibrate.formats import run_rig_export

    for path in run_rig_export(rig_file, fmt, out):
        click.echo(f"wrote {path}")

# -------------------------------------------------------------------------- laser
def _laser_defaults() -> dict[str, Any]:
    from dataclasses import fields

    from slitcli.laser.params import LaserParams

    return {f.name: f.default for f in fields(LaserParams)}


_LD = _laser_defaults()


@cli.command("laser")
@click.argument("seq", type=click.Path(path_type=Path))
@click.option("-o", "--out", "out", required=True, type=click.Path(path_type=Path),
              help="Output folder; OUT/laser.csv is written (schema: docs/laser.md).")
@click.option("--rig", "rig_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Rig file (default: SEQ/rig.yaml, else the paper rig).")
@click.option("--overlay", is_flag=True,
              help="Also write OUT/laser_overlay/<frame>.png: stripe drawn, ranges annotated "
                   "(paper Fig. 4 style).")
@click.option("--min-th", type=float, default=_LD["min_th"], show_default=True,
              help="Eq. 2: minimum red chromaticity R = r/(r+g+b) (unitless; grey is 0.333).")
@click.option("--min-delta-th", type=float, default=_LD["min_delta_th"], show_default=True,
              help="Eq. 2: minimum R - max(G, B) (unitless).")
@click.option("--alpha", type=float, default=_LD["alpha"], show_default=True,
              help="Eq. 3 white-brightness rejection (paper 0.32): red contrast minus white "
                   "contrast must exceed alpha x red contrast (unitless).")
@click.option("--beta", type=float, default=_LD["beta"], show_default=True,
              help="Eq. 4 weight of the continuity term f(y) (paper 0.25).")
@click.option("--gamma", type=float, default=_LD["gamma"], show_default=True,
              help="Eq. 4 weight of the narrowness term g(I) (paper 0.25).")
@click.option("--max-width-px", type=float, default=_LD["max_width_px"], show_default=True,
              help="Widest stripe run (equivalent width = sum / peak of red contrast), px.")
@click.option("--background-window-px", type=int, default=_LD["background_window_px"],
              show_default=True,
              help="Vertical window of the background estimate (odd, > 2 x max width), px.")
@click.option("--min-peak-dn", type=float, default=_LD["min_peak_dn"], show_default=True,
              help="Minimum red contrast of the stripe above its background, DN.")
@click.option("--noise-k", type=float, default=_LD["noise_k"], show_default=True,
              help="Stripe contrast must also exceed noise-k x the estimated noise sigma.")
@click.option("--seed-fraction", type=float, default=_LD["seed_fraction"], show_default=True,
              help="Pixels join a candidate run above this fraction of the acceptance "
                   "contrast (unitless).")
@click.option("--saturation-dn", type=int, default=_LD["saturation_dn"], show_default=True,
              help="Red level from which a pixel counts as saturated, DN.")
@click.option("--continuity-px", type=float, default=_LD["continuity_px"], show_default=True,
              help="Scale of the continuity term f(y), px.")
@click.option("--max-jump-px", type=float, default=_LD["max_jump_px"], show_default=True,
              help="Largest row step between neighbouring columns of one segment, px.")
@click.option("--min-segment-cols", type=int, default=_LD["min_segment_cols"],
              show_default=True, help="Shorter stripe segments are dropped, columns.")
@click.option("--max-search-range-m", type=float, default=_LD["max_search_range_m"],
              show_default=True,
              help="Search only rows whose laser-plane range is at most this, m.")
def laser_cmd(seq: Path, out: Path, rig_path: Path | None, overlay: bool,
              **tuning: Any) -> None:
    """Extract the red laser stripe (paper Eqs. 1-4) and triangulate it (Eqs. 5-7).

    Reads the left images of the sequence SEQ and writes OUT/laser.csv: one row per
    frame and image column with a stripe (frame, u_px, v_px, strength [DN], x_m,
    y_m, range_m, bearing_deg in the sensor frame, in_band = 1 inside the rig's
    laser band). Points outside the band stay in the table, flagged in_band = 0.

    Example: slitcli laser out/corridor -o out/laser --overlay
    """
    from slitcli.laser.batch import run_laser
    from slitcli.laser.params import LaserParams

    params = LaserParams(**tuning)
    path = run_laser(seq, out, rig_path=rig_path, params=params, overlay=overlay)
    click.echo(f"wrote {path}")


# ---------------------------------------------------------------------------- dwa
def _floats(n: int | None, what: str):
    """A click callback parsing comma-separated numbers (exactly ``n`` of them if given)."""

    def parse(ctx: click.Context, param: click.Parameter, value: str | None) -> Any:
        if value is None:
            return None
        try:
            nums = tuple(float(x) for x in value.split(","))
        except ValueError:
            raise click.BadParameter(f"{value!r} is not {what}") from None
        if (n is not None and len(nums) != n) or not all(x == x and abs(x) != float("inf")
                                                          for x in nums):
            raise click.BadParameter(f"{value!r} is not {what}")
        return nums

    return parse


def _dwa_options(f: Any) -> Any:
    """The planner's parameters (slitcli.dwa.DwaParams), shared by dwa and simulate-dwa."""
    from slitcli.dwa import DwaParams

    d = DwaParams()
    opts = [
        ("--v-max-mps", d.v_max_mps, "Speed limit, m/s (paper: 0.2)."),
        ("--w-max-dps", d.w_max_dps, "Turn-rate limit, deg/s (paper: 7.5)."),
        ("--acc-mps2", d.acc_mps2, "Translational acceleration limit, m/s^2 (paper: 0.2)."),
        ("--ang-acc-dps2", d.ang_acc_dps2, "Angular acceleration limit, deg/s^2."),
        ("--dt-s", d.dt_s, "Control period T, s (paper: 0.2)."),
        ("--heading-clamp-deg", d.heading_clamp_deg, "Clamp of the goal bearing, deg."),
        ("--v-res-mps", d.v_res_mps, "Window sampling of v, m/s."),
        ("--w-res-dps", d.w_res_dps, "Window sampling of w, deg/s."),
        ("--heading-horizon-s", d.heading_horizon_s, "Horizon T_h of the heading term, s."),
        ("--goal-close-m", d.goal_close_m, "Eq. 13 switch and arrival radius, m."),
        ("--d-max-m", d.d_max_m, "Cap of D_collision, m."),
        ("--alpha", d.alpha, "Weight of the heading term (Eq. 12)."),
        ("--beta", d.beta, "Weight of the clearance term (Eq. 12)."),
        ("--gamma", d.gamma, "Weight of the velocity term (Eqs. 12-13)."),
    ]
    for name, default, text in reversed(opts):
        f = click.option(name, type=float, default=default, show_default=True, help=text)(f)
    f = click.option("--discrete-braking/--no-discrete-braking", default=d.discrete_braking,
                     show_default=True,
                     help="Admissibility counts the v*T/2 driven while a command is held "
                          "(off: the paper's v <= sqrt(2 D acc)).")(f)
    f = click.option("--turn-circle-close/--no-turn-circle-close", default=d.turn_circle_close,
                     show_default=True,
                     help="Eq. 13 also brakes while the goal is inside the current turning "
                          "circle (off: only within --goal-close-m).")(f)
    return f


def _dwa_params(kw: dict[str, Any], footprint_radius_m: float | None = None) -> Any:
    from slitcli.dwa import DwaParams

    names = ("v_max_mps", "w_max_dps", "acc_mps2", "ang_acc_dps2", "dt_s", "heading_clamp_deg",
             "v_res_mps", "w_res_dps", "heading_horizon_s", "goal_close_m", "d_max_m", "alpha",
             "beta", "gamma", "turn_circle_close", "discrete_braking")
    extra = {} if footprint_radius_m is None else {"footprint_radius_m": footprint_radius_m}
    return DwaParams(**{k: kw.pop(k) for k in names}, **extra)


@cli.command("dwa")
@click.argument("ranges", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--goal", required=True, metavar="X,Y",
              callback=_floats(2, "two numbers X,Y in metres"),
              help="Goal X,Y in metres, in the robot frame at the first frame "
                   "(x forward, y left).")
@click.option("-o", "--out", "out", required=True,
              type=click.Path(dir_okay=False, path_type=Path), help="CMDS.csv to write.")
@click.option("--rig", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Rig file (for mount.forward_m). Default: the paper rig.")
@click.option("--range-column", default="fused_range_m", show_default=True,
              type=click.Choice(["fused_range_m", "laser_range_m", "stereo_range_m"]),
              help="Which range of the table the planner uses.")
@click.option("--footprint-radius-m", type=float, default=0.3, show_default=True,
              help="Robot radius plus safety margin, m.")
@click.option("--memory-s", type=float, default=10.0, show_default=True,
              help="Remember obstacle points this long, s (0 = off).")
@click.option("--memory-cell-m", type=float, default=0.05, show_default=True,
              help="One remembered point per grid cell of this size, m.")
@_dwa_options
def dwa_cmd(ranges: Path, goal: tuple[float, float], out: Path, rig: Path | None,
            range_column: str, footprint_radius_m: float, memory_s: float, memory_cell_m: float,
            **kw: Any) -> None:
    """Offline modified DWA (Eqs. 12-13) over a recorded range table.

    RANGES is a range table written by `slitcli detect` (columns frame, time_s,
    bearing_deg, ..., fused_range_m; empty = no return). For every frame the planner
    writes the command (v_mps, w_dps) it would have sent. A range table has no
    odometry, so the robot is ASSUMED TO HAVE MOVED EXACTLY AS COMMANDED between
    frames; poses and the goal are in the robot frame at the first frame. Output
    columns: docs/dwa.md.

    Example: slitcli dwa out/det/ranges.csv --goal 4,0.5 -o out/cmds.csv
    """
    from slitcli.dwa_table import dwa_offline
    from slitcli.rig import load_rig, paper_rig

    params = _dwa_params(kw, footprint_radius_m)
    the_rig = load_rig(rig) if rig is not None else paper_rig()
    cmds = dwa_offline(ranges, goal, out, params, range_column=range_column,
                       forward_m=the_rig.mount.forward_m, memory_s=memory_s,
                       memory_cell_m=memory_cell_m)
    counts = cmds["status"].value_counts().to_dict()
    click.echo(f"wrote {out}: {len(cmds)} frames ("
               + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())) + ")")


@cli.command("simulate-dwa")
@click.argument("world", required=False, type=click.Path(dir_okay=False, path_type=Path))
@click.option("-o", "--out", "out", required=True,
              type=click.Path(file_okay=False, path_type=Path), help="Output folder.")
@click.option("--scenario", type=click.Choice(["paper", "random"]), default=None,
              help="Built-in worlds instead of WORLD: 'paper' (box in the way, sensing ranges "
                   "0.6,1,1.5,2 m) or 'random' (--worlds seeded worlds, 3 m).")
@click.option("--sensing", type=click.Choice(["perfect"]), default="perfect", show_default=True,
              help="Sensing mode: 'perfect' = true ranges per 1-deg bearing bin over the "
                   "camera's field of view, cut at the sensing range.")
@click.option("--sensing-range", "sensing_range", metavar="R[,R...]",
              callback=_floats(None, "comma-separated ranges in metres"), default=None,
              help="Sensing range(s), m, one run each, e.g. 0.6,1,1.5,2. Default: the "
                   "scenario's, 3 for a WORLD file.")
@click.option("--worlds", type=int, default=100, show_default=True,
              help="Number of random worlds (--scenario random).")
@click.option("--seed", type=int, default=0, show_default=True,
              help="Seed of the first random world.")
@click.option("--start", metavar="X,Y,YAW_DEG", default=None,
              callback=_floats(3, "three numbers X,Y,YAW_DEG"),
              help="Override the world's start: X,Y in m, heading in deg.")
@click.option("--goal", metavar="X,Y", callback=_floats(2, "two numbers X,Y in metres"),
              default=None,
              help="Override the world's goal X,Y, m.")
@click.option("--rig", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Rig file (field of view, mount.forward_m). Default: the paper rig.")
@click.option("--bin-deg", type=float, default=1.0, show_default=True,
              help="Bearing bin width of the sensed range table, deg.")
@click.option("--safety-margin-m", type=float, default=0.05, show_default=True,
              help="Planner footprint = robot radius + this, m.")
@click.option("--memory-s", type=float, default=10.0, show_default=True,
              help="Remember obstacle points this long, s (0 = off).")
@click.option("--memory-cell-m", type=float, default=0.05, show_default=True,
              help="One remembered point per grid cell of this size, m.")
@click.option("--max-time-s", type=float, default=300.0, show_default=True,
              help="Give up after this simulated time, s.")
@click.option("--stuck-timeout-s", type=float, default=30.0, show_default=True,
              help="Report 'stuck' when the goal distance has not improved by 5 cm for "
                   "this long, s.")
@click.option("--save-ranges", is_flag=True,
              help="Also write OUT/ranges_<case>.csv, the sensed range table of each run "
                   "(replay it with slitcli dwa).")
@click.option("--overwrite", is_flag=True, help="Replace OUT if it exists.")
@_dwa_options
def simulate_dwa_cmd(world: Path | None, out: Path, scenario: str | None, sensing: str,
                     sensing_range: tuple[float, ...] | None, worlds: int, seed: int,
                     start: tuple[float, float, float] | None,
                     goal: tuple[float, float] | None, rig: Path | None, bin_deg: float,
                     safety_margin_m: float, memory_s: float, memory_cell_m: float,
                     max_time_s: float, stuck_timeout_s: float, save_ranges: bool,
                     overwrite: bool, **kw: Any) -> None:
    """Closed-loop modified DWA: sense -> plan -> move, per world and sensing range.

    WORLD is a scene file (docs/scene.md) whose robot.start and goal_xy_m are the
    start and goal; or use --scenario. Writes OUT/trajectory_<case>.csv,
    OUT/metrics.csv, the world(s) as YAML and OUT/params.yaml (docs/dwa.md).

    \b
    Examples:
      slitcli simulate-dwa --scenario paper -o out/dwa
      slitcli simulate-dwa --scenario random --worlds 100 -o out/random
      slitcli simulate-dwa my_world.yaml --sensing-range 1,3 -o out/mine
    """
    from slitcli.rig import load_rig, paper_rig
    from slitcli.sim.loop import SimParams, simulate_dwa

    params = _dwa_params(kw)
    sim = SimParams(safety_margin_m=safety_margin_m, memory_s=memory_s,
                    memory_cell_m=memory_cell_m, max_time_s=max_time_s,
                    stuck_timeout_s=stuck_timeout_s)
    the_rig = load_rig(rig) if rig is not None else paper_rig()
    metrics = simulate_dwa(out, the_rig, params, sim, sensing=sensing, world_path=world,
                           scenario=scenario, sensing_ranges_m=sensing_range, worlds=worlds,
                           seed=seed, start=start, goal_xy_m=goal, bin_deg=bin_deg,
                           overwrite=overwrite, save_ranges=save_ranges)
    n = len(metrics)
    reached = int(metrics["reached_goal"].sum())
    collided = int(metrics["collided"].sum())
    click.echo(f"wrote {out}: {n} runs, reached {reached}, collided {collided}, "
               f"stuck {int((metrics['outcome'] == 'stuck').sum())}, "
               f"timeout {int((metrics['outcome'] == 'timeout').sum())}")

# ---------------------------------------------------------------------------- stereo
def _parse_window(text: str) -> tuple[int, int]:
    """``9`` -> (9, 9); ``9x7`` -> (9, 7) (width x height, pixels)."""
    parts = text.lower().split("x")
    try:
        if len(parts) == 1:
            w = h = int(parts[0])
        elif len(parts) == 2:
            w, h = int(parts[0]), int(parts[1])
        else:
            raise ValueError
    except ValueError:
        raise SlitcliError(f"--window {text!r} is not a size; give W or WxH in pixels, odd, "
                           "e.g. --window 9 or --window 9x7") from None
    return w, h


@cli.command("stereo")
@click.argument("seq", type=click.Path(file_okay=False, path_type=Path))
@click.option("-o", "--out", required=True, type=click.Path(file_okay=False, path_type=Path),
              help="Output folder for disparity/, distance/, mask/ and stereo_ranges.csv.")
@click.option("--rig", "rig_path", type=click.Path(dir_okay=False, path_type=Path),
              default=None, help="Rig file [default: SEQ/rig.yaml, else the paper rig].")
@click.option("--matcher", type=click.Choice(["nssd", "bm", "sgbm"]), default="nssd",
              show_default=True, help="nssd = the paper's normalised SSD (Eq. 10); bm, sgbm "
              "= OpenCV's StereoBM / StereoSGBM.")
@click.option("--num-disparities", type=int, default=48, show_default=True,
              help="Disparities searched, px (48 px: 0.46 m and beyond for the paper rig).")
@click.option("--min-disparity", type=int, default=0, show_default=True,
              help="Smallest disparity searched, px.")
@click.option("--window", "window", default="9", show_default=True,
              help="Correlation window W or WxH, odd, px (the (2m+1)x(2n+1) of Eq. 10).")
@click.option("--prefilter", type=click.Choice(["none", "mean", "xsobel", "log"]),
              default="mean", show_default=True, help="Image filter before matching.")
@click.option("--texture-min", type=float, default=1.0, show_default=True,
              help="Minimum window standard deviation of the filtered image, DN (0 = off).")
@click.option("--uniqueness", type=float, default=0.15, show_default=True,
              help="Uniqueness ratio: other disparities must cost (1 + ratio) x more (0 = off).")
@click.option("--lr-max-diff", type=int, default=1, show_default=True,
              help="Left-right check tolerance, px (negative = off).")
@click.option("--support-min", type=float, default=0.4, show_default=True,
              help="Minimum 3x3 zero-mean correlation at the chosen disparity (0 = off).")
@click.option("--speckle-window", type=int, default=100, show_default=True,
              help="Remove disparity blobs up to this many pixels (0 = off).")
@click.option("--speckle-range", type=float, default=2.0, show_default=True,
              help="Disparity step that separates blobs, px.")
@click.option("--subpixel", type=click.Choice(["parabola", "none"]), default="parabola",
              show_default=True, help="Subpixel refinement of the winning disparity.")
@click.option("--floor-margin", type=float, default=0.05, show_default=True,
              help="Points lower than this above the floor are floor, m.")
@click.option("--robot-height", type=float, default=0.8, show_default=True,
              help="Points higher than this are above the robot (not obstacles), m.")
@click.option("--max-range", type=float, default=None,
              help="Obstacles farther than this are ignored, m [default: the rig's "
              "stereo.max_range_m].")
@click.option("--overwrite", is_flag=True, help="Replace results made with other settings.")
def stereo_cmd(seq: Path, out: Path, rig_path: Path | None, matcher: str,
               num_disparities: int, min_disparity: int, window: str, prefilter: str,
               texture_min: float, uniqueness: float, lr_max_diff: int, support_min: float,
               speckle_window: int, speckle_range: float, subpixel: str, floor_margin: float,
               robot_height: float, max_range: float | None, overwrite: bool) -> None:
    """Disparity, distance and obstacle-mask images of a stereo sequence (paper Eqs. 8-10).

    Writes OUT/disparity/NAME.png (uint16, disparity x 256, 0 = invalid),
    OUT/distance/NAME.png (uint16, depth in mm, 0 = invalid), OUT/mask/NAME.png (uint8,
    255 = obstacle) per input frame and OUT/stereo_ranges.csv (nearest obstacle per
    1-degree bearing bin, m). A re-run skips finished frames. See docs/stereo.md.

    Example: slitcli stereo out/corridor -o out/corridor-stereo --window 9x7
    """
    from slitcli.io.progress import progress_bar
    from slitcli.stereo.matcher import MatcherParams
    from slitcli.stereo.obstacles import ObstacleParams
    from slitcli.stereo.pipeline import StereoParams
    from slitcli.stereo.run import run_stereo

    w, h = _parse_window(window)
    params = StereoParams(
        matcher=MatcherParams(matcher, num_disparities, min_disparity, w, h,
                              prefilter=prefilter, texture_min_dn=texture_min,
                              uniqueness_ratio=uniqueness, lr_max_diff_px=lr_max_diff,
                              support_min_zncc=support_min,
                              speckle_window_px=speckle_window,
                              speckle_range_px=speckle_range, subpixel=subpixel),
        obstacles=ObstacleParams(floor_margin_m=floor_margin, robot_height_m=robot_height,
                                 max_range_m=max_range))
    bar = progress_bar(0, "stereo")
    with bar:
        def tick(done: int, total: int) -> None:
            bar.total = total
            bar.update(done - bar.n)

        summary = run_stereo(seq, out, rig_path=rig_path, params=params,
                             overwrite=overwrite, on_frame=tick)
    click.echo(f"stereo: {summary['frames']} frames to {out} ({summary['computed']} computed, "
               f"{summary['skipped']} already done); mean valid disparity fraction "
               f"{summary['valid_fraction']:.3f}")
