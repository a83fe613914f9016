"""``slitcli calibrate mount``: camera height, tilt and roll from the floor seen in stereo.

For rigs whose tilt was not measured: the robot stands (or drives) on a flat, textured
floor; each stereo frame is rectified, matched (:func:`floor_disparity`, OpenCV
StereoSGBM: only a plane is wanted here, not the paper's Eq. 10 matcher), and
reprojected to 3-D in the rig's camera frame (Eq. 8: ``Z = f W / disparity``). A plane
``n . X = d`` is found by RANSAC and refined by weighted least squares on its inliers;
point weights and the inlier threshold follow the stereo depth error
``sigma_Z = Z^2 sigma_d / (f W)``. With ``n`` pointing away from the floor's up side
(``d > 0``) the mount (conventions of :class:`slitcli.rig.Mount`) is

    height_m = d,  tilt_deg = asin(n_z),  roll_deg = atan2(n_x, n_y).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import cv2
import numpy as np

from slitcli.calibrate.rectify import rectify_pair
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
    ``min_inlier_fraction``: refuse when fewer of the points lie on the plane.
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
    min_inlier_fraction: float = 0.3
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
    sigma = p[:, 2] ** 2 * params.disparity_sigma_px / fb
    thr = params.inlier_sigmas * sigma
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
        res = np.abs(pf @ n[s:s + 64].T.astype(np.float32) - d[s:s + 64].astype(np.float32))
        scores[s:s + 64] = (res <= thr[:, None]).sum(axis=0)
    best = int(np.argmax(scores))
    normal, offset = n[best], float(d[best])
    inl = np.abs(p @ normal - offset) <= thr
    for _ in range(5):
        w = 1.0 / sigma[inl] ** 2
        c = (p[inl] * w[:, None]).sum(axis=0) / w.sum()
        _, _, vt = np.linalg.svd((p[inl] - c) * np.sqrt(w)[:, None], full_matrices=False)
        normal = vt[2] if vt[2][1] >= 0 else -vt[2]
        offset = float(normal @ c)
        new = np.abs(p @ normal - offset) <= thr
        if np.array_equal(new, inl):
            break
        inl = new
    if offset <= 0 or inl.sum() < params.min_inlier_fraction * p.shape[0]:
        raise SlitcliError(f"{source}: only {int(inl.sum())} of {p.shape[0]} stereo points lie "
                           "on one floor plane; record a view with mostly flat, textured floor")
    r = p[inl] @ normal - offset
    return FloorPlane(normal=tuple(float(v) for v in normal), height_m=offset,
                      inliers=int(inl.sum()), points=int(p.shape[0]),
                      residual_rms_m=float(np.sqrt(np.mean(r**2))))


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
                f"residual_rms_mm {1000 * self.floor.residual_rms_m:.2f}",
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
    for left, right in pairs:
        lr, rr = rectify_pair(rig, left, right)
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
    n = np.asarray(plane.normal)
    fb = rig.focal_px * rig.baseline_m
    frames = []
    for (gl, gr), pts, (u, v) in zip(grays, clouds, pixels, strict=True):
        z = pts[:, 2]
        thr = params.inlier_sigmas * z**2 * params.disparity_sigma_px / fb
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
