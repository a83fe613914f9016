"""times.csv is read with the csv module (no pandas on the detect path): the times are
those pandas.read_csv + pandas.to_numeric read before, float for float."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from slitcli.errors import SlitcliError
from slitcli.io.sequence import _read_times


def _pandas_times(path, n: int) -> np.ndarray:
    """The reading this module did before (the reference)."""
    t = pd.read_csv(path, dtype=str, keep_default_na=False)
    frames = pd.to_numeric(t["frame"]).to_numpy(dtype=np.int64)
    out = np.full(n, np.nan)
    out[frames] = pd.to_numeric(t["time_s"]).to_numpy(dtype=float)
    return out


def _spelled(rng: np.random.Generator, t: float) -> str:
    """One way a time may be written: repr, %.Ng, exponent, fixed, padded. (Not with a
    leading '+': pandas read some of those one unit in the last place off; see below.)"""
    k = int(rng.integers(5))
    digits = int(rng.integers(1, 18))
    return [repr(t), f"{t:.{digits}g}", f"{t:.{digits}e}", f"{t:.{digits % 10}f}",
            f" {t!r} "][k]


@pytest.mark.parametrize("seed", range(6))
def test_times_are_the_floats_pandas_read(tmp_path, seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 300))
    order = rng.permutation(n)
    scale = 10.0 ** rng.integers(-3, 10)
    times = (rng.uniform(0, 1, n) * scale).tolist()
    lines = ["frame,time_s", *(f"{i},{_spelled(rng, times[i])}" for i in order)]
    for _ in range(int(rng.integers(0, 3))):  # blank lines are no rows for either reader
        lines.insert(int(rng.integers(1, len(lines) + 1)), "")
    end = "\r\n" if seed % 2 else "\n"
    path = tmp_path / "times.csv"
    path.write_bytes(("\ufeff" if seed % 3 == 0 else "").encode() +
                     (end.join(lines) + end).encode())
    np.testing.assert_array_equal(_read_times(path, n), _pandas_times(path, n))


@pytest.mark.parametrize("seed", range(5))
def test_a_signed_time_reads_as_the_nearest_float(tmp_path, seed):
    """'+0.38515232422627244' is the float 0.38515232422627244 (Python's correctly
    rounded reading; pandas.to_numeric gave the next float up for this one)."""
    rng = np.random.default_rng(seed)
    times = (rng.uniform(0, 1, 50) * 10.0 ** rng.integers(-3, 10)).tolist()
    path = tmp_path / "times.csv"
    path.write_text("frame,time_s\n" + "".join(f"{i},+{t!r}\n" for i, t in enumerate(times)))
    assert _read_times(path, len(times)).tolist() == times


def test_a_row_with_more_than_two_cells_is_refused_naming_its_line(tmp_path):
    path = tmp_path / "times.csv"
    path.write_text("frame,time_s\n0,0\n1,0.2,7\n")
    with pytest.raises(SlitcliError, match=r"times.csv: line 3: 3 cells, expected 2"):
        _read_times(path, 2)


@pytest.mark.parametrize("cell", ["0x10", "1_0", "nan", "Infinity", "1,5", "", "abc"])
def test_a_cell_that_is_no_finite_decimal_is_refused(tmp_path, cell):
    path = tmp_path / "times.csv"
    path.write_text(f'frame,time_s\n0,"{cell}"\n')
    with pytest.raises(SlitcliError, match="line 2: time_s"):
        _read_times(path, 1)


def test_a_missing_file_gives_nan_and_an_empty_one_is_refused(tmp_path):
    assert np.isnan(_read_times(tmp_path / "times.csv", 3)).all()
    (tmp_path / "times.csv").write_text("")
    with pytest.raises(SlitcliError, match="not a CSV"):
        _read_times(tmp_path / "times.csv", 3)
