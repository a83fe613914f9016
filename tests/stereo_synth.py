"""Synthetic stereo pairs with exactly known disparity, for the stereo tests.

A procedural texture (a sum of sinusoids, band-limited below 0.25 cycles/px) is
evaluated analytically at shifted coordinates, so the right image of a fronto-parallel
plane at disparity d is the left image shifted by exactly d pixels, with no resampling
error: ``right(u, v) = tex(u + d, v)`` and ``left(u, v) = tex(u, v)``.

A pair's ``seed`` draws everything random in it: the textures' sinusoids and the sensor
noise (:func:`draw_seeds`), so a test run over several seeds sees different textures,
not only different noise.
"""

from __future__ import annotations

import numpy as np


def texture(u: np.ndarray, v: np.ndarray, *, seed: int = 1, contrast_dn: float = 40.0,
            mean_dn: float = 128.0) -> np.ndarray:
    """Band-limited texture at (u, v) (float arrays, pixels), grey levels."""
    rng = np.random.default_rng(seed)
    out = np.zeros(np.broadcast(u, v).shape)
    for _ in range(12):
        f = rng.uniform(0.03, 0.22)
        th = rng.uniform(0.0, np.pi)
        ph = rng.uniform(0.0, 2.0 * np.pi)
        out += np.sin(2.0 * np.pi * f * (np.cos(th) * u + np.sin(th) * v) + ph)
    return mean_dn + contrast_dn * out / np.sqrt(6.0)


def draw_seeds(seed: int, count: int) -> list[int]:
    """``count`` independent integer seeds (textures, noise) drawn from one pair seed."""
    return [int(s) for s in np.random.SeedSequence(seed).generate_state(count)]


def quantise(img: np.ndarray, noise_dn: float, rng: np.random.Generator) -> np.ndarray:
    """Add Gaussian sensor noise and round to uint8."""
    noisy = img + rng.normal(0.0, noise_dn, img.shape) if noise_dn > 0 else img
    return np.clip(np.rint(noisy), 0, 255).astype(np.uint8)


def plane_pair(disparity_px: float, *, width: int = 320, height: int = 240,
               noise_dn: float = 1.0, seed: int = 0, plain_cols: tuple[int, int] | None = None,
               plain_dn: float = 140.0) -> tuple[np.ndarray, np.ndarray]:
    """Grey pair of a textured fronto-parallel plane at ``disparity_px``.

    ``plain_cols = (a, b)`` paints the plane's columns a..b-1 (left-image coordinates)
    a uniform ``plain_dn``: a textureless patch on the same plane, so it appears at
    columns a - d .. b - d in the right image. ``seed`` draws the texture and the noise.
    """
    tex_seed, noise_seed = draw_seeds(seed, 2)
    u, v = np.meshgrid(np.arange(width, dtype=float), np.arange(height, dtype=float))
    left = texture(u, v, seed=tex_seed)
    right = texture(u + disparity_px, v, seed=tex_seed)
    if plain_cols is not None:
        a, b = plain_cols
        left = np.where((u >= a) & (u < b), plain_dn, left)
        right = np.where((u + disparity_px >= a) & (u + disparity_px < b), plain_dn, right)
    rng = np.random.default_rng(noise_seed)
    return quantise(left, noise_dn, rng), quantise(right, noise_dn, rng)


def occlusion_pair(background_px: float, foreground_px: float, box: tuple[int, int, int, int],
                   *, noise_dn: float = 1.0, seed: int = 0, width: int = 320,
                   height: int = 240, foreground_contrast_dn: float = 40.0,
                   background_contrast_dn: float = 40.0,
                   background_dn: float = 128.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A textured square (left-image columns x0..x1-1, rows y0..y1-1) in front of a
    textured background plane. Returns left, right (uint8) and the true left disparity.

    The textures' contrasts (``texture``'s ``contrast_dn``) are set apart; a background
    contrast of 0 gives a plain background of ``background_dn``. ``seed`` draws both
    textures and the noise.
    """
    x0, x1, y0, y1 = box
    fg_seed, bg_seed, noise_seed = draw_seeds(seed, 3)
    u, v = np.meshgrid(np.arange(width, dtype=float), np.arange(height, dtype=float))
    in_rows = (v >= y0) & (v < y1)
    fg_left = in_rows & (u >= x0) & (u < x1)
    fg_right = in_rows & (u + foreground_px >= x0) & (u + foreground_px < x1)

    def fg(uu: np.ndarray) -> np.ndarray:
        return texture(uu, v, seed=fg_seed, contrast_dn=foreground_contrast_dn)

    def bg(uu: np.ndarray) -> np.ndarray:
        return texture(uu, v, seed=bg_seed, contrast_dn=background_contrast_dn,
                       mean_dn=background_dn)

    left = np.where(fg_left, fg(u), bg(u))
    right = np.where(fg_right, fg(u + foreground_px), bg(u + background_px))
    truth = np.where(fg_left, foreground_px, background_px)
    rng = np.random.default_rng(noise_seed)
    return quantise(left, noise_dn, rng), quantise(right, noise_dn, rng), truth
