"""Parameters of the laser slit extraction (paper Eqs. 1-4) with the paper's defaults."""

from __future__ import annotations

from dataclasses import dataclass, fields

from slitcli.errors import SlitcliError


@dataclass(frozen=True, kw_only=True)
class LaserParams:
    """Thresholds and weights of the stripe extractor (see docs/laser.md).

    Attributes
    ----------
    min_th : float
        Eq. 2: minimum red chromaticity ``R = r / (r + g + b)`` of the light a pixel
        adds above its background (its contrast; unitless, 1/3 is grey). The paper
        gives no value; 0.35.
    min_delta_th : float
        Eq. 2: minimum ``R - max(G, B)`` of the contrast (unitless). The paper gives no
        value; 0.02.
    alpha : float
        Eq. 3 white-brightness rejection, paper value 0.32: the laser estimate of a
        pixel (its red contrast less what its green and blue explain along the
        surface's colour) must exceed ``alpha`` times its white contrast
        ``max(t_g, t_b)``.
    beta : float
        Eq. 4 weight of the continuity term f(y) (paper 0.25).
    gamma : float
        Eq. 4 weight of the narrowness term g(I) (paper 0.25).
    max_width_px : float
        Widest stripe: its equivalent width (2.5 fitted Gaussian sigmas) may not
        exceed this, and a candidate run longer than three times it is an object,
        pixels.
    background_window_px : int
        Length of the vertical window of the morphological opening that estimates
        the background under the stripe, pixels (odd; narrower features are "contrast").
    min_peak_dn : float
        Minimum peak brightness of a stripe (the red light it adds, before the pixels'
        blur), as the running median along its segment, DN. The renderer's truth calls
        a stripe visible from an expected peak of 20 DN.
    noise_k : float
        Significance (fitted amplitude over its standard error) of a strong candidate;
        weak ones, which need an agreeing neighbour, 0.6 of it (unitless).
    seed_fraction : float
        Candidates are seeded where the laser evidence exceeds this fraction of
        ``max(min_peak_dn, noise_k x noise sigma)`` (and three noise sigmas of the
        evidence) (unitless).
    saturation_dn : int
        Values at or above this are saturated (DN); a saturated red core is exempt
        from Eqs. 2-3 when a red pixel borders it, and is fitted on its flanks.
    continuity_px : float
        Scale of the continuity term: f(y) = exp(-dv^2 / (2 continuity_px^2)), pixels.
    max_jump_px : float
        Largest row change between neighbouring columns of one stripe segment, pixels
        (along a steep stripe the profile's own width allows more).
    min_segment_cols : int
        Stripe segments shorter than this many columns are dropped unless each of
        their columns is 1.6 ``noise_k`` significant.
    max_search_range_m : float
        Only rows whose laser-plane intersection lies within this horizontal range
        are searched, metres.
    sheet_sigma_mm : float
        Thickness of the laser sheet (Gaussian sigma across the plane), millimetres.
        With the rig geometry, a candidate whose fitted width implies a sheet more
        than 1.6 times thicker or thinner is not the laser (a frame that shows its own
        thickness clearly uses that); 0 turns the test off.
    """

    min_th: float = 0.35
    min_delta_th: float = 0.02
    alpha: float = 0.32
    beta: float = 0.25
    gamma: float = 0.25
    max_width_px: float = 8.0
    background_window_px: int = 21
    min_peak_dn: float = 19.0
    noise_k: float = 5.0
    seed_fraction: float = 0.35
    saturation_dn: int = 250
    continuity_px: float = 2.0
    max_jump_px: float = 3.0
    min_segment_cols: int = 8
    max_search_range_m: float = 3.0
    sheet_sigma_mm: float = 4.0

    def __post_init__(self) -> None:
        checks = {
            "min_th": 0.0 <= self.min_th < 1.0,
            "min_delta_th": -1.0 < self.min_delta_th < 1.0,
            "alpha": 0.0 <= self.alpha < 1.0,
            "beta": self.beta >= 0.0,
            "gamma": self.gamma >= 0.0,
            "max_width_px": self.max_width_px >= 1.0,
            "background_window_px": (self.background_window_px >= 3
                                     and self.background_window_px % 2 == 1
                                     and self.background_window_px > 2 * self.max_width_px),
            "min_peak_dn": 0.0 < self.min_peak_dn < 255.0,
            "noise_k": self.noise_k >= 0.0,
            "seed_fraction": 0.0 < self.seed_fraction <= 1.0,
            "saturation_dn": 1 <= self.saturation_dn <= 255,
            "continuity_px": self.continuity_px > 0.0,
            "max_jump_px": self.max_jump_px > 0.0,
            "min_segment_cols": self.min_segment_cols >= 1,
            "max_search_range_m": self.max_search_range_m > 0.0,
            "sheet_sigma_mm": self.sheet_sigma_mm >= 0.0,
        }
        for name, ok in checks.items():
            if not ok:
                raise SlitcliError(f"laser parameter {name} = {getattr(self, name)!r} is out of "
                                   f"range; {_RANGES[name]}")

    def as_dict(self) -> dict[str, float]:
        """The parameters as a plain mapping (for logs and docs)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}


_RANGES = {
    "min_th": "give a chromaticity in [0, 1)",
    "min_delta_th": "give a chromaticity difference in (-1, 1)",
    "alpha": "give a fraction in [0, 1)",
    "beta": "give a weight >= 0",
    "gamma": "give a weight >= 0",
    "max_width_px": "give a width >= 1 px",
    "background_window_px": "give an odd length >= 3 px and more than twice max_width_px",
    "min_peak_dn": "give a contrast in (0, 255) DN",
    "noise_k": "give a factor >= 0",
    "seed_fraction": "give a fraction in (0, 1]",
    "saturation_dn": "give a level in 1..255 DN",
    "continuity_px": "give a scale > 0 px",
    "max_jump_px": "give a row step > 0 px",
    "min_segment_cols": "give a whole number of columns >= 1",
    "max_search_range_m": "give a range > 0 m",
    "sheet_sigma_mm": "give a thickness >= 0 mm (0: no test)",
}
