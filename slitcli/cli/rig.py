"""Commands ``rig init``, ``rig show``, ``rig import``, ``rig export``."""

from __future__ import annotations

from pathlib import Path

import click

from slitcli.cli.main import cli
from slitcli.errors import SlitcliError


@cli.group("rig")
def rig_group() -> None:
    """Create, inspect, edit, import and export rig files (docs/rig.md).

    \b
    Example:
      slitcli rig init rig.yaml
      slitcli rig set rig.yaml --mount-height-m 0.42 --tilt-deg 12
      slitcli rig show rig.yaml
    """


def _size_wh(text: str | None) -> tuple[int, int] | None:
    if text is None:
        return None
    parts = text.lower().replace("x", ",").split(",")
    try:
        w, h = (int(p) for p in parts)
    except ValueError:
        raise click.BadParameter(f"'{text}' is not W,H (whole pixels, e.g. 640,480)",
                                 param_hint="--image-size") from None
    return w, h


# library parameters of slitcli.rig_tools -> this group's options
_RIG_FLAGS = {"height_m": "--mount-height-m", "tilt_deg": "--tilt-deg",
              "roll_deg": "--roll-deg", "forward_m": "--forward-m",
              "laser_height_m": "--laser-height-m", "image_size_px": "--image-size",
              "fx_px": "--fx-px", "baseline_m": "--baseline-m"}


def _flagged(e: SlitcliError) -> SlitcliError:
    """The error with its quoted library parameters named as this group's options."""
    text = str(e)
    for name in e.params:
        text = text.replace(f"`{name}`", _RIG_FLAGS.get(name, name))
    return SlitcliError(text)


@rig_group.command("init")
@click.argument("file", required=False, type=click.Path(dir_okay=False, path_type=Path))
@click.option("-o", "--out", "out_opt", type=click.Path(dir_okay=False, path_type=Path),
              default=None, help="Rig file to write (or give it as FILE) [default: FILE].")
@click.option("--force", is_flag=True, help="Overwrite FILE if it exists.")
@click.option("--image-size", default=None, metavar="W,H",
              help="Factory calibration: image width and height of the rectified images, px "
              "[default: the paper rig's 320,240].")
@click.option("--fx-px", type=float, default=None,
              help="Factory calibration: focal length of the rectified left camera, px "
              "[default: the paper rig's 250].")
@click.option("--fy-px", type=float, default=None, help="Vertical focal length, px "
              "[default: --fx-px].")
@click.option("--cx-px", type=float, default=None, help="Principal point column, px "
              "[default: (W-1)/2].")
@click.option("--cy-px", type=float, default=None, help="Principal point row, px "
              "[default: (H-1)/2].")
@click.option("--baseline-m", type=float, default=None,
              help="Factory calibration: distance between the optical centres, metres "
              "[default: the paper rig's 0.088].")
def rig_init(file: Path | None, out_opt: Path | None, force: bool, image_size: str | None,
             fx_px: float | None, fy_px: float | None, cx_px: float | None,
             cy_px: float | None, baseline_m: float | None) -> None:
    """Write a rig file: the paper's rig, or a camera with a factory calibration.

    The paper rig: 320x240 px, f = 250 px, baseline 0.088 m, camera 0.65 m above the
    floor tilted 20 deg down, horizontal laser sheet 0.60 m below the camera.

    With --image-size, --fx-px and --baseline-m (a stereo camera that delivers rectified
    images, e.g. an OAK-D or a ZED with its factory calibration) the rig describes that
    camera; mount and laser sheet are the paper's placeholders (the sheet kept where it
    is in the world): set them with `slitcli rig set` or `slitcli calibrate mount/laser`.

    \b
    Examples:
      slitcli rig init rig.yaml
      slitcli rig init -o oak.yaml --image-size 640,400 --fx-px 402.5 --baseline-m 0.075
    """
    from slitcli.cli.config import pick_out
    from slitcli.io.atomic import write_text_atomic
    from slitcli.rig import paper_rig
    from slitcli.rig_tools import factory_rig

    file = pick_out(file, out_opt, "FILE")
    if file.exists() and not force:
        raise SlitcliError(f"{file}: already exists; pass --force to overwrite it")
    factory = (image_size, fx_px, baseline_m)
    if any(v is not None for v in (*factory, fy_px, cx_px, cy_px)):
        if any(v is None for v in factory):
            raise click.UsageError("a factory rig needs --image-size, --fx-px and --baseline-m")
        size = _size_wh(image_size)
        assert size is not None and fx_px is not None and baseline_m is not None
        try:
            rig = factory_rig(size, fx_px, baseline_m, fy_px=fy_px, cx_px=cx_px, cy_px=cy_px,
                              name=file.stem)
        except SlitcliError as e:
            raise _flagged(e) from None
        write_text_atomic(file, PLACEHOLDER_COMMENT + rig.to_yaml())
        click.echo("slitcli: note: mount and laser plane are the paper rig's placeholders; "
                   "set them with `slitcli rig set` or `slitcli calibrate mount/laser`",
                   err=True)
    else:
        write_text_atomic(file, paper_rig().to_yaml())
    click.echo(f"wrote {file}")


PLACEHOLDER_COMMENT = (
    "# mount and laser were NOT calibrated: they are placeholders (the paper rig's mount,\n"
    "# or the --base rig's). Measure them: `slitcli calibrate mount`, `slitcli calibrate\n"
    "# laser`, or `slitcli rig set RIG --mount-height-m H --tilt-deg T --laser-height-m Z`.\n")


@rig_group.command("set")
@click.argument("rig_file", type=click.Path(dir_okay=False, path_type=Path))
@click.option("-o", "--out", "out", type=click.Path(dir_okay=False, path_type=Path),
              default=None, help="Rig file to write [default: update RIG_FILE in place].")
@click.option("--mount-height-m", type=float, default=None,
              help="Camera optical centre above the floor, metres [default: unchanged].")
@click.option("--tilt-deg", type=float, default=None,
              help="Pitch of the optical axis below horizontal, degrees [default: unchanged].")
@click.option("--roll-deg", type=float, default=None, help="Roll about the optical axis, deg "
              "[default: unchanged].")
@click.option("--forward-m", type=float, default=None,
              help="Camera ahead of the robot's rotation centre, metres [default: unchanged].")
@click.option("--laser-height-m", type=float, default=None,
              help="Make the laser sheet horizontal at this height above the floor, metres "
              "[default: keep the sheet where it is on the robot].")
def rig_set(rig_file: Path, out: Path | None, mount_height_m: float | None,
            tilt_deg: float | None, roll_deg: float | None, forward_m: float | None,
            laser_height_m: float | None) -> None:
    """Edit the mount or the laser height; the laser sheet stays where it is in the world.

    The rig stores the laser plane in the camera frame, so editing `mount` by hand
    would move the sheet with the camera. This command re-expresses the sheet for the
    new mount (it is fixed to the robot); --laser-height-m replaces it by a horizontal
    sheet at that height. Values not given are kept. Prints the old and new mount and
    the laser sheet height.

    \b
    Examples:
      slitcli rig set rig.yaml --mount-height-m 0.42 --tilt-deg 18.5
      slitcli rig set rig.yaml --laser-height-m 0.05 -o rig_low_laser.yaml
    """
    from slitcli.rig import load_rig
    from slitcli.rig_tools import laser_height_m as sheet_height
    from slitcli.rig_tools import run_rig_set

    before = load_rig(rig_file)
    try:
        rig = run_rig_set(rig_file, out, height_m=mount_height_m, tilt_deg=tilt_deg,
                          roll_deg=roll_deg, forward_m=forward_m,
                          laser_height_m=laser_height_m)
    except SlitcliError as e:
        raise _flagged(e) from None
    for tag, r in (("before", before), ("after", rig)):
        m = r.mount
        click.echo(f"{tag}: height_m {m.height_m:.4f}, tilt_deg {m.tilt_deg:.3f}, roll_deg "
                   f"{m.roll_deg:.3f}, forward_m {m.forward_m:g}; laser sheet "
                   f"{sheet_height(r):.4f} m above the floor")
    click.echo(f"wrote {out or rig_file}")


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
    from slitcli.rig_tools import rig_warnings

    for warning in rig_warnings(rig):
        click.echo(f"# WARNING: {warning}")



# ---------------------------------------------------------------------------- rig import/export
@rig_group.command("import")
@click.argument("files", nargs=-1, required=True, type=click.Path(path_type=Path))
@click.option("-o", "--out", "--output", "out", required=True,
              type=click.Path(dir_okay=False, path_type=Path), help="Rig file to write (YAML).")
@click.option("--format", "fmt", type=click.Choice(["auto", "ros", "opencv", "kalibr"]),
              default="auto", show_default=True, help="Format of FILES (auto: from content).")
@click.option("--base", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Rig whose mount, laser plane and range limits are kept "
                   "[default: the paper rig's].")
@click.option("--name", default=None, help="Rig name [default: the base rig's, or 'imported'].")
@click.option("--image-size", default=None, metavar="W,H",
              help="Raw image size in pixels, for files that do not give it (OpenCV files "
              "without image_width/image_height, camchains without resolution) [default: "
              "read from the files].")
@click.option("--overwrite", is_flag=True, help="Replace the output rig file if it exists.")
def rig_import(files: tuple[Path, ...], out: Path, fmt: str, base: Path | None,
               name: str | None, image_size: str | None, overwrite: bool) -> None:
    """Build a rig from ROS, OpenCV or Kalibr stereo calibration files.

    \b
    ros:    left.yaml right.yaml   camera_info (plumb_bob / rational_polynomial /
            equidistant)
    opencv: intrinsics.yml extrinsics.yml   cv2.FileStorage (%YAML:1.0 or YAML 1.2),
            M1 D1 M2 D2 R T [R1 R2 P1 P2]
    kalibr: camchain.yaml   cam0/cam1 pinhole-radtan or pinhole-equidistant; cam1 pose
            from T_cn_cnm1, else T_cam_imu or T_imu_cam of both cameras
    Other camera models (omni, eucm, ds, fov) are refused.

    Example: slitcli rig import camchain.yaml -o rig.yaml
    """
    from slitcli.calibrate.formats import run_rig_import

    rig = run_rig_import(list(files), out, fmt=fmt, base_rig=base, name=name,
                         image_size_px=_size_wh(image_size), overwrite=overwrite)
    click.echo("slitcli: note: mount and laser plane are placeholders (the base rig's); set "
               "them with `slitcli rig set` or `slitcli calibrate mount/laser`", err=True)
    click.echo(f"rectified: fx {rig.left.fx_px:.3f} px, baseline_m {rig.baseline_m:.5f}, "
               f"{rig.image_size_px[0]}x{rig.image_size_px[1]} px")
    click.echo(f"wrote {out}")


@rig_group.command("export")
@click.argument("rig_file", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--format", "fmt", required=True, type=click.Choice(["ros", "opencv", "kalibr"]),
              help="ros: left.yaml + right.yaml; opencv: intrinsics.yml + extrinsics.yml; "
                   "kalibr: camchain.yaml.")
@click.option("-o", "--out", "--output", "out", required=True,
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

