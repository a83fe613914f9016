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


#: the laser tuning options: (LaserParams field, help, choices); the flag is the field's
#: name with dashes, the default and type LaserParams' own
_LASER_OPTIONS: tuple[tuple[str, str, list[str] | None], ...] = (
    ("method",
     "model: the stripe model with noise, width, profile and laser colour measured on each "
     "image; paper: the paper's Eqs. 1-4 taken literally per pixel (a baseline for "
     "comparison).",
     ["model", "paper"]),
    ("search",
     "rig: only rows where the rig's laser plane lies within --max-search-range-m; full: "
     "every row (a camera whose geometry is unknown or differs from the rig).",
     ["rig", "full"]),
    ("min_th",
     "Eq. 2: minimum red chromaticity R = r/(r+g+b) of the light a stripe adds above the "
     "surface (unitless; grey is 0.333).",
     None),
    ("min_delta_th",
     "Eq. 2: minimum R - max(G, B) of that added light (unitless).",
     None),
    ("alpha",
     "Eq. 3 white rejection (paper 0.32), --method paper: red must exceed alpha x max(g, b) "
     "(unitless).",
     None),
    ("beta",
     "Eq. 4 weight of the continuity term f(y) (paper 0.25); the model method weighs the "
     "previous frame's row with it.",
     None),
    ("gamma",
     "Eq. 4 weight of the narrowness term g(I) (paper 0.25), --method paper.",
     None),
    ("max_width_share",
     "Widest stripe (equivalent width, 2.5 Gaussian sigmas) as a share of the image height: "
     "8 px at 240 rows, 32 px at 960 (unitless).",
     None),
    ("seed_z",
     "Candidates start where the laser evidence is this many noise sigmas high (noise "
     "measured on each image; unitless).",
     None),
    ("min_z",
     "Significance (peak over its standard error) of a segment, summed along it and "
     "compared with the shortest segment's length at this level (unitless).",
     None),
    ("weak_z",
     "Least significance of one column of a segment (unitless, <= --min-z).",
     None),
    ("shape_error",
     "Relative error of the Gaussian profile (speckle, demosaicing, JPEG) allowed by the "
     "shape test (unitless).",
     None),
    ("max_chi2",
     "Largest reduced chi-square of a Gaussian profile; a worse fit is centred by its upper "
     "half instead (unitless).",
     None),
    ("colour_error",
     "Share by which a candidate's colour may leave the plane of the laser's colour "
     "(measured on the frame) and the surface's (unitless); 1 = no such test (the "
     "default: camera tone curves whiten bright cores).",
     None),
    ("max_hue_deg",
     "Largest hue of the light a stripe adds, towards yellow, degrees from red, at three "
     "noise sigmas (a red laser stays near red; 90 = no test).",
     None),
    ("min_texture_ratio",
     "Least texture-to-noise ratio along the surface colour that the laser evidence assumes "
     "(unitless); between it and --max-texture-ratio the ratio is measured on each image.",
     None),
    ("max_texture_ratio",
     "Largest texture-to-noise ratio along the surface colour that the laser evidence "
     "assumes (unitless).",
     None),
    ("noise_floor_dn",
     "Smallest noise sigma of the laser evidence (quantisation and compression), DN.",
     None),
    ("saturation_dn",
     "Level from which a pixel counts as clipped, DN.",
     None),
    ("continuity_px",
     "Scale of the row change between neighbouring columns, px.",
     None),
    ("max_jump_px",
     "Largest row step between neighbouring columns of one segment, px.",
     None),
    ("min_segment_share",
     "Shorter segments (share of the image width; 8 columns at 320) are dropped unless their"
     " columns are strong (unitless).",
     None),
    ("min_stripe_share",
     "A frame whose longest segment spans less than this share of the width shows no stripe "
     "(unitless).",
     None),
    ("max_search_range_m",
     "--search rig: rows whose laser-plane range is at most this, m.",
     None),
    ("sheet_sigma_mm",
     "--search rig: laser sheet thickness (Gaussian sigma across the plane), mm; 0 = no "
     "thickness test.",
     None),
    ("sheet_tolerance",
     "A candidate whose width implies a sheet this many times thicker or thinner is rejected"
     " (> 1).",
     None),
    ("chroma_smoothness_max",
     "Images whose chroma is this much smoother than their luma (ratio; ~1: as rough) are "
     "taken for JPEG 4:2:0: the sheet test adds its blur; 0 = off (unitless).",
     None),
    ("luma_rows",
     "Under JPEG 4:2:0 chroma, fit the rows again on the luma (full resolution; from its "
     "own peak within two of the evidence's sigmas) and combine them with the evidence's.",
     None),
    ("luma_min_z",
     "Under JPEG 4:2:0 chroma, drop a piece of stripe whose luma shows no light at its rows: "
     "least combined significance of the luma there (unitless); 0 = off.",
     None),
    ("luma_widths",
     "Under JPEG 4:2:0 chroma, a strong candidate too wide on its evidence is judged again "
     "on its width fitted on the luma (the codec widens chroma beside colour edges).",
     None),
    ("strong_share",
     "A column this many times --min-z significant is strong: a short segment of strong "
     "columns is kept, and such a fit on its own column is kept without the averaged one "
     "(unitless, >= 1).",
     None),
    ("gap_z_share",
     "A column inside a segment without a chosen stripe is fitted where the segment "
     "passes; that fit needs this share of --weak-z (unitless).",
     None),
    ("width_spread",
     "Frame width test: an unclipped candidate at most this many times wider than the "
     "median width of the frame's strong columns (unitless); inf = no test.",
     None),
    ("laser_share_z",
     "Laser-share test: the light a candidate adds must show the frame's laser colour "
     "across the surface colour at this significance (unitless); 0 = no test.",
     None),
    ("own_z",
     "Own-light test: a fit on the evidence averaged along the stripe must show in its "
     "column's own evidence, short of it by at most this many standard errors "
     "(unitless); inf = no test.",
     None),
    ("choice_rounds",
     "The choice along the stripe is made again without the segments that fail, at most "
     "this many times (1 = one choice).",
     None),
    ("surface_step",
     "Surface test: the surface just above and below a candidate has one colour; sides "
     "whose chromaticity differs by more than this (plus the noise) are two surfaces "
     "(unitless); inf = no test.",
     None),
    ("surface_min_dn",
     "Surface test: sides darker than this (mean per channel) are not judged, DN.",
     None),
    ("one_crossing",
     "One crossing per column: of two overlapping fits of a column the wider, fainter one "
     "is out (false = both kept).",
     None),
)


def laser_options(f: Any) -> Any:
    """The laser tuning options (fields of :class:`slitcli.laser.params.LaserParams`), shared
    by ``laser`` and ``detect``."""
    for field, text, choices in reversed(_LASER_OPTIONS):
        kind = click.Choice(choices) if choices else type(_LD[field])
        f = click.option("--" + field.replace("_", "-"), type=kind, default=_LD[field],
                         show_default=True, help=text)(f)
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
    (add --search full for a camera whose geometry differs from the rig)
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


