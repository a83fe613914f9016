"""``slitcli calibrate mount``: camera height, tilt and roll from the floor seen in stereo.

For rigs whose tilt was not measured: the robot stands (or drives) on a flat, textured
floor; each stereo frame is rectified, matched (:func:`floor_disparity`, OpenCV
StereoSGBM: only a plane is wanted here, not the paper's Eq. 10 matcher), and
reprojected to 3-D in the rig's camera frame (Eq. 8: ``Z = f W / disparity``). A plane
``n . X = d`` is found by RANSAC and refined by weighted least squares on its inliers;
point weights and the inlier threshold follow the stereo depth error
``sigma_Z = Z^2 sigma_d / (f W)``: a point moves along its ray, so its distance to the
plane ``n . X = d`` varies by ``sigma_perp = sigma_Z |n . X| / Z`` (``= s Z |n . r|``
with the relative noise ``s = Z sigma_d / (f W)``). With ``n`` pointing away from the
floor's up side (``d > 0``) the mount (conventions of :class:`slitcli.rig.Mount`) is

    height_m = d,  tilt_deg = asin(n_z),  roll_deg = atan2(n_x, n_y).

A fit is refused when it does not look like a floor (:func:`floor_plane_check`). The
two thresholds follow from the same noise model: an inlier's residual, divided by its
``sigma_perp``, is a standard normal cut at ``+-k`` (``k = inlier_sigmas``), whose RMS is
``rho_G = sqrt(1 - 2 k phi(k) / (2 Phi(k) - 1))`` (0.987 for k = 3); points that do not
lie on one plane spread evenly over the band, RMS ``rho_U = k / sqrt(3)`` (1.732). The
fit is refused above the midpoint ``(rho_G + rho_U) / 2`` (1.36 for k = 3; a true
floor whose disparity noise is 1.6 x ``disparity_sigma_px`` still passes). The floor
must also hold the majority of the points in the depth band (``min_inlier_fraction``
0.5; a floor-only view holds ``2 Phi(k) - 1`` = 99.7 %): with fewer, the plane is not
what the view mostly shows and RANSAC may have picked any flat patch.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import cv2
import numpy as np

from slitcli.calibrate.rectify import RectificationMaps, rectify_pair
from slitcli.errors import SlitcliError
from slitcli.io.frames import open_frames
from slitcli.rig import Mount, Rig, load_rig, save_rig


@dataclass(frozen=True)
class MountParams:
    """Options of the mount calibration.

    ``max_frames``: frames used, spread evenly over the sequence.
    ``min_depth_m``, ``max_depth_m``: depth band of the floor points used.
    ``disparity_sigma_px``: assumed disparity noise, scales the inlier threshold.
    ``inlier_sigmas``: inlier threshold in depth standard deviations.
    ``ransac_iterations``: candidate planes; ``max_points``: points used (seeded sample).
    ``max_tilt_deg``: candidate floors must have ``|tilt|`` below this (rejects walls).
    ``min_inlier_fraction``: refuse when fewer of the points lie on the plane (the
    majority rule of the module docstring).
    ``max_normalised_rms``: refuse when the inliers' RMS residual, in units of their
    predicted ``sigma_Z``, exceeds this (default: midpoint of the floor and no-plane
    hypotheses, :func:`normalised_rms_threshold`).
    ``photometric_refinement``: polish the RANSAC plane by direct image alignment
    (:func:`refine_floor_photometric`).
    """

    max_frames: int = 5
    min_depth_m: float = 0.3
    max_depth_m: float = 3.0
    disparity_sigma_px: float = 0.5
    inlier_sigmas: float = 3.0
    ransac_iterations: int = 400
    max_points: int = 20000
    max_tilt_deg: float = 75.0
    min_inlier_fraction: float = 0.5
    max_normalised_rms: float | None = None
    photometric_refinement: bool = True
    seed: int = 0


def floor_disparity(left_rect: np.ndarray, right_rect: np.ndarray, rig: Rig, *,
                    min_depth_m: float = 0.3) -> np.ndarray:
    """Disparity of a rectified pair (H, W) in pixels, NaN where invalid (StereoSGBM)."""
    max_d = rig.focal_px * rig.baseline_m / min_depth_m
    num = int(min(max(16, 16 * math.ceil(max_d / 16)), 16 * (rig.width_px // 32)))
    block = 5
    sgbm = cv2.StereoSGBM_create(minDisparity=0, numDisparities=num, blockSize=block,
                                 P1=8 * block * block, P2=32 * block * block, disp12MaxDiff=1,
                                 uniquenessRatio=10, speckleWindowSize=100, speckleRange=2)
    gl = cv2.cvtColor(left_rect, cv2.COLOR_BGR2GRAY) if left_rect.ndim == 3 else left_rect
    gr = cv2.cvtColor(right_rect, cv2.COLOR_BGR2GRAY) if right_rect.ndim == 3 else right_rect
    d = sgbm.compute(gl, gr).astype(np.float64) / 16.0
    return np.where(d > 0, d, np.nan)


@dataclass(frozen=True)
class FloorPlane:
    """``normal . X = height_m`` in the rig camera frame; ``normal`` points down to the floor."""

    normal: tuple[float, float, float]
    height_m: float
    inliers: int
    points: int
    residual_rms_m: float
    normalised_rms: float = float("nan")


def normalised_rms_threshold(inlier_sigmas: float) -> float:
    """Midpoint between the normalised inlier RMS of a floor and of no plane.

    ``rho_G``: RMS of a standard normal truncated at ``+-k``; ``rho_U = k / sqrt(3)``:
    RMS of residuals spread evenly over the band (module docstring).
    """
    k = float(inlier_sigmas)
    pdf = math.exp(-0.5 * k * k) / math.sqrt(2.0 * math.pi)
    mass = math.erf(k / math.sqrt(2.0))
    rho_g = math.sqrt(max(0.0, 1.0 - 2.0 * k * pdf / mass))
    return 0.5 * (rho_g + k / math.sqrt(3.0))


def floor_plane_check(plane: FloorPlane, params: MountParams, *, source: str = "floor") -> None:
    """Refuse a fitted plane that is not a floor (thresholds: module docstring).

    Each failure has its own message naming the measured number and its threshold.
    """
    share = plane.inliers / max(plane.points, 1)
    if share < params.min_inlier_fraction:
        raise SlitcliError(
            f"{source}: only {plane.inliers} of {plane.points} stereo points "
            f"({100 * share:.0f} %, at least {100 * params.min_inlier_fraction:.0f} % needed) "
            "lie on the best floor plane; the views show no floor, or too little of it: "
            "record views with mostly flat, textured floor")
    limit = (params.max_normalised_rms if params.max_normalised_rms is not None
             else normalised_rms_threshold(params.inlier_sigmas))
    if not plane.normalised_rms <= limit:
        raise SlitcliError(
            f"{source}: the floor plane's residual RMS is {1000 * plane.residual_rms_m:.1f} mm "
            f"= {plane.normalised_rms:.2f} x the stereo depth noise (at most {limit:.2f} for "
            "a floor); the points do not lie on one plane: record views of a flat, textured "
            "floor, all from one robot pose on it")


def fit_floor_ransac(points_xyz: np.ndarray, rig: Rig, params: MountParams, *,
                     source: str = "floor") -> FloorPlane:
    """RANSAC plane with depth-weighted least-squares refinement (see module docstring).

    Parameters
    ----------
    points_xyz : ndarray, shape (N, 3), rig camera frame, metres.
    """
    p = np.asarray(points_xyz, dtype=float)
    z = p[:, 2]
    p = p[(z >= params.min_depth_m) & (z <= params.max_depth_m)]
    if p.shape[0] < 100:
        raise SlitcliError(f"{source}: only {p.shape[0]} stereo points between "
                           f"{params.min_depth_m:g} and {params.max_depth_m:g} m; the floor "
                           "needs texture and to be in view")
    rng = np.random.default_rng(params.seed)
    if p.shape[0] > params.max_points:
        p = p[rng.choice(p.shape[0], params.max_points, replace=False)]
    fb = rig.focal_px * rig.baseline_m
    # relative depth noise sigma_Z / Z; times |n . X| it is the point-to-plane sigma
    rel = p[:, 2] * params.disparity_sigma_px / fb
    k_rel = params.inlier_sigmas * rel
    k = params.ransac_iterations
    idx = rng.integers(0, p.shape[0], size=(k, 3))
    a, b, c = p[idx[:, 0]], p[idx[:, 1]], p[idx[:, 2]]
    n = np.cross(b - a, c - a)
    norm = np.linalg.norm(n, axis=1)
    good = norm > 1e-9
    n = n[good] / norm[good, None]
    d = np.einsum("ij,ij->i", n, a[good])
    flip = d < 0
    n[flip], d[flip] = -n[flip], -d[flip]
    floor_like = n[:, 1] >= math.cos(math.radians(params.max_tilt_deg))
    n, d = n[floor_like], d[floor_like]
    if n.shape[0] == 0:
        raise SlitcliError(f"{source}: no floor-like plane among the stereo points; the camera "
                           "must see the floor (tilt below "
                           f"{params.max_tilt_deg:g} deg)")
    scores = np.zeros(n.shape[0], dtype=np.int64)
    pf = p.astype(np.float32)
    for s in range(0, n.shape[0], 64):
        dist = pf @ n[s:s + 64].T.astype(np.float32)
        res = np.abs(dist - d[s:s + 64].astype(np.float32))
        scores[s:s + 64] = (res <= k_rel[:, None].astype(np.float32) * np.abs(dist)).sum(axis=0)
    best = int(np.argmax(scores))
    normal, offset = n[best], float(d[best])
    inl = np.abs(p @ normal - offset) <= k_rel * np.abs(p @ normal)
    if inl.sum() < 3:
        raise SlitcliError(f"{source}: no plane holds more than {int(inl.sum())} of the "
                           f"{p.shape[0]} stereo points; record views of a flat, textured floor")
    for _ in range(5):
        w = 1.0 / rel[inl] ** 2
        c = (p[inl] * w[:, None]).sum(axis=0) / w.sum()
        _, _, vt = np.linalg.svd((p[inl] - c) * np.sqrt(w)[:, None], full_matrices=False)
        normal = vt[2] if vt[2][1] >= 0 else -vt[2]
        offset = float(normal @ c)
        new = np.abs(p @ normal - offset) <= k_rel * np.abs(p @ normal)
        if np.array_equal(new, inl):
            break
        inl = new
    tilt = math.degrees(math.acos(min(1.0, float(normal[1]))))
    if tilt > params.max_tilt_deg:
        raise SlitcliError(f"{source}: the refined plane is tilted {tilt:.1f} deg from the "
                           f"image's down axis (at most {params.max_tilt_deg:g}); it is a wall "
                           "or a slope, not the floor: record views of the floor")
    if offset <= 0:
        raise SlitcliError(f"{source}: the fitted plane passes {abs(offset):.3f} m above the "
                           "camera, not below it; the camera must look down at the floor")
    r = p[inl] @ normal - offset
    rn = r / (rel[inl] * np.abs(p[inl] @ normal))
    return FloorPlane(normal=tuple(float(v) for v in normal), height_m=offset,
                      inliers=int(inl.sum()), points=int(p.shape[0]),
                      residual_rms_m=float(np.sqrt(np.mean(r**2))),
                      normalised_rms=float(np.sqrt(np.mean(rn**2))))


def mount_from_floor(plane: FloorPlane, forward_m: float = 0.0) -> Mount:
    """Height, tilt and roll of the rig camera from its floor plane (module docstring)."""
    nx, ny, nz = plane.normal
    return Mount(height_m=plane.height_m,
                 tilt_deg=math.degrees(math.asin(max(-1.0, min(1.0, nz)))),
                 roll_deg=math.degrees(math.atan2(nx, ny)), forward_m=forward_m)


@dataclass(frozen=True)
class MountCalibration:
    """The fitted floor, the rig carrying the new mount, and the frames used."""

    rig: Rig
    floor: FloorPlane
    frames: tuple[str, ...]

    def report_lines(self) -> list[str]:
        m = self.rig.mount
        return [f"frames: {len(self.frames)} ({', '.join(self.frames)})",
                f"floor plane (rig camera frame): normal [{self.floor.normal[0]:.5f}, "
                f"{self.floor.normal[1]:.5f}, {self.floor.normal[2]:.5f}], "
                f"distance {self.floor.height_m:.4f} m",
                f"inliers: {self.floor.inliers} of {self.floor.points} points (RANSAC), "
                f"residual_rms_mm {1000 * self.floor.residual_rms_m:.2f} "
                f"({self.floor.normalised_rms:.2f} x the stereo depth noise)",
                f"mount: height_m {m.height_m:.4f}, tilt_deg {m.tilt_deg:.3f}, roll_deg "
                f"{m.roll_deg:.3f} (forward_m {m.forward_m:g} kept)"]


def refine_floor_photometric(frames: list[tuple[np.ndarray, np.ndarray, np.ndarray]],
                             rig: Rig, plane: FloorPlane, *, iterations: int = 20,
                             source: str = "floor") -> FloorPlane:
    """Polish a floor plane by aligning the right image to the left through the plane.

    A plane ``n . X = d`` induces the disparity ``D(u, v) = f W (q . r(u, v))`` with
    ``q = n / d`` and ``r`` the pixel's ray (Eq. 8 with ``Z = 1 / (q . r)``), affine in
    (u, v). Gauss-Newton on ``q`` minimises ``sum (I_R(u - D, v) - I_L(u, v))^2`` over the
    floor pixels, with Huber weights (scale from the median absolute residual) against
    pixels off the floor. This removes the sub-pixel bias of block matching on the
    strongly slanted floor.

    Parameters
    ----------
    frames : (left_gray, right_gray, floor_mask) per frame: rectified float32 (H, W)
        images and a bool (H, W) mask of the floor pixels found by RANSAC.
    """
    q = np.asarray(plane.normal, dtype=float) / plane.height_m
    fb = rig.focal_px * rig.baseline_m
    prepared = []
    for gl, gr, mask in frames:
        v, u = np.nonzero(mask)
        rays = rig.pixel_rays_cam(u, v)
        grad = np.gradient(gr, axis=1).astype(np.float32)
        prepared.append((gl[v, u].astype(np.float64), gr.astype(np.float64),
                         grad.astype(np.float64), u.astype(np.float64), v, rays))
    for _ in range(iterations):
        H = np.zeros((3, 3))
        g = np.zeros(3)
        for il, gr, grad, u, v, rays in prepared:
            xs = u - fb * (rays @ q)
            ok = (xs >= 1) & (xs <= gr.shape[1] - 3)
            x0 = np.floor(xs[ok]).astype(np.intp)
            fx = xs[ok] - x0
            rows = v[ok]
            # rows are integers in rectified images: interpolation is along the row only
            ir = gr[rows, x0] * (1 - fx) + gr[rows, x0 + 1] * fx
            gx = grad[rows, x0] * (1 - fx) + grad[rows, x0 + 1] * fx
            e = ir - il[ok]
            J = -gx[:, None] * fb * rays[ok]
            scale = 1.4826 * float(np.median(np.abs(e))) + 1e-6
            w = np.minimum(1.0, 1.345 * scale / np.maximum(np.abs(e), 1e-12))
            H += (J * w[:, None]).T @ J
            g += (J * w[:, None]).T @ e
        try:
            dq = -np.linalg.solve(H, g)
        except np.linalg.LinAlgError:
            raise SlitcliError(f"{source}: the floor has too little texture to align the "
                               "stereo pair") from None
        q = q + dq
        if np.linalg.norm(dq) < 1e-9 * np.linalg.norm(q):
            break
    d = 1.0 / float(np.linalg.norm(q))
    n = q * d
    return replace(plane, normal=tuple(float(x) for x in n), height_m=d)


def calibrate_mount_frames(names: list[str], pairs: list[tuple[np.ndarray, np.ndarray]],
                           rig: Rig, params: MountParams, *,
                           source: str = "sequence") -> MountCalibration:
    """Fit the floor from raw (or, without ``rig.raw``, rectified) stereo pairs."""
    grays, clouds, pixels = [], [], []
    # the remap tables once per run, not per frame
    maps = RectificationMaps.for_rig(rig) if rig.raw is not None else None
    for left, right in pairs:
        lr, rr = rectify_pair(rig, left, right, maps=maps)
        assert rr is not None
        gl = cv2.cvtColor(lr, cv2.COLOR_BGR2GRAY) if lr.ndim == 3 else lr
        gr = cv2.cvtColor(rr, cv2.COLOR_BGR2GRAY) if rr.ndim == 3 else rr
        disp = floor_disparity(gl, gr, rig, min_depth_m=params.min_depth_m)
        v, u = np.nonzero(np.isfinite(disp))
        z = rig.depth_from_disparity(disp[v, u])
        clouds.append(rig.pixel_rays_cam(u, v) * z[:, None])
        pixels.append((u, v))
        grays.append((gl.astype(np.float32), gr.astype(np.float32)))
    plane = fit_floor_ransac(np.concatenate(clouds), rig, params, source=source)
    floor_plane_check(plane, params, source=source)
    n = np.asarray(plane.normal)
    fb = rig.focal_px * rig.baseline_m
    frames = []
    for (gl, gr), pts, (u, v) in zip(grays, clouds, pixels, strict=True):
        z = pts[:, 2]
        thr = params.inlier_sigmas * z * params.disparity_sigma_px / fb * np.abs(pts @ n)
        on = (np.abs(pts @ n - plane.height_m) <= thr) & (z >= params.min_depth_m) \
            & (z <= params.max_depth_m)
        mask = np.zeros(gl.shape, dtype=bool)
        mask[v[on], u[on]] = True
        frames.append((gl, gr, mask))
    if params.photometric_refinement:
        plane = refine_floor_photometric(frames, rig, plane, source=source)
    mount = mount_from_floor(plane, forward_m=rig.mount.forward_m)
    return MountCalibration(rig=replace(rig, mount=mount), floor=plane, frames=tuple(names))


def run_calibrate_mount(rig_path: str | Path, seq_dir: str | Path, params: MountParams, *,
                        out_rig: str | Path | None = None) -> MountCalibration:
    """``slitcli calibrate mount``: fit and write the mount into the rig (atomically).

    ``out_rig`` defaults to ``rig_path``. Nothing is written on error.
    """
    rig = load_rig(rig_path)
    src = open_frames(seq_dir)
    n = len(src)
    take = np.unique(np.linspace(0, n - 1, min(n, max(1, params.max_frames))).round()
                     .astype(int))
    frames = list(src.frames(rig, skip=frozenset(range(n)) - frozenset(take.tolist())))
    result = calibrate_mount_frames([f.name for f in frames],
                                    [(f.left_bgr, f.right_bgr) for f in frames], rig, params,
                                    source=str(seq_dir))
    save_rig(result.rig, out_rig if out_rig is not None else rig_path)
    return result
