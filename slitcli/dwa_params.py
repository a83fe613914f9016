"""Parameters of the modified DWA (paper Eqs. 12-13): :class:`DwaParams`, checked once."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from types import MappingProxyType

from slitcli.errors import SlitcliError


@dataclass(frozen=True, kw_only=True)
class DwaParams:
    """Parameters of the modified DWA (DESIGN §8). Units are in the names.

    Attributes
    ----------
    v_max_mps, w_max_dps : float
        Speed limits (paper §4: 0.2 m/s, 7.5 deg/s). v is never negative.
    acc_mps2 : float
        Translational acceleration and braking limit (paper: 0.2 m/s^2).
    ang_acc_dps2 : float
        Angular acceleration limit. The paper gives none; 75 deg/s^2 lets the robot go
        from standing to full turn rate (7.5 deg/s) within 0.1 s, i.e. inside one
        control period, so the window spans every turn rate and the paper's sampling
        gives 9 x 151 = 1359 pairs per step (about 1.4k).
    dt_s : float
        Control period T (the paper's "0.2 ms" read as 0.2 s). The window is what the
        robot can reach within T.
    heading_clamp_deg : float
        The goal bearing theta in Eq. 12 is clamped to +-this (paper: +-90 deg).
    v_res_mps, w_res_dps : float
        Sampling of the window. Samples lie on the lattice k * resolution so that
        v = 0 and w = 0 are always samples when the window contains them.
    heading_horizon_s : float
        Horizon of Eq. 12's heading term, 1 - |theta - w T_h| / pi. With T_h = T the
        term moves by at most 1.5 deg / 180 deg across the window and cannot steer;
        2 s makes it a proportional heading controller (w = theta / 2 s) that saturates
        at w_max for heading errors above 15 deg.
    goal_close_m : float
        Radius of Eq. 13's switch: within it V = 1 - v / v_max (brake), outside it
        V = v / v_max. It is also the arrival radius: a robot standing inside it is
        commanded (0, 0) and nothing else (no rotation chasing the goal bearing).
    footprint_radius_m : float
        Disc used for D_collision: the robot radius plus a safety margin.
    d_max_m : float
        Cap on D_collision and the normaliser of Eq. 12's clearance term. Arcs that
        meet nothing within d_max_m of travel score 1.
    alpha, beta, gamma : float
        Weights of the heading, clearance and velocity terms of Eq. 12.
    turn_circle_close : bool
        Also count the robot as close to the goal (Eq. 13's braking branch) while the
        goal lies inside its current turning circle; see :func:`goal_is_close`.
    discrete_braking : bool
        Admissibility counts the distance covered while a command is held for T; see
        :func:`admissible`.
    predict_horizon_s, predict_step_s : float
        Moving obstacles (:class:`MovingDiscs`) are predicted at constant velocity for
        this long and compared with the robot's position on each arc every
        ``predict_step_s``; see :func:`moving_contact_time`.
    moving_buffer_m : float
        A pair passing a moving obstacle this far (footprint to obstacle) or farther
        gets the full clearance term; see :func:`evaluate_pairs`.
    """

    v_max_mps: float = 0.2
    w_max_dps: float = 7.5
    acc_mps2: float = 0.2
    ang_acc_dps2: float = 75.0
    dt_s: float = 0.2
    heading_clamp_deg: float = 90.0
    v_res_mps: float = 0.01
    w_res_dps: float = 0.1
    heading_horizon_s: float = 2.0
    goal_close_m: float = 0.3
    footprint_radius_m: float = 0.3
    d_max_m: float = 3.0
    alpha: float = 1.0
    beta: float = 1.0
    gamma: float = 1.0
    turn_circle_close: bool = True
    discrete_braking: bool = True
    predict_horizon_s: float = 5.0
    predict_step_s: float = 0.1
    moving_buffer_m: float = 0.5

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if f.type in ("bool", bool):
                if not isinstance(value, bool):
                    raise _bad(f.name, value, "must be true or false")
                continue
            if isinstance(value, bool) or not isinstance(value, int | float) \
                    or not math.isfinite(value):
                raise _bad(f.name, value, "must be a finite number")
        for name in ("v_max_mps", "w_max_dps", "acc_mps2", "ang_acc_dps2", "dt_s",
                     "v_res_mps", "w_res_dps", "heading_horizon_s", "goal_close_m",
                     "footprint_radius_m", "d_max_m", "predict_horizon_s", "predict_step_s",
                     "moving_buffer_m"):
            if getattr(self, name) <= 0:
                raise _bad(name, getattr(self, name), "must be > 0")
        for name in ("alpha", "beta", "gamma"):
            if getattr(self, name) < 0:
                raise _bad(name, getattr(self, name), "must be >= 0")
        if self.alpha + self.beta + self.gamma <= 0:
            raise _bad("alpha", self.alpha, "and beta, gamma are all 0; give one a weight > 0")
        if not 0 < self.heading_clamp_deg <= 180:
            raise _bad("heading_clamp_deg", self.heading_clamp_deg, "must be in (0, 180]")
        for name, high in _HIGH.items():
            if getattr(self, name) > high:
                raise _bad(name, getattr(self, name), f"is out of range; give at most {high:g}")
        if self.dt_s < 1e-3:
            raise _bad("dt_s", self.dt_s, "is below 1 ms; give a control period of at least 0.001")
        pairs = window_size_bound(self)
        if pairs > MAX_WINDOW_PAIRS:
            nv = self.v_max_mps / self.v_res_mps
            nw = 2 * self.w_max_dps / self.w_res_dps
            name = "v_res_mps" if nv >= nw else "w_res_dps"
            raise _bad(name, getattr(self, name),
                       f"samples the window into up to {pairs:.3g} (v, w) pairs, more than "
                       f"{MAX_WINDOW_PAIRS}; give a coarser resolution")
        if self.v_res_mps > self.v_max_mps or self.w_res_dps > self.w_max_dps:
            raise _bad("v_res_mps" if self.v_res_mps > self.v_max_mps else "w_res_dps",
                       self.v_res_mps if self.v_res_mps > self.v_max_mps else self.w_res_dps,
                       "is coarser than the speed limit; give a finer resolution")

    @property
    def w_max_rps(self) -> float:
        """Turn-rate limit in rad/s."""
        return math.radians(self.w_max_dps)

    @property
    def ang_acc_rps2(self) -> float:
        """Angular acceleration limit in rad/s^2."""
        return math.radians(self.ang_acc_dps2)


# Upper bounds: beyond them a parameter is no robot's (and squares, counts and the
# window's sample count stop being representable or affordable).
_HIGH = MappingProxyType({
    "v_max_mps": 100.0, "w_max_dps": 3600.0, "acc_mps2": 1000.0, "ang_acc_dps2": 1e5,
    "dt_s": 10.0, "heading_horizon_s": 1000.0, "goal_close_m": 1000.0,
    "footprint_radius_m": 100.0, "d_max_m": 1000.0, "alpha": 1e6, "beta": 1e6, "gamma": 1e6,
})
MAX_WINDOW_PAIRS = 200_000
"""Most (v, w) pairs one window may hold (the paper's sampling gives 1359)."""


def window_size_bound(params: DwaParams) -> float:
    """Most (v, w) pairs any dynamic window of ``params`` can hold (lattice counts + 1)."""
    p = params
    nv = min(p.v_max_mps, 2 * p.acc_mps2 * p.dt_s) / p.v_res_mps + 1
    nw = min(2 * p.w_max_dps, 2 * p.ang_acc_dps2 * p.dt_s) / p.w_res_dps + 1
    return nv * nw


def _bad(name: str, value: object, problem: str) -> SlitcliError:
    # the parameter in backticks: the command line names its option instead
    return SlitcliError(f"DWA parameter `{name}` = {value!r} {problem}", param=name)


