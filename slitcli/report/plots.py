"""The report's figures of one run (matplotlib; imported only when a report is drawn).

Each ``draw_*`` function draws onto the axes it is given from the arrays of a
:class:`~slitcli.report.run.DetectRun`; nothing here computes detection results.
"""

from __future__ import annotations

import numpy as np
from matplotlib.axes import Axes

from slitcli.report.run import SOURCES

SOURCE_COLOURS = {"laser": "#d62728", "stereo": "#1f77b4", "none": "#c7c7c7"}


def _edges(centres: np.ndarray, default_step: float) -> np.ndarray:
    """Cell edges around ascending centres (half-way between neighbours)."""
    c = np.asarray(centres, dtype=np.float64)
    if c.size == 1:
        return np.array([c[0] - default_step / 2, c[0] + default_step / 2])
    mid = 0.5 * (c[1:] + c[:-1])
    return np.r_[c[0] - (mid[0] - c[0]), mid, c[-1] + (c[-1] - mid[-1])]


def draw_range_heatmap(ax: Axes, times_s: np.ndarray, bearing_deg: np.ndarray,
                       range_m: np.ndarray, *, vmax_m: float, time_label: str) -> object:
    """Range per bearing over time: x = time, y = bearing, colour = range (m).

    Parameters
    ----------
    times_s : ndarray (F,)
        Ascending frame times (or frame indices; ``time_label`` says which).
    bearing_deg : ndarray (B,)
    range_m : ndarray (F, B)
        NaN (no return) is drawn light grey.
    vmax_m : float
        Top of the colour scale, metres.

    Returns
    -------
    The colour bar.
    """
    import matplotlib

    cmap = matplotlib.colormaps["turbo"].with_extremes(bad="0.85")
    mesh = ax.pcolormesh(_edges(times_s, 1.0), _edges(bearing_deg, 1.0),
                         np.ma.masked_invalid(np.asarray(range_m).T), cmap=cmap, vmin=0.0,
                         vmax=vmax_m, shading="flat")
    ax.set_xlabel(time_label)
    ax.set_ylabel("bearing (deg, + = left)")
    ax.set_title("Fused range per bearing over time (grey: no return)")
    cb = ax.figure.colorbar(mesh, ax=ax, pad=0.02)
    cb.set_label("fused range (m)")
    return cb


def draw_birdseye(ax: Axes, bearing_deg: np.ndarray, bin_deg: float, range_m: np.ndarray,
                  source: np.ndarray, times_s: np.ndarray, *, laser_band_m: tuple[float, float],
                  max_range_m: float, time_label: str) -> int:
    """The fused points of every frame in the sensor frame, seen from above.

    Forward (x) points up the page and left (y) to the left. Points are coloured by
    frame time; laser ranges are circles, stereo ranges dots. The field of view's edges
    and the laser band's arcs are drawn for reference.

    Returns
    -------
    int
        Points drawn.
    """
    import matplotlib

    b = np.radians(np.asarray(bearing_deg))[None, :]
    r = np.asarray(range_m, dtype=np.float64)
    x, y = r * np.cos(b), r * np.sin(b)
    t = np.broadcast_to(np.asarray(times_s, dtype=np.float64)[:, None], r.shape)
    cmap = matplotlib.colormaps["viridis"]
    tmin, tmax = float(np.min(times_s)), float(np.max(times_s))
    drawn, sc = 0, None
    for code, marker, size, face in ((1, ".", 14, None), (0, "o", 18, "none")):
        sel = (source == code) & np.isfinite(r)
        if not sel.any():
            continue
        kw = {"facecolors": "none", "edgecolors": cmap((t[sel] - tmin) / max(tmax - tmin,
                                                                           1e-12))} \
            if face == "none" else {"c": t[sel], "cmap": cmap, "vmin": tmin, "vmax": tmax}
        sc_ = ax.scatter(-y[sel], x[sel], s=size, marker=marker, linewidths=0.8,
                         label=f"{SOURCES[code]} range", **kw)
        sc = sc_ if face is None else sc
        drawn += int(sel.sum())
    edge = np.radians([bearing_deg[0] - bin_deg / 2, bearing_deg[-1] + bin_deg / 2])
    for e in edge:
        ax.plot([0, -max_range_m * np.sin(e)], [0, max_range_m * np.cos(e)], color="0.5",
                lw=0.8, ls="--")
    arc = np.linspace(edge[0], edge[1], 60)
    for rr, ls in ((laser_band_m[0], ":"), (laser_band_m[1], ":")):
        ax.plot(-rr * np.sin(arc), rr * np.cos(arc), color="tab:red", lw=0.8, ls=ls)
    ax.plot([], [], color="tab:red", lw=0.8, ls=":", label="laser band")
    ax.plot(0, 0, "k^", ms=7, label="sensor")
    if sc is not None:
        cb = ax.figure.colorbar(sc, ax=ax, pad=0.02)
        cb.set_label(time_label)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("lateral position (m, + = right)")
    ax.set_ylabel("forward x (m)")
    ax.set_title("Fused points of all frames, sensor frame, from above")
    ax.grid(alpha=0.3)
    ax.legend(loc="lower left", fontsize=8)
    return drawn


def draw_source_share(ax: Axes, frame_x: np.ndarray, source: np.ndarray, *,
                      time_label: str) -> dict[str, float]:
    """Share of bins ranged by the laser, by stereo, by neither, per frame (stacked).

    Returns
    -------
    dict
        Share of all bins of the run per source, 0-1.
    """
    counts = np.stack([(source == k).sum(axis=1) for k in range(len(SOURCES))])
    share = counts / max(source.shape[1], 1)
    total = {name: float(counts[k].sum() / max(source.size, 1))
             for k, name in enumerate(SOURCES)}
    labels = [f"{name} ({100 * total[name]:.1f} % of all bins)" for name in SOURCES]
    x = np.asarray(frame_x, dtype=np.float64)
    colours = [SOURCE_COLOURS[n] for n in SOURCES]
    if x.size <= 60:  # few frames: one stacked bar each
        width = float(np.min(np.diff(x))) * 0.8 if x.size > 1 else 0.8
        bottom = np.zeros(x.size)
        for k, (lab, col) in enumerate(zip(labels, colours, strict=True)):
            ax.bar(x, 100 * share[k], width, bottom=bottom, color=col, label=lab)
            bottom += 100 * share[k]
        ax.set_xlim(x[0] - width, x[-1] + width)
    else:
        ax.stackplot(x, 100 * share, labels=labels, colors=colours)
        ax.set_xlim(x[0], x[-1])
    ax.set_ylim(0, 100)
    ax.set_xlabel(time_label)
    ax.set_ylabel("share of bearing bins (%)")
    ax.set_title("Which sensor ranged each bin (fused source)")
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.2), ncol=3, fontsize=8)
    return total


__all__ = ["draw_birdseye", "draw_range_heatmap", "draw_source_share"]
