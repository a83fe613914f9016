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
