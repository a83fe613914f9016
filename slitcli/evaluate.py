"""Measured results against the ground truth and against the paper's claims.

Reads tables (detect's ``ranges.csv``, render's ``gt/ranges.csv`` and
``gt/laser_ranges.csv``, simulate-dwa's ``metrics.csv``) and reduces them to the
numbers in ``docs/reproduction.md``.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
import pandas as pd

SENSORS = ("fused", "laser", "stereo")


def range_errors(ranges: pd.DataFrame, truth: pd.DataFrame) -> pd.DataFrame:
    """Join a detect range table with the true ranges (same frame and bearing).

    Returns one row per bin with a true obstacle: ``true_m`` and, per sensor,
    ``<sensor>_range_m`` and ``<sensor>_err_m`` (NaN where that sensor has no return).
    """
    t = truth.rename(columns={"range_m": "true_m"})[["frame", "bearing_deg", "true_m"]]
    j = ranges.merge(t, on=["frame", "bearing_deg"], how="inner")
    j = j[np.isfinite(j["true_m"])]
    out = pd.DataFrame({"true_m": j["true_m"].to_numpy()})
    for k in SENSORS:
        out[f"{k}_range_m"] = j[f"{k}_range_m"].to_numpy()
        out[f"{k}_err_m"] = out[f"{k}_range_m"] - out["true_m"]
    if "fused_source" in j:
        out["fused_source"] = j["fused_source"].to_numpy()
    return out


def binned_accuracy(errors: pd.DataFrame, sensor: str, edges_m: list[float], *,
                    tol_rel: float = 0.05, tol_abs_m: float = 0.05) -> pd.DataFrame:
    """Per true-distance bin: how often a sensor returns a range within tolerance, and
    its median absolute and relative error where it returns one.

    A bin counts as detected when ``|err| <= max(tol_abs_m, tol_rel * true)``.
    """
    rows = []
    for lo, hi in itertools.pairwise(edges_m):
        sel = errors[(errors["true_m"] >= lo) & (errors["true_m"] < hi)]
        err = sel[f"{sensor}_err_m"]
        ok = err.abs() <= np.maximum(tol_abs_m, tol_rel * sel["true_m"])
        has = err.notna()
        rows.append({
            "true_from_m": lo, "true_to_m": hi, "bins": len(sel),
            "returned": float(has.mean()) if len(sel) else np.nan,
            "within_tol": float(ok.mean()) if len(sel) else np.nan,
            "median_abs_err_m": float(err[has].abs().median()) if has.any() else np.nan,
            "median_rel_err": float((err[has].abs() / sel["true_m"][has]).median())
            if has.any() else np.nan,
        })
    return pd.DataFrame(rows)


@dataclass(frozen=True)
class Claim:
    """One claim of the paper, what this run measured, and whether it holds."""

    claim: str
    measured: str
    holds: str

    def row(self) -> str:
        return f"| {self.claim} | {self.measured} | {self.holds} |"


def laser_range_claim(ranges: pd.DataFrame, truth_laser_ranges: pd.DataFrame
                      ) -> tuple[Claim, pd.DataFrame]:
    """"An active sensor minimum range is 0.6 m and maximum range is 1 m" (paper §4).

    Scored on the bins where the sheet truly lights an obstacle the camera sees: the
    renderer's ``gt/laser_ranges.csv`` (frame, bearing_deg, laser_true_m), computed from
    the scene's geometry alone (:func:`slitcli.sim.laser_truth.lit_wedge_ranges`), so
    obstacles above the sheet or outside the image do not count against the laser, and
    no part of the laser's own estimator enters its truth.
    """
    t = truth_laser_ranges[["frame", "bearing_deg", "laser_true_m"]]
    t = t[np.isfinite(t["laser_true_m"])]
    j = ranges.merge(t, on=["frame", "bearing_deg"], how="inner")
    err = pd.DataFrame({"true_m": j["laser_true_m"],
                        "laser_err_m": j["laser_range_m"] - j["laser_true_m"]})
    table = binned_accuracy(err, "laser", [0.6, 0.8, 1.0, 1.2, 1.5], tol_rel=0.01,
                            tol_abs_m=0.0)
    band = table[table["true_to_m"] <= 1.0]
    n_band = int(band["bins"].sum())
    rate = float((band["within_tol"] * band["bins"]).sum() / max(n_band, 1))
    far = table[table["true_from_m"] >= 1.2]
    holds = "yes" if rate >= 0.95 else "partly" if rate >= 0.5 else "no"
    measured = (f"where the sheet lights an obstacle at 0.6-1.0 m, ranged within 1 % in "
                f"{100 * rate:.1f} % of {n_band} bins (median error "
                f"{1000 * float(band['median_abs_err_m'].median()):.1f} mm); at 1.2-1.5 m "
                f"the stripe fades and is found in {100 * float(far['returned'].iloc[0]):.0f} %"
                " of the lit bins")
    return Claim("laser (active) range 0.6-1 m", measured, holds), table


def stereo_range_claim(errors: pd.DataFrame) -> tuple[Claim, pd.DataFrame]:
    """"A passive sensor range can be up to 3 m" (paper §4)."""
    table = binned_accuracy(errors, "stereo", [0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5],
                            tol_rel=0.05, tol_abs_m=0.05)
    upto = table[table["true_to_m"] <= 3.0]
    n = int(upto["bins"].sum())
    rate = float((upto["within_tol"] * upto["bins"]).sum() / max(n, 1))
    worst = upto.loc[upto["bins"] > 0, "within_tol"].min()
    holds = "yes" if rate >= 0.8 and worst >= 0.5 else "partly" if rate >= 0.5 else "no"
    returned = float((upto["returned"] * upto["bins"]).sum() / max(n, 1))
    med = float(upto["median_rel_err"].max())
    measured = (f"obstacles up to 3 m (textureless ones included) returned in "
                f"{100 * returned:.0f} % and ranged within max(5 cm, 5 %) in {100 * rate:.0f} %"
                f" of {n} bins (worst 0.5 m band {100 * worst:.0f} %); median relative error "
                f"at most {100 * med:.1f} % up to 3 m")
    return Claim("stereo (passive) range up to 3 m", measured, holds), table


def dwa_claim(metrics: pd.DataFrame) -> Claim:
    """"When sensing distance is within 1~2 m range, the mobile robot can be better to
    avoid obstacle. However, when sensing distance is over 2 m, ... worse" (paper §4).

    Scored by outcome: a collision or a missed goal is worst, then the time to the goal.
    """
    m = metrics.copy()
    m["cost_s"] = np.where((m["collided"] == 1) | (m["reached_goal"] == 0), np.inf,
                           m["time_to_goal_s"])
    short = m[m["sensing_range_m"] < 1.0]
    mid = m[(m["sensing_range_m"] >= 1.0) & (m["sensing_range_m"] <= 2.0)]
    far = m[m["sensing_range_m"] > 2.0]

    def times(d: pd.DataFrame) -> str:
        return ", ".join(f"{r.sensing_range_m:g} m: " + (
            "collided" if r.collided else f"{r.time_to_goal_s:.1f} s" if r.reached_goal
            else "goal not reached") for r in d.itertuples())

    better = bool(len(short)) and mid["cost_s"].mean() < short["cost_s"].min()
    worse = bool(len(far)) and far["cost_s"].min() > mid["cost_s"].max() + 0.5
    measured = (f"time to goal (no collision in any run) below 1 m: {times(short)}; "
                f"1-2 m: {times(mid)}; past 2 m: {times(far) or 'not run'}")
    holds = ("yes" if better and worse else
             "partly: better with 1-2 m than below 1 m, but not worse past 2 m" if better
             else "partly: worse past 2 m only" if worse else "no")
    return Claim("DWA avoids best with 1-2 m sensing, worse past 2 m", measured, holds)


def markdown_table(df: pd.DataFrame, *, floatfmt: str = "{:.3g}") -> str:
    """A DataFrame as a GitHub markdown table (no extra dependency)."""
    head = "| " + " | ".join(df.columns) + " |"
    sep = "|" + "|".join("---" for _ in df.columns) + "|"
    lines = [head, sep]
    for row in df.itertuples(index=False):
        cells = [floatfmt.format(v) if isinstance(v, float) else str(v) for v in row]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)
