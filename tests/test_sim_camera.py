"""The renderer's camera model (slitcli.sim.camera) against hand-derived physics."""

import hashlib
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from slitcli.cli import cli
from slitcli.errors import SlitcliError
from slitcli.rig import paper_rig
from slitcli.sim.camera import (
    PRESETS,
    CameraModel,
    apply_camera,
    bloom,
    camera_preset,
    camera_to_scene,
    cfa_channel,
    jpeg_round_trip,
    read_out,
    speckle_field,
)
from slitcli.sim.render import render_frame
from slitcli.sim.scene import load_scene, scene_from_dict
from slitcli.sim.sequence import scene_to_dict

ROOT = Path(__file__).resolve().parent.parent
SEEDS = [0, 1, 2, 3, 4]


# ------------------------------------------------------------------ off by default
# SHA-256 of left + right bytes of frame_index 1, rendered by commit 2bfd795 (before the
# camera model existed): a scene without image.camera must keep its exact look.
GOLDEN = {
    "fig4": "b9026ea63aa0ac26a5de44b436da6dcdd200534fd37db9ee5cebe33e0f306d19",
    "distractors": "71be53fe8c353ce27de06e70e61dbf8ee0ba9898e599724b354f8a66fc2edf5f",
}


@pytest.mark.parametrize("name", sorted(GOLDEN))
def test_scene_without_camera_renders_bit_identically(name):
    scene = load_scene(ROOT / "sample_data" / f"{name}.yaml")
    assert scene.image.camera is None
    f = render_frame(scene, paper_rig(), scene.poses()[0], frame_index=1)
    digest = hashlib.sha256(f.left_bgr.tobytes() + f.right_bgr.tobytes()).hexdigest()
    assert digest == GOLDEN[name]


@pytest.mark.parametrize("seed", range(5))
def test_default_model_only_rounds(seed):
    """Every stage is off in CameraModel(): the output is the rounded, clipped input."""
    rng = np.random.default_rng(5 + seed)
    light = rng.uniform(-20, 300, (40, 60, 3))
    out = apply_camera(light, CameraModel(adc_bits=16), rng)
    # 16-bit ADC then 8-bit rounding: within half an 8-bit step plus the ADC's step
    want = np.clip(light, 0, 255)[..., ::-1]
    assert np.abs(out - want).max() <= 0.5 + 255 / 65535 + 1e-9


# ------------------------------------------------------------------ sensor noise
@pytest.mark.parametrize("seed", SEEDS)
def test_raw_noise_variance_is_gain_times_signal_plus_read_squared(seed):
    """var(DN) = g mean(DN) + (g sigma_read)^2 + 1/12 (ADC rounding)."""
    g, read = 0.5, 3.0
    model = CameraModel(gain_dn_per_e=g, read_noise_e=read, adc_bits=16)
    rng = np.random.default_rng(seed)
    levels_e = np.array([50.0, 200.0, 800.0, 2000.0, 5000.0, 12000.0])
    n = 128 * 128
    means, varis = [], []
    for e in levels_e:
        raw = read_out(np.full((128, 128), e), model, rng)
        means.append(raw.mean())
        varis.append(raw.var(ddof=1))
    means, varis = np.array(means), np.array(varis)
    se = varis * math.sqrt(2.0 / (n - 1))  # standard error of a Gaussian sample variance
    coef, cov = np.polyfit(means, varis, 1, w=1.0 / se, cov="unscaled")
    slope_se, icpt_se = np.sqrt(np.diag(cov))
    assert abs(coef[0] - g) < 4 * slope_se
    assert abs(coef[1] - ((g * read) ** 2 + 1 / 12)) < 4 * icpt_se
    assert slope_se < 0.01  # the test resolves the gain to 2 %


@pytest.mark.parametrize("seed", SEEDS)
def test_output_noise_per_channel_follows_the_filter_response(seed):
    """Linear output, no CFA: var_c = 255 L / (N_white r_c) + (255 s / (N_white r_c))^2
    + 1/12, so a channel with half the response is twice as noisy (white balance)."""
    resp = (0.5, 1.0, 0.8)
    model = CameraModel(gain_dn_per_e=1.0, read_noise_e=3.0, adc_bits=10,
                        channel_response_rgb=resp)
    nw = model.electrons_at_white
    assert nw == 1023
    rng = np.random.default_rng(seed)
    level = 100.0
    out = apply_camera(np.full((160, 160, 3), level), model, rng)[..., ::-1].astype(float)
    n = 160 * 160
    for c in range(3):
        k = 255.0 / (nw * resp[c])
        want = k * 255.0 * level / 255.0 + (k * 3.0) ** 2 + 1 / 12 + (k / 12 if k < 1 else 0)
        var = out[..., c].var(ddof=1)
        assert abs(var - want) < 4 * want * math.sqrt(2.0 / n) + k ** 2 / 12
        assert abs(out[..., c].mean() - level) < 4 * math.sqrt(want / n) + 0.5


@pytest.mark.parametrize("seed", SEEDS)
def test_colour_matrix_amplifies_colour_noise(seed):
    """Filter overlap x, undone by (I - x J) / (1 - 3x): each output channel's variance is
    sum_j Minv_cj^2 var_j = ((1 - x)^2 + 2 x^2) / (1 - 3x)^2 times the raw channel's."""
    x, level = 0.2, 100.0
    model = CameraModel(gain_dn_per_e=1.0, adc_bits=10, colour_crosstalk=x)
    out = apply_camera(np.full((160, 160, 3), level), model, np.random.default_rng(seed))
    out = out.astype(float)
    n = 160 * 160
    per_raw = 255.0 * level / model.electrons_at_white  # a raw channel's 8-bit variance
    want = per_raw * ((1 - x) ** 2 + 2 * x ** 2) / (1 - 3 * x) ** 2 + 1 / 12
    assert want / per_raw > 4  # the test tells an amplified channel from a plain one
    for c in range(3):
        assert out[..., c].var(ddof=1) == pytest.approx(want, abs=4 * want * math.sqrt(2 / n))
        assert out[..., c].mean() == pytest.approx(level, abs=4 * math.sqrt(want / n) + 0.5)
    # grey stays grey: the luminance noise is the plain one (the matrix keeps J)
    grey = out.mean(axis=2)
    assert grey.var(ddof=1) == pytest.approx(per_raw / 3, rel=6 * math.sqrt(2 / n) + 0.02)


# ------------------------------------------------------------------ full well, blooming
@pytest.mark.parametrize("seed", SEEDS)
def test_no_blooming_below_full_well(seed):
    e = np.random.default_rng(seed).uniform(0, 999, (30, 40))
    assert np.array_equal(bloom(e, 1000.0, 1.0, 0.9), e)


@pytest.mark.parametrize("seed", SEEDS)
def test_blooming_spreads_only_from_full_pixels(seed):
    """Without cascades (neighbours stay below the well), the spill is exact: each
    neighbour of a full pixel gets share * excess * (column_share or 1 - column_share) / 2,
    nothing else changes, and (1 - share) of the excess is drained."""
    rng = np.random.default_rng(seed)
    fw, share, col = 1000.0, 0.6, 0.8
    e = rng.uniform(0, 400, (50, 60))
    grid = rng.choice(8 * 10, 6, replace=False)  # 6 spots at least 6 px apart
    ys, xs = 3 + 6 * (grid // 10), 3 + 6 * (grid % 10)
    e[ys, xs] = fw + rng.uniform(0, 900, len(ys))  # a neighbour gets < 400 + 216
    excess = np.maximum(e - fw, 0)
    out = bloom(e, fw, share, col)
    want = np.minimum(e, fw)
    s = share * excess
    want[1:] += 0.5 * col * s[:-1]
    want[:-1] += 0.5 * col * s[1:]
    want[:, 1:] += 0.5 * (1 - col) * s[:, :-1]
    want[:, :-1] += 0.5 * (1 - col) * s[:, 1:]
    assert np.all(want[excess == 0] < fw)  # no cascade: the formula is exact
    np.testing.assert_allclose(out, np.minimum(want, fw), rtol=0, atol=1e-9)
    far = np.ones_like(e, bool)
    for dy, dx in ((0, 0), (1, 0), (-1, 0), (0, 1), (0, -1)):
        far[ys + dy, xs + dx] = False
    assert np.array_equal(out[far], e[far])
    assert out.sum() == pytest.approx(e.sum() - (1 - share) * excess.sum(), rel=1e-12)


@pytest.mark.parametrize("over", [2.5, 4.0, 5.5, 7.0, 9.5])
def test_blooming_streak_along_the_column(over):
    """All excess spilled up and down a column: the streak holds it, full pixels next to
    the spot and one partial pixel at each end (charge passes a pixel only when it is full).
    With share 1/2 each full pixel passed halves what flows on."""
    fw = 1000.0
    e = np.zeros((41, 9))
    e[20, 4] = fw * (1 + over)
    out = bloom(e, fw, 1.0, 1.0)
    assert out.sum() == pytest.approx(e.sum(), rel=1e-5)
    col = out[:, 4]
    assert np.all(np.delete(out, 4, axis=1) == 0)
    k, part = divmod(over / 2, 1.0)  # per side: k full pixels and a fraction
    for side in (1, -1):
        run = col[20 + side * np.arange(1, int(k) + 2)]
        np.testing.assert_allclose(run[:-1], fw, rtol=1e-5)
        assert run[-1] == pytest.approx(part * fw, abs=2e-3 * fw)
    assert col[20] == fw
    half = bloom(e, fw, 0.5, 1.0)[:, 4]
    q, k = 0.5 * 0.5 * over * fw, 1  # per side, flowing into pixel 20 + k
    while q > fw:
        assert half[20 + k] == half[20 - k] == fw
        q, k = 0.5 * (q - fw), k + 1
    assert half[20 + k] == pytest.approx(q, rel=1e-12)
    assert np.all(half[20 + k + 1:] == 0)


# ------------------------------------------------------------------ demosaicing
@pytest.mark.parametrize("bayer", ["RGGB", "BGGR", "GRBG", "GBRG"])
@pytest.mark.parametrize("method", ["bilinear", "edge_aware", "vng"])
@pytest.mark.parametrize("seed", SEEDS)
def test_demosaicing_a_flat_colour_returns_it(bayer, method, seed):
    rng = np.random.default_rng(seed)
    colour = rng.uniform(20, 240, 3)
    model = CameraModel(bayer=bayer, demosaic=method, adc_bits=12,
                        channel_response_rgb=tuple(rng.uniform(0.4, 1.0, 3)),
                        colour_crosstalk=0.2 * (seed % 2))
    out = apply_camera(np.broadcast_to(colour, (24, 32, 3)), model, rng)[..., ::-1]
    inner = out[2:-2, 2:-2].reshape(-1, 3).astype(float)
    # a raw step is 255 / 4095 / response of 8-bit DN, times up to 1.4 + 2 x 0.5 through
    # the colour matrix; VNG rounds to 8 bits first (and again around the colour matrix)
    step = 255 / 4095 / 0.4 * (2.4 if model.colour_crosstalk else 1.0)
    vng = (1.0 if not model.colour_crosstalk else 2.5) if method == "vng" else 0.0
    assert np.abs(inner - colour).max() <= 0.5 + step + vng


@pytest.mark.parametrize("bayer", ["RGGB", "BGGR", "GRBG", "GBRG"])
def test_cfa_layout(bayer):
    names = np.array(list("RGB"))[cfa_channel((2, 2), bayer)]
    assert "".join(names.ravel()) == bayer


# ------------------------------------------------------------------ vignetting
@pytest.mark.parametrize("loss", [0.05, 0.2, 0.35, 0.6, 0.9])
@pytest.mark.parametrize("curve", ["linear", "srgb"])
def test_vignetting_corner_and_half_field(loss, curve):
    """cos^4 law: corner keeps 1 - loss; at half the corner radius cos^4(atan(t / 2))."""
    h, w, level = 61, 81, 200.0  # odd sizes: a pixel sits on the optical centre
    model = CameraModel(vignetting_corner_loss=loss, tone_curve=curve, adc_bits=16)
    # every noise stage is off: the generator is never drawn from, so one seed suffices
    out = apply_camera(np.full((h, w, 3), level), model, np.random.default_rng(0))

    def encode(x):
        return 255 * x if curve == "linear" else 255 * (1.055 * x ** (1 / 2.4) - 0.055)

    t = math.sqrt((1 - loss) ** -0.5 - 1)
    step = 0.5 + 1.0  # 8-bit rounding and the sRGB slope times the 16-bit ADC step
    for (y, x), rho in (((0, 0), 1.0), ((h - 1, w - 1), 1.0), ((30, 40), 0.0),
                        ((15, 20), 0.5), ((45, 60), 0.5)):
        v = math.cos(math.atan(t * rho)) ** 4
        assert out[y, x, 1] == pytest.approx(encode(level / 255 * v), abs=step)
    if curve == "linear":
        assert out[0, 0, 1] / out[30, 40, 1] == pytest.approx(1 - loss, abs=1.0 / 200)


# ------------------------------------------------------------------ speckle
@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize(("contrast", "grain"), [(0.3, 4.0), (0.6, 6.0), (1.0, 4.0),
                                                 (0.5, 8.0)])
def test_speckle_contrast_mean_and_grain(seed, contrast, grain):
    """Mean 1 and std/mean = contrast; intensity autocorrelation 1/2 at half the grain.

    Standard errors of correlated samples: mean c sqrt(2 pi s^2 / N); std
    c sqrt(8 pi s^2 / N) / 2 (exponential intensity, 4th moment 9); s = grain / 2.355.
    """
    n_side = 512
    sp = speckle_field((n_side, n_side), contrast, grain, np.random.default_rng(seed))
    s = grain / (2 * math.sqrt(2 * math.log(2)))
    n = n_side ** 2
    assert abs(sp.mean() - 1) < 4 * contrast * math.sqrt(2 * math.pi * s * s / n)
    assert abs(sp.std() - contrast) < 4 * contrast * math.sqrt(8 * math.pi * s * s / n) / 2
    lag = int(grain / 2)
    d = sp - sp.mean()
    rho = np.mean([(d[:, lag:] * d[:, :-lag]).mean(), (d[lag:] * d[:-lag]).mean()]) / d.var()
    assert rho == pytest.approx(0.5, abs=0.05)
    assert sp.min() >= 1 - contrast - 1e-12


@pytest.mark.parametrize("seed", SEEDS)
def test_speckle_is_on_the_laser_light_only(seed):
    rng = np.random.default_rng(seed)
    scene_light = rng.uniform(10, 40, (200, 200, 3))
    laser = np.zeros((200, 200, 3))
    laser[:, 100:, 0] = 30.0  # clips (255) only past 16x the mean speckle: p < 1e-7
    model = CameraModel(speckle_contrast=0.4, speckle_grain_px=3.0, adc_bits=16)
    out = apply_camera(scene_light, model, rng, laser_rgb_dn=laser)[..., ::-1].astype(float)
    step = 0.5 + 255 / 65535
    assert np.abs(out[:, :100] - scene_light[:, :100]).max() <= step
    lit = out[:, 100:, 0] - scene_light[:, 100:, 0]
    s = 3.0 / 2.355
    se = 0.4 * math.sqrt(8 * math.pi * s * s / lit.size) / 2
    # 8-bit rounding of the output and of the subtracted light adds 2/12 DN^2
    want = math.sqrt(0.4 ** 2 + 2 / 12 / 30 ** 2)
    assert lit.std() / lit.mean() == pytest.approx(want, abs=4 * se)
    assert lit.mean() == pytest.approx(30, abs=4 * 0.4 * 30 * math.sqrt(
        2 * math.pi * s * s / lit.size))


# ------------------------------------------------------------------ tone curve, white balance
@pytest.mark.parametrize("level", [5.0, 40.0, 100.0, 180.0, 250.0])
def test_tone_curves(level):
    x = level / 255
    # noise off: the generator is never drawn from, so one seed suffices
    for curve, want in (("linear", x), ("gamma", x ** (1 / 2.2)),
                        ("srgb", 1.055 * x ** (1 / 2.4) - 0.055)):
        out = apply_camera(np.full((4, 4, 3), level),
                           CameraModel(tone_curve=curve, adc_bits=16),
                           np.random.default_rng(0))
        assert np.all(np.abs(out - 255 * want) <= 0.5 + 2.0 * 255 / 65535 * 255 / level)


def test_white_balance_gains_make_a_cast():
    # noise off: the generator is never drawn from, so one seed suffices
    out = apply_camera(np.full((4, 4, 3), 100.0),
                       CameraModel(white_balance_rgb=(1.5, 1.0, 0.5), adc_bits=16),
                       np.random.default_rng(0))[..., ::-1]
    assert np.all(np.abs(out[0, 0] - np.array([150, 100, 50])) <= 1)


# ------------------------------------------------------------------ JPEG
def _textured(seed: int) -> np.ndarray:
    """A natural-looking test image: fine luminance texture, slowly varying tint."""
    from slitcli.sim.texture import value_noise

    yy, xx = np.mgrid[0:120, 0:160] * 0.01
    lum = value_noise(xx.ravel(), yy.ravel(), seed=seed, scale_m=0.05)
    tint = np.stack([value_noise(xx.ravel(), yy.ravel(), seed=seed * 3 + c + 100,
                                 scale_m=0.3) for c in range(3)], -1)
    return (255 * lum[:, None] * (0.4 + 0.6 * tint)).reshape(120, 160, 3)


@pytest.mark.parametrize("seed", SEEDS)
def test_jpeg_quality_lowers_psnr_monotonically(seed):
    light = _textured(seed)
    rng = np.random.default_rng(seed)
    clean = apply_camera(light, CameraModel(), rng).astype(float)
    psnr = {}
    for chroma in ("420", "444"):
        psnr[chroma] = []
        for q in (98, 90, 75, 50, 25, 10):
            out = apply_camera(light, CameraModel(jpeg_quality=q, jpeg_chroma=chroma), rng)
            err = np.mean((out.astype(float) - clean) ** 2)
            psnr[chroma].append(10 * math.log10(255 ** 2 / err))
        assert np.all(np.diff(psnr[chroma]) < 0), psnr
    # chroma subsampling loses information at every quality
    assert np.all(np.array(psnr["420"]) < np.array(psnr["444"])), psnr


@pytest.mark.parametrize("row", [40, 41, 42, 43, 44])
def test_jpeg_420_halves_then_spreads_the_chroma_of_a_thin_line(row):
    """A 1-px red line: 4:2:0 averages chroma over 2 rows (c / 2) and libjpeg's triangular
    upsampling gives the line's row 3/4 of that: 0.375 of the 4:4:4 chroma."""
    img = np.full((96, 128, 3), 100, np.uint8)
    img[row, :, 2] = 220
    excess = {}
    for chroma in ("444", "420"):
        out = jpeg_round_trip(img, 95, chroma).astype(float)
        excess[chroma] = (out[row, 8:-8, 2] - (out[row, 8:-8, 1] + out[row, 8:-8, 0]) / 2
                          ).mean()
    assert excess["444"] == pytest.approx(120, abs=6)
    assert excess["420"] / excess["444"] == pytest.approx(0.375, abs=0.08)


# ------------------------------------------------------------------ scene keys
def _scene(camera) -> dict:
    return {"slitcli_scene": 1, "image": {"camera": camera}}


def test_scene_keys_presets_and_overrides():
    s = scene_from_dict(_scene("webcam"))
    assert s.image.camera == camera_preset("webcam")
    s = scene_from_dict(_scene({"preset": "robot", "jpeg_quality": 60, "bayer": "gbrg",
                                "jpeg_chroma": 444, "white_balance_rgb": [2, 1, 1.5]}))
    assert s.image.camera == camera_preset("robot", jpeg_quality=60, bayer="GBRG",
                                           jpeg_chroma="444", white_balance_rgb=(2, 1, 1.5))
    assert scene_from_dict(_scene(None)).image.camera is None
    for name in PRESETS:  # written back by `slitcli render` as plain YAML, read again
        d = scene_to_dict(scene_from_dict(_scene(name)))
        again = scene_from_dict(yaml.safe_load(yaml.safe_dump(d)))
        assert again.image.camera == camera_preset(name)
        assert camera_to_scene(again.image.camera) == d["image"]["camera"]


@pytest.mark.parametrize(("camera", "key"), [
    ({"gain_dn_per_e": 1, "shot": 2}, "image.camera.shot"),
    ({"jpeg_quality": 101}, "image.camera.jpeg_quality"),
    ({"jpeg_quality": 50.5}, "image.camera.jpeg_quality"),
    ({"gain_dn_per_e": float("nan")}, "image.camera.gain_dn_per_e"),
    ({"gain_dn_per_e": 0}, "image.camera.gain_dn_per_e"),
    ({"read_noise_e": 2}, "image.camera.read_noise_e"),
    ({"blooming_share": 0.2}, "image.camera.blooming_share"),
    ({"bayer": "RGBG"}, "image.camera.bayer"),
    ({"demosaic": "ahd"}, "image.camera.demosaic"),
    ({"vignetting_corner_loss": 1.0}, "image.camera.vignetting_corner_loss"),
    ({"speckle_grain_px": 0.2}, "image.camera.speckle_grain_px"),
    ({"white_balance_rgb": [1, 1]}, "image.camera.white_balance_rgb"),
    ({"colour_crosstalk": 0.4}, "image.camera.colour_crosstalk"),
    ({"preset": "dslr"}, "image.camera.preset"),
    ("dslr", "image.camera"),
    ([1, 2], "image.camera"),
])
def test_bad_camera_keys_name_the_key(tmp_path, camera, key):
    with pytest.raises(SlitcliError, match=key.replace(".", r"\.")):
        scene_from_dict(_scene(camera), "s.yaml")
    if isinstance(camera, dict) and any(isinstance(v, float) and math.isnan(v)
                                        for v in camera.values()):
        return
    scene = tmp_path / "bad.yaml"
    scene.write_text(yaml.safe_dump(_scene(camera)))
    res = CliRunner().invoke(cli, ["render", str(scene), str(tmp_path / "out")])
    assert res.exit_code == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and key in lines[0]
    assert not (tmp_path / "out").exists()


def test_library_model_checks_its_parameters():
    with pytest.raises(SlitcliError, match="speckle_contrast"):
        CameraModel(speckle_contrast=1.5)
    with pytest.raises(SlitcliError, match="preset"):
        camera_preset("dslr")


def test_speckle_belongs_to_the_view_not_the_frame():
    """A still view keeps its speckle from frame to frame (a stable laser on a still
    surface); the other camera and a moved robot see other patterns. The first is an
    identity of the draw and the others need two independent patterns to differ, which
    any seed gives: one seed suffices."""
    from slitcli.sim.scene import Pose2D

    d = {"slitcli_scene": 1, "seed": 2,
         "image": {"supersample": 1, "camera": {"speckle_contrast": 0.6, "exposure_scale": 0.5,
                                                "speckle_grain_px": 2.0}},
         "objects": [{"type": "wall", "from_xy_m": [1.0, -3.0], "to_xy_m": [1.0, 3.0],
                      "height_m": 2.0, "surface": {"texture": "plain"}}]}
    scene = scene_from_dict(d)
    rig = paper_rig()
    a = render_frame(scene, rig, Pose2D(0, 0, 0), frame_index=0)
    b = render_frame(scene, rig, Pose2D(0, 0, 0), frame_index=1)
    moved = render_frame(scene, rig, Pose2D(0.02, 0, 0), frame_index=0)
    stripe = np.isfinite(a.truth.stripe_v_px)
    rows = np.rint(a.truth.stripe_v_px[stripe]).astype(int)
    cols = np.nonzero(stripe)[0]
    assert len(cols) > 200
    red = {k: f.left_bgr[rows, cols, 2].astype(float) for k, f in
           (("a", a), ("b", b), ("moved", moved))}
    assert np.array_equal(a.left_bgr, b.left_bgr)
    assert np.corrcoef(red["a"], red["moved"])[0, 1] < 0.5
    right = a.right_bgr[rows, cols, 2].astype(float)
    assert np.corrcoef(red["a"], right)[0, 1] < 0.5
    # the speckle is there to compare: without it neighbouring columns differ by < 1 DN
    assert np.abs(np.diff(red["a"])).mean() > 5
