"""Synthetic left images with an exactly known laser stripe, for the laser tests and bench.

The image is ``albedo * ambient + colour * laser`` per channel (``colour`` the surface's
albedo colour without its texture, as in the renderer), plus seeded Gaussian noise,
rounded and clipped to 0..255 (clipping is the saturation model). The laser profile
across the stripe is a Gaussian of standard deviation ``sigma_px`` integrated over
each pixel's extent [v - 0.5, v + 0.5] with erf, so the true centre row is exact.
The stripe rows come from the rig geometry: on a wall ``forward_m`` ahead the
stripe is a straight image line, taken from ``rig.stripe_row_on_wall`` at two
columns and interpolated (exact for a line).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy.special import erf

from slitcli.rig import Rig


@dataclass(frozen=True)
class Synth:
    """One synthetic frame and its truth (per column: NaN where no stripe is drawn)."""

    bgr: np.ndarray
    stripe_v_px: np.ndarray
    red_object_cols: np.ndarray  # bool (W,): the stripe crosses the wide red object here


def wall_stripe_rows(rig: Rig, forward_m: float) -> np.ndarray:
    """True stripe row of every column for a wall ``forward_m`` ahead (shape (W,))."""
    w = rig.width_px
    v0 = rig.stripe_row_on_wall(forward_m, 0.0)
    v1 = rig.stripe_row_on_wall(forward_m, float(w - 1))
    return v0 + (v1 - v0) * np.arange(w) / (w - 1)


def textured_albedo(shape: tuple[int, int], rng: np.random.Generator, *, scale_px: float = 3.0,
                    contrast: float = 0.25) -> np.ndarray:
    """Grey albedo texture in (0, 1): smoothed seeded noise around 1, relative ``contrast``."""
    n = rng.normal(size=shape).astype(np.float32)
    n = cv2.GaussianBlur(n, (0, 0), scale_px)
    n /= max(float(n.std()), 1e-6)
    return np.clip(1.0 + contrast * n, 0.2, 1.8)


def stripe_profile(stripe_v_px: np.ndarray, height: int, sigma_px) -> np.ndarray:
    """Pixel-integrated unit-peak Gaussian stripe, shape (H, W); zero where the row is NaN.

    ``sigma_px`` is a number or one value per column (shape (W,)).
    """
    v = np.arange(height, dtype=float)[:, None]
    c = np.asarray(stripe_v_px, dtype=float)[None, :]
    s = np.sqrt(2.0) * np.asarray(sigma_px, dtype=float)
    with np.errstate(invalid="ignore"):
        mass = 0.5 * (erf((v + 0.5 - c) / s) - erf((v - 0.5 - c) / s))
    # scale so that a stripe centred on a pixel has that pixel at 1 (peak of the area)
    peak = erf(0.5 / s)
    return np.nan_to_num(mass / peak)


def make_frame(rig: Rig, *, forward_m: float = 0.8, sigma_px=1.2,
               laser_dn: float = 110.0, ambient_dn: float = 70.0, noise_dn: float = 2.5,
               crosstalk: tuple[float, float] = (0.12, 0.08), seed: int = 0,
               red_rect: tuple[int, int, int, int] | None = None,
               red_rect_off_laser: tuple[int, int, int, int] | None = None,
               white_blob: tuple[int, int, int] | None = None,
               stripe_cols: tuple[int, int] | None = None,
               texture_contrast: float = 0.1) -> Synth:
    """Render one synthetic left image (BGR uint8) of a textured wall with the stripe.

    Parameters
    ----------
    forward_m : wall distance ahead (sensor x), metres; sets the true stripe rows.
    sigma_px : stripe Gaussian standard deviation across the stripe, pixels (a number
        or one per column).
    laser_dn : laser peak added to the red channel on unit albedo, DN (before clipping).
    ambient_dn : ambient light on unit albedo, DN.
    noise_dn : additive Gaussian noise standard deviation, DN.
    crosstalk : laser light seen by the green and blue channels, fraction of red.
    red_rect : (u0, v0, u1, v1) a wide red object (albedo red 1.6, green/blue 0.25)
        that the stripe crosses (it must contain the stripe rows); the laser light on
        it is scaled by the object's red albedo but, as in the project's renderer, not
        by its texture.
    red_rect_off_laser : (u0, v0, u1, v1) a red object away from the stripe.
    white_blob : (u, v, radius_px) a saturated white highlight.
    stripe_cols : (u0, u1) columns where the stripe is drawn (default: all).
    """
    rng = np.random.default_rng(seed)
    h, w = rig.height_px, rig.width_px
    truth = wall_stripe_rows(rig, forward_m)
    if stripe_cols is not None:
        keep = np.zeros(w, bool)
        keep[stripe_cols[0]:stripe_cols[1]] = True
        truth = np.where(keep, truth, np.nan)
    prof = stripe_profile(truth, h, sigma_px)
    alb = textured_albedo((h, w), rng, contrast=texture_contrast)
    albedo = np.repeat(alb[:, :, None], 3, axis=2)  # RGB order here
    red_cols = np.zeros(w, bool)
    for rect, crossed in ((red_rect, True), (red_rect_off_laser, False)):
        if rect is None:
            continue
        u0, v0, u1, v1 = rect
        tex = alb[v0:v1, u0:u1]
        albedo[v0:v1, u0:u1, 0] = 1.6 * tex
        albedo[v0:v1, u0:u1, 1] = 0.25 * tex
        albedo[v0:v1, u0:u1, 2] = 0.25 * tex
        if crossed:
            red_cols[u0:u1] = np.isfinite(truth[u0:u1])
    light = np.empty((h, w, 3))
    light[:, :, 0] = ambient_dn + laser_dn * prof
    light[:, :, 1] = ambient_dn + laser_dn * crosstalk[0] * prof
    light[:, :, 2] = ambient_dn + laser_dn * crosstalk[1] * prof
    img = albedo * ambient_dn + rng.normal(scale=noise_dn, size=(h, w, 3))
    # the laser adds light scaled by the surface's albedo colour, not its texture
    colour = np.ones((h, w, 3))
    for rect, _ in ((red_rect, True), (red_rect_off_laser, False)):
        if rect is not None:
            u0, v0, u1, v1 = rect
            colour[v0:v1, u0:u1] = (1.6, 0.25, 0.25)
    img += colour * (light - ambient_dn)
    if white_blob is not None:
        bu, bv, br = white_blob
        yy, xx = np.mgrid[0:h, 0:w]
        blob = np.exp(-((xx - bu) ** 2 + (yy - bv) ** 2) / (2.0 * (br / 2.0) ** 2))
        img += 400.0 * blob[:, :, None]
    rgb = np.clip(np.rint(img), 0, 255).astype(np.uint8)
    return Synth(bgr=np.ascontiguousarray(rgb[:, :, ::-1]), stripe_v_px=truth,
                 red_object_cols=red_cols)
