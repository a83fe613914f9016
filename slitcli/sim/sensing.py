"""What the closed loop senses: one range scan per control step (sensor frame).

Shared by the loop (:mod:`slitcli.sim.loop`) and the sensors that feed it (perfect
sensing there, :mod:`slitcli.sim.vision`), so neither imports the other.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class RangeScan:
    """One sensed frame: a per-bearing range table in the sensor frame.

    ``bearing_deg`` (B,) bin centres, positive left; ``range_m`` (B,) horizontal range
    from the sensor origin, NaN = no return; the sensor origin is ``forward_m`` ahead
    of the robot's rotation centre. ``free_m``: up to this range a bin with no return
    is reliably free (the obstacle memory may clear it); 0 = a missed return says
    nothing (vision: a textureless or unlit obstacle gives no return).
    """

    bearing_deg: np.ndarray
    range_m: np.ndarray
    forward_m: float
    free_m: float = 0.0


__all__ = ["RangeScan"]
