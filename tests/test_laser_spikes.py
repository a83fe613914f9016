"""Rendered regressions: no stripe row is reported off the laser's light (issue 4).

Each scene is rendered by the project's renderer (slitcli.sim, fixed seeds) with its
exact truth. The property checked in every column where the truth's stripe is not
visible (expected peak under 20 DN): a reported row must lie within 1.5 px of the row
where any laser light falls (a real stripe below the visibility level, computed again
with ``visible_min_dn`` 1 DN), or there must be no report at all.
"""

from pathlib import Path

import numpy as np
import pytest
import yaml

from slitcli.laser import LaserGeometry, LaserParams, detect_laser
from slitcli.rig import paper_rig
from slitcli.sim.render import frame_truth, render_left
from slitcli.sim.scene import scene_from_dict

ROOT = Path(__file__).resolve().parent.parent
RIG = paper_rig()
PARAMS = LaserParams()
GEOM = LaserGeometry.from_rig(RIG, PARAMS)
#: a reported row this far from every laser row counts as off the stripe, px
OFF_PX = 1.5


def _render(d, frame):
    """Render ``frame`` of scene dict ``d``; returns the frame, the detection (with the
    previous frame's result when there is one) and the rows of any laser light."""
    scene = scene_from_dict(d)
    poses = scene.poses(frame + 1)
    prev = None
    if frame > 0:
        r0 = render_left(scene, RIG, poses[frame - 1], frame_index=frame - 1)
        prev = detect_laser(r0.left_bgr, RIG, PARAMS, geometry=GEOM)
    r = render_left(scene, RIG, poses[frame], frame_index=frame)
    f = detect_laser(r.left_bgr, RIG, PARAMS, previous=prev, geometry=GEOM)
    lit_d = {**d, "laser": {**d.get("laser", {}), "visible_min_dn": 1.0}}
    lit = frame_truth(scene_from_dict(lit_d), RIG, poses[frame]).stripe_v_px
    return r, f, lit


def _off_stripe(r, f, lit):
    """Columns reported where the truth's stripe is not visible, more than OFF_PX
    from any laser light; and the visible columns' count, found share and rows off."""
    t = r.truth.stripe_v_px
    vis = np.isfinite(t)
    off = f.found & ~vis & ~(np.abs(np.nan_to_num(f.v_px - lit, nan=np.inf)) <= OFF_PX)
    both = vis & f.found
    wrong = np.abs(f.v_px[both] - t[both]) > OFF_PX
    return np.flatnonzero(off), int(vis.sum()), both.sum() / max(vis.sum(), 1), int(wrong.sum())


def _corridor(power_dn):
    d = yaml.safe_load((ROOT / "sample_data" / "corridor.yaml").read_text())
    d.setdefault("laser", {})["power_dn"] = power_dn
    return d


@pytest.mark.xfail(reason="issue 19 re-layering: regression on this rendered frame, "
                   "docs/laser.md Limits", strict=True)
@pytest.mark.parametrize(("d", "frame"), [
    # the sample corridor, ninth frame: the stripe on the textured box 1.45 m ahead is
    # faint (expected peak under 20 DN) over 30 columns; in one of them the box's
    # bottom edge on the floor, 9 rows below, passed as the stripe, joined across the
    # two faint columns before it (3 px per column allowed there), and tracking then
    # filled those columns at the faint stripe's own row, leaving it alone between them
    (_corridor(900.0), 8),
])
def test_rendered_no_row_off_the_laser_light(d, frame):
    r, f, lit = _render(d, frame)
    off, n_vis, found, wrong = _off_stripe(r, f, lit)
    assert off.size == 0, (off, f.v_px[off], lit[off])
    assert n_vis >= 40 and found >= 0.99 and wrong == 0
