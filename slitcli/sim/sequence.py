"""Render a scene into a stereo sequence folder with ground truth (DESIGN §12).

Layout written by :func:`render_sequence` (docs/sequence.md, docs/ground-truth.md)::

    OUT/left/000000.png  OUT/right/000000.png   colour stereo pairs (BGR PNG)
    OUT/times.csv        frame,time_s
    OUT/rig.yaml         the rig the images were rendered with
    OUT/scene.yaml       the scene as rendered (after --seed)
    OUT/gt/disparity/000000.png   16-bit, disparity_px * 256, 0 = none
    OUT/gt/distance/000000.png    16-bit, depth along the optical axis in mm, 0 = none
    OUT/gt/mask/000000.png        8-bit, 255 = obstacle pixel
    OUT/gt/laser.csv     laser-table columns for the true stripe points
    OUT/gt/laser_ranges.csv   frame,time_s,bearing_deg,laser_true_m (nearest lit point)
    OUT/gt/ranges.csv    frame,time_s,bearing_deg,range_m (true nearest obstacle)
    OUT/gt/poses.csv     frame,time_s,x_m,y_m,yaw_deg (robot rotation centre, world)
    OUT/gt/frame_000000.npz   lossless float truth (every FrameTruth array)

The folder is rendered into a temporary sibling and renamed into place at the end.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from slitcli.errors import SlitcliError
from slitcli.io.atomic import atomic_directory, write_png_atomic
from slitcli.io.png import encode_depth_png, encode_disparity_png, encode_mask_png
from slitcli.rig import Rig
from slitcli.sim.camera import camera_to_scene
from slitcli.sim.laser_truth import lit_wedge_ranges
from slitcli.sim.render import FrameTruth, render_frame
from slitcli.sim.scene import MAX_SEED, Box, Cylinder, Scene, Wall

FRAME_NAME = "{:06d}"


def scene_to_dict(scene: Scene) -> dict:
    """The scene in its YAML form (inverse of :func:`slitcli.sim.scene.scene_from_dict`)."""
    def surf(s):
        d = {"colour_rgb": list(s.colour_rgb), "texture": s.texture, "scale_m": s.scale_m,
             "contrast": s.contrast}
        if s.seed is not None:
            d["seed"] = s.seed
        return d

    objects = []
    for ob in scene.objects:
        if isinstance(ob, Box):
            o = {"type": "box", "centre_xy_m": list(ob.centre_xy_m), "size_m": list(ob.size_m),
                 "yaw_deg": ob.yaw_deg}
        elif isinstance(ob, Cylinder):
            o = {"type": "cylinder", "centre_xy_m": list(ob.centre_xy_m),
                 "radius_m": ob.radius_m, "height_m": ob.height_m}
        else:
            assert isinstance(ob, Wall)
            o = {"type": "wall", "from_xy_m": list(ob.from_xy_m), "to_xy_m": list(ob.to_xy_m),
                 "height_m": ob.height_m}
        o["z_min_m"] = ob.z_min_m
        if not isinstance(ob, Wall) and ob.motion:
            o["motion"] = {"waypoints": [{"t_s": t, "xy_m": [x, y]} for t, x, y in ob.motion]}
        o["surface"] = surf(ob.surface)
        objects.append(o)
    r = scene.robot

    def pose(p):
        return [p.x_m, p.y_m, math.degrees(p.yaw_rad)]

    robot = {"start": pose(r.start), "motion": r.motion, "speed_mps": r.speed_mps,
             "yaw_rate_dps": r.yaw_rate_dps, "frames": r.frames,
             "frame_rate_hz": r.frame_rate_hz, "radius_m": r.radius_m, "height_m": r.height_m}
    if r.poses:
        robot["poses"] = [pose(p) for p in r.poses]
    out = {
        "slitcli_scene": 1, "name": scene.name, "seed": scene.seed, "floor": surf(scene.floor),
        "objects": objects,
        "highlights": [{"position_xyz_m": list(h.position_xyz_m), "radius_m": h.radius_m,
                        "brightness": h.brightness} for h in scene.highlights],
        "laser": asdict(scene.laser),
        "image": _image_dict(scene),
        "robot": robot, "max_range_m": scene.max_range_m,
    }
    if scene.goal_xy_m is not None:
        out["goal_xy_m"] = list(scene.goal_xy_m)
    return out


def _image_dict(scene: Scene) -> dict:
    """``image:`` keys as plain YAML; ``camera`` only when the scene has one."""
    out = {**asdict(scene.image), "light_dir_xyz": list(scene.image.light_dir_xyz)}
    del out["camera"]
    if scene.image.camera is not None:
        out["camera"] = camera_to_scene(scene.image.camera)
    return out


def truth_laser_rows(frame: int, truth: FrameTruth) -> pd.DataFrame:
    """True stripe points of one frame in the laser-table columns (DESIGN §12)."""
    u = np.nonzero(np.isfinite(truth.stripe_v_px))[0]
    xyz = truth.stripe_sensor_xyz[u]
    return pd.DataFrame({
        "frame": frame, "u_px": u, "v_px": truth.stripe_v_px[u],
        "strength": truth.stripe_peak_dn[u], "x_m": xyz[:, 0], "y_m": xyz[:, 1],
        "range_m": np.hypot(xyz[:, 0], xyz[:, 1]),
        "bearing_deg": np.degrees(np.arctan2(xyz[:, 1], xyz[:, 0])),
    })


def write_truth_npz(path: Path, truth: FrameTruth) -> None:
    """All truth arrays of a frame, lossless."""
    p = truth.pose
    np.savez_compressed(
        path, depth_m=truth.depth_m, disparity_px=truth.disparity_px,
        obstacle_mask=truth.obstacle_mask, textured=truth.textured,
        object_id=truth.object_id.astype(np.int16), stripe_v_px=truth.stripe_v_px,
        stripe_peak_dn=truth.stripe_peak_dn, stripe_sensor_xyz=truth.stripe_sensor_xyz,
        bearing_deg=truth.bearing_deg, range_m=truth.range_m,
        pose_xy_yaw=np.array([p.x_m, p.y_m, p.yaw_rad]),
    )


def render_sequence(scene: Scene, rig: Rig, out: str | Path, *, frames: int | None = None,
                    seed: int | None = None, overwrite: bool = False,
                    on_frame: Callable[[int, int], None] | None = None,
                    inputs: Sequence[str | Path] = ()) -> dict:
    """Render every frame of a scene into a sequence folder with ground truth.

    Parameters
    ----------
    scene, rig : the world and the stereo rig.
    out : path
        Output folder; must not exist unless ``overwrite``.
    frames : int, optional
        Number of frames (default: the scene's ``robot.frames``).
    seed : int, optional
        Replaces the scene's seed (textures and noise).
    on_frame : callable(done, total), optional
        Progress callback.
    inputs : paths
        The files the scene and rig were read from: ``overwrite`` never replaces them.

    Returns
    -------
    dict with ``frames``, ``obstacle_bins`` and ``stripe_columns`` summaries.
    """
    if seed is not None:
        if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed <= MAX_SEED:
            raise SlitcliError(f"seed = {seed!r} is out of range; give a whole number from 0 "
                               f"to {MAX_SEED}")
        scene = replace(scene, seed=seed)
    poses = scene.poses(frames)
    times = scene.times_s(frames)
    laser_tables, range_tables, lit_tables, pose_rows = [], [], [], []
    _, bin_lo, bin_hi = rig.bearing_bins(1.0)
    stripe_cols = 0
    with atomic_directory(out, overwrite=overwrite, inputs=inputs) as tmp:
        for sub in ("left", "right", "gt/disparity", "gt/distance", "gt/mask"):
            (tmp / sub).mkdir(parents=True)
        for i, pose in enumerate(poses):
            # moving objects are where they are at the frame's time (truth follows)
            fr = render_frame(scene.at_time(float(times[i])), rig, pose, frame_index=i)
            name = FRAME_NAME.format(i) + ".png"
            write_png_atomic(tmp / "left" / name, fr.left_bgr)
            write_png_atomic(tmp / "right" / name, fr.right_bgr)
            t = fr.truth
            write_png_atomic(tmp / "gt/disparity" / name, encode_disparity_png(t.disparity_px))
            write_png_atomic(tmp / "gt/distance" / name, encode_depth_png(t.depth_m))
            write_png_atomic(tmp / "gt/mask" / name, encode_mask_png(t.obstacle_mask))
            write_truth_npz(tmp / "gt" / f"frame_{FRAME_NAME.format(i)}.npz", t)
            laser_tables.append(truth_laser_rows(i, t))
            stripe_cols += int(np.isfinite(t.stripe_v_px).sum())
            range_tables.append(pd.DataFrame({"frame": i, "time_s": times[i],
                                              "bearing_deg": t.bearing_deg,
                                              "range_m": t.range_m}))
            lit_tables.append(pd.DataFrame({
                "frame": i, "time_s": times[i], "bearing_deg": t.bearing_deg,
                "laser_true_m": lit_wedge_ranges(scene, rig, pose, bin_lo, bin_hi)}))
            pose_rows.append((i, times[i], pose.x_m, pose.y_m, math.degrees(pose.yaw_rad)))
            if on_frame is not None:
                on_frame(i + 1, len(poses))
        fmt = "%.9g"
        pd.DataFrame({"frame": np.arange(len(poses)), "time_s": times}).to_csv(
            tmp / "times.csv", index=False, float_format=fmt, lineterminator="\n")
        pd.concat(laser_tables).to_csv(tmp / "gt/laser.csv", index=False, float_format=fmt,
                                       lineterminator="\n")
        pd.concat(lit_tables).to_csv(tmp / "gt/laser_ranges.csv", index=False,
                                     float_format=fmt, lineterminator="\n", na_rep="")
        ranges = pd.concat(range_tables)
        ranges.to_csv(tmp / "gt/ranges.csv", index=False, float_format=fmt,
                      lineterminator="\n", na_rep="")
        pd.DataFrame(pose_rows, columns=["frame", "time_s", "x_m", "y_m", "yaw_deg"]).to_csv(
            tmp / "gt/poses.csv", index=False, float_format=fmt, lineterminator="\n")
        (tmp / "rig.yaml").write_text(rig.to_yaml())
        (tmp / "scene.yaml").write_text(yaml.safe_dump(scene_to_dict(scene), sort_keys=False))
    return {"frames": len(poses), "stripe_columns": stripe_cols,
            "obstacle_bins": int(np.isfinite(ranges["range_m"]).sum())}
