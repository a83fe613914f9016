"""A warm one-frame `slitcli detect` imports neither pandas, nor all of scipy.linalg, nor
matplotlib (docs/install.md), and no JIT compiler (numba: the kernels are built ahead of
time)."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CORRIDOR = ROOT / "sample_data" / "sequences" / "corridor"
HEAVY = ("numba", "pandas", "scipy.linalg", "matplotlib", "skimage")


def _run(code: str) -> dict:
    res = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True,
                         text=True, cwd=ROOT, timeout=600)
    assert res.returncode == 0, res.stderr[-2000:]
    return json.loads(res.stdout.strip().splitlines()[-1])


def _one_frame(tmp_path: Path) -> Path:
    one = tmp_path / "one"
    for side in ("left", "right"):
        (one / side).mkdir(parents=True)
        first = sorted((CORRIDOR / side).iterdir())[0]
        shutil.copy(first, one / side / first.name)
    shutil.copy(CORRIDOR / "rig.yaml", one / "rig.yaml")
    (one / "times.csv").write_text("frame,time_s\n0,0.25\n")
    return one


def test_importing_detect_imports_no_heavy_module():
    out = _run(f"""
        import json, sys
        import slitcli.detect
        print(json.dumps([m for m in {HEAVY!r} if m in sys.modules]))
        """)
    assert out == []


def test_a_one_frame_detect_imports_no_heavy_module(tmp_path):
    """The command runs (exit 0, one frame's rows) without numba, pandas, scipy.linalg
    and matplotlib."""
    one = _one_frame(tmp_path)
    out = _run(f"""
        import json, sys
        from slitcli.cli import main
        sys.argv = ["slitcli", "detect", {str(one)!r}, "-o", {str(tmp_path / "out")!r}]
        try:
            main()
        except SystemExit as e:
            code = e.code
        print(json.dumps({{"code": code, "heavy": [m for m in {HEAVY!r} if m in sys.modules]}}))
        """)
    assert out["code"] in (0, None)
    assert out["heavy"] == []
    lines = (tmp_path / "out" / "ranges.csv").read_text().splitlines()
    assert len(lines) > 1 and all(line.split(",")[:2] == ["0", "0.25"] for line in lines[1:])
