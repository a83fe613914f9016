"""Prediction of moving obstacles for the DWA (docs/dwa.md §1 step 3b).

Moving obstacles are discs (outline points with a radius, usually 0) at constant
velocity; every (v, w) pair of the window is held for the horizon and the robot's
position on its arc is compared with each disc's position at the same instants.
Robot frame at the planning instant: origin at the rotation centre, x forward, y left,
metres, seconds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class MovingDiscs:
    """Moving obstacles as discs at constant velocity, robot frame at the planning instant.

    ``centre_xy`` (T, 2) m, ``velocity_xy`` (T, 2) m/s (in the robot frame's axes: the
    world velocity rotated, not relative to the robot's own motion), ``radius_m`` (T,).
    """

    centre_xy: np.ndarray
    velocity_xy: np.ndarray
    radius_m: np.ndarray

    @staticmethod
    def none() -> MovingDiscs:
        """No moving obstacle."""
        return MovingDiscs(np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0))


def arc_positions(v_mps: np.ndarray, w_rps: np.ndarray, t_s: np.ndarray) -> np.ndarray:
    """Robot centre after holding each pair for each time, shape (P, K, 2), robot frame.

    x = v t sin(a)/a, y = v t (1 - cos a)/a with a = w t, written with sinc so that
    w = 0 (a straight line) needs no special case.
    """
    v = np.asarray(v_mps, dtype=float)[:, None]
    a = np.asarray(w_rps, dtype=float)[:, None] * np.asarray(t_s, dtype=float)[None, :]
    s = v * np.asarray(t_s, dtype=float)[None, :]
    return np.stack([s * np.sinc(a / np.pi), s * 0.5 * a * np.sinc(a / (2 * np.pi)) ** 2],
                    axis=-1)


def moving_contact_time(v_mps: np.ndarray, w_rps: np.ndarray, moving: MovingDiscs, *,
                        radius_m: float, horizon_s: float, step_s: float
                        ) -> tuple[np.ndarray, np.ndarray]:
    """First time each pair's footprint meets a predicted moving disc, and the closest pass.

    Every pair is held for the whole horizon and every disc moves at its velocity; the
    two are compared at the same instants t_k = k ``step_s`` up to ``horizon_s`` (the
    same time on the arc and on the obstacle's track, which is what a prediction
    means). Contact at t_k: the centres are closer than ``radius_m`` + the disc radius
    + half the relative travel of one step (so that a contact between two samples is
    not missed), and closer than at t_(k-1) (a disc that already overlaps the margin
    but moves apart does not block the robot from leaving).

    Arrays are (P, K, T) for P pairs, K instants and T discs (tens).

    Returns
    -------
    t_contact_s : ndarray, shape (P,)
        inf where the pair meets nothing within the horizon.
    min_gap_m : ndarray, shape (P,)
        Smallest free distance between the footprint and any disc over the horizon
        (negative where they meet).
    """
    v = np.asarray(v_mps, dtype=float)
    if len(moving.radius_m) == 0:
        return np.full(v.shape, np.inf), np.full(v.shape, np.inf)
    t = np.arange(0.0, horizon_s + 1e-9, step_s)
    robot = arc_positions(v, w_rps, t)                                         # (P, K, 2)
    disc = moving.centre_xy[None, :, :] + t[:, None, None] * moving.velocity_xy[None]  # (K, T, 2)
    reach = radius_m + moving.radius_m[None, :] + 0.5 * step_s * (
        v[:, None] + np.hypot(*moving.velocity_xy.T)[None, :])                 # (P, T)
    from slitcli._prediction_kernel import contact_kernel  # compiled: loaded on first use

    return contact_kernel(robot, disc, reach, t)
