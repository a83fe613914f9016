"""Modified Dynamic Window Approach (paper §3, Eqs. 12-13; DESIGN §8).

One planning step, in the order of the classic DWA (Fox, Burgard and Thrun 1997, and
the PythonRobotics layout): dynamic window -> per-pair arc prediction (D_collision)
-> admissibility -> cost terms -> choice. Every (v, w) pair of the window is
evaluated at once in array code.

Frames and units
----------------
The planner works in the *robot frame*: origin at the rotation centre, x forward,
y left, metres; angles in radians inside, degrees at the interfaces that say so.
Obstacle points are (N, 2) floor positions in that frame; the goal is one (x, y).
A pair (v, w) is a translational speed v >= 0 (m/s) and a turn rate w (rad/s,
positive = counter-clockwise = left). Held constant, it moves the robot along a
circular arc of curvature w / v (a straight line for w = 0, rotation in place for
v = 0).

The footprint is a disc of radius ``footprint_radius_m`` centred on the rotation
centre, so rotating in place can never hit anything.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from types import MappingProxyType

import numpy as np

from slitcli.errors import SlitcliError
from slitcli.prediction import MovingDiscs, moving_contact_time

# Work arrays of D_collision have (pairs x points) elements; blocks of points keep them
# near 8 MB each whatever the size of the obstacle memory.
_MAX_BLOCK_ELEMENTS = 1 << 20

# Option spelled on the command line for each parameter, so errors name what users type.
_OPTION = MappingProxyType({
    "v_max_mps": "--v-max-mps", "w_max_dps": "--w-max-dps", "acc_mps2": "--acc-mps2",
    "ang_acc_dps2": "--ang-acc-dps2", "dt_s": "--dt-s",
    "heading_clamp_deg": "--heading-clamp-deg", "v_res_mps": "--v-res-mps",
    "w_res_dps": "--w-res-dps", "heading_horizon_s": "--heading-horizon-s",
    "goal_close_m": "--goal-close-m", "footprint_radius_m": "--footprint-radius-m",
    "d_max_m": "--d-max-m", "alpha": "--alpha", "beta": "--beta", "gamma": "--gamma",
    "turn_circle_close": "--turn-circle-close/--no-turn-circle-close",
    "discrete_braking": "--discrete-braking/--no-discrete-braking",
    "predict_horizon_s": "--predict-horizon-s", "predict_step_s": "--predict-step-s",
    "moving_buffer_m": "--moving-buffer-m",
})


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
    return SlitcliError(f"DWA parameter {name} ({_OPTION.get(name, name)}) = {value!r} "
                        f"{problem}")


# ------------------------------------------------------------------ the window
def dynamic_window(v_mps: float, w_rps: float, params: DwaParams) -> tuple[np.ndarray, np.ndarray]:
    """Velocities reachable within one control period, sampled (DESIGN §8).

    Parameters
    ----------
    v_mps, w_rps : float
        Current translational speed (m/s) and turn rate (rad/s).
    params : DwaParams

    Returns
    -------
    v_mps : ndarray, shape (Nv,)
        Speeds in [max(0, v - acc T), min(v_max, v + acc T)], on the v_res lattice.
    w_rps : ndarray, shape (Nw,)
        Turn rates in [w - ang_acc T, w + ang_acc T] within +-w_max, on the w_res
        lattice (rad/s).
    """
    p = params
    v_lo = max(0.0, v_mps - p.acc_mps2 * p.dt_s)
    v_hi = min(p.v_max_mps, v_mps + p.acc_mps2 * p.dt_s)
    w_dps = math.degrees(w_rps)
    w_lo = max(-p.w_max_dps, w_dps - p.ang_acc_dps2 * p.dt_s)
    w_hi = min(p.w_max_dps, w_dps + p.ang_acc_dps2 * p.dt_s)
    v = _lattice(v_lo, v_hi, p.v_res_mps)
    w = _lattice(w_lo, w_hi, p.w_res_dps)
    return v, np.radians(w)


def _lattice(lo: float, hi: float, res: float) -> np.ndarray:
    k0 = math.ceil(lo / res - 1e-9)
    k1 = math.floor(hi / res + 1e-9)
    if k1 < k0:  # window narrower than one step: keep the reachable value nearest the centre
        return np.array([min(max(0.5 * (lo + hi), lo), hi)])
    return np.arange(k0, k1 + 1) * res


def window_pairs(v_mps: float, w_rps: float, params: DwaParams) -> tuple[np.ndarray, np.ndarray]:
    """All (v, w) pairs of the window, v-major: two arrays of shape (P,) (m/s, rad/s)."""
    v, w = dynamic_window(v_mps, w_rps, params)
    vv, ww = np.meshgrid(v, w, indexing="ij")
    return vv.ravel(), ww.ravel()


# ------------------------------------------------------------------ prediction
def collision_distance(v_mps: np.ndarray, w_rps: np.ndarray, points_xy: np.ndarray, *,
                       radius_m: float, d_max_m: float) -> np.ndarray:
    """D_collision of Eq. 12: distance travelled along each pair's arc before contact.

    Exact, not sampled: the footprint centre runs on a circle of radius r = v / |w|
    about (0, r sign w); an obstacle point P at distance rho from that centre is
    touched where the centre comes within ``radius_m`` of P, i.e. at the angles
    psi +- phi around the circle with cos phi = (r^2 + rho^2 - R^2) / (2 r rho)
    (law of cosines), and first at travel angle (psi - phi) measured from the
    start in the direction of motion. A straight line (w = 0) meets P at
    s = x - sqrt(R^2 - y^2) when |y| <= R and x > 0.

    Points already inside the footprint (possible only with a safety margin, or
    after sensing noise) stop every forward motion when they lie ahead (x > 0:
    every arc starts along +x, so the distance to them shrinks) and are ignored
    otherwise (the robot is leaving them).

    Parameters
    ----------
    v_mps, w_rps : ndarray, shape (P,)
        The pairs (m/s, rad/s). v = 0 (rotation in place) never collides.
    points_xy : ndarray, shape (N, 2)
        Obstacle points in the robot frame, metres.
    radius_m : float
        Footprint radius.
    d_max_m : float
        Cap: arcs meeting nothing within this travel get ``d_max_m``.

    Returns
    -------
    d_collision_m : ndarray, shape (P,)
        In [0, d_max_m].
    """
    v = np.asarray(v_mps, dtype=float).ravel()
    w = np.asarray(w_rps, dtype=float).ravel()
    out = np.full(v.shape, float(d_max_m))
    pts = np.asarray(points_xy, dtype=float).reshape(-1, 2)
    # A point farther than d_max + R from the centre cannot be reached within d_max.
    pts = pts[np.hypot(pts[:, 0], pts[:, 1]) <= d_max_m + radius_m]
    inside = pts[:, 0] ** 2 + pts[:, 1] ** 2 < radius_m * radius_m
    moving = v > 0
    if np.any(inside & (pts[:, 0] > 0)):
        return np.where(moving, 0.0, out)
    pts = pts[~inside]
    if len(pts) == 0 or not np.any(moving):
        return out
    # A straight line's contact does not depend on the speed: one value per point.
    x, y = pts[:, 0], pts[:, 1]
    lat = radius_m * radius_m - y * y
    s_line = np.where((lat >= 0) & (x > 0), x - np.sqrt(np.maximum(lat, 0.0)), np.inf)
    line = moving & (w == 0)
    out[line] = np.minimum(out[line], s_line.min())
    for side in (1.0, -1.0):
        # Mirror right turns onto left turns: every arc then turns counter-clockwise.
        arc = np.flatnonzero(moving & (w * side > 0))
        if len(arc) == 0:
            continue
        block = max(1, _MAX_BLOCK_ELEMENTS // len(arc))
        best = np.full(len(arc), np.inf)
        for i in range(0, len(pts), block):  # blocks of points bound the work arrays
            part = pts[i:i + block]
            best = np.minimum(best, _arc_contact(v[arc] / np.abs(w[arc]), part[:, 0],
                                                 side * part[:, 1], radius_m))
        out[arc] = np.minimum(out[arc], best)
    return out


def _arc_contact(r: np.ndarray, x: np.ndarray, y: np.ndarray, radius_m: float) -> np.ndarray:
    """Travel along counter-clockwise arcs to the first contact with any point, shape (P,).

    ``r`` (P,) are the turn radii, (x, y) (n,) the points (all outside the footprint);
    inf where an arc touches none.

    The turn centre is (0, r). With q = |P|^2 - R^2 - 2 r y = rho^2 - r^2 - R^2, the
    point is touched iff |rho - r| <= R, i.e. |q| <= 2 r R, and then
    cos phi = (2 r^2 + q) / (2 r rho).
    """
    r2 = radius_m * radius_m
    two_r = 2.0 * r[:, None]
    q = (x * x + y * y - r2)[None, :] - two_r * y[None, :]
    rows, cols = np.nonzero(np.abs(q) <= two_r * radius_m)
    best = np.full(r.shape, np.inf)
    if len(rows) == 0:
        return best
    rr = r[rows]
    qq = q[rows, cols]
    rho = np.sqrt(np.maximum(qq + rr * rr + r2, 1e-24))
    phi = np.arccos(np.clip((2.0 * rr * rr + qq) / (2.0 * rr * rho), -1.0, 1.0))
    # The start lies at angle -pi/2 seen from the turn centre.
    along = np.mod(np.arctan2(y[cols] - rr, x[cols]) + 0.5 * np.pi - phi, 2.0 * np.pi)
    starts = np.flatnonzero(np.r_[True, rows[1:] != rows[:-1]])
    best[rows[starts]] = np.minimum.reduceat(rr * along, starts)
    return best


def admissible(v_mps: np.ndarray, w_rps: np.ndarray, d_collision_m: np.ndarray,
               params: DwaParams) -> np.ndarray:
    """Pairs that can stop before the obstacle on their arc (DESIGN §8).

    Translation: v <= sqrt(2 D acc). Rotation, "likewise for w": braking w at ang_acc
    turns the robot by w^2 / (2 ang_acc), which must not exceed the heading change
    Theta_c = |w| D / v the arc allows before contact, i.e. |w| <= sqrt(2 Theta_c
    ang_acc). Both together mean the robot can brake on the arc it is on. Rotation in
    place (v = 0) is always admissible.

    With ``discrete_braking`` (default), D is first reduced by v T / 2: the chosen pair
    is held for a whole period T before the next step can brake, and braking then goes
    down in steps of acc T, so the robot's real stopping distance is
    v^2 / (2 acc) + v T / 2 (2 cm at 0.2 m/s), not the continuous v^2 / (2 acc) of the
    paper's condition, which lets the robot end up to that much inside its margin.

    Parameters
    ----------
    v_mps, w_rps, d_collision_m : ndarray, shape (P,)
    params : DwaParams

    Returns
    -------
    ok : ndarray of bool, shape (P,)
    """
    v = np.asarray(v_mps, dtype=float)
    aw = np.abs(np.asarray(w_rps, dtype=float))
    d = np.asarray(d_collision_m, dtype=float)
    if params.discrete_braking:
        d = np.maximum(d - 0.5 * params.dt_s * v, 0.0)
    tol = 1e-12
    stop_v = v <= np.sqrt(2.0 * d * params.acc_mps2) + tol
    with np.errstate(divide="ignore", invalid="ignore"):
        theta_c = np.where(v > 0, aw * d / np.where(v > 0, v, 1.0), np.inf)
    stop_w = aw <= np.sqrt(2.0 * theta_c * params.ang_acc_rps2) + tol
    return (stop_v & stop_w) | (v <= 0)


# ------------------------------------------------------------------ cost terms
def goal_bearing(goal_xy: tuple[float, float] | np.ndarray) -> tuple[float, float]:
    """Goal bearing theta (rad, positive left) and distance (m) from the robot frame."""
    gx, gy = float(goal_xy[0]), float(goal_xy[1])
    return math.atan2(gy, gx), math.hypot(gx, gy)


def heading_term(theta_rad: float, w_rps: np.ndarray, params: DwaParams) -> np.ndarray:
    """Eq. 12 heading term 1 - |theta - w T_h| / pi, theta clamped to +-heading_clamp.

    Parameters
    ----------
    theta_rad : float
        Goal bearing relative to the robot heading.
    w_rps : ndarray, shape (P,)

    Returns
    -------
    ndarray, shape (P,), in [0, 1] for the default clamp.
    """
    clamp = math.radians(params.heading_clamp_deg)
    theta = min(max(theta_rad, -clamp), clamp)
    return 1.0 - np.abs(theta - np.asarray(w_rps, dtype=float) * params.heading_horizon_s) / math.pi


def clearance_term(d_collision_m: np.ndarray, params: DwaParams) -> np.ndarray:
    """Eq. 12 clearance term D_collision / D_max, shape (P,), in [0, 1]."""
    return np.asarray(d_collision_m, dtype=float) / params.d_max_m


def goal_is_close(goal_distance_m: float, theta_rad: float, v_mps: float,
                  params: DwaParams) -> bool:
    """Eq. 13's switch: is the robot "close to the goal"?

    Close when the goal is within ``goal_close_m``. With ``turn_circle_close`` the
    robot is also close when the goal lies inside the circle it would drive at its
    current speed and full turn rate, d < 2 (v / w_max) |sin theta|: it cannot turn
    into the goal without slowing down, and a DWA that keeps full speed there orbits
    the goal for ever (the robot's 7.5 deg/s gives a 1.5 m turn radius at 0.2 m/s).
    """
    if goal_distance_m <= params.goal_close_m:
        return True
    if not params.turn_circle_close:
        return False
    return goal_distance_m < 2.0 * (v_mps / params.w_max_rps) * abs(math.sin(theta_rad))


def velocity_term(v_mps: np.ndarray, close: bool, params: DwaParams) -> np.ndarray:
    """Eq. 13: v / v_max far from the goal, 1 - v / v_max close to it (:func:`goal_is_close`)."""
    ratio = np.asarray(v_mps, dtype=float) / params.v_max_mps
    return 1.0 - ratio if close else ratio


# ------------------------------------------------------------------ one step
@dataclass(frozen=True)
class PairScores:
    """Every pair of one step and its terms; all arrays have shape (P,).

    ``score`` is Eq. 12 (-inf for inadmissible pairs); ``t_contact_s`` the time to the
    first predicted contact with a moving obstacle (inf: none within the horizon).
    """

    v_mps: np.ndarray
    w_rps: np.ndarray
    d_collision_m: np.ndarray
    admissible: np.ndarray
    heading: np.ndarray
    clearance: np.ndarray
    velocity: np.ndarray
    score: np.ndarray
    t_contact_s: np.ndarray


def evaluate_pairs(v_mps: float, w_rps: float, goal_xy: tuple[float, float] | np.ndarray,
                   points_xy: np.ndarray, params: DwaParams,
                   moving: MovingDiscs | None = None) -> PairScores:
    """Window, prediction, admissibility and Eq. 12 for every pair at once.

    With ``moving`` obstacles, D_collision of each pair is also capped at the distance
    it travels before meeting one of them (v x :func:`moving_contact_time`), so that the
    clearance term and the admissibility test see the obstacle where it will be when
    the robot gets there.

    Parameters
    ----------
    v_mps, w_rps : float
        Current velocities.
    goal_xy : (2,)
        Goal in the robot frame, metres.
    points_xy : ndarray, shape (N, 2)
        Static obstacle points in the robot frame, metres.
    params : DwaParams
    moving : MovingDiscs, optional
    """
    v, w = window_pairs(v_mps, w_rps, params)
    d = collision_distance(v, w, points_xy, radius_m=params.footprint_radius_m,
                           d_max_m=params.d_max_m)
    ok = admissible(v, w, d, params)
    c = clearance_term(d, params)
    t_c = np.full(v.shape, np.inf)
    if moving is not None and len(moving.radius_m):
        t_c, gap = moving_contact_time(v, w, moving, radius_m=params.footprint_radius_m,
                                       horizon_s=params.predict_horizon_s,
                                       step_s=params.predict_step_s)
        hit = np.isfinite(t_c)
        t_hit = np.where(hit, t_c, 0.0)
        # braking: the robot must be able to stop before the place of contact
        d = np.minimum(d, np.where(hit, v * t_hit, np.inf))
        ok = admissible(v, w, d, params)
        # clearance against moving obstacles, in [0, 1] like D / D_max: a pair that
        # meets one scores half its time to contact as a share of the horizon (whatever
        # its speed: a slower pair meets the person at the same time, only nearer the
        # start); one that passes scores from 1/2 (grazing) to 1 (a buffer away)
        pass_c = 0.5 + 0.5 * np.clip(gap / params.moving_buffer_m, 0.0, 1.0)
        c = np.minimum(c, np.where(hit, 0.5 * t_hit / params.predict_horizon_s, pass_c))
        # a pair predicted to meet a moving obstacle is chosen only if every pair does
        if np.any(ok & ~hit):
            ok &= ~hit
    theta, dist = goal_bearing(goal_xy)
    h = heading_term(theta, w, params)
    vel = velocity_term(v, goal_is_close(dist, theta, v_mps, params), params)
    s = params.alpha * h + params.beta * c + params.gamma * vel
    return PairScores(v, w, d, ok, h, c, vel, np.where(ok, s, -np.inf), t_c)


@dataclass(frozen=True)
class DwaCommand:
    """The velocity command of one step.

    ``status`` is one of
    ``move``    the best admissible pair (Eq. 12) translates;
    ``goal``    within ``goal_close_m``: braking (Eq. 13 close branch), or (0, 0) once standing;
    ``rotate``  far from the goal no translating pair beats standing still (a local minimum
                in front of an obstacle): rotate in place at the window's largest turn rate,
                away from the nearest obstacle point, until one does;
    ``wait``    far from the goal the best pair is a standing one because translating
                pairs would meet a moving obstacle's predicted path: the best standing
                pair (Eq. 12), i.e. stand and let it pass;
    ``brake``   no admissible pair at all (an obstacle appeared inside the stopping
                distance): full braking on the current arc.
    ``d_collision_m`` and ``score`` belong to the chosen pair (NaN for ``brake``).
    """

    v_mps: float
    w_rps: float
    status: str
    d_collision_m: float
    score: float
    n_pairs: int
    n_admissible: int

    @property
    def w_dps(self) -> float:
        """Turn rate in deg/s."""
        return math.degrees(self.w_rps)


def plan_step(v_mps: float, w_rps: float, goal_xy: tuple[float, float] | np.ndarray,
              points_xy: np.ndarray, params: DwaParams,
              moving: MovingDiscs | None = None) -> DwaCommand:
    """One modified-DWA step: the command to hold for the next control period.

    Parameters
    ----------
    v_mps, w_rps : float
        The robot's current velocities (m/s, rad/s).
    goal_xy : (2,)
        Goal in the robot frame (rotation centre origin, x forward, y left), metres.
    points_xy : ndarray, shape (N, 2)
        Static obstacle points in the robot frame, metres (N may be 0).
    params : DwaParams
    moving : MovingDiscs, optional
        Predicted moving obstacles (:func:`evaluate_pairs`).

    Returns
    -------
    DwaCommand
    """
    _theta, dist = goal_bearing(goal_xy)
    at_goal = dist <= params.goal_close_m
    if at_goal and v_mps <= 1e-12:
        return DwaCommand(0.0, 0.0, "goal", params.d_max_m, float("nan"), 0, 0)
    sc = evaluate_pairs(v_mps, w_rps, goal_xy, points_xy, params, moving)
    n_ok = int(sc.admissible.sum())
    if n_ok == 0:
        dv = params.acc_mps2 * params.dt_s
        dw = params.ang_acc_rps2 * params.dt_s
        w_new = math.copysign(max(abs(w_rps) - dw, 0.0), w_rps)
        return DwaCommand(max(v_mps - dv, 0.0), w_new, "brake", float("nan"), float("nan"),
                          sc.v_mps.size, 0)
    i = int(np.argmax(sc.score))
    if at_goal:
        status = "goal"
    elif sc.v_mps[i] > 0:
        status = "move"
    elif np.any((sc.v_mps > 0) & np.isfinite(sc.t_contact_s)):
        # forward pairs are blocked by a moving obstacle's predicted path, not by a
        # wall: stand (turning to the goal at most) and let it pass
        status = "wait"
    else:
        status = "rotate"
        i = _rotate_away(sc, points_xy, v_mps, w_rps)
    return DwaCommand(float(sc.v_mps[i]), float(sc.w_rps[i]), status, float(sc.d_collision_m[i]),
                      float(sc.score[i]), sc.v_mps.size, n_ok)


def _rotate_away(sc: PairScores, points_xy: np.ndarray, v_mps: float = 1.0,
                 w_rps: float = 0.0) -> int:
    """Index of the in-place rotation with the largest turn rate away from the nearest point.

    Turning away from the nearest point is self-consistent (as the robot turns, that
    point moves further to the other side), so the robot does not dither between
    turning left and right in front of a symmetric obstacle. A robot already rotating
    in place keeps its direction: between two obstacles the nearest point can swap
    sides as it turns, and re-deciding every step then dithers on the spot for ever.
    """
    pts = np.asarray(points_xy, dtype=float).reshape(-1, 2)
    side = 1.0
    if v_mps <= 0 and w_rps != 0:
        side = math.copysign(1.0, w_rps)
    elif len(pts):
        nearest = pts[np.argmin(np.hypot(pts[:, 0], pts[:, 1]))]
        side = -1.0 if nearest[1] > 0 else 1.0
    cand = np.flatnonzero((sc.v_mps <= 0) & sc.admissible)
    return int(cand[np.argmax(side * sc.w_rps[cand])])
