"""times.csv is checked cell by cell: a bad cell is exit 2 naming the file and line."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from click.testing import CliRunner

from slitcli.cli import cli

BUNDLED = Path(__file__).resolve().parent.parent / "sample_data" / "sequences" / "corridor"


@pytest.mark.parametrize(("text", "what"), [
    ("frame,time_s\n0,0.0\n0,0.2\n", "listed more than once"),
    ("frame,time_s\n0,0.0\n1,abc\n", "line 3: time_s 'abc'"),
    ("frame,time_s\n0,0.0\n1.5,1\n", "line 3: frame '1.5'"),
    ("frame,time_s\n0,0.0\n99,1\n", "line 3: frame '99'"),
    ("frame,time_s\n0,inf\n", "line 2: time_s 'inf'"),
    ("a,b\n0,0\n", "expected frame,time_s"),
    (None, "is not a file"),
])
def test_bad_times_are_exit_2_naming_the_line(tmp_path, text, what):
    seq = tmp_path / "seq"
    shutil.copytree(BUNDLED, seq)
    times = seq / "times.csv"
    times.unlink()
    if text is None:
        times.mkdir()
    else:
        times.write_text(text)
    res = CliRunner().invoke(cli, ["detect", str(seq), "-o", str(tmp_path / "out")])
    assert res.exit_code == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and what in lines[0] and "times.csv" in lines[0]
    assert not (tmp_path / "out" / "ranges.csv").exists()
