"""Plain-Python reference of one modified-DWA step (kept for tests and `make bench`).

Loops over every (v, w) pair and every obstacle point with the math module only,
written separately from the array code in slitcli/dwa.py (signed turn centre, no
mirroring). Used to check that the array version makes the identical choice, and
to measure its speed-up. ``contact_marching`` is a third, brute-force way to the
same number (march along the arc, then bisect) for spot checks.
"""

from __future__ import annotations

import math

from slitcli.dwa import DwaParams


def window(v: float, w: float, p: DwaParams) -> tuple[list[float], list[float]]:
    """Window samples on the resolution lattice (m/s, rad/s)."""
    v_lo, v_hi = max(0.0, v - p.acc_mps2 * p.dt_s), min(p.v_max_mps, v + p.acc_mps2 * p.dt_s)
    wd = math.degrees(w)
    w_lo = max(-p.w_max_dps, wd - p.ang_acc_dps2 * p.dt_s)
    w_hi = min(p.w_max_dps, wd + p.ang_acc_dps2 * p.dt_s)
    vs = [k * p.v_res_mps for k in range(math.ceil(v_lo / p.v_res_mps - 1e-9),
                                         math.floor(v_hi / p.v_res_mps + 1e-9) + 1)]
    ws = [math.radians(k * p.w_res_dps) for k in range(math.ceil(w_lo / p.w_res_dps - 1e-9),
                                                       math.floor(w_hi / p.w_res_dps + 1e-9) + 1)]
    return vs, ws


def pose_at(v: float, w: float, s: float) -> tuple[float, float]:
    """Robot centre after travelling s metres along the arc of (v, w) from the origin."""
    if w == 0:
        return s, 0.0
    k = w / v
    return math.sin(k * s) / k, (1.0 - math.cos(k * s)) / k


def contact(v: float, w: float, px: float, py: float, radius: float) -> float:
    """Travel to the first contact with point (px, py), closed form. inf if none."""
    if v <= 0:
        return math.inf
    if px * px + py * py < radius * radius:
        return 0.0 if px > 0 else math.inf
    if w == 0:
        if abs(py) <= radius and px > 0:
            return px - math.sqrt(radius * radius - py * py)
        return math.inf
    rs = v / w                      # signed turn radius: centre at (0, rs)
    r = abs(rs)
    rho = math.hypot(px, py - rs)
    if abs(rho - r) > radius:
        return math.inf
    c = (r * r + rho * rho - radius * radius) / (2 * r * max(rho, 1e-12))
    phi = math.acos(min(1.0, max(-1.0, c)))
    a0 = math.atan2(-rs, 0.0)       # where the robot starts, seen from the centre
    ap = math.atan2(py - rs, px)    # where the point is
    delta = ((ap - a0) * (1.0 if w > 0 else -1.0)) % (2 * math.pi)
    return r * ((delta - phi) % (2 * math.pi))


def contact_marching(v: float, w: float, px: float, py: float, radius: float, d_max: float,
                     step: float = 0.001) -> float:
    """Brute force: march along the arc in ``step`` metres, bisect the entering step."""
    """Travel to the first contact with point (px, py): march, then bisect. inf if none."""
    if v <= 0:
        return math.inf
    if px * px + py * py < radius * radius:
        return 0.0 if px > 0 else math.inf
    s_prev = 0.0
    n = math.ceil(d_max / step)
    for i in range(1, n + 1):
        s = min(i * step, d_max)
        x, y = pose_at(v, w, s)
        if (x - px) ** 2 + (y - py) ** 2 <= radius * radius:
            lo, hi = s_prev, s
            for _ in range(50):
                mid = 0.5 * (lo + hi)
                x, y = pose_at(v, w, mid)
                if (x - px) ** 2 + (y - py) ** 2 <= radius * radius:
                    hi = mid
                else:
                    lo = mid
            return hi
        s_prev = s
    return math.inf


def d_collision(v: float, w: float, points: list[tuple[float, float]], p: DwaParams) -> float:
    """D_collision of one pair: nearest contact over all points, capped at D_max."""
    if v > 0:
        for px, py in points:
            if px * px + py * py < p.footprint_radius_m ** 2 and px > 0:
                return 0.0
    best = p.d_max_m
    for px, py in points:
        if math.hypot(px, py) > p.d_max_m + p.footprint_radius_m:
            continue
        best = min(best, contact(v, w, px, py, p.footprint_radius_m))
    return best


def moving_contact(v: float, w: float, discs: list[tuple[float, float, float, float, float]],
                   p: DwaParams) -> tuple[float, float]:
    """First predicted contact time with moving discs (x, y, vx, vy, r), and the closest pass.

    Same instants and contact rule as slitcli.dwa.moving_contact_time, written as loops.
    """
    n = math.floor(p.predict_horizon_s / p.predict_step_s + 1e-9)
    prev = [math.hypot(x, y) for x, y, _, _, _ in discs]
    t_c, min_free = math.inf, math.inf
    for k in range(1, n + 1):
        t = k * p.predict_step_s
        if w == 0:
            rx, ry = v * t, 0.0
        else:
            rx, ry = math.sin(w * t) * v / w, (1.0 - math.cos(w * t)) * v / w
        for j, (x, y, vx, vy, r) in enumerate(discs):
            gap = math.hypot(rx - (x + vx * t), ry - (y + vy * t))
            reach = p.footprint_radius_m + r + 0.5 * p.predict_step_s * (v + math.hypot(vx, vy))
            min_free = min(min_free, gap - reach)
            if gap < reach and gap < prev[j] and t_c == math.inf:
                t_c = t
            prev[j] = gap
    return t_c, min_free


def choose(v0: float, w0: float, goal: tuple[float, float], points: list[tuple[float, float]],
           p: DwaParams, discs: list[tuple[float, float, float, float, float]] | None = None
           ) -> tuple[float, float, float]:
    """Best admissible (v, w) by Eq. 12 (first maximum in v-major order) and its score.

    ``discs``: moving obstacles (x, y, vx, vy, radius), robot frame.
    """
    vs, ws = window(v0, w0, p)
    theta_raw = math.atan2(goal[1], goal[0])
    dist = math.hypot(goal[0], goal[1])
    clamp = math.radians(p.heading_clamp_deg)
    theta = min(max(theta_raw, -clamp), clamp)
    close = dist <= p.goal_close_m or (
        p.turn_circle_close
        and dist < 2 * v0 / math.radians(p.w_max_dps) * abs(math.sin(theta_raw)))
    rows = []
    for v in vs:
        for w in ws:
            d = d_collision(v, w, points, p)
            c = d / p.d_max_m
            t_c = math.inf
            if discs:
                t_c, free = moving_contact(v, w, discs, p)
                if t_c < math.inf:
                    d = min(d, v * t_c)
                    c = min(c, 0.5 * t_c / p.predict_horizon_s)
                else:
                    c = min(c, 0.5 + 0.5 * min(max(free / p.moving_buffer_m, 0.0), 1.0))
            ok = True
            if v > 0:
                d_brake = max(d - 0.5 * p.dt_s * v, 0.0) if p.discrete_braking else d
                theta_c = abs(w) * d_brake / v
                ok = (v <= math.sqrt(2 * d_brake * p.acc_mps2) + 1e-12
                      and abs(w) <= math.sqrt(2 * theta_c * math.radians(p.ang_acc_dps2)) + 1e-12)
            h = 1 - abs(theta - w * p.heading_horizon_s) / math.pi
            vel = v / p.v_max_mps
            if close:
                vel = 1 - vel
            rows.append((ok, t_c, p.alpha * h + p.beta * c + p.gamma * vel, v, w))
    # a pair meeting a moving obstacle is chosen only if every admissible pair does
    free_exists = any(ok and t_c == math.inf for ok, t_c, _, _, _ in rows)
    best = (-math.inf, math.nan, math.nan)
    for ok, t_c, s, v, w in rows:
        if ok and not (free_exists and t_c < math.inf) and s > best[0]:
            best = (s, v, w)
    return best[1], best[2], best[0]
