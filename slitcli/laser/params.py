"""Parameters of the laser stripe extraction (paper Eqs. 1-4) and their defaults."""

from __future__ import annotations

from dataclasses import dataclass, fields

from slitcli.errors import SlitcliError

METHODS = ("model", "paper")
SEARCHES = ("rig", "full")


@dataclass(frozen=True, kw_only=True)
class LaserParams:
    """How the stripe is found (docs/laser.md, "How the stripe is found").

    Attributes
    ----------
    method : {"model", "paper"}
        ``model``: the stripe model with its terms estimated from each image (default);
        ``paper``: the paper's Eqs. 1-4 taken literally, per pixel on the raw image (a
        baseline for comparison).
    search : {"rig", "full"}
        ``rig``: only rows whose ray meets the laser plane within
        ``max_search_range_m`` (the rig's geometry); ``full``: every row (a camera whose
        geometry is unknown or differs from the rig).
    min_th, min_delta_th : float
        Eq. 2: minimum red chromaticity ``R = r / (r + g + b)`` and minimum
        ``R - max(G, B)`` (unitless; grey is 1/3, 0). The model method applies them to
        the light a candidate adds above the surface; the paper method to raw pixels.
    alpha : float
        Eq. 3, white rejection (paper 0.32): red must exceed ``alpha`` times the white
        brightness ``max(g, b)`` (paper method; the model method cancels white light).
    beta, gamma : float
        Eq. 4 weights of the continuity term f(y) and the narrowness term g(I)
        (paper 0.25 each).
    max_width_share : float
        Widest stripe as a share of the image height: its equivalent width (2.5 fitted
        Gaussian sigmas) may not exceed ``max_width_share x height`` pixels (8 px at
        240 rows, 32 px at 960).
    seed_z : float
        Candidates are seeded at local maxima of the laser evidence at least this many
        of its noise sigmas high (the noise measured on the image, unitless).
    min_z : float
        Significance (fitted peak over its standard error, against the local noise) of
        a segment, summed along it (``sqrt(sum z^2)``) and compared with that of the
        shortest segment kept, ``min_segment_cols`` columns at ``min_z`` (unitless).
    weak_z : float
        Least significance of one column of a segment (unitless).
    shape_error : float
        Relative error of the Gaussian profile model (speckle, demosaicing, JPEG): the
        fit's residual variance per row is ``noise^2 + (shape_error x profile)^2``.
    max_chi2 : float
        Largest reduced chi-square of the profile fit under that variance.
    colour_error : float
        Relative error of the laser colour: with ``colour_error`` < 1, the light a
        candidate adds may differ from the laser's colour (estimated on the frame)
        across it and the surface colour by this share of its size plus three noise
        sigmas; 1 (the default): no such test. Mixing the two colours linearly holds
        for a linear sensor only: the tone curve's shoulder whitens bright cores, and
        on real photographs the test rejected true stripe columns (docs/laser.md).
    max_hue_deg : float
        Largest hue of the light a candidate adds, towards yellow, degrees from red
        (``atan2(sqrt 3 (g - b), 2 r - g - b)``; tested at three noise sigmas of its
        core's mean; 90: no test). A red diode laser reaches a camera's green and blue
        filters through their tails alone, so its light stays near red (-26 to +8
        degrees on the real photographs measured, magenta where blue leaks more); light
        whose green exceeds its blue by far is broadband (a warm, yellow surface), not
        the laser's.
    min_texture_ratio, max_texture_ratio : float
        Range of the texture-to-noise ratio ``r = tau / sigma`` along the surface colour
        that the evidence assumes (unitless); it removes the share ``r^2 / (r^2 + 1)`` of
        the surface colour. Within the range the ratio is measured on each image
        (texture along the surface colour against the noise across it); equal bounds fix
        it. The cap keeps the share below 1, which would amplify the noise without bound
        on surfaces of the laser's colour (5: 0.96). Default 2 to 5: renders without a
        camera model measure 9.5-12.7 (5), the development set's robot photographs 0-0.8
        (2); the floor of 2 keeps the stripe of such cameras on surfaces of the laser's
        own colour under a tone curve, and bounds the texture the evidence keeps
        (docs/laser.md, Ablation and Limits).
    noise_floor_dn : float
        Smallest noise sigma of the laser evidence, DN: quantisation (0.35 DN for the
        evidence's weights) and compression leave at least this much.
    saturation_dn : int
        Values at or above this are clipped (DN).
    continuity_px : float
        Scale of f(y): ``exp(-dv^2 / (2 continuity_px^2))``, pixels.
    max_jump_px : float
        Largest row step between neighbouring columns of one segment, pixels (a steep
        stripe's own width allows more).
    min_segment_share : float
        Segments shorter than this share of the image width (8 columns at 320) are
        dropped unless each column is twice ``min_z`` significant.
    min_stripe_share : float
        A frame whose longest segment spans less than this share of the searched
        columns (the image width, or the columns a search mask reaches) shows no stripe
        (32 columns at 320).
    max_search_range_m : float
        ``search="rig"``: rows whose laser-plane point lies within this horizontal
        range, metres.
    sheet_sigma_mm : float
        ``search="rig"``: the sheet's thickness (Gaussian sigma across the plane), mm; a
        candidate whose width implies a sheet ``sheet_tolerance`` times thicker or
        thinner is not the laser. 0 turns the test off.
    sheet_tolerance : float
        Factor of that test (> 1).
    chroma_smoothness_max : float
        An image whose red-difference chroma is smoother down the columns than its luma
        by this ratio or more (:func:`slitcli.laser.luma.chroma_smoothness`: short-lag
        over long-lag differences, chroma's over luma's; about 1 or more when as rough,
        near 0 subsampled) is taken for JPEG 4:2:0 (subsampled chroma): the sheet test
        adds the 4:2:0 chain's blur (``slitcli.laser.luma.CHAIN_VAR_PX2``, 0.92 px^2) to
        the stripe's width. 0 turns it off. Default 0.85: renders without a camera model
        measure 1.4-2.4, through the camera model's presets with JPEG 4:4:4 0.93-1.4,
        its 4:2:0 presets 0.26-0.37 (``webcam``) and 0.72-0.80 (``robot``), the
        development set's robot photographs (4:2:0) 0.54-0.60 (docs/laser.md).
    strong_share : float
        A column this many times ``min_z`` significant is strong: a segment shorter
        than ``min_segment_share`` is kept when each of its columns is, and a fit this
        significant on its column's own evidence is kept without one on the evidence
        averaged along the stripe (unitless, at least 1).
    gap_z_share : float
        A column inside a segment without a chosen stripe is fitted where the segment
        says the stripe passes (one place tried, not every row); the fit needs this
        share of ``weak_z`` (unitless).
    width_spread : float
        Frame width test: an unclipped candidate may be at most this many times wider
        than the median width of the frame's strong columns (the sheet's width changes
        with range and incidence, not by more); inf: no such test.
    laser_share_z : float
        Laser-share test: where the frame shows the laser's colour, the light a
        candidate adds must show the laser's share across the surface colour at this
        significance (:func:`slitcli.laser.judge.laser_share`; unitless); 0: no test.
    own_z : float
        Own-light test: a fit on the evidence averaged along the stripe stands for its
        column only where the column's own evidence shows that light, short of it by at
        most this many standard errors (one-sided; unitless; inf: no test).
    choice_rounds : int
        The choice along the stripe is made again without the segments that fail, at
        most this many times (1: one choice).
    surface_step : float
        Surface test: the laser adds light to one surface, so the surface just above
        and below a candidate has one colour; sides whose chromaticity (any channel)
        differs by more than this plus four noise sigmas are two surfaces (an object's
        edge), and the candidate is not the laser (unitless; inf: no test).
    surface_min_dn : float
        Sides darker than this, DN per channel on average, show no colour and are not
        judged by the surface test.
    one_crossing : bool
        One crossing per column: of two overlapping valid fits of one column the wider,
        fainter one is out; False: both kept.
    luma_rows : bool
        Under subsampled chroma (above), fit each found column's row again on the luma
        (full resolution), from the luma's own peak within two of the evidence's sigmas
        of its row (:func:`slitcli.laser.luma.luma_rows`), and combine it with the
        evidence's row by their variances (:func:`slitcli.laser.luma.combined_rows`): the
        camera's chroma processing blurs and can displace the evidence's hump, the luma
        marks the light. False: the evidence's rows.
    luma_min_z : float
        Under subsampled chroma (above), a piece of stripe whose luma does not show the
        laser's light is dropped: the luma's matched filter at the stripe's rows, over
        the piece's unclipped columns, must reach this combined significance
        (``sum(z) / sqrt(n)``, :func:`slitcli.laser.luma.luma_segments`; unitless). The
        codec's chroma makes red bumps on colourful texture with no light behind them
        (docs/laser.md). 0 turns the test off.
    luma_widths : bool
        Under subsampled chroma (above), a strong candidate (``strong_share x min_z``)
        of the frame's laser colour that fails the width tests (the sheet's thickness,
        the frame's width spread) on its evidence is judged again on its width fitted on
        the luma (full resolution; :func:`slitcli.laser.luma.luma_widths`): beside a
        colour edge the codec's chroma widens the evidence, not the light. False: the
        evidence's width alone.
    """

    method: str = "model"
    search: str = "rig"
    min_th: float = 0.35
    min_delta_th: float = 0.02
    alpha: float = 0.32
    beta: float = 0.25
    gamma: float = 0.25
    max_width_share: float = 1.0 / 30.0
    seed_z: float = 3.0
    min_z: float = 5.0
    weak_z: float = 3.0
    shape_error: float = 0.25
    max_chi2: float = 4.0
    colour_error: float = 1.0
    max_hue_deg: float = 40.0
    min_texture_ratio: float = 2.0
    max_texture_ratio: float = 5.0
    noise_floor_dn: float = 0.5
    saturation_dn: int = 250
    continuity_px: float = 2.0
    max_jump_px: float = 3.0
    min_segment_share: float = 0.025
    min_stripe_share: float = 0.1
    max_search_range_m: float = 3.0
    sheet_sigma_mm: float = 4.0
    sheet_tolerance: float = 1.6
    chroma_smoothness_max: float = 0.85
    luma_rows: bool = True
    luma_min_z: float = 2.0
    luma_widths: bool = True
    strong_share: float = 2.0
    gap_z_share: float = 2.0 / 3.0
    width_spread: float = 2.5
    laser_share_z: float = 3.0
    own_z: float = 3.0
    choice_rounds: int = 6
    surface_step: float = 0.1
    surface_min_dn: float = 10.0
    one_crossing: bool = True

    def __post_init__(self) -> None:
        checks = {
            "method": self.method in METHODS,
            "search": self.search in SEARCHES,
            "min_th": 0.0 <= self.min_th < 1.0,
            "min_delta_th": -1.0 < self.min_delta_th < 1.0,
            "alpha": 0.0 <= self.alpha < 1.0,
            "beta": self.beta >= 0.0,
            "gamma": self.gamma >= 0.0,
            "max_width_share": 0.0 < self.max_width_share <= 0.25,
            "seed_z": self.seed_z > 0.0,
            "min_z": self.min_z > 0.0,
            "weak_z": 0.0 < self.weak_z <= self.min_z,
            "shape_error": 0.0 <= self.shape_error < 1.0,
            "max_chi2": self.max_chi2 > 0.0,
            "colour_error": 0.0 <= self.colour_error <= 1.0,
            "max_hue_deg": 0.0 < self.max_hue_deg <= 90.0,
            # the maximum first: a bad maximum is named, not the minimum it bounds
            "max_texture_ratio": 0.0 <= self.max_texture_ratio <= 100.0,
            "min_texture_ratio": 0.0 <= self.min_texture_ratio <= self.max_texture_ratio,
            "noise_floor_dn": self.noise_floor_dn > 0.0,
            "saturation_dn": 1 <= self.saturation_dn <= 255,
            "continuity_px": self.continuity_px > 0.0,
            "max_jump_px": self.max_jump_px > 0.0,
            "min_segment_share": 0.0 <= self.min_segment_share < 1.0,
            "min_stripe_share": 0.0 <= self.min_stripe_share < 1.0,
            "max_search_range_m": self.max_search_range_m > 0.0,
            "sheet_sigma_mm": self.sheet_sigma_mm >= 0.0,
            "sheet_tolerance": self.sheet_tolerance > 1.0,
            "chroma_smoothness_max": 0.0 <= self.chroma_smoothness_max <= 10.0,
            "luma_rows": isinstance(self.luma_rows, bool),
            "luma_min_z": 0.0 <= self.luma_min_z <= 10.0,
            "luma_widths": isinstance(self.luma_widths, bool),
            "strong_share": 1.0 <= self.strong_share <= 100.0,
            "gap_z_share": 0.0 < self.gap_z_share <= 10.0,
            "width_spread": self.width_spread >= 1.0,
            "laser_share_z": 0.0 <= self.laser_share_z <= 100.0,
            "own_z": self.own_z > 0.0,
            "choice_rounds": isinstance(self.choice_rounds, int)
            and not isinstance(self.choice_rounds, bool) and 1 <= self.choice_rounds <= 100,
            "surface_step": self.surface_step > 0.0,
            "surface_min_dn": 0.0 <= self.surface_min_dn <= 255.0,
            "one_crossing": isinstance(self.one_crossing, bool),
        }
        for name, ok in checks.items():
            if not ok:
                raise SlitcliError(f"laser parameter `{name}` = {getattr(self, name)!r} is out "
                                   f"of range; {_RANGES[name]}", param=name)

    def texture_share_range(self) -> tuple[float, float]:
        """Smallest and largest share of the surface colour the evidence removes,
        ``r^2 / (r^2 + 1)`` of ``min_texture_ratio`` and ``max_texture_ratio``."""
        lo, hi = self.min_texture_ratio ** 2, self.max_texture_ratio ** 2
        return lo / (lo + 1.0), hi / (hi + 1.0)

    def max_width_px(self, height_px: int) -> float:
        """Widest stripe's equivalent width in an image of ``height_px`` rows, pixels
        (at least 4)."""
        return max(4.0, self.max_width_share * height_px)

    def min_segment_cols(self, width_px: int) -> int:
        """Shortest segment kept without strong columns, in an image ``width_px`` wide."""
        return max(2, round(self.min_segment_share * width_px))

    def as_dict(self) -> dict[str, float | str]:
        """The parameters as a plain mapping (for logs and docs)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}


_RANGES = {
    "method": "give one of " + ", ".join(METHODS),
    "search": "give one of " + ", ".join(SEARCHES),
    "min_th": "give a chromaticity in [0, 1)",
    "min_delta_th": "give a chromaticity difference in (-1, 1)",
    "alpha": "give a fraction in [0, 1)",
    "beta": "give a weight >= 0",
    "gamma": "give a weight >= 0",
    "max_width_share": "give a share of the image height in (0, 0.25]",
    "seed_z": "give a significance > 0",
    "min_z": "give a significance > 0",
    "weak_z": "give a significance in (0, min_z]",
    "shape_error": "give a relative error in [0, 1)",
    "max_chi2": "give a reduced chi-square > 0",
    "colour_error": "give a relative error in [0, 1] (1: no colour-plane test)",
    "max_hue_deg": "give an angle in (0, 90] degrees (90: no hue test)",
    "min_texture_ratio": "give a ratio from 0 up to the maximum texture ratio",
    "max_texture_ratio": "give a ratio in [0, 100]",
    "noise_floor_dn": "give a noise level > 0 DN",
    "saturation_dn": "give a level in 1..255 DN",
    "continuity_px": "give a scale > 0 px",
    "max_jump_px": "give a row step > 0 px",
    "min_segment_share": "give a share of the image width in [0, 1)",
    "min_stripe_share": "give a share of the image width in [0, 1)",
    "max_search_range_m": "give a range > 0 m",
    "sheet_sigma_mm": "give a thickness >= 0 mm (0: no test)",
    "sheet_tolerance": "give a factor > 1",
    "chroma_smoothness_max": "give a ratio in [0, 10] (0: off)",
    "luma_rows": "give true or false",
    "luma_min_z": "give a significance in [0, 10] (0: off)",
    "luma_widths": "give true or false",
    "strong_share": "give a multiple of min_z in [1, 100]",
    "gap_z_share": "give a share of weak_z in (0, 10]",
    "width_spread": "give a factor >= 1 (inf: no frame width test)",
    "laser_share_z": "give a significance in [0, 100] (0: no laser-share test)",
    "own_z": "give a significance > 0 (inf: no own-light test)",
    "choice_rounds": "give a whole number of rounds in 1..100",
    "surface_step": "give a chromaticity step > 0 (inf: no surface test)",
    "surface_min_dn": "give a level in [0, 255] DN",
    "one_crossing": "give true or false",
}
