"""Commands ``rig init``, ``rig show``, ``rig import``, ``rig export``."""

from __future__ import annotations

from pathlib import Path

import click

from slitcli.cli.main import cli
from slitcli.errors import SlitcliError


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
@click.option("--overwrite", is_flag=True, help="Replace the output rig file if it exists.")
def rig_import(files: tuple[Path, ...], out: Path, fmt: str, base: Path | None,
               name: str | None, overwrite: bool) -> None:
    """Build a rig from ROS, OpenCV or Kalibr stereo calibration files.

    \b
    ros:    left.yaml right.yaml   camera_info (plumb_bob / rational_polynomial)
    opencv: intrinsics.yml extrinsics.yml   cv2.FileStorage, M1 D1 M2 D2 R T [R1 R2 P1 P2]
    kalibr: camchain.yaml   cam0/cam1 pinhole-radtan, cam1.T_cn_cnm1
    Other camera models (fisheye, omni, ...) are refused.

    Example: slitcli rig import camchain.yaml -o rig.yaml
    """
    from slitcli.calibrate.formats import run_rig_import

    rig = run_rig_import(list(files), out, fmt=fmt, base_rig=base, name=name,
                         overwrite=overwrite)
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

