"""Measured results against the ground truth and against the paper's claims.

Reads tables (detect's ``ranges.csv``, render's ``gt/ranges.csv``, simulate-dwa's
``metrics.csv``) and reduces them to the numbers in ``docs/reproduction.md``.
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


def laser_range_claim(errors: pd.DataFrame) -> tuple[Claim, pd.DataFrame]:
    """"An active sensor minimum range is 0.6 m and maximum range is 1 m" (paper §4)."""
    table = binned_accuracy(errors, "laser", [0.6, 0.8, 1.0, 1.2, 1.5, 2.0, 3.0],
                            tol_rel=0.01, tol_abs_m=0.0)
    band = table[table["true_to_m"] <= 1.0]
    beyond = table[table["true_from_m"] >= 1.2]
    n_band = int(band["bins"].sum())
    rate = float((band["within_tol"] * band["bins"]).sum() / max(n_band, 1))
    n_far = int(beyond["bins"].sum())
    far_rate = float((beyond["returned"] * beyond["bins"]).sum() / max(n_far, 1))
    holds = "yes" if rate >= 0.9 and far_rate <= 0.2 else "partly" if rate >= 0.5 else "no"
    measured = (f"obstacles at 0.6-1.0 m ranged within 1 % in {100 * rate:.0f} % of "
                f"{n_band} bins; beyond 1.2 m the laser returns in {100 * far_rate:.0f} % of "
                f"{n_far} bins")
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
    measured = (f"textured obstacles up to 3 m ranged within max(5 cm, 5 %) in "
                f"{100 * rate:.0f} % of {n} bins (worst 0.5 m band {100 * worst:.0f} %)")
    return Claim("stereo (passive) range up to 3 m", measured, holds), table


def dwa_claim(metrics: pd.DataFrame) -> Claim:
    """"When sensing distance is within 1~2 m range, the mobile robot can be better to
    avoid obstacle. However, when sensing distance is over 2 m, ... worse" (paper §4)."""
    m = metrics.copy()
    m["score"] = m["min_clearance_m"]
    mid = m[(m["sensing_range_m"] >= 1.0) & (m["sensing_range_m"] <= 2.0)]
    short = m[m["sensing_range_m"] < 1.0]
    far = m[m["sensing_range_m"] > 2.0]
    def describe(r) -> str:
        goal = f"goal in {r.time_to_goal_s:.1f} s" if r.reached_goal else "goal not reached"
        hit = "collided" if r.collided else "no collision"
        return (f"{r.sensing_range_m:g} m: clearance {r.min_clearance_m:.2f} m, {hit}, {goal},"
                f" path {r.path_length_m:.2f} m")

    parts = [describe(r) for r in m.itertuples()]
    better_than_short = (not len(short) or mid["min_clearance_m"].min()
                         >= short["min_clearance_m"].max())
    worse_far = bool(len(far)) and far["min_clearance_m"].max() < mid["min_clearance_m"].min()
    if not len(far):
        holds = "better with 1-2 m than below 1 m: " + ("yes" if better_than_short else "no") \
            + "; past 2 m: not run"
    else:
        holds = ("yes" if better_than_short and worse_far else
                 "partly" if better_than_short or worse_far else "no")
    return Claim("DWA avoids best with 1-2 m sensing, worse past 2 m", "; ".join(parts), holds)


def markdown_table(df: pd.DataFrame, *, floatfmt: str = "{:.3g}") -> str:
    """A DataFrame as a GitHub markdown table (no extra dependency)."""
    head = "| " + " | ".join(df.columns) + " |"
    sep = "|" + "|".join("---" for _ in df.columns) + "|"
    lines = [head, sep]
    for row in df.itertuples(index=False):
        cells = [floatfmt.format(v) if isinstance(v, float) else str(v) for v in row]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)
