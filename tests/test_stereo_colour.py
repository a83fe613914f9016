"""The noise-whitened matching images of a noisy colour pair (slitcli.stereo.cost's
colour_matching_image / smoothing, slitcli.stereo.noise.estimate_channel_noise,
slitcli.stereo.whiten.noise_whitened_pair): the per-channel noise estimate against
the noise the camera model put in, the combination's texture-to-noise ratio against
the hand-derived optimum, the low-pass's noise factor against measured correlated
noise, and the local matcher on textured planes seen through the ``robot`` and
``webcam`` camera presets, scored against the true disparity."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from slitcli.errors import SlitcliError
from slitcli.sim.camera import apply_camera, camera_preset
from slitcli.stereo.cost import (
    colour_matching_image,
    gaussian_noise_factor,
    smooth_image,
    smoothing_sigma_px,
    to_grey,
)
from slitcli.stereo.matcher import MatcherParams, compute_disparity
from slitcli.stereo.noise import ChannelNoise, estimate_channel_noise

SEEDS = [0, 1, 2, 3, 4]
WHITE = MatcherParams(colour_whiten=True)
SMOOTH = MatcherParams(colour_whiten=True, noise_smoothing=True)
DISPARITY_PX = 9
H, W = 120, 200
RED_RGB = np.array([0.85, 0.12, 0.10])      # the distractors scene's red box
GREY_RGB = np.array([0.55, 0.5, 0.45])      # its floor


def _texture(rng: np.random.Generator, width: int) -> np.ndarray:
    """Zero-mean, unit-variance smooth random texture (H, width), features of 2-4 px."""
    t = cv2.GaussianBlur(rng.normal(0.0, 1.0, (H, width)), (0, 0), 1.5)
    return (t - t.mean()) / t.std()


def _plane(seed: int, preset: str, colour: np.ndarray, contrast: float):
    """Left and right BGR views of a fronto-parallel plane at DISPARITY_PX whose
    reflectance ``colour`` is modulated by ``contrast`` (a texture of the albedo, as the
    renderer's noise textures), lit at 170 linear DN, through a camera preset."""
    rng = np.random.default_rng(seed)
    tex = _texture(rng, W + DISPARITY_PX)
    albedo = np.clip(1.0 + contrast * tex, 0.2, 1.8)
    model = camera_preset(preset)
    views = []
    for k, cols in enumerate((slice(0, W), slice(DISPARITY_PX, None))):   # L(x) = R(x-d)
        light = 200.0 * albedo[:, cols, None] * colour[None, None, :]
        views.append(apply_camera(light, model, np.random.default_rng([seed, k])))
    return views


def _scores(res) -> tuple[float, float, float]:
    """Share of the pixels (away from the left border, where the range is cut) with a
    disparity within 1 px of the truth, with one further off, and with one more than
    2 px off (a wrong patch, not the spread of a right one)."""
    d = res.disparity_px[:, 48:]
    err = np.abs(d - DISPARITY_PX)
    return float(np.mean(err <= 1.0)), float(np.mean(err > 1.0)), float(np.mean(err > 2.0))


def test_matched_weights_on_independent_channel_noise():
    """A texture moving each channel by the same share of its level, with independent
    noise of variances v_c: the weights mu_c / v_c reach the optimum SNR
    sum(mu_c^2 / v_c) x contrast^2, above luma's; checked on a synthetic image."""
    rng = np.random.default_rng(7)
    mu = np.array([45.0, 50.0, 130.0])                 # B, G, R of a red surface
    sd = np.array([16.0, 15.0, 10.0])                  # its noise (robot preset's)
    tex = _texture(rng, W)
    signal = mu[None, None, :] * (1.0 + 0.05 * tex[..., None])
    noisy = signal + rng.normal(0.0, 1.0, (H, W, 3)) * sd
    img = np.clip(np.rint(noisy), 0, 255).astype(np.uint8)
    table = ChannelNoise(tuple(np.array([0.0, 255.0]) for _ in range(3)),
                         tuple(np.full(2, v * v) for v in sd))
    got = colour_matching_image(img, 9, 9, table)
    luma = to_grey(img).astype(float)

    def snr(image: np.ndarray) -> float:
        # texture share by regression on the known texture, in the image's interior
        x, t = image[10:-10, 10:-10].ravel(), tex[10:-10, 10:-10].ravel()
        x = x - x.mean()
        gain = float(x @ t / (t @ t))
        noise = x - gain * t
        return gain ** 2 / float(noise.var())

    optimum = float(np.sum(mu ** 2 / sd ** 2)) * 0.05 ** 2
    luma_snr = float((0.114 * mu[0] + 0.587 * mu[1] + 0.299 * mu[2]) ** 2 * 0.05 ** 2
                     / np.sum((np.array([0.114, 0.587, 0.299]) * sd) ** 2))
    assert snr(luma) == pytest.approx(luma_snr, rel=0.25)
    # the texture's part at the window's scale rides on the window means, which enter
    # with the luma weights (a ninth of the texture's variance or so, at luma's ratio):
    # within 25 % of the optimum, 2x luma's
    assert snr(got) == pytest.approx(optimum, rel=0.25)
    assert snr(got) > 2.0 * luma_snr


def test_black_image_keeps_luma():
    img = np.zeros((20, 30, 3), np.uint8)
    table = ChannelNoise(tuple(np.array([0.0]) for _ in range(3)),
                         tuple(np.array([4.0]) for _ in range(3)))
    np.testing.assert_array_equal(colour_matching_image(img, 9, 9, table), 0.0)


@pytest.mark.parametrize("seed", SEEDS)
def test_channel_noise_of_robot_camera(seed):
    """The red surface through the ``robot`` camera at a known disparity: each
    channel's estimated noise against the camera's (noisy minus noiseless render of the
    same light), within 25 % (the truth pools all levels, the estimate weighs them by
    where the slope is low, and JPEG's errors differ between the views); its green and
    blue noisier than its red, as the colour matrix makes them."""
    rng = np.random.default_rng(seed)
    tex = _texture(rng, W + DISPARITY_PX)
    albedo = np.clip(1.0 + 0.3 * tex, 0.2, 1.8)
    model = camera_preset("robot")
    clean_model = camera_preset("robot", gain_dn_per_e=None, read_noise_e=0.0,
                                full_well_e=None, blooming_share=0.0)
    noisy, res = [], []
    for k, cols in enumerate((slice(0, W), slice(DISPARITY_PX, None))):
        light = 200.0 * albedo[:, cols, None] * RED_RGB[None, None, :]
        n = apply_camera(light, model, np.random.default_rng([seed, k]))
        c = apply_camera(light, clean_model, np.random.default_rng([seed, k]))
        noisy.append(n)
        res.append((n.astype(float) - c.astype(float))[8:-8, 8:-8])
    truth = np.sqrt(np.mean([r.var(axis=(0, 1)) for r in res], axis=0))
    disp = np.full((H, W), float(DISPARITY_PX), np.float32)
    valid = np.zeros((H, W), bool)
    valid[4:-4, DISPARITY_PX + 4:-4] = True
    est = estimate_channel_noise(noisy[0], noisy[1], disp, valid)
    assert est is not None
    for c in range(3):
        level = np.median(noisy[0][..., c])
        assert np.sqrt(est.variance_at(c, level)) == pytest.approx(truth[c], rel=0.25)
    assert truth[0] > truth[2] and truth[1] > truth[2]


def test_channel_noise_needs_matches():
    img = np.zeros((20, 30, 3), np.uint8)
    assert estimate_channel_noise(img, img, np.zeros((20, 30), np.float32),
                                  np.zeros((20, 30), bool)) is None


def test_smoothing_needs_whitening():
    with pytest.raises(SlitcliError, match="colour_whiten"):
        MatcherParams(noise_smoothing=True)


@pytest.mark.parametrize("rho", [0.0, 0.3, 0.45])
def test_smoothing_factor_of_correlated_noise(rho):
    """Noise with lag-1 correlation rho along x and y and none further (white noise
    plus b times its next neighbour, b / (1 + b^2) = rho, along both axes): the
    measured variance after the low-pass over the variance before is the factor; the
    smoothing that the helper picks brings 6 DN down to 1.5 DN."""
    rng = np.random.default_rng(3)
    white = rng.normal(0.0, 1.0, (600, 600))
    b = 0.5 * (1.0 - np.sqrt(1.0 - 4.0 * rho ** 2)) / rho if rho else 0.0
    k = np.array([0.0, 1.0, b]) / np.sqrt(1.0 + b * b)
    noise = cv2.sepFilter2D(white, -1, k, k)[5:-5, 5:-5]
    rx = float(np.mean(noise[:, 1:] * noise[:, :-1]) / noise.var())
    rd = float(np.mean(noise[1:, 1:] * noise[:-1, :-1]) / noise.var())
    sigma = 1.3
    out = smooth_image(noise.astype(np.float32), sigma)[10:-10, 10:-10]
    factor = gaussian_noise_factor(sigma, rx, rx, rd)
    assert out.var() / noise.var() == pytest.approx(factor, rel=0.05)
    s = smoothing_sigma_px(6.0, rx, rx, rd, 1.5, 4.0)
    out = smooth_image((6.0 * noise / noise.std()).astype(np.float32), s)[10:-10, 10:-10]
    assert out.std() == pytest.approx(1.5, rel=0.05)


def test_no_smoothing_at_or_below_the_reference():
    assert smoothing_sigma_px(1.5, 0.3, 0.3, 0.1, 1.5, 2.0) == 0.0
    assert smoothing_sigma_px(0.0, 0.0, 0.0, 0.0, 1.5, 2.0) == 0.0
    assert smoothing_sigma_px(50.0, 0.0, 0.0, 0.0, 1.5, 2.0) == 2.0   # capped
    assert gaussian_noise_factor(0.0, 0.5, 0.5, 0.2) == 1.0


@pytest.mark.parametrize("seed", SEEDS)
def test_red_plane_through_robot_camera(seed):
    """The distractors' red surface (texture contrast 0.3) through the ``robot`` camera.
    Luma's texture-to-noise ratio there is about 0.1 per pixel, the whitened
    combination's about 0.3: matched on luma (today's grey input) under 1 pixel in 100
    finds its disparity, on the whitened channels more, and low-passed down to the
    reference noise (``noise_smoothing``) most pixels do, at most 1 in 200 more than
    2 px off (a wrong match needs a second patch that fits within the lowered noise)
    and 3 in 100 more than 1 px off (the subpixel spread's tail)."""
    left, right = _plane(seed, "robot", RED_RGB, 0.3)
    grey = _scores(compute_disparity(to_grey(left), to_grey(right)))
    white = _scores(compute_disparity(left, right, WHITE))
    smooth = _scores(compute_disparity(left, right, SMOOTH))
    assert grey[0] < 0.01
    assert white[0] > 2.0 * grey[0]
    assert white[2] <= 0.005
    assert smooth[0] >= 0.5
    assert smooth[2] <= 0.005
    assert smooth[1] <= 0.03


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("preset", ["robot", "webcam"])
def test_grey_plane_through_camera(seed, preset):
    """The floor's colour (contrast 0.5) through both presets: on a grey surface the
    whitened combination weighs the channels about equally where luma favours green,
    about the same texture-to-noise ratio: the right share stays within 0.5 % of
    luma's (the webcam's estimated luma noise, 2.2-2.4 DN, is just above the gate), no
    more wrong ones; low-passed (``noise_smoothing``), more right and no more wrong
    (more than 2 px off; 0.5 % slack)."""
    left, right = _plane(seed, preset, GREY_RGB, 0.5)
    off = _scores(compute_disparity(left, right))
    white = _scores(compute_disparity(left, right, WHITE))
    smooth = _scores(compute_disparity(left, right, SMOOTH))
    assert white[0] >= off[0] - 0.005
    assert white[2] <= off[2] + 0.005
    assert smooth[0] > off[0]
    assert smooth[2] <= off[2] + 0.005


@pytest.mark.parametrize("seed", SEEDS)
def test_quiet_colour_pair_is_matched_as_grey(seed):
    """2 DN of i.i.d. noise per channel (the plain renders): the luma's noise (1.3 DN)
    is below ``colour_whiten_min_noise_dn``, so the colour pair is matched on its luma,
    bit for bit."""
    rng = np.random.default_rng(seed)
    tex = _texture(rng, W + DISPARITY_PX)
    base = 120.0 + 40.0 * tex[..., None] * np.array([1.0, 0.9, 0.8])
    views = []
    for cols in (slice(0, W), slice(DISPARITY_PX, None)):
        v = base[:, cols] + rng.normal(0.0, 2.0, (H, W, 3))
        views.append(np.clip(np.rint(v), 0, 255).astype(np.uint8))
    left, right = views
    a = compute_disparity(left, right, SMOOTH)
    b = compute_disparity(to_grey(left), to_grey(right))
    np.testing.assert_array_equal(a.disparity_px, b.disparity_px)
    np.testing.assert_array_equal(a.invalid_reason, b.invalid_reason)


def _red_box_render(seed: int):
    """The distractors' red box (0.85 m, texture contrast 0.3) before a wall at 3 m,
    rendered through the ``robot`` camera (laser off)."""
    from slitcli.rig import paper_rig
    from slitcli.sim.render import render_frame
    from slitcli.sim.scene import scene_from_dict

    d = {"slitcli_scene": 1, "name": "redbox", "seed": seed,
         "objects": [{"type": "box", "centre_xy_m": [0.95, 0.05], "size_m": [0.2, 0.7, 0.6],
                      "surface": {"colour_rgb": [0.85, 0.12, 0.1], "texture": "noise",
                                  "scale_m": 0.02, "contrast": 0.3}},
                     {"type": "wall", "from_xy_m": [3.0, -2.0], "to_xy_m": [3.0, 2.0],
                      "height_m": 2.0,
                      "surface": {"colour_rgb": [0.7, 0.68, 0.62], "texture": "noise",
                                  "scale_m": 0.04, "contrast": 0.5}}],
         "laser": {"enabled": False}, "image": {"camera": "robot"}, "robot": {"frames": 1}}
    scene = scene_from_dict(d)
    return render_frame(scene, paper_rig(), scene.poses(1)[0])


@pytest.mark.parametrize("seed", SEEDS)
def test_rendered_red_box_through_robot_camera(seed):
    """The rendered red box through the ``robot`` camera, its pixels against the truth
    disparity: the whitened channels find at least as many right disparities as luma
    (their texture-to-noise ratio is the larger), and low-passed half the box or more
    (luma: 6-10 %), with at most 2 % of the box more than 2 px off."""
    frame = _red_box_render(seed)
    truth = frame.truth.disparity_px
    box = (frame.truth.object_id == 0) & np.isfinite(truth)

    def right_wrong(res) -> tuple[float, float]:
        err = np.abs(res.disparity_px[box] - truth[box])
        return float(np.mean(err <= 1.0)), float(np.mean(err > 2.0))

    luma = right_wrong(compute_disparity(to_grey(frame.left_bgr), to_grey(frame.right_bgr)))
    white = right_wrong(compute_disparity(frame.left_bgr, frame.right_bgr, WHITE))
    smooth = right_wrong(compute_disparity(frame.left_bgr, frame.right_bgr, SMOOTH))
    assert luma[0] < 0.2
    assert white[0] >= luma[0]
    assert smooth[0] >= 0.4
    assert smooth[1] <= 0.02


NEAR_PX, FAR_PX, NEAR_COLS = 20, 8, (80, 140)


def _step_pair(seed: int, preset: str):
    """A textured plane at NEAR_PX over columns NEAR_COLS of the left view before a
    textured plane at FAR_PX (each view drawn from the same two albedo maps, so the
    right view hides the band left of the near plane that the left one sees), through
    a camera preset."""
    rng = np.random.default_rng(seed)
    far = np.clip(1.0 + 0.5 * _texture(rng, W + 40), 0.2, 1.8)
    near = np.clip(1.0 + 0.5 * _texture(rng, W + 40), 0.2, 1.8)
    x = np.arange(W)
    a, b = NEAR_COLS
    left = np.where((x >= a) & (x < b), near[:, x], far[:, x])
    xn = x + NEAR_PX                                  # the left column a right pixel shows
    right = np.where((xn >= a) & (xn < b), near[:, np.minimum(xn, W + 39)], far[:, x + FAR_PX])
    model = camera_preset(preset)
    colour = np.array([0.7, 0.6, 0.5])
    return [apply_camera(200.0 * v[..., None] * colour, model, np.random.default_rng([seed, k]))
            for k, v in enumerate((left, right))]


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("preset", ["robot", "webcam"])
def test_low_pass_does_not_carry_a_near_plane_past_its_edges(seed, preset):
    """A near plane before a far one through a camera preset, low-passed
    (``noise_smoothing``): the low-passed window carries the near plane's disparity a
    few columns past both silhouettes (8-27 pixels within 15 columns of them without
    the depth-step trim, slitcli.stereo.whiten.trim_depth_steps); with it at most 4
    such pixels remain, and at least 75 % of the near plane keeps its disparity
    within 1 px (about 81 %: the trim costs its 4-5 edge columns)."""
    left, right = _step_pair(seed, preset)
    d = compute_disparity(left, right, SMOOTH).disparity_px
    x = np.arange(W)[None, :]
    a, b = NEAR_COLS
    beside = ((x >= a - 15) & (x < a)) | ((x >= b) & (x < b + 15))
    carried = np.isfinite(d) & beside & (d > FAR_PX + 2.0)
    inside = np.broadcast_to((x >= a) & (x < b), d.shape)
    right_share = np.mean(np.abs(d[inside] - NEAR_PX) <= 1.0)
    assert np.count_nonzero(carried) <= 4
    assert right_share >= 0.75


def test_depth_step_trim_cuts_run_ends_at_steps_only():
    """trim_depth_steps on a hand-made row: a run ending across a gap on a farther or a
    nearer surface loses its last ``reach`` pixels; one whose gap ends on its own
    disparity (a hole) or reaches the image border keeps them."""
    from slitcli.stereo.reasons import Reason
    from slitcli.stereo.whiten import trim_depth_steps

    d = np.array([[5, 5, 5, 5, 9, 9, 9, 9, 9, 9, 0, 0, 5, 5, 5, 9, 9, 9, 0, 9, 9, 0, 0, 0,
                   3, 3, 3, 0, 0]], np.float32)
    reason = np.zeros(d.shape, np.uint8)
    reason[0, [10, 11, 18, 21, 22, 23, 27, 28]] = Reason.UNIQUENESS
    before = reason.copy()
    trim_depth_steps(d, reason, 2, 1.0)
    cut = np.nonzero(reason[0] != before[0])[0].tolist()
    # 8-9: 9 before 5 (farther); 12-13: 5 after 9 (nearer); 19-20: 9 before 3;
    # 24-25: 3 after 9; 15-17 (a hole, 9 on both sides) and 26 (gap to the border) stay
    assert cut == [8, 9, 12, 13, 19, 20, 24, 25]
    assert np.all(reason[0, cut] == Reason.BOUNDARY)
    trim_depth_steps(d, reason, 0, 1.0)               # reach 0: nothing more
    assert np.count_nonzero(reason[0] != before[0]) == 8
