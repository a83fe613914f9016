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
    """Console-script entry point."""
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
@click.option("--support-min", type=float, default=0.45, show_default=True,
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
