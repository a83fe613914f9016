"""Options that hung or exhausted memory are refused at once; dwa tables are checked."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from robust_helpers import invoke, one_error_line

from slitcli.dwa import DwaParams, window_pairs
from slitcli.dwa_params import MAX_WINDOW_PAIRS, window_size_bound
from slitcli.errors import SlitcliError

SIMULATE = ["simulate-dwa", "--scenario", "random"]


@pytest.mark.parametrize("extra, names", [
    (["--dt-s", "1e-6"], "--dt-s"),
    (["--worlds", "1000000000"], "--worlds"),
    (["--bin-deg", "1e-6"], "--bin-deg"),
    (["--v-res-mps", "1e-9"], "--v-res-mps"),
    (["--w-res-dps", "1e-9"], "--w-res-dps"),
    (["--v-max-mps", "1e300"], "--v-max-mps"),
    (["--seed", "-1"], "--seed"),
    (["--max-time-s", "1e9"], "--max-time"),
    (["--dt-s", "0.001", "--max-time-s", "1000"], "--dt-s"),
    (["--alpha", "1e300"], "--alpha"),
])
def test_simulate_dwa_options_that_hung(tmp_path, extra, names):
    one_error_line(invoke([*SIMULATE, "-o", tmp_path / "out", *extra]), names=names)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("extra, names", [
    (["--jobs", "100000"], "--jobs"),
    (["--max-dt", "inf"], "--max-dt"),
    (["--max-dt", "0"], "--max-dt"),
    (["--bin-deg", "1e-6"], "--bin-deg"),
])
def test_detect_options_bounded(tmp_path, extra, names):
    one_error_line(invoke(["detect", tmp_path, "-o", tmp_path / "out", *extra]), names=names)


@pytest.mark.parametrize("seed", range(5))
def test_window_never_exceeds_its_bound(seed):
    """The count bound holds for the windows actually built (random accepted settings)."""
    rng = np.random.default_rng(seed)
    for _ in range(40):
        kw = {"v_max_mps": rng.uniform(0.05, 3), "w_max_dps": rng.uniform(1, 180),
              "acc_mps2": rng.uniform(0.05, 5), "ang_acc_dps2": rng.uniform(1, 500),
              "dt_s": rng.uniform(0.01, 1), "v_res_mps": 10 ** rng.uniform(-4, -1.5),
              "w_res_dps": 10 ** rng.uniform(-3, 0)}
        try:
            p = DwaParams(**kw)
        except SlitcliError as e:
            assert "pairs" in str(e) or "coarser" in str(e)
            continue
        for v in np.linspace(0, p.v_max_mps, 3):
            for w in np.radians(np.linspace(-p.w_max_dps, p.w_max_dps, 3)):
                vv, _ = window_pairs(v, w, p)
                assert vv.size <= window_size_bound(p) <= MAX_WINDOW_PAIRS


def _table(path, frames=4, *, times=True, ranges=None):
    rows = []
    for f in range(frames):
        for b in range(-30, 31, 5):
            r = 2.0 - 0.1 * f if abs(b) < 8 else np.nan
            rows.append((f, f * 0.2 if times else np.nan, float(b),
                         r if ranges is None else ranges))
    table = pd.DataFrame(rows, columns=["frame", "time_s", "bearing_deg", "fused_range_m"])
    table.to_csv(path, index=False, na_rep="")
    return path


def test_negative_range_names_the_line(tmp_path):
    path = _table(tmp_path / "r.csv")
    text = path.read_text().splitlines()
    text[3] = ",".join([*text[3].split(",")[:3], "-1.5"])
    path.write_text("\n".join(text) + "\n")
    line = one_error_line(invoke(["dwa", path, "--goal", "3,0", "-o", tmp_path / "c.csv"]),
                          names="line 4: column fused_range_m is negative")
    assert str(path) in line and not (tmp_path / "c.csv").exists()


def test_empty_times_ask_for_period(tmp_path):
    path = _table(tmp_path / "r.csv", times=False)
    line = one_error_line(invoke(["dwa", path, "--goal", "3,0", "-o", tmp_path / "c.csv"]),
                          names="time_s is empty")
    assert "--period-s" in line


@pytest.mark.parametrize("period", [0.1, 0.2, 0.25, 0.5, 1.0])
def test_period_dates_frames_as_times_would(tmp_path, period):
    """--period-s P on a table without times = the same table with time_s = frame x P."""
    timed = _table(tmp_path / "t.csv")
    df = pd.read_csv(timed)
    df["time_s"] = df["frame"] * period
    df.to_csv(timed, index=False, na_rep="")
    untimed = _table(tmp_path / "u.csv", times=False)
    a = invoke(["dwa", timed, "--goal", "3,0.5", "-o", tmp_path / "a.csv"])
    b = invoke(["dwa", untimed, "--goal", "3,0.5", "-o", tmp_path / "b.csv", "--period-s",
                str(period)])
    assert a.exit_code == 0 and b.exit_code == 0, (a.output, b.output)
    assert (tmp_path / "a.csv").read_bytes() == (tmp_path / "b.csv").read_bytes()


@pytest.mark.parametrize("period", ["0", "-1", "inf", "1e9"])
def test_bad_period(tmp_path, period):
    path = _table(tmp_path / "r.csv", times=False)
    one_error_line(invoke(["dwa", path, "--goal", "3,0", "-o", tmp_path / "c.csv",
                           "--period-s", period]), names="--period-s")


@pytest.mark.parametrize("column, value", [("frame", "-1"), ("frame", "1.5"),
                                           ("bearing_deg", "500"), ("fused_range_m", "inf")])
def test_other_impossible_cells(tmp_path, column, value):
    path = _table(tmp_path / "r.csv")
    df = pd.read_csv(path, dtype=str, keep_default_na=False)
    df.loc[5, column] = value
    df.to_csv(path, index=False)
    one_error_line(invoke(["dwa", path, "--goal", "3,0", "-o", tmp_path / "c.csv"]),
                   names=f"line 7: column {column}")
