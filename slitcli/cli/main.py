"""The ``slitcli`` command group, its error funnel and the options commands share.

Every command calls one library function. The library's own :class:`SlitcliError`
becomes exit status 2 with one line on stderr; click's usage errors too; any other
exception is an internal error (exit 1, one line; the traceback with ``--debug``).
"""

from __future__ import annotations

import contextlib
import signal
import sys
import traceback
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import click

from slitcli import __version__
from slitcli.errors import SlitcliError
from slitcli.io.progress import Terminated, on_signal, reset_signals

# Library parameter names (SlitcliError.param) and the options that set them. One
# table for every command: a parameter keeps its meaning, so its option keeps its name.
PARAM_FLAGS: dict[str, str] = {
    "bin_deg": "--bin-deg", "rig_path": "--rig", "rig": "--rig", "jobs": "--jobs",
    "overwrite": "--overwrite", "max_dt_s": "--max-dt", "left_topic": "--left-topic",
    "right_topic": "--right-topic", "fusion_mode": "--fusion",
    "laser_depth_check": "--laser-depth-check",
    "stereo_sheet_check": "--stereo-sheet-check",
    "range_column": "--range-column", "memory_s": "--memory-s", "period_s": "--period-s",
    "memory_cell_m": "--memory-cell-m", "goal_xy_m": "--goal",
    "sensing_range_m": "--sensing-range",
    "matcher": "--matcher", "prefilter": "--prefilter", "subpixel": "--subpixel",
    "num_disparities": "--num-disparities", "min_disparity": "--min-disparity",
    "window_w_px": "--window", "window_h_px": "--window", "window": "--window",
    "texture_min_dn": "--texture-min", "uniqueness_ratio": "--uniqueness",
    "lr_max_diff_px": "--lr-max-diff", "support_min_zncc": "--support-min",
    "support_cross_min_zncc": "--support-cross-min",
    "speckle_window_px": "--speckle-window", "speckle_range_px": "--speckle-range",
    "floor_margin_m": "--floor-margin", "robot_height_m": "--robot-height",
    "max_range_m": "--max-range", "frames": "--frames", "seed": "--seed",
    "v_max_mps": "--v-max-mps",
    "w_max_dps": "--w-max-dps",
    "acc_mps2": "--acc-mps2",
    "ang_acc_dps2": "--ang-acc-dps2",
    "dt_s": "--dt-s",
    "heading_clamp_deg": "--heading-clamp-deg",
    "v_res_mps": "--v-res-mps",
    "w_res_dps": "--w-res-dps",
    "heading_horizon_s": "--heading-horizon-s",
    "goal_close_m": "--goal-close-m",
    "footprint_radius_m": "--footprint-radius-m",
    "d_max_m": "--d-max-m",
    "alpha": "--alpha",
    "beta": "--beta",
    "gamma": "--gamma",
    "turn_circle_close": "--turn-circle-close/--no-turn-circle-close",
    "discrete_braking": "--discrete-braking/--no-discrete-braking",
    "predict_horizon_s": "--predict-horizon-s",
    "predict_step_s": "--predict-step-s",
    "moving_buffer_m": "--moving-buffer-m",
    "on_bad": "--on-bad-frame", "on_bad_frame": "--on-bad-frame",
    "cluster": "--cluster", "chunk_frames": "--chunk-frames", "inputs": "--inputs",
    "sources": "SEQ|BAG",
    "search": "--search", "max_search_range_m": "--max-search-range-m",
    "mode": "--fusion", "fps": "--fps", "dpi": "--dpi", "save_images": "--save-images",
    "frame_id": "--frame-id", "camera_frame_id": "--camera-frame-id",
    "board": "--board", "square_m": "--square-m", "image_size_px": "--image-size",
    "fmt": "--format", "source": "--source", "world_path": "WORLD",
    "scenario": "--scenario", "start": "--start", "sensing": "--sensing",
    "sensing_ranges_m": "--sensing-range", "worlds": "--worlds",
    "max_time_s": "--max-time-s", "memory": "--memory", "safety_margin_m": "--safety-margin-m",
    "stuck_timeout_s": "--stuck-timeout-s", "stuck_new_ground_m": "--stuck-new-ground-m",
    "recovery_after_s": "--recovery-after-s", "recovery_back_m": "--recovery-back-m",
    "min_disparity_px": "--min-disparity", "bin_width_deg": "--bin-deg", "base_rig": "--base",
    "aggregation": "--aggregation",
    # the laser's tuning (LaserParams; alpha, beta, gamma, search and max_search_range_m
    # above): each field's option is its name with dashes
    "method": "--method", "min_th": "--min-th", "min_delta_th": "--min-delta-th",
    "max_width_share": "--max-width-share", "seed_z": "--seed-z", "min_z": "--min-z",
    "weak_z": "--weak-z", "shape_error": "--shape-error", "max_chi2": "--max-chi2",
    "colour_error": "--colour-error",
    "max_hue_deg": "--max-hue-deg",
    "min_texture_ratio": "--min-texture-ratio", "max_texture_ratio": "--max-texture-ratio",
    "noise_floor_dn": "--noise-floor-dn", "saturation_dn": "--saturation-dn",
    "continuity_px": "--continuity-px", "max_jump_px": "--max-jump-px",
    "min_segment_share": "--min-segment-share", "min_stripe_share": "--min-stripe-share",
    "sheet_sigma_mm": "--sheet-sigma-mm", "sheet_tolerance": "--sheet-tolerance",
    "chroma_smoothness_max": "--chroma-smoothness-max", "luma_rows": "--luma-rows",
    "luma_min_z": "--luma-min-z", "luma_widths": "--luma-widths", "strong_share": "--strong-share",
    "gap_z_share": "--gap-z-share", "width_spread": "--width-spread",
    "laser_share_z": "--laser-share-z", "own_z": "--own-z", "choice_rounds": "--choice-rounds",
    "surface_step": "--surface-step", "surface_min_dn": "--surface-min-dn",
    "one_crossing": "--one-crossing",
}


def to_flags(text: str, names: tuple[str, ...] | None = None) -> str:
    """``text`` with the library parameters it quotes in backticks (`bin_deg`) replaced
    by CLI flags (``names``: only these; default every known parameter). A parameter the
    command line has no option for keeps its library name, unquoted."""
    for name in PARAM_FLAGS if names is None else names:
        text = text.replace(f"`{name}`", PARAM_FLAGS.get(name, name))
    return text


def user_message(e: SlitcliError) -> str:
    """The error's message with its library parameter names replaced by CLI flags."""
    return to_flags(str(e), e.params)


def echo_notes(notes: tuple[str, ...]) -> None:
    """A run's notes on stderr, one line each, in the command line's terms."""
    for note in notes:
        click.echo(f"slitcli: note: {to_flags(note)}", err=True)


@contextlib.contextmanager
def _process_settings() -> Iterator[None]:
    """For one command: SIGINT / SIGTERM handled between frames, numpy's floating-point
    warnings hidden.

    Signals: :func:`slitcli.io.progress.on_signal` records them and raises
    ``KeyboardInterrupt`` / :class:`Terminated` at the next frame boundary (at once
    outside a frame loop), so clean-up and the one stderr line always happen. The
    warnings (overflow, invalid value, empty slices) arise on extreme but accepted
    numbers whose results are handled (NaN = no return); they are not the user's
    business and must not interleave with progress and data.
    """
    reset_signals()
    previous: dict[int, Any] = {}
    with contextlib.suppress(ValueError):  # not the main thread: leave signals alone
        for signum in (signal.SIGINT, signal.SIGTERM):
            previous[signum] = signal.signal(signum, on_signal)
    try:
        with warnings.catch_warnings():
            warnings.filterwarnings(
                "ignore", category=RuntimeWarning,
                message=r"(overflow|invalid value|divide by zero|underflow) encountered|"
                        r"Mean of empty slice|All-NaN (slice|axis)|Degrees of freedom")
            yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)


def _load_config(ctx: click.Context, param: click.Parameter, value: Path | None) -> None:
    """``--config FILE``: option values from a YAML mapping become the command's defaults
    (click's ``default_map``), so options on the command line still win
    (:func:`slitcli.cli.config.load_config`: keys by flag or parameter name, values
    checked by the option's type, unknown keys refused naming the key)."""
    if value is None:
        return
    from slitcli.cli.config import load_config

    ctx.default_map = {**(ctx.default_map or {}), **load_config(value, ctx)}


class _Command(click.Command):
    """A command that also takes ``--config FILE`` (YAML of option values)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.params.append(click.Option(
            ["--config"], type=click.Path(dir_okay=False, path_type=Path), is_eager=True,
            expose_value=False, callback=_load_config,
            help="YAML file of option values (e.g. 'bin-deg: 2'); options given on the "
            "command line win [default: none]. Example: --config detect.yaml"))


# The top-level commands, the module that defines each and its one-line help: `slitcli
# --help` lists them and `slitcli detect` imports one module, not all eleven (a command
# module may import numpy or the library at decoration time for its defaults).
# tests/test_cli_lazy.py checks this table against the commands the modules define.
COMMANDS: dict[str, tuple[str, str]] = {
    "calibrate": ("slitcli.cli.calibrate", "Calibrate the rig: stereo from chessboards, the "
                  "laser plane, the camera mount."),
    "detect": ("slitcli.cli.detect", "Per-bearing obstacle ranges of a sequence or bag."),
    "dwa": ("slitcli.cli.dwa", "Offline modified DWA over a recorded range table."),
    "export": ("slitcli.cli.export", "Write a detect run as ROS LaserScan messages (bag)."),
    "figures": ("slitcli.cli.figures", "Draw Figs. 4, 7, 8, 9 and range accuracy."),
    "laser": ("slitcli.cli.laser", "Laser stripe rows and ranges of a sequence."),
    "render": ("slitcli.cli.sim", "Render a generated scene into a stereo sequence with "
               "ground truth."),
    "report": ("slitcli.cli.report", "HTML report and overlay video of a detect run."),
    "rig": ("slitcli.cli.rig", "Create, inspect, edit, import and export rig files "
            "(docs/rig.md)."),
    "simulate-dwa": ("slitcli.cli.dwa", "Closed-loop modified DWA: sense -> plan -> move, per "
                     "world and sensing range."),
    "stereo": ("slitcli.cli.stereo", "Disparity, distance and obstacle images (Eq. 10)."),
}


class _LazyCommands(dict):  # type: ignore[type-arg]
    """A group's commands that imports a command's module when the command is looked up
    (by name, iteration or membership), so code that reads ``group.commands`` sees every
    command while a start-up that names one command imports one module."""

    def __init__(self, where: dict[str, tuple[str, str]]) -> None:
        super().__init__()
        self.where = where

    def names(self) -> list[str]:
        """Every command name, importing nothing."""
        return sorted({*super().keys(), *self.where})

    def _load(self, name: str) -> None:
        if not super().__contains__(name) and name in self.where:
            import importlib

            importlib.import_module(self.where[name][0])

    def _load_all(self) -> None:
        for name in self.where:
            self._load(name)

    def __missing__(self, name: str) -> Any:
        self._load(name)
        if super().__contains__(name):
            return super().__getitem__(name)
        raise KeyError(name)

    def get(self, name: Any, default: Any = None) -> Any:
        try:
            return self[name]
        except KeyError:
            return default

    def __contains__(self, name: object) -> bool:
        return super().__contains__(name) or name in self.where

    def __iter__(self) -> Iterator[str]:
        self._load_all()
        return super().__iter__()

    def __len__(self) -> int:
        self._load_all()
        return super().__len__()

    def keys(self) -> Any:
        self._load_all()
        return super().keys()

    def values(self) -> Any:
        self._load_all()
        return super().values()

    def items(self) -> Any:
        self._load_all()
        return super().items()


class _Group(click.Group):
    """A group whose errors are one line on stderr (exit 2 for bad input, 1 for bugs);
    its commands (and its subgroups' commands) take ``--config``."""

    command_class = _Command
    group_class = type

    def list_commands(self, ctx: click.Context) -> list[str]:
        if isinstance(self.commands, _LazyCommands):
            return self.commands.names()
        return super().list_commands(ctx)

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        """The command list from the :data:`COMMANDS` table: no command module imported."""
        if not isinstance(self.commands, _LazyCommands):
            super().format_commands(ctx, formatter)
            return
        names = self.list_commands(ctx)
        limit = formatter.width - 6 - max(len(n) for n in names)
        rows = []
        for name in names:
            if name in self.commands.where:
                text = click.Command(name, short_help=self.commands.where[name][1])
                rows.append((name, text.get_short_help_str(limit)))
            else:
                rows.append((name, self.commands[name].get_short_help_str(limit)))
        with formatter.section("Commands"):
            formatter.write_dl(rows)

    def main(self, args: Any = None, prog_name: str | None = None,
             complete_var: str | None = None, standalone_mode: bool = True,
             **extra: Any) -> Any:
        argv = list(sys.argv[1:] if args is None else args)
        debug = "--debug" in argv
        try:
            with _process_settings():
                rv = super().main(args=argv, prog_name=prog_name or "slitcli",
                                  complete_var=complete_var, standalone_mode=False, **extra)
        except SlitcliError as e:
            if debug:
                traceback.print_exc()
            click.echo(f"slitcli: error: {_one_line(user_message(e))}", err=True)
            sys.exit(2)
        except click.exceptions.NoArgsIsHelpError as e:
            click.echo(e.ctx.get_help() if e.ctx else str(e), err=True)
            sys.exit(2)
        except click.UsageError as e:
            where = f" (see '{e.ctx.command_path} --help')" if e.ctx is not None else ""
            click.echo(f"slitcli: error: {_one_line(e.format_message())}{where}", err=True)
            sys.exit(2)
        except click.ClickException as e:
            click.echo(f"slitcli: error: {_one_line(e.format_message())}", err=True)
            sys.exit(e.exit_code)
        except (click.exceptions.Abort, KeyboardInterrupt):
            click.echo("slitcli: interrupted", err=True)
            sys.exit(130)
        except Terminated:
            click.echo("slitcli: terminated (SIGTERM); finished results are kept, temporary "
                       "files removed", err=True)
            sys.exit(143)
        except MemoryError:
            click.echo("slitcli: error: out of memory; give smaller inputs or fewer --jobs",
                       err=True)
            sys.exit(2)
        except OSError as e:
            from slitcli.io.atomic import os_error_message

            msg = os_error_message(e)
            if msg is None:
                _internal_error(e, debug)
            if debug:
                traceback.print_exc()
            click.echo(f"slitcli: error: {_one_line(msg)}", err=True)
            sys.exit(2)
        except Exception as e:
            _internal_error(e, debug)
        sys.exit(rv if isinstance(rv, int) else 0)


def _one_line(text: str, limit: int = 2000) -> str:
    """A message as one bounded line, whatever a library message echoed."""
    flat = " ".join(text.split("\n"))
    return flat if len(flat) <= limit else flat[: limit - 3] + "..."


def _internal_error(e: BaseException, debug: bool) -> None:
    """A bug: one line (the traceback with --debug), exit status 1."""
    if debug:
        traceback.print_exc()
    text = str(e)
    msg = text.splitlines()[0][:300] if text else ""
    click.echo(f"slitcli: internal error: {e.__class__.__name__}: {msg} "
               "(run with --debug for the traceback)", err=True)
    sys.exit(1)


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


cli.commands = _LazyCommands(COMMANDS)


def bag_options(f: Any) -> Any:
    """The options that read a ROS bag as a frame source (``laser``, ``stereo``, ``detect``)."""
    from slitcli.io.frames import DEFAULT_LEFT_TOPIC, DEFAULT_MAX_DT_S, DEFAULT_RIGHT_TOPIC

    options = [
        click.option("--left-topic", default=DEFAULT_LEFT_TOPIC, show_default=True,
                     help="Bag topic of the left images."),
        click.option("--right-topic", default=DEFAULT_RIGHT_TOPIC, show_default=True,
                     help="Bag topic of the right images."),
        click.option("--max-dt", type=click.FloatRange(0.0, 60.0, min_open=True),
                     default=DEFAULT_MAX_DT_S, show_default=True,
                     help="Largest left/right stamp difference that pairs two bag images, "
                     "seconds. Synchronised cameras: a few ms; free-running cameras: half the "
                     "frame period (0.05 at 10 Hz). Unpaired images are reported."),
    ]
    for option in reversed(options):
        f = option(f)
    return f


def bad_frame_option(f: Any) -> Any:
    """``--on-bad-frame {stop,skip}`` (``laser``, ``stereo``, ``detect``)."""
    return click.option(
        "--on-bad-frame", "on_bad_frame", type=click.Choice(["stop", "skip"]), default="stop",
        show_default=True, help="A frame that cannot be read (unreadable image, wrong size): "
        "stop = exit 2 naming the file (finished frames are kept for a re-run); skip = "
        "leave it out, list it in OUT/skipped_frames.csv and go on.")(f)


def main() -> None:
    """Console-script entry point (also ``python -m slitcli``)."""
    cli.main()
