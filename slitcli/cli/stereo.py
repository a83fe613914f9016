"""Command ``stereo`` and the matcher options shared with ``detect`` (Eqs. 8-10)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from slitcli.cli.main import bad_frame_option, bag_options, cli, echo_notes
from slitcli.errors import SlitcliError


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


_AGGREGATION_KEY = "slitcli.stereo.aggregation"


def _keep_aggregation(ctx: click.Context, _param: click.Parameter, value: str) -> str:
    # not passed to the command functions (their signatures stay as they are):
    # stereo_params reads it from the context
    ctx.meta[_AGGREGATION_KEY] = value
    return value


def matcher_options(f: Any) -> Any:
    """The Eq. 10 matcher and obstacle options, shared by ``stereo`` and ``detect``."""
    options = [
        click.option("--matcher", type=click.Choice(["nssd", "bm", "sgbm"]), default="nssd",
              show_default=True, help="nssd = the paper's normalised SSD (Eq. 10); bm, sgbm "
              "= OpenCV's StereoBM / StereoSGBM."),
        click.option("--aggregation", type=click.Choice(["none", "sgm"]), default="none",
              show_default=True, expose_value=False, callback=_keep_aggregation,
              help="nssd only: none = the paper's local Eq. 10 window; sgm = semi-global "
              "aggregation of the Eq. 10 cost along 4 paths (denser on weak texture and "
              "on plain surfaces between agreeing textured borders, follows slanted "
              "floors; about 3x slower), then the same checks. Example: "
              "--aggregation sgm"),
        click.option("--num-disparities", type=int, default=48, show_default=True,
              help="Disparities searched, px (48 px: 0.46 m and beyond for the paper rig)."),
        click.option("--min-disparity", type=int, default=0, show_default=True,
              help="Smallest disparity searched, px."),
        click.option("--window", "window", default="9", show_default=True,
              help="Correlation window W or WxH, odd, px (the (2m+1)x(2n+1) of Eq. 10)."),
        click.option("--prefilter", type=click.Choice(["none", "mean", "xsobel", "log"]),
              default="mean", show_default=True, help="Image filter before matching."),
        click.option("--texture-min", type=float, default=1.0, show_default=True,
              help="Minimum window standard deviation of the filtered image, DN (0 = off)."),
        click.option("--uniqueness", type=float, default=0.15, show_default=True,
              help="Uniqueness ratio: other disparities must cost (1 + ratio) x more (0 = off)."),
        click.option("--lr-max-diff", type=int, default=1, show_default=True,
              help="Left-right check tolerance, px (negative = off)."),
        click.option("--support-min", type=float, default=0.2, show_default=True,
              help="Minimum 3x3 zero-mean correlation at the chosen disparity, in [-1, 1] "
              "(0 = off, and no cross support)."),
        click.option("--support-cross-min", type=float, default=0.4, show_default=True,
              help="Minimum zero-mean correlation, at the chosen disparity, of both 3x3 "
              "blocks just above and below the pixel, or of both just left and right of "
              "it, in [-1, 1] (0 = off); pixels whose own 3x3 correlation reaches 0.95 "
              "are not tested."),
        click.option("--speckle-window", type=int, default=100, show_default=True,
              help="Remove disparity blobs up to this many pixels (0 = off)."),
        click.option("--speckle-range", type=float, default=2.0, show_default=True,
              help="Disparity step that separates blobs, px."),
        click.option("--subpixel", type=click.Choice(["parabola", "none"]), default="parabola",
              show_default=True, help="Subpixel refinement of the winning disparity."),
        click.option("--floor-margin", type=float, default=0.05, show_default=True,
              help="Points lower than this above the floor are floor, m."),
        click.option("--robot-height", type=float, default=0.8, show_default=True,
              help="Points higher than this are above the robot (not obstacles), m."),
        click.option("--max-range", type=float, default=None,
              help="Obstacles farther than this are ignored, m [default: the rig's "
              "stereo.max_range_m]."),
    ]
    for option in reversed(options):
        f = option(f)
    return f


def stereo_params(matcher: str, num_disparities: int, min_disparity: int, window: str,
                  prefilter: str, texture_min: float, uniqueness: float, lr_max_diff: int,
                  support_min: float, support_cross_min: float, speckle_window: int,
                  speckle_range: float, subpixel: str, floor_margin: float,
                  robot_height: float, max_range: float | None) -> Any:
    """Build the StereoParams dataclass from the :func:`matcher_options` values."""
    from slitcli.stereo.matcher import MatcherParams
    from slitcli.stereo.obstacles import ObstacleParams
    from slitcli.stereo.pipeline import StereoParams

    w, h = _parse_window(window)
    ctx = click.get_current_context(silent=True)
    aggregation = ctx.meta.get(_AGGREGATION_KEY, "none") if ctx is not None else "none"
    return StereoParams(
        matcher=MatcherParams(matcher, num_disparities, min_disparity, w, h,
                              aggregation=aggregation,
                              prefilter=prefilter, texture_min_dn=texture_min,
                              uniqueness_ratio=uniqueness, lr_max_diff_px=lr_max_diff,
                              support_min_zncc=support_min,
                              support_cross_min_zncc=support_cross_min,
                              speckle_window_px=speckle_window,
                              speckle_range_px=speckle_range, subpixel=subpixel),
        obstacles=ObstacleParams(floor_margin_m=floor_margin, robot_height_m=robot_height,
                                 max_range_m=max_range))


@cli.command("stereo", short_help="Disparity, distance and obstacle images (Eq. 10).")
@click.argument("seq", metavar="SEQ|BAG", type=click.Path(path_type=Path))
@click.option("-o", "--out", required=True, type=click.Path(file_okay=False, path_type=Path),
              help="Output folder for disparity/, distance/, mask/ and stereo_ranges.csv.")
@click.option("--rig", "rig_path", type=click.Path(dir_okay=False, path_type=Path),
              default=None, help="Rig file [default: SEQ/rig.yaml, else the paper rig; "
              "required for bags].")
@bag_options
@bad_frame_option
@matcher_options
@click.option("--overwrite", is_flag=True, help="Replace results made with other settings.")
def stereo_cmd(seq: Path, out: Path, rig_path: Path | None, left_topic: str,
               right_topic: str, max_dt: float, on_bad_frame: str, matcher: str,
               num_disparities: int, min_disparity: int, window: str, prefilter: str,
               texture_min: float, uniqueness: float, lr_max_diff: int, support_min: float,
               support_cross_min: float, speckle_window: int, speckle_range: float,
               subpixel: str, floor_margin: float, robot_height: float,
               max_range: float | None, overwrite: bool) -> None:
    """Disparity, distance and obstacle-mask images of a stereo sequence (paper Eqs. 8-10).

    Writes OUT/disparity/NAME.png (uint16, disparity x 256, 0 = invalid),
    OUT/distance/NAME.png (uint16, depth in mm, 0 = invalid), OUT/mask/NAME.png (uint8,
    255 = obstacle) per input frame and OUT/stereo_ranges.csv (nearest obstacle per
    1-degree bearing bin, m). A re-run skips finished frames. See docs/stereo.md.

    Example: slitcli stereo out/corridor -o out/corridor-stereo --window 9x7
    """
    from slitcli.io.progress import progress
    from slitcli.stereo.run import run_stereo

    params = stereo_params(matcher, num_disparities, min_disparity, window, prefilter,
                           texture_min, uniqueness, lr_max_diff, support_min,
                           support_cross_min, speckle_window,
                           speckle_range, subpixel, floor_margin, robot_height, max_range)
    with progress("stereo") as on_progress:
        summary = run_stereo(seq, out, rig_path=rig_path, params=params,
                             overwrite=overwrite, left_topic=left_topic,
                             right_topic=right_topic, max_dt_s=max_dt,
                             on_bad_frame=on_bad_frame, on_progress=on_progress)
    echo_notes(summary.notes)
    click.echo(summary.line(f"mean valid disparity fraction "
                            f"{summary.counts['valid_fraction']:.3f}"))
