"""The range table's CSV rows without pandas (slitcli.ranges.format_csv_rows,
RangeTable.csv_rows) are the bytes pandas' to_csv wrote (csv_rows of a DataFrame)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from slitcli.ranges import FUSED_SOURCES, RangeTable, csv_rows, format_csv_rows

SEEDS = range(6)


def _awkward_floats(rng: np.random.Generator, n: int) -> np.ndarray:
    """Ranges with every case the format meets: NaN, +-inf, -0.0, sub-micrometre,
    huge, values on a rounding edge of 6 significant digits, ordinary metres."""
    v = rng.uniform(0.05, 12.0, n) * 10.0 ** rng.integers(-9, 10, n)
    special = np.array([np.nan, np.inf, -np.inf, -0.0, 0.0, 1.0000005, 9.9999995, 123456.5,
                        5e-324, 1.7976931348623157e308])
    pick = rng.random(n) < 0.3
    v[pick] = rng.choice(special, pick.sum())
    return v


def _f32(v: np.ndarray) -> np.ndarray:
    with np.errstate(over="ignore"):  # huge values become inf in float32, on purpose
        return v.astype(np.float32)


@pytest.mark.parametrize("seed", SEEDS)
def test_range_rows_are_the_bytes_pandas_wrote(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(0, 120))
    table = RangeTable(
        np.sort(rng.uniform(-40, 40, n)), _awkward_floats(rng, n),
        _f32(_awkward_floats(rng, n)) if seed % 2 else _awkward_floats(rng, n),
        rng.random(n) < 0.5, _awkward_floats(rng, n), rng.choice(FUSED_SOURCES, n))
    frame = int(rng.integers(0, 10**7))
    for time_s in (np.nan, 0.0, 0.2 * frame, 1_700_000_000 + rng.uniform(0, 1e4),
                   float(rng.uniform(0, 1e-6))):
        assert table.csv_rows(frame, time_s) == csv_rows(table.rows(frame, time_s))


@pytest.mark.parametrize("seed", SEEDS)
def test_any_columns_are_the_bytes_pandas_writes(seed):
    """Integers, booleans, float32/float64 and text that needs quoting (commas, quotes,
    line breaks, empty), with missing values as None and NaN."""
    rng = np.random.default_rng(100 + seed)
    n = int(rng.integers(1, 60))
    words = np.array(["laser", "a,b", 'say "hi"', "two\nlines", "", " pad ", "ünï"],
                     dtype=object)
    text = rng.choice(words, n)
    text[rng.random(n) < 0.2] = None
    cols = {"i": rng.integers(-10**12, 10**12, n), "b": rng.random(n) < 0.5,
            "f32": _f32(_awkward_floats(rng, n)), "f64": _awkward_floats(rng, n),
            "text": text, "u": rng.choice(["stereo", "none"], n)}
    expected = csv_rows(pd.DataFrame(cols))
    assert format_csv_rows(list(cols.values())) == expected


def test_no_rows_is_empty_text():
    empty = RangeTable(*(np.zeros(0) for _ in range(5)), np.zeros(0, dtype=str))
    assert empty.csv_rows(3, 1.5) == "" == csv_rows(empty.rows(3, 1.5))


def test_columns_of_different_lengths_are_refused():
    with pytest.raises(ValueError):
        format_csv_rows([np.zeros(3), np.zeros(4)])
