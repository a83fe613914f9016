"""Start-up of the command line: `slitcli --help` and a warm one-frame `slitcli detect`.

Measures, after the set-up (the kernels built), each over N runs (default 21):

- wall and CPU time (user + sys of the child process) of `python -c pass` (the
  interpreter alone), `slitcli --help` and a warm `slitcli detect` of a one-frame
  sequence (the first frame of SEQ);
- the CPU breakdown of that detect measured inside the process: numpy, OpenCV, loading
  the compiled (Cython) kernel modules, importing slitcli's command-line and detect
  modules, and the command itself (reading, the frame's work, writing); which heavy
  modules it imported;
- `python -X importtime -c "import slitcli.detect"`: cumulative import time of the
  largest packages.

Medians over the runs. Wall times follow the machine's load (docs/notes/startup.md: the
project's machine is shared); CPU times much less. Run directly for a table and JSON:

    .venv/bin/python bench/bench_startup.py [SEQ] [--runs 21] [--json out.json]

`make bench` calls :func:`bench` (rows for bench/results.json).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SLITCLI = Path(sys.executable).parent / "slitcli"
CORRIDOR = ROOT / "sample_data" / "sequences" / "corridor"
HEAVY = ("pandas", "scipy.linalg", "matplotlib", "skimage")

# One warm detect, timed from inside: the parts of its CPU time (process_time).
_BREAKDOWN = r'''
import importlib, json, pathlib, sys, time
T = time.process_time
t_start = T()
t0 = T(); import numpy; t_numpy = T() - t0
t0 = T(); import cv2; t_cv2 = T() - t0
import slitcli
root = pathlib.Path(slitcli.__file__).parent
compiled = sorted("slitcli." + ".".join(p.relative_to(root).parts[:-1] + (p.name.split(".")[0],))
                  for p in root.rglob("*.so"))
t0 = T()
for name in compiled:
    importlib.import_module(name)
t_compiled = T() - t0
t0 = T(); from slitcli.cli import main; import slitcli.detect; t_modules = T() - t0
sys.argv = ["slitcli", "detect", sys.argv[1], "-o", sys.argv[2]]
t0 = T()
try:
    main()
except SystemExit:
    pass
t_cmd = T() - t0
print(json.dumps({
    "numpy": t_numpy, "cv2": t_cv2, "compiled": t_compiled, "n_compiled": len(compiled),
    "modules": t_modules, "command": t_cmd, "total": T() - t_start,
    "heavy": [m for m in HEAVY if m in sys.modules]}))
'''.replace("HEAVY", repr(HEAVY))

PARTS = ("numpy", "cv2", "compiled", "modules", "command", "total")
IMPORTS = ("numpy", "scipy", "cv2", "yaml", "click", "pandas", "matplotlib")


def one_frame(seq: Path, where: Path) -> Path:
    """A copy of the first frame of ``seq`` as a one-frame sequence folder."""
    one = where / "one"
    for side in ("left", "right"):
        first = sorted((seq / side).iterdir())[0]
        (one / side).mkdir(parents=True)
        shutil.copy(first, one / side / first.name)
    if (seq / "rig.yaml").exists():
        shutil.copy(seq / "rig.yaml", one / "rig.yaml")
    (one / "times.csv").write_text("frame,time_s\n0,0\n")
    return one


def _timed(cmd: list[str]) -> tuple[float, float]:
    """Wall and CPU (user + sys) seconds of one child process."""
    before = os.times()
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    after = os.times()
    return wall, (after.children_user - before.children_user
                  + after.children_system - before.children_system)


def _importtime() -> dict[str, float]:
    """Cumulative import time (s) of :data:`IMPORTS` and all of slitcli.detect, one run."""
    res = subprocess.run([sys.executable, "-X", "importtime", "-c", "import slitcli.detect"],
                         check=True, capture_output=True, text=True)
    out = dict.fromkeys((*IMPORTS, "slitcli.detect"), 0.0)  # 0: not imported
    for line in res.stderr.splitlines():  # each module is listed once, when first imported
        m = re.match(r"import time:\s+\d+ \|\s+(\d+) \| *(\S+)$", line)
        if m and m.group(2) in out:
            out[m.group(2)] = int(m.group(1)) * 1e-6
    return out


def measure(seq: Path = CORRIDOR, runs: int = 21,
            say: Callable[[str], None] = lambda _line: None) -> dict:
    """Every start-up measurement, medians over ``runs`` (see the module docstring)."""
    result: dict = {"runs": runs, "load_before": os.getloadavg()[0], "cases": {}}
    with tempfile.TemporaryDirectory() as tmp:
        one = one_frame(seq, Path(tmp))
        cases = {"python -c pass": lambda i: [sys.executable, "-c", "pass"],
                 "slitcli --help": lambda i: [str(SLITCLI), "--help"],
                 "slitcli detect (1 frame, warm)":
                     lambda i: [str(SLITCLI), "detect", str(one), "-o", f"{tmp}/out{i}"]}
        for name, make in cases.items():
            say(f"{name} x {runs}")
            _timed(make(-1))  # fills the OS's file cache
            walls, cpus = zip(*(_timed(make(i)) for i in range(runs)), strict=True)
            result["cases"][name] = {
                "wall_median_s": statistics.median(walls), "wall_min_s": min(walls),
                "cpu_median_s": statistics.median(cpus), "cpu_min_s": min(cpus)}
        say(f"breakdown x {runs}")
        rows = [json.loads(subprocess.run(
            [sys.executable, "-c", _BREAKDOWN, str(one), f"{tmp}/bd{i}"], check=True,
            capture_output=True, text=True).stdout.splitlines()[-1]) for i in range(runs)]
    result["breakdown_cpu_s"] = {k: statistics.median(r[k] for r in rows) for k in PARTS}
    result["compiled_modules"] = rows[0]["n_compiled"]
    result["heavy_modules_imported"] = rows[0]["heavy"]
    say(f"importtime x {runs}")
    imports = [_importtime() for _ in range(runs)]
    result["importtime_s"] = {k: statistics.median(r[k] for r in imports)
                              for k in (*IMPORTS, "slitcli.detect")}
    result["load_after"] = os.getloadavg()[0]
    return result


def table(result: dict) -> str:
    """The measurements as Markdown tables."""
    lines = [f"runs: {result['runs']} (medians); load average {result['load_before']:.1f} "
             f"before, {result['load_after']:.1f} after", "",
             "| what | wall median | wall min | CPU median | CPU min |", "|---|---|---|---|---|"]
    for name, c in result["cases"].items():
        lines.append(f"| `{name}` | {c['wall_median_s']:.3f} s | {c['wall_min_s']:.3f} s | "
                     f"{c['cpu_median_s']:.3f} s | {c['cpu_min_s']:.3f} s |")
    b = result["breakdown_cpu_s"]
    lines += ["", "| warm detect, CPU inside the process | s |", "|---|---|"]
    labels = {"numpy": "numpy import", "cv2": "OpenCV import",
              "compiled": f"the {result['compiled_modules']} compiled kernel modules "
                          "(with the packages that hold them)",
              "modules": "slitcli's command line and detect modules (import)",
              "command": "the command: reading, the frame's work, writing",
              "total": "total"}
    lines += [f"| {labels[k]} | {b[k]:.3f} |" for k in PARTS]
    lines += ["", "heavy modules imported: " + (", ".join(result["heavy_modules_imported"])
                                                or "none of " + ", ".join(HEAVY)), "",
              "| `import slitcli.detect`: cumulative import time | s |", "|---|---|"]
    lines += [f"| {k} | {v:.3f} |" for k, v in result["importtime_s"].items()]
    return "\n".join(lines)


def bench(timer: object) -> list[dict]:
    """Rows for `make bench` (bench/run.py): wall medians, with the CPU medians in the note."""
    result = measure(runs=21, say=lambda line: print(f"  {line}", file=sys.stderr, flush=True))
    rows = [{"name": f"startup: {name}", "median_s": c["wall_median_s"],
             "min_s": c["wall_min_s"], "runs": result["runs"], "cpu_median_s": c["cpu_median_s"],
             "note": f"CPU median {c['cpu_median_s']:.3f} s"}
            for name, c in result["cases"].items()]
    b = result["breakdown_cpu_s"]
    rows.append({"name": "startup: warm detect CPU breakdown", "runs": result["runs"],
                 "breakdown_cpu_s": b, "compiled_modules": result["compiled_modules"],
                 "heavy_modules_imported": result["heavy_modules_imported"],
                 "note": ", ".join(f"{k} {v:.3f} s" for k, v in b.items())})
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("seq", nargs="?", type=Path, default=CORRIDOR)
    ap.add_argument("--runs", type=int, default=21)
    ap.add_argument("--json", type=Path, default=None, help="also write the numbers here")
    args = ap.parse_args()
    result = measure(args.seq, args.runs, say=lambda line: print(line, file=sys.stderr,
                                                                     flush=True))
    print(table(result))
    if args.json is not None:
        args.json.write_text(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
