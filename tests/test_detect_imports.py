"""A warm one-frame `slitcli detect` imports neither numba (its kernels are compiled ahead
of time), nor pandas, nor all of scipy.linalg, nor matplotlib (docs/install.md); a
command that does load numba (SGM) still lets it find SciPy's BLAS."""

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


def test_numba_dot_uses_the_preloaded_blas():
    """After the command line's preload, a kernel calling np.dot compiles (numba links
    SciPy's BLAS through the preloaded module) and gives numpy's result."""
    out = _run("""
        import importlib.util, json, sys
        from slitcli.compile_notice import announce_compiles
        announce_compiles(lambda line: None)
        import numba
        import numpy as np
        if importlib.util.find_spec("scipy") is None:
            print(json.dumps({"skipped": True}))
            raise SystemExit
        @numba.njit(cache=False)
        def dot(a, b):
            return np.dot(a, b)
        rng = np.random.default_rng(3)  # an equality for any matrices: one seed
        a, b = rng.normal(size=(5, 7)), rng.normal(size=(7, 3))
        print(json.dumps({"preloaded": "scipy.linalg.cython_blas" in sys.modules,
                          "linalg": "scipy.linalg" in sys.modules,
                          "err": float(np.abs(dot(a, b) - a @ b).max())}))
        """)
    if out.get("skipped"):
        return
    assert out["preloaded"] and not out["linalg"]
    assert out["err"] <= 1e-12  # both BLAS products of the same doubles, 7 terms
