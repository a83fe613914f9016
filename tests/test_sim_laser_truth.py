"""The laser's truth from the scene's geometry (slitcli.sim.laser_truth)."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from slitcli.rig import paper_rig
from slitcli.sim.laser_truth import lit_wedge_ranges
from slitcli.sim.render import frame_truth
from slitcli.sim.scene import Pose2D, Wall, load_scene

ROOT = Path(__file__).resolve().parent.parent
RIG = paper_rig()
CENTRES, LO, HI = RIG.bearing_bins(1.0)


@pytest.mark.parametrize("distance_m", [0.7, 0.8, 0.9, 1.0, 1.2])
def test_wall_ahead_is_lit_at_its_nearest_bearing(distance_m):
    """A wall across the view at x = D (rotation-centre frame): the nearest lit point of
    a wedge is at the wedge's bearing nearest 0, range (D - forward) / cos(b)."""
    base = load_scene(ROOT / "sample_data" / "corridor.yaml")
    wall = replace(next(o for o in base.objects if isinstance(o, Wall)),
                   from_xy_m=(distance_m, -6.0), to_xy_m=(distance_m, 6.0), z_min_m=0.0,
                   height_m=1.0)
    scene = replace(base, objects=(wall,))
    r = lit_wedge_ranges(scene, RIG, Pose2D(0.0, 0.0, 0.0), LO, HI)
    near_b = np.where(LO > 0, LO, np.where(HI < 0, HI, 0.0))
    want = (distance_m - RIG.mount.forward_m) / np.cos(np.radians(near_b))
    lit = np.isfinite(r)
    np.testing.assert_allclose(r[lit], want[lit], rtol=1e-9)
    assert lit[np.abs(CENTRES) <= 10].all()


def _random_pose(seed: int, start: Pose2D) -> Pose2D:
    rng = np.random.default_rng(seed)
    return Pose2D(start.x_m + rng.uniform(-0.2, 0.2), start.y_m + rng.uniform(-0.2, 0.2),
                  start.yaw_rad + math.radians(rng.uniform(-12, 12)))


@pytest.mark.parametrize("name", ["corridor", "overhang", "distractors"])
@pytest.mark.parametrize("seed", range(5))
def test_no_lit_column_is_nearer_than_the_truth(name, seed):
    """The renderer's true stripe points (one per image column, from its ray casting)
    are lit points: none lies nearer than the wedge's truth, and every wedge holding one
    has a truth (the truth is the nearest point of the whole lit outline, which the
    columns only sample)."""
    scene = load_scene(ROOT / "sample_data" / f"{name}.yaml")
    pose = _random_pose(seed, scene.robot.start)
    t = frame_truth(scene, RIG, pose)
    geo = lit_wedge_ranges(scene, RIG, pose, LO, HI)
    xyz = t.stripe_sensor_xyz[np.isfinite(t.stripe_v_px)]
    b = np.degrees(np.arctan2(xyz[:, 1], xyz[:, 0]))
    rng = np.hypot(xyz[:, 0], xyz[:, 1])
    k = np.floor(b + 0.5).astype(int) - int(CENTRES[0])
    ok = (k >= 0) & (k < CENTRES.size)
    assert np.isfinite(geo[k[ok]]).all()
    assert (geo[k[ok]] <= rng[ok] + 1e-6).all()
    assert ok.any()  # the sheet lights something in every sampled pose
