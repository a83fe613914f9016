"""Start-up and module structure: quick --help, no import cycle, no caches keyed by rig."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "slitcli"
HEAVY = ("numba", "pandas", "matplotlib")


def _modules() -> list[str]:
    out = []
    for p in sorted(PACKAGE.rglob("*.py")):
        parts = list(p.relative_to(ROOT).with_suffix("").parts)
        if parts[-1] == "__main__":
            continue
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out.append(".".join(parts))
    return out


def _run(code: str) -> str:
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         cwd=ROOT, timeout=300)
    assert res.returncode == 0, res.stderr[-2000:]
    return res.stdout


def test_every_help_imports_no_heavy_module():
    """`slitcli --help` and every command's --help leave numba, pandas and matplotlib
    unimported."""
    code = f"""
import sys
import click
from click.testing import CliRunner
from slitcli.cli import cli
runner = CliRunner()
seen = 0
def walk(cmd, path):
    global seen
    res = runner.invoke(cli, [*path, "--help"])
    assert res.exit_code == 0 and "Usage:" in res.output, (path, res.output)
    seen += 1
    if isinstance(cmd, click.Group):
        for name, sub in cmd.commands.items():
            walk(sub, [*path, name])
walk(cli, [])
print(seen, [m for m in {HEAVY!r} if m in sys.modules])
"""
    seen, heavy = _run(code).strip().split(" ", 1)
    assert int(seen) >= 12  # the group, its commands and the rig/calibrate subcommands
    assert heavy == "[]"


def test_import_slitcli_is_cheap_and_the_api_resolves():
    out = _run("""
import sys
import slitcli
light = [m for m in ("numpy", "cv2", "numba", "pandas") if m in sys.modules]
names = sorted(n for n in slitcli.__all__ if getattr(slitcli, n) is None)
print(light, names)
""")
    assert out.strip() == "[] []"


def test_every_module_imports_first_in_a_clean_interpreter():
    """Each module imported first (every slitcli module unloaded before): an import
    cycle would leave a partly initialised module and fail here."""
    mods = _modules()
    code = f"""
import sys
import numpy, cv2, pandas, scipy, yaml, click  # third-party stays loaded: speed
bad = []
for name in {mods!r}:
    for m in [m for m in sys.modules if m == "slitcli" or m.startswith("slitcli.")]:
        del sys.modules[m]
    try:
        __import__(name)
    except Exception as e:
        bad.append(f"{{name}}: {{e.__class__.__name__}}: {{e}}")
print("\\n".join(bad) or "ok")
"""
    assert _run(code).strip() == "ok"


def _import_graph() -> dict[str, set[str]]:
    """Every import statement between slitcli modules (function-level imports too,
    TYPE_CHECKING blocks not)."""
    mods = set(_modules())
    graph: dict[str, set[str]] = {}
    for name in mods:
        rel = Path(*name.split("."))
        path = ROOT / (rel / "__init__.py" if (ROOT / rel).is_dir() else rel.with_suffix(".py"))
        tree = ast.parse(path.read_text())
        typing_only = {id(n) for node in ast.walk(tree) if isinstance(node, ast.If)
                       and "TYPE_CHECKING" in ast.unparse(node.test) for n in ast.walk(node)}
        deps: set[str] = set()
        for node in ast.walk(tree):
            if id(node) in typing_only:
                continue
            if isinstance(node, ast.Import):
                deps |= {a.name for a in node.names}
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                deps |= {f"{node.module}.{a.name}" if f"{node.module}.{a.name}" in mods
                         else node.module for a in node.names}
        graph[name] = {d for d in deps if d in mods and d != name}
    return graph


def test_no_import_cycle_even_through_deferred_imports():
    graph = _import_graph()
    state: dict[str, int] = {}

    def visit(m: str, path: list[str]) -> None:
        state[m] = 1
        for d in sorted(graph[m]):
            if state.get(d) == 1:
                pytest.fail("import cycle: " + " -> ".join([*path[path.index(d):], d]))
            if d not in state:
                visit(d, [*path, d])
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m, [m])


@pytest.mark.parametrize("module", ["slitcli/ranges.py", "slitcli/detect.py",
                                    "slitcli/evaluate.py", "slitcli/io/frames.py",
                                    "slitcli/laser/frame.py", "slitcli/laser/geometry.py",
                                    "slitcli/laser/edges.py", "slitcli/laser/bins.py",
                                    "slitcli/laser/batch.py",
                                    "slitcli/sim/truth.py", "slitcli/__init__.py"])
def test_no_module_level_cache(module):
    """No lru_cache / cache decorators in the plumbing: per-rig state lives in objects
    (Detector, BearingBins, LaserGeometry)."""
    tree = ast.parse((ROOT / module).read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            for dec in node.decorator_list:
                target = dec.func if isinstance(dec, ast.Call) else dec
                assert "cache" not in ast.unparse(target).lower(), (module, node.name)
