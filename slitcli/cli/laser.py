"""Command ``laser``: the laser slit table of a sequence (Eqs. 1-7)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from slitcli.cli.main import bad_frame_option, bag_options, cli, echo_notes


def _laser_defaults() -> dict[str, Any]:
    from dataclasses import fields

    from slitcli.laser.params import LaserParams

    return {f.name: f.default for f in fields(LaserParams)}


_LD = _laser_defaults()


def laser_options(f: Any) -> Any:
    """The laser tuning options (fields of :class:`slitcli.laser.params.LaserParams`), shared
    by ``laser`` and ``detect``."""
    options = [
        click.option("--min-th", type=float, default=_LD["min_th"], show_default=True,
                     help="Eq. 2: minimum red chromaticity R = r/(r+g+b) of the light a pixel adds "
                          "above its background (unitless; grey is 0.333)."),
        click.option("--min-delta-th", type=float, default=_LD["min_delta_th"], show_default=True,
                     help="Eq. 2: minimum R - max(G, B) of that added light (unitless)."),
        click.option("--alpha", type=float, default=_LD["alpha"], show_default=True,
                     help="Eq. 3 white-brightness rejection (paper 0.32): a pixel's laser estimate "
                          "(red contrast less what green and blue explain along the surface's "
                          "colour) must exceed alpha x its white contrast max(t_g, t_b) "
                          "(unitless)."),
        click.option("--beta", type=float, default=_LD["beta"], show_default=True,
                     help="Eq. 4 weight of the continuity term f(y) (paper 0.25)."),
        click.option("--gamma", type=float, default=_LD["gamma"], show_default=True,
                     help="Eq. 4 weight of the narrowness term g(I) (paper 0.25)."),
        click.option("--max-width-px", type=float, default=_LD["max_width_px"], show_default=True,
                     help="Widest stripe: equivalent width (2.5 fitted Gaussian sigmas) at most "
                          "this; a candidate run over 3x this is an object, px."),
        click.option("--background-window-px", type=int, default=_LD["background_window_px"],
                     show_default=True,
                     help="Vertical window of the background estimate (odd, > 2 x max width), px."),
        click.option("--min-peak-dn", type=float, default=_LD["min_peak_dn"], show_default=True,
                     help="Minimum peak brightness the stripe adds (before pixel blur), as the "
                          "running median along its segment, DN."),
        click.option("--noise-k", type=float, default=_LD["noise_k"], show_default=True,
                     help="Significance (fitted amplitude / its standard error) of a strong "
                          "candidate; a weak one needs 0.6 of it and an agreeing neighbour "
                          "(unitless)."),
        click.option("--seed-fraction", type=float, default=_LD["seed_fraction"], show_default=True,
                     help="Candidates are seeded where the laser evidence exceeds this fraction "
                          "of max(min-peak-dn, noise-k x noise sigma) (unitless)."),
        click.option("--saturation-dn", type=int, default=_LD["saturation_dn"], show_default=True,
                     help="Red level from which a pixel counts as saturated, DN."),
        click.option("--continuity-px", type=float, default=_LD["continuity_px"], show_default=True,
                     help="Scale of the continuity term f(y), px."),
        click.option("--max-jump-px", type=float, default=_LD["max_jump_px"], show_default=True,
                     help="Largest row step between neighbouring columns of one segment, px."),
        click.option("--min-segment-cols", type=int, default=_LD["min_segment_cols"],
                     show_default=True, help="Shorter stripe segments are dropped, columns."),
        click.option("--max-search-range-m", type=float, default=_LD["max_search_range_m"],
                     show_default=True,
                     help="Search only rows whose laser-plane range is at most this, m."),
        click.option("--sheet-sigma-mm", type=float, default=_LD["sheet_sigma_mm"],
                     show_default=True,
                     help="Laser sheet thickness (Gaussian sigma across the plane), mm; a "
                          "candidate whose fitted width implies a sheet 1.6x thicker or "
                          "thinner is rejected; 0 = off."),
    ]
    for option in reversed(options):
        f = option(f)
    return f


LASER_OPTION_NAMES = tuple(_LD)


@cli.command("laser", short_help="Laser stripe rows and ranges of a sequence.")
@click.argument("seq", metavar="SEQ|BAG", type=click.Path(path_type=Path))
@click.option("-o", "--out", "out", required=True, type=click.Path(path_type=Path),
              help="Output folder; OUT/laser.csv is written: per stripe column frame, u_px, "
              "v_px, strength, x_m, y_m, range_m, bearing_deg, in_band (docs/laser.md).")
@click.option("--rig", "rig_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Rig file (default: SEQ/rig.yaml, else the paper rig; required for bags). "
              "A rig with a raw calibration rectifies the images first.")
@click.option("--overlay", is_flag=True,
              help="Also write OUT/laser_overlay/<frame>.png: stripe drawn, ranges annotated "
                   "(paper Fig. 4 style).")
@bag_options
@bad_frame_option
@laser_options
def laser_cmd(seq: Path, out: Path, rig_path: Path | None, overlay: bool, left_topic: str,
              right_topic: str, max_dt: float, on_bad_frame: str, **tuning: Any) -> None:
    """Extract the red laser stripe (paper Eqs. 1-4) and triangulate it (Eqs. 5-7).

    Reads the left images of the sequence folder or ROS bag SEQ and writes
    OUT/laser.csv: one row per frame and image column with a stripe (frame, u_px,
    v_px, strength [DN], x_m, y_m, range_m, bearing_deg in the sensor frame,
    in_band = 1 inside the rig's laser band). Points outside the band stay in the
    table, flagged in_band = 0.

    Example: slitcli laser sample_data/sequences/corridor -o out/laser --overlay
    """
    from slitcli.io.progress import progress
    from slitcli.laser.batch import run_laser
    from slitcli.laser.params import LaserParams

    params = LaserParams(**tuning)
    with progress("laser") as on_progress:
        summary = run_laser(seq, out, rig_path=rig_path, params=params, overlay=overlay,
                            left_topic=left_topic, right_topic=right_topic, max_dt_s=max_dt,
                            on_bad_frame=on_bad_frame, on_progress=on_progress)
    echo_notes(summary.notes)
    click.echo(summary.line(f"{summary.counts['stripe_columns']} stripe columns"))


