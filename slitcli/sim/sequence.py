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

The folder is rendered into a hidden sibling (:func:`staging_folder`), one frame at a time
with a manifest, and renamed into place at the end: an interrupted render (Ctrl-C,
SIGTERM, ``kill -9``) continues where it stopped when run again with the same scene,
rig and frames, and gives the same bytes as an uninterrupted one; another render into
the same OUT meanwhile is refused.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import math
import os
import shutil
import zipfile
from collections.abc import Callable, Iterator, Sequence
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from slitcli.errors import SlitcliError
from slitcli.io import atomic
from slitcli.io.atomic import (
    atomic_directory,
    check_output_folder,
    write_png_atomic,
    write_text_atomic,
)
from slitcli.io.batch import FrameBatch
from slitcli.io.lock import lock_output
from slitcli.io.png import encode_depth_png, encode_disparity_png, encode_mask_png
from slitcli.rig import Rig
from slitcli.sim.camera import camera_to_scene
from slitcli.sim.laser_truth import lit_wedge_ranges
from slitcli.sim.render import FrameTruth, render_frame
from slitcli.sim.scene import MAX_SEED, Box, Cylinder, Pose2D, Scene, Wall

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
    """All truth arrays of a frame, lossless, written atomically.

    The archive is deflated ``.npy`` members with a fixed date, so one frame always
    gives the same bytes (``numpy.savez_compressed`` stamps the current time).
    """
    p = truth.pose
    arrays = {
        "depth_m": truth.depth_m, "disparity_px": truth.disparity_px,
        "obstacle_mask": truth.obstacle_mask, "textured": truth.textured,
        "object_id": truth.object_id.astype(np.int16), "stripe_v_px": truth.stripe_v_px,
        "stripe_peak_dn": truth.stripe_peak_dn, "stripe_sensor_xyz": truth.stripe_sensor_xyz,
        "bearing_deg": truth.bearing_deg, "range_m": truth.range_m,
        "pose_xy_yaw": np.array([p.x_m, p.y_m, p.yaw_rad]),
    }
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        for key, arr in arrays.items():
            info = zipfile.ZipInfo(f"{key}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            member = io.BytesIO()
            np.lib.format.write_array(member, np.asanyarray(arr), allow_pickle=False)
            zf.writestr(info, member.getvalue())
    atomic.write_bytes_atomic(path, buf.getvalue())


@contextlib.contextmanager
def _named_at(stage: Path, out: Path) -> Iterator[None]:
    """Report an OSError on a staged path (disk full...) at the output path the user gave."""
    try:
        yield
    except OSError as e:
        name = e.filename
        if isinstance(name, str) and name.startswith(str(stage)):
            raise OSError(e.errno, e.strerror, str(out) + name[len(str(stage)):]) from None
        raise


def staging_folder(out: str | Path) -> Path:
    """Where :func:`render_sequence` builds ``out``: a hidden sibling named by a digest
    of ``out``'s absolute path (short whatever the name). It survives an interruption,
    so the next render into ``out`` continues it."""
    where = Path(os.path.abspath(Path(out).expanduser()))
    key = hashlib.sha256(str(where).encode("utf-8", "surrogateescape")).hexdigest()[:16]
    return where.parent / f".slitcli-render-{key}"


_TABLES = {  # part kind -> (file in OUT, columns)
    "laser": ("gt/laser.csv", ("frame", "u_px", "v_px", "strength", "x_m", "y_m", "range_m",
                               "bearing_deg")),
    "lit": ("gt/laser_ranges.csv", ("frame", "time_s", "bearing_deg", "laser_true_m")),
    "ranges": ("gt/ranges.csv", ("frame", "time_s", "bearing_deg", "range_m")),
    "poses": ("gt/poses.csv", ("frame", "time_s", "x_m", "y_m", "yaw_deg")),
}
_IMAGE_DIRS = ("left", "right", "gt/disparity", "gt/distance", "gt/mask")
_FMT = "%.9g"


def _rows(table: pd.DataFrame) -> str:
    return table.to_csv(header=False, index=False, float_format=_FMT, lineterminator="\n",
                        na_rep="")


def _render_one(scene: Scene, rig: Rig, stage: Path, batch: FrameBatch, i: int, pose: Pose2D,
                time_s: float, bins: tuple[np.ndarray, np.ndarray]) -> None:
    """Render frame ``i`` into ``stage``: its images and truth, then its table parts (the
    ``poses`` part last: it marks the frame as finished)."""
    # moving objects are where they are at the frame's time (the truth follows)
    scene = scene.at_time(time_s)
    fr = render_frame(scene, rig, pose, frame_index=i)
    name = FRAME_NAME.format(i) + ".png"
    t = fr.truth
    write_png_atomic(stage / "left" / name, fr.left_bgr)
    write_png_atomic(stage / "right" / name, fr.right_bgr)
    write_png_atomic(stage / "gt/disparity" / name, encode_disparity_png(t.disparity_px))
    write_png_atomic(stage / "gt/distance" / name, encode_depth_png(t.depth_m))
    write_png_atomic(stage / "gt/mask" / name, encode_mask_png(t.obstacle_mask))
    write_truth_npz(stage / "gt" / f"frame_{FRAME_NAME.format(i)}.npz", t)
    parts = {
        "laser": truth_laser_rows(i, t),
        "lit": pd.DataFrame({"frame": i, "time_s": time_s, "bearing_deg": t.bearing_deg,
                             "laser_true_m": lit_wedge_ranges(scene, rig, pose, *bins)}),
        "ranges": pd.DataFrame({"frame": i, "time_s": time_s, "bearing_deg": t.bearing_deg,
                                "range_m": t.range_m}),
        "poses": pd.DataFrame([(i, time_s, pose.x_m, pose.y_m, math.degrees(pose.yaw_rad))],
                              columns=list(_TABLES["poses"][1])),
    }
    for kind, table in parts.items():
        write_text_atomic(batch.part_path(i, kind), _rows(table))


def _publish(stage: Path, tmp: Path) -> None:
    """Hard-link the staged outputs (everything but the ``.slitcli`` state) into ``tmp``."""
    for folder, dirs, files in os.walk(stage):
        rel = Path(folder).relative_to(stage)
        if rel.parts[:1] == (".slitcli",):
            continue
        dirs[:] = [d for d in dirs if rel != Path(".") or d != ".slitcli"]
        for d in dirs:
            (tmp / rel / d).mkdir(exist_ok=True)
        for f in files:
            try:
                os.link(Path(folder) / f, tmp / rel / f)
            except OSError:  # a file system without hard links
                shutil.copyfile(Path(folder) / f, tmp / rel / f)


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
    _, bin_lo, bin_hi = rig.bearing_bins(1.0)
    check_output_folder(out, overwrite=overwrite, inputs=inputs)  # before any rendering
    stage = staging_folder(out)
    n = len(poses)
    manifest = {"command": "render", "format": 1, "scene": scene_to_dict(scene),
                "rig": rig.to_dict(), "frames": n}
    lock = lock_output(stage, shown=out)  # one render into OUT at a time
    batch = FrameBatch(stage, "render", manifest, overwrite=True, shared=True,
                       subfolders=(*_IMAGE_DIRS, "gt"))
    with lock, batch, _named_at(stage, Path(out)):
        if batch.fresh:  # another scene, rig or frame count: none of the staged frames
            for entry in stage.iterdir():
                if entry.name != ".slitcli":
                    shutil.rmtree(entry) if entry.is_dir() else entry.unlink()
        for sub in _IMAGE_DIRS:
            (stage / sub).mkdir(parents=True, exist_ok=True)
        for i, pose in enumerate(poses):
            if not batch.is_done(i, ("poses",)):
                _render_one(scene, rig, stage, batch, i, pose, float(times[i]), (bin_lo, bin_hi))
            if on_frame is not None:
                on_frame(i + 1, n)
        with atomic_directory(out, overwrite=overwrite, inputs=inputs) as tmp:
            _publish(stage, tmp)
            for kind, (file, columns) in _TABLES.items():
                batch.assemble(n, kind, tmp / file, ",".join(columns))
            pd.DataFrame({"frame": np.arange(n), "time_s": times}).to_csv(
                tmp / "times.csv", index=False, float_format=_FMT, lineterminator="\n")
            (tmp / "rig.yaml").write_text(rig.to_yaml())
            (tmp / "scene.yaml").write_text(yaml.safe_dump(scene_to_dict(scene),
                                                           sort_keys=False))
            # the staged files are linked into tmp: the state can go before the rename
            shutil.rmtree(stage, ignore_errors=True)
    ranges = pd.read_csv(Path(out) / "gt/ranges.csv", usecols=["range_m"])
    laser = pd.read_csv(Path(out) / "gt/laser.csv", usecols=["frame"])
    return {"frames": n, "stripe_columns": len(laser),
            "obstacle_bins": int(np.isfinite(ranges["range_m"]).sum())}
