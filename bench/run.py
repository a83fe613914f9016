"""`make bench`: run every bench/bench_*.py module, print a table, write bench/results.json.

Each module defines ``bench(timer) -> list[dict]``. ``timer(fn, runs=21)`` calls ``fn``
``runs`` times (after one warm-up call) and returns a dict with ``median_s``, ``min_s``
and ``runs``; a module returns rows that add a ``name`` and, where it compares things
measured side by side in this same run, a ``ratio`` and a ``note``.
Speed claims are ratios measured in one run, never absolute wall-clock asserts.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import platform
import statistics
import sys
import time
from collections.abc import Callable
from importlib import metadata
from pathlib import Path

HERE = Path(__file__).resolve().parent
PACKAGES = ("numpy", "opencv-python-headless", "Cython", "pandas", "scikit-image", "slitcli")


def timer(fn: Callable[[], object], runs: int = 21, warmup: int = 1) -> dict:
    """Median and minimum wall time of ``fn`` over ``runs`` calls, seconds."""
    for _ in range(warmup):
        fn()
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return {"median_s": statistics.median(times), "min_s": min(times), "runs": runs}


def _versions() -> dict[str, str]:
    out = {}
    for p in PACKAGES:
        try:
            out[p] = metadata.version(p)
        except metadata.PackageNotFoundError:
            out[p] = "not installed"
    return out


def _load(path: Path):
    spec = importlib.util.spec_from_file_location(path.stem, path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-k", default="", help="run only modules whose name contains this")
    ap.add_argument("-o", default=str(HERE / "results.json"), help="JSON output path")
    args = ap.parse_args()
    rows: list[dict] = []
    for path in sorted(HERE.glob("bench_*.py")):
        if args.k and args.k not in path.stem:
            continue
        print(f"# {path.stem} ...", file=sys.stderr, flush=True)
        for row in _load(path).bench(timer):
            row = {"module": path.stem, **row}
            rows.append(row)
    w = max([len(r["name"]) for r in rows] + [4])
    print(f"{'name':<{w}}  {'median_ms':>10}  {'min_ms':>9}  {'runs':>4}  note")
    for r in rows:
        med = f"{1e3 * r['median_s']:10.3f}" if "median_s" in r else f"{'':>10}"
        mn = f"{1e3 * r['min_s']:9.3f}" if "min_s" in r else f"{'':>9}"
        print(f"{r['name']:<{w}}  {med}  {mn}  {r.get('runs', ''):>4}  {r.get('note', '')}")
    result = {
        "machine": {"platform": platform.platform(), "processor": platform.processor(),
                    "cpu_count": os.cpu_count(), "python": platform.python_version()},
        "versions": _versions(),
        "rows": rows,
    }
    out = Path(args.o)
    tmp = out.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(result, indent=2))
    os.replace(tmp, out)
    print(f"wrote {out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
