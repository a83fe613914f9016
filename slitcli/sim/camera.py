"""The camera model of the renderer (DESIGN §10, issue 19): what a real camera does to light.

The renderer computes linear radiance in *linear DN*: 255 is the sensor's white level at
the scene's exposure, values above it are over-exposed light (a close laser stripe reaches
3-4 x white). :func:`apply_camera` turns that into the 8-bit BGR image a real camera would
deliver, stage by stage, each stage optional and off in a default :class:`CameraModel`:

1. laser speckle: the laser's own radiance times a correlated grain field of contrast
   ``speckle_contrast`` (std / mean) and grain ``speckle_grain_px``;
2. vignetting: a cos^4 law whose strength is given by the light lost in the image corner;
3. the colour filter array: each raw pixel sees one channel (``bayer``), with the filters'
   relative response ``channel_response_rgb`` and spectral overlap ``colour_crosstalk``;
4. the sensor: photo-electrons with shot noise (Poisson), a full well with blooming (the
   excess charge of a full pixel spills into its neighbours, mostly along its column), read
   noise, and the ADC (``gain_dn_per_e``, ``adc_bits``);
5. the image processor: demosaicing (OpenCV's bilinear, edge-aware or VNG), white balance,
   the colour matrix that undoes the filters' overlap, a tone curve (gamma or sRGB), 8-bit
   rounding, and JPEG with chroma subsampling.

The exposure is tied to the sensor's white level: linear 255 on the green channel collects
``electrons_at_white`` = min(ADC full scale / gain, full well) electrons, so the gain sets
the noise (a dim room needs a high gain: fewer electrons at white, more noise), not the
brightness.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

import cv2
import numpy as np

from slitcli.errors import SlitcliError
from slitcli.sim._c.camera import bloom_kernel as _bloom_kernel

BAYER_PATTERNS = ("none", "RGGB", "BGGR", "GRBG", "GBRG")
DEMOSAIC_METHODS = ("bilinear", "edge_aware", "vng")
TONE_CURVES = ("linear", "gamma", "srgb")
JPEG_CHROMA = ("420", "422", "444")

# OpenCV names a Bayer pattern by the 2x2 block that starts at the second row and second
# column, so our top-left-first names map to its codes shifted by one pixel both ways.
_CV_BAYER = {"RGGB": "BG", "BGGR": "RG", "GRBG": "GB", "GBRG": "GR"}
_CV_DEMOSAIC = {"bilinear": "", "edge_aware": "_EA", "vng": "_VNG"}
_JPEG_SAMPLING = {"420": 0x221111, "422": 0x211111, "444": 0x111111}
_FWHM_PER_SIGMA = 2.0 * math.sqrt(2.0 * math.log(2.0))


@dataclass(frozen=True)
class CameraModel:
    """A camera's sensor and image processor; the default changes nothing but rounding.

    Attributes
    ----------
    exposure_scale : float
        Exposure time x aperture relative to the scene's, 0.01-100: scales all light, the
        laser's too (a camera that exposes for its mid-tones under a tone curve needs
        about 0.5).
    gain_dn_per_e : float or None
        Conversion gain, raw DN per photo-electron. None: a noiseless sensor (no shot or
        read noise, no full well).
    read_noise_e : float
        Read noise, electrons RMS (needs ``gain_dn_per_e``).
    full_well_e : float or None
        Charge a pixel holds, electrons; None: only the ADC clips (needs ``gain_dn_per_e``).
    adc_bits : int
        Raw bit depth, 8-16; the ADC full scale is ``2**adc_bits - 1`` DN.
    blooming_share : float
        Share 0-1 of a full pixel's excess charge that spills into its neighbours (the rest
        goes to the anti-blooming drain); needs ``full_well_e``.
    blooming_column_share : float
        Share 0-1 of the spilled charge that goes up and down the column (the rest left and
        right): CMOS and CCD pixels leak mostly along their column.
    bayer : str
        Colour filter array: ``none`` (every pixel sees R, G and B) or the 2x2 pattern from
        the top-left pixel, ``RGGB``, ``BGGR``, ``GRBG``, ``GBRG``.
    demosaic : str
        ``bilinear``, ``edge_aware`` or ``vng`` (OpenCV's demosaicing; VNG works on 8-bit
        data, so with it white balance and the tone curve are applied before it).
    channel_response_rgb : (3,) float
        Relative response of the R, G, B filters (quantum efficiency): a channel of
        response 1 collects ``electrons_at_white`` at linear 255, one of 0.5 half of that.
    colour_crosstalk : float
        Spectral overlap 0-0.3 of the colour filters: each filter also passes this share
        of each other colour's light (raw colours come out washed out). The processor's
        colour matrix undoes it, which amplifies colour noise by up to ``1 / (1 - 3 x)``.
    white_balance_rgb : (3,) float or None
        Gains applied to the raw channels; None: neutral, ``1 / channel_response_rgb``.
        Other gains give a colour cast.
    vignetting_corner_loss : float
        Share 0-0.95 of the light lost in the image corner; the fall-off is the cos^4 law
        of a lens whose corner field angle gives that loss.
    speckle_contrast : float
        Std / mean 0-1 of the laser light's speckle (0: none, 1: fully developed).
    speckle_grain_px : float
        Mean speckle grain diameter, pixels (FWHM of the intensity autocorrelation), >= 1.
    tone_curve : str
        ``linear``, ``gamma`` (``out = in ** (1 / gamma)``) or ``srgb`` (IEC 61966-2-1).
    gamma : float
        Exponent of the ``gamma`` tone curve.
    jpeg_quality : int or None
        JPEG quality 1-100 of an encode/decode round trip; None: no compression.
    jpeg_chroma : str
        JPEG chroma subsampling: ``420`` (webcams, MJPEG), ``422`` or ``444``.
    """

    exposure_scale: float = 1.0
    gain_dn_per_e: float | None = None
    read_noise_e: float = 0.0
    full_well_e: float | None = None
    adc_bits: int = 12
    blooming_share: float = 0.0
    blooming_column_share: float = 0.9
    bayer: str = "none"
    demosaic: str = "bilinear"
    channel_response_rgb: tuple[float, float, float] = (1.0, 1.0, 1.0)
    colour_crosstalk: float = 0.0
    white_balance_rgb: tuple[float, float, float] | None = None
    vignetting_corner_loss: float = 0.0
    speckle_contrast: float = 0.0
    speckle_grain_px: float = 1.5
    tone_curve: str = "linear"
    gamma: float = 2.2
    jpeg_quality: int | None = None
    jpeg_chroma: str = "420"

    def __post_init__(self) -> None:
        problems = camera_problems(_values(self))
        if problems:
            name, problem, fix = problems[0]
            raise SlitcliError(f"camera parameter '{name}' {problem}; {fix}")

    @property
    def raw_max_dn(self) -> int:
        """ADC full scale, raw DN."""
        return 2 ** self.adc_bits - 1

    @property
    def electrons_at_white(self) -> float:
        """Electrons a green pixel collects at linear 255 (the white level)."""
        if self.gain_dn_per_e is None:
            return float(self.raw_max_dn)
        n = self.raw_max_dn / self.gain_dn_per_e
        return n if self.full_well_e is None else min(n, self.full_well_e)

    @property
    def white_level_dn(self) -> float:
        """Raw DN of a pixel at the white level (saturated pixels come out white)."""
        gain = 1.0 if self.gain_dn_per_e is None else self.gain_dn_per_e
        return self.electrons_at_white * gain

    @property
    def wb_gains_rgb(self) -> np.ndarray:
        """White balance gains applied to the raw R, G, B channels."""
        if self.white_balance_rgb is not None:
            return np.asarray(self.white_balance_rgb, dtype=float)
        return 1.0 / np.asarray(self.channel_response_rgb, dtype=float)


def _values(m: CameraModel) -> dict[str, Any]:
    return {f.name: getattr(m, f.name) for f in fields(m)}


def camera_problems(values: Mapping[str, Any]) -> list[tuple[str, str, str]]:
    """Everything wrong with camera parameters (all :class:`CameraModel` fields), as
    (parameter, problem, fix) triples."""
    out: list[tuple[str, str, str]] = []
    m = _Fields(values)

    def rng_check(name: str, v: Any, lo: float, hi: float, *, lo_open: bool = False,
                  integer: bool = False, optional: bool = False) -> None:
        if v is None and optional:
            return
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            out.append((name, f"= {v!r} is not a finite number", "give a number"))
        elif integer and v != int(v):
            out.append((name, f"= {v!r} is not a whole number", "give an integer"))
        elif v < lo or (lo_open and v == lo) or v > hi:
            side = ">" if lo_open else ">="
            out.append((name, f"= {v!r} is out of range", f"it must be {side} {lo:g} and "
                        f"<= {hi:g}"))

    rng_check("exposure_scale", m.exposure_scale, 0.01, 100.0)
    rng_check("gain_dn_per_e", m.gain_dn_per_e, 0.0, 1e3, lo_open=True, optional=True)
    rng_check("read_noise_e", m.read_noise_e, 0.0, 1e4)
    rng_check("full_well_e", m.full_well_e, 1.0, 1e7, optional=True)
    rng_check("adc_bits", m.adc_bits, 8, 16, integer=True)
    rng_check("blooming_share", m.blooming_share, 0.0, 1.0)
    rng_check("blooming_column_share", m.blooming_column_share, 0.0, 1.0)
    rng_check("colour_crosstalk", m.colour_crosstalk, 0.0, 0.3)
    rng_check("vignetting_corner_loss", m.vignetting_corner_loss, 0.0, 0.95)
    rng_check("speckle_contrast", m.speckle_contrast, 0.0, 1.0)
    rng_check("speckle_grain_px", m.speckle_grain_px, 1.0, 50.0)
    rng_check("gamma", m.gamma, 0.2, 5.0)
    rng_check("jpeg_quality", m.jpeg_quality, 1, 100, integer=True, optional=True)
    for name, v, lo in (("channel_response_rgb", m.channel_response_rgb, 0.05),
                        ("white_balance_rgb", m.white_balance_rgb, 0.05)):
        if v is None:
            continue
        if (not isinstance(v, tuple | list) or len(v) != 3 or not all(
                isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x)
                and lo <= x <= 20.0 for x in v)):
            shown = list(v) if isinstance(v, tuple) else v
            out.append((name, f"= {shown!r} is not three numbers in [{lo:g}, 20]",
                        "give [r, g, b]"))
    for name, v, allowed in (("bayer", m.bayer, BAYER_PATTERNS),
                             ("demosaic", m.demosaic, DEMOSAIC_METHODS),
                             ("tone_curve", m.tone_curve, TONE_CURVES),
                             ("jpeg_chroma", m.jpeg_chroma, JPEG_CHROMA)):
        if v not in allowed:
            out.append((name, f"= {v!r} is unknown", f"use one of {', '.join(allowed)}"))
    if m.gain_dn_per_e is None:
        for name, on in (("read_noise_e", m.read_noise_e != 0),
                         ("full_well_e", m.full_well_e is not None)):
            if on:
                out.append((name, "needs a sensor gain", "give gain_dn_per_e too"))
    if m.blooming_share and m.full_well_e is None:
        out.append(("blooming_share", "needs a full well", "give full_well_e too"))
    return out


class _Fields:
    """Attribute access to a mapping of camera parameters (checked before a model exists)."""

    def __init__(self, values: Mapping[str, Any]) -> None:
        self.__dict__.update(values)


# ------------------------------------------------------------------ presets
PRESETS: dict[str, dict[str, Any]] = {
    # a 1/4" USB webcam in an office: 10-bit sensor near unity gain, cheap bilinear ISP,
    # strong lens vignetting, sRGB output as MJPEG at quality 80. Speckle 0.25: on the
    # dev set's photographs the stripe's column-to-column flicker is no larger than the
    # noise's, so grain that pixels and optics have not averaged away is weak.
    "webcam": {"exposure_scale": 0.5, "gain_dn_per_e": 0.25, "read_noise_e": 4.0,
               "full_well_e": 6000.0, "adc_bits": 10, "blooming_share": 0.3,
               "bayer": "BGGR", "demosaic": "bilinear",
               "channel_response_rgb": (0.55, 1.0, 0.7), "colour_crosstalk": 0.15,
               "vignetting_corner_loss": 0.35,
               "speckle_contrast": 0.25, "speckle_grain_px": 1.5, "tone_curve": "srgb",
               "jpeg_quality": 80, "jpeg_chroma": "420"},
    # a robot's low stereo camera in a dim room: high analog gain (512 electrons at white,
    # so strong shot noise), gamma 2.2, JPEG 4:2:0 at quality 95 (the quantisation tables
    # and sampling factors of the dev set's robot photographs). Checked against those six
    # photographs with bench/camera_match.py (robust 5x5-residual noise, surface 8-40 rows
    # off the stripe): red-excess noise 6.1-7.7 DN on the sample scenes vs 4.7-11.0 DN,
    # surface R, G 112-130, 110-118 vs 112-132, 95-121, stripe colour (G+B)/2R 0.07-0.28
    # vs 0.15-0.32: all within the photographs' spread. Their stripe is ~3x brighter over
    # the room light than the sample scenes' laser at 0.9 m (a scene term, laser.power_dn),
    # which no camera term can make up: exposure 1 lifts the surface to 150-180 DN.
    "robot": {"exposure_scale": 0.5, "gain_dn_per_e": 2.0, "read_noise_e": 3.0,
              "full_well_e": 9000.0, "adc_bits": 10, "blooming_share": 0.5,
              "bayer": "RGGB", "demosaic": "edge_aware",
              "channel_response_rgb": (0.6, 1.0, 0.75), "colour_crosstalk": 0.2,
              "vignetting_corner_loss": 0.25,
              "speckle_contrast": 0.25, "speckle_grain_px": 1.5, "tone_curve": "gamma",
              "gamma": 2.2, "jpeg_quality": 95, "jpeg_chroma": "420"},
}


def camera_preset(name: str, **overrides: Any) -> CameraModel:
    """A named preset (``webcam``, ``robot``; see :data:`PRESETS`) with fields overridden."""
    if name not in PRESETS:
        raise SlitcliError(f"camera preset '{name}' is unknown; use one of "
                           f"{', '.join(PRESETS)}")
    return CameraModel(**{**PRESETS[name], **overrides})


# ------------------------------------------------------------------ stages
def speckle_field(shape_hw: tuple[int, int], contrast: float, grain_px: float,
                  rng: np.random.Generator) -> np.ndarray:
    """Multiplicative laser speckle: mean 1, std ``contrast``, grain ``grain_px``.

    A circular complex Gaussian field low-passed by the imaging pupil (a Gaussian PSF of
    sigma ``s``) has an exponentially distributed intensity (fully developed speckle,
    contrast 1) whose autocorrelation coefficient is ``exp(-d^2 / (2 s^2))``, so its FWHM,
    the grain diameter, is ``2.355 s``. Share ``contrast`` of the light carries it and the
    rest is uniform (depolarised or averaged over the exposure): ``1 - c + c I``, whose
    std / mean is exactly ``c``.

    Returns
    -------
    (H, W) float
    """
    h, w = shape_hw
    if contrast <= 0:
        return np.ones((h, w))
    s = grain_px / _FWHM_PER_SIGMA
    half = math.ceil(4 * s)
    k = cv2.getGaussianKernel(2 * half + 1, s, cv2.CV_64F)
    # filtering white noise of unit power with k leaves sum(k^2) of it (per axis)
    power = float((k ** 2).sum()) ** 2
    field = []
    for _ in range(2):  # real and imaginary parts, each half the power
        n = rng.standard_normal((h + 2 * half, w + 2 * half)) * math.sqrt(0.5)
        f = cv2.sepFilter2D(n, cv2.CV_64F, k, k, borderType=cv2.BORDER_REFLECT)
        field.append(f[half:half + h, half:half + w])
    intensity = (field[0] ** 2 + field[1] ** 2) / power
    return 1.0 - contrast + contrast * intensity


def vignetting_map(shape_hw: tuple[int, int], corner_loss: float) -> np.ndarray:
    """Relative illumination ``cos^4(theta)`` with ``tan(theta) = t r / r_corner``.

    ``t`` is chosen so that the corner pixel keeps ``1 - corner_loss`` of the centre's
    light: ``t^2 = (1 - corner_loss)^(-1/2) - 1``. The optical centre is the image centre.

    Returns
    -------
    (H, W) float in (0, 1]
    """
    h, w = shape_hw
    if corner_loss <= 0:
        return np.ones((h, w))
    cy, cx = (h - 1) / 2.0, (w - 1) / 2.0
    yy, xx = np.mgrid[0:h, 0:w]
    rho2 = ((yy - cy) ** 2 + (xx - cx) ** 2) / (cy ** 2 + cx ** 2)
    t2 = (1.0 - corner_loss) ** -0.5 - 1.0
    return 1.0 / (1.0 + t2 * rho2) ** 2


def cfa_channel(shape_hw: tuple[int, int], bayer: str) -> np.ndarray:
    """Colour (0 R, 1 G, 2 B) each raw pixel of a Bayer pattern sees, (H, W) int."""
    code = {"R": 0, "G": 1, "B": 2}
    tile = np.array([[code[bayer[0]], code[bayer[1]]], [code[bayer[2]], code[bayer[3]]]])
    h, w = shape_hw
    return np.tile(tile, ((h + 1) // 2, (w + 1) // 2))[:h, :w]

def bloom(electrons: np.ndarray, full_well_e: float, share: float,
          column_share: float) -> np.ndarray:
    """Clip charge at the full well; ``share`` of each full pixel's excess spills over.

    Of the spilled charge, ``column_share / 2`` flows up and down the column and
    ``(1 - column_share) / 2`` left and right. Flowing away from its pixel it fills the
    next pixel; once that is full, it passes on ``share`` of what is left (its own
    anti-blooming drain takes the rest), so a strongly over-exposed spot draws a vertical
    streak. Charge that flows past the border is lost. With ``share = 1`` and no border in
    reach every electron is kept.

    Parameters
    ----------
    electrons : (H, W) float
        Collected charge per raw pixel, electrons (not changed).

    Returns
    -------
    (H, W) float, electrons, every value <= ``full_well_e``.
    """
    e = np.ascontiguousarray(electrons, dtype=np.float64)
    return _bloom_kernel(e, float(full_well_e), float(share), float(column_share))


def read_out(electrons_mean: np.ndarray, model: CameraModel,
             rng: np.random.Generator) -> np.ndarray:
    """Sensor and ADC: shot noise, full well and blooming, read noise, quantisation.

    Parameters
    ----------
    electrons_mean : (H, W) or (H, W, C) float
        Expected photo-electrons per raw pixel.

    Returns
    -------
    Same shape, float: raw DN, whole numbers in [0, ``model.raw_max_dn``].
    """
    mean = np.maximum(np.asarray(electrons_mean, dtype=float), 0.0)
    if model.gain_dn_per_e is None:
        return np.clip(np.rint(mean), 0, model.raw_max_dn)
    e = rng.poisson(mean).astype(float)
    if model.full_well_e is not None:
        if model.blooming_share > 0:
            planes = e[..., None] if e.ndim == 2 else e
            e = np.stack([bloom(planes[..., c], model.full_well_e, model.blooming_share,
                                model.blooming_column_share)
                          for c in range(planes.shape[-1])], axis=-1).reshape(e.shape)
        else:
            e = np.minimum(e, model.full_well_e)
    if model.read_noise_e > 0:
        e = e + rng.normal(0.0, model.read_noise_e, e.shape)
    return np.clip(np.rint(model.gain_dn_per_e * e), 0, model.raw_max_dn)


def tone(x01: np.ndarray, model: CameraModel) -> np.ndarray:
    """The tone curve on linear values in [0, 1] (clipped first); output in [0, 1]."""
    x = np.clip(x01, 0.0, 1.0)
    if model.tone_curve == "gamma":
        return x ** (1.0 / model.gamma)
    if model.tone_curve == "srgb":
        return np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)
    return x


def colour_mixing(crosstalk: float) -> np.ndarray:
    """Raw colour from true colour, (3, 3): ``(1 - 3 x) I + x J`` (rows sum to 1, so white
    stays white); its inverse ``(I - x J) / (1 - 3 x)`` is the processor's colour matrix."""
    return (1.0 - 3.0 * crosstalk) * np.eye(3) + crosstalk


def untone(y01: np.ndarray, model: CameraModel) -> np.ndarray:
    """Inverse of :func:`tone` on [0, 1]."""
    y = np.clip(y01, 0.0, 1.0)
    if model.tone_curve == "gamma":
        return y ** model.gamma
    if model.tone_curve == "srgb":
        return np.where(y <= 0.04045, y / 12.92, ((y + 0.055) / 1.055) ** 2.4)
    return y


def _colour_matrix(rgb01: np.ndarray, model: CameraModel) -> np.ndarray:
    if model.colour_crosstalk <= 0:
        return rgb01
    return np.clip(rgb01, 0.0, 1.0) @ np.linalg.inv(colour_mixing(model.colour_crosstalk)).T


def jpeg_round_trip(bgr: np.ndarray, quality: int, chroma: str = "420") -> np.ndarray:
    """Encode and decode an 8-bit BGR image as JPEG (OpenCV/libjpeg)."""
    params = [cv2.IMWRITE_JPEG_QUALITY, int(quality),
              cv2.IMWRITE_JPEG_SAMPLING_FACTOR, _JPEG_SAMPLING[chroma]]
    ok, buf = cv2.imencode(".jpg", bgr, params)
    if not ok:  # pragma: no cover - libjpeg refuses only impossible input
        raise SlitcliError("JPEG encoding failed; check jpeg_quality")
    return cv2.imdecode(buf, cv2.IMREAD_COLOR)


def _to_8bit(x01: np.ndarray) -> np.ndarray:
    return np.clip(np.rint(255.0 * x01), 0, 255).astype(np.uint8)


def _process(raw_dn: np.ndarray, model: CameraModel) -> np.ndarray:
    """Image processor: demosaic, white balance (clipped at white, so saturated is white),
    colour matrix, tone curve -> 8-bit RGB (H, W, 3)."""
    wb = model.wb_gains_rgb / model.white_level_dn
    if model.bayer == "none":
        return _to_8bit(tone(_colour_matrix(raw_dn * wb, model), model))
    code = f"COLOR_Bayer{_CV_BAYER[model.bayer]}2RGB{_CV_DEMOSAIC[model.demosaic]}"
    if model.demosaic == "vng":  # OpenCV's VNG takes 8-bit data only: tone curve first
        chan = cfa_channel(raw_dn.shape, model.bayer)
        encoded = _to_8bit(tone(raw_dn * wb[chan], model))
        rgb8 = cv2.cvtColor(encoded, getattr(cv2, code))
        if model.colour_crosstalk <= 0:
            return rgb8
        return _to_8bit(tone(_colour_matrix(untone(rgb8 / 255.0, model), model), model))
    rgb = cv2.cvtColor(raw_dn.astype(np.uint16), getattr(cv2, code)).astype(float)
    return _to_8bit(tone(_colour_matrix(rgb * wb, model), model))


def apply_camera(linear_rgb_dn: np.ndarray, model: CameraModel, rng: np.random.Generator,
                 *, laser_rgb_dn: np.ndarray | None = None,
                 speckle_rng: np.random.Generator | None = None) -> np.ndarray:
    """The image a camera delivers from the light that reaches it.

    Parameters
    ----------
    linear_rgb_dn : (H, W, 3) float
        Linear radiance of the scene without the laser, RGB, linear DN (255 = white level;
        brighter light over-exposes). Not changed.
    model : CameraModel
    rng : numpy Generator
        Speckle and sensor noise.
    laser_rgb_dn : (H, W, 3) float, optional
        The laser's own radiance, RGB, linear DN; speckle applies to it alone.
    speckle_rng : numpy Generator, optional
        Draws the speckle pattern (default: ``rng``). The pattern belongs to the geometry
        of laser, surface and camera, so a still view keeps it from frame to frame: pass
        a generator seeded by the view for that.

    Returns
    -------
    (H, W, 3) uint8, BGR (OpenCV order).
    """
    light = np.asarray(linear_rgb_dn, dtype=float)
    h, w = light.shape[:2]
    if laser_rgb_dn is not None:
        grain = speckle_field((h, w), model.speckle_contrast, model.speckle_grain_px,
                              rng if speckle_rng is None else speckle_rng)
        light = light + np.asarray(laser_rgb_dn, dtype=float) * grain[..., None]
    light = light * (model.exposure_scale
                     * vignetting_map((h, w), model.vignetting_corner_loss)[..., None])
    if model.colour_crosstalk > 0:
        light = light @ colour_mixing(model.colour_crosstalk).T
    electrons = light * (np.asarray(model.channel_response_rgb) * model.electrons_at_white
                         / 255.0)
    if model.bayer != "none":
        chan = cfa_channel((h, w), model.bayer)
        electrons = np.take_along_axis(electrons, chan[..., None], axis=2)[..., 0]
    raw = read_out(electrons, model, rng)
    bgr = np.ascontiguousarray(_process(raw, model)[..., ::-1])
    if model.jpeg_quality is not None:
        bgr = jpeg_round_trip(bgr, model.jpeg_quality, model.jpeg_chroma)
    return bgr


# ------------------------------------------------------------------ scene keys
_FIELDS = tuple(f.name for f in fields(CameraModel))
_CHOICE_KEYS = ("bayer", "demosaic", "tone_curve", "jpeg_chroma")


def camera_from_scene(v: Any, key: str, keys: Any) -> CameraModel | None:
    """Build the camera model from the scene's ``image.camera`` value (docs/scene.md).

    ``v`` is None (no camera model), a preset name, or a mapping of :class:`CameraModel`
    fields plus an optional ``preset`` whose values they override. ``keys`` is the scene
    loader's key checker (``mapping`` and ``err``), so messages name the file and key.
    """
    if v is None:
        return None
    preset_key = key
    if not isinstance(v, str | Mapping):
        raise keys.err(key, f"= {v!r} is neither a preset name nor a mapping",
                       f"give one of {', '.join(PRESETS)} or camera keys (docs/scene.md)")
    if isinstance(v, str):
        v = {"preset": v}
    else:
        preset_key = f"{key}.preset"
    m: Mapping[str, Any] = keys.mapping(v, key, ("preset", *_FIELDS))
    base: dict[str, Any] = {}
    if "preset" in m:
        if m["preset"] not in PRESETS:
            raise keys.err(preset_key, f"= {m['preset']!r} is not a camera preset",
                           f"use one of {', '.join(PRESETS)} or give the keys")
        base = dict(PRESETS[m["preset"]])
    kw = {**base, **{k: x for k, x in m.items() if k != "preset"}}
    for k in ("channel_response_rgb", "white_balance_rgb"):
        if isinstance(kw.get(k), list):
            kw[k] = tuple(kw[k])
    for k in _CHOICE_KEYS:  # YAML reads 420 as a number
        if isinstance(kw.get(k), int) and not isinstance(kw[k], bool):
            kw[k] = str(kw[k])
    for k in ("adc_bits", "jpeg_quality"):  # 12.0 is 12
        if isinstance(kw.get(k), float) and kw[k].is_integer():
            kw[k] = int(kw[k])
    if isinstance(kw.get("bayer"), str) and kw["bayer"] != "none":
        kw["bayer"] = kw["bayer"].upper()
    # check before building, so the message names the scene key, not the parameter
    problems = camera_problems({**_values(CameraModel()), **kw})
    if problems:
        name, problem, fix = problems[0]
        raise keys.err(f"{key}.{name}", problem, fix)
    return CameraModel(**kw)


def camera_to_scene(model: CameraModel | None) -> dict[str, Any] | None:
    """The ``image.camera`` mapping that :func:`camera_from_scene` reads back (plain YAML
    types: lists, not tuples)."""
    if model is None:
        return None
    out: dict[str, Any] = {}
    for f in _FIELDS:
        v = getattr(model, f)
        out[f] = list(v) if isinstance(v, tuple) else v
    return out
