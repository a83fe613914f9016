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
from dataclasses import dataclass

import numpy as np

from slitcli.dwa_params import DwaParams
from slitcli.prediction import MovingDiscs, moving_contact_time

# Work arrays of D_collision have (pairs x points) elements; blocks of points keep them
# near 8 MB each whatever the size of the obstacle memory.
_MAX_BLOCK_ELEMENTS = 1 << 20

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
