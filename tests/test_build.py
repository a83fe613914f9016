"""The compiled kernels (setup.py): every Cython module of the package is built, loads as
an extension, and is not older than its sources (a stale build would run old code)."""

from __future__ import annotations

import importlib
import re
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "slitcli"
SOURCES = sorted(PACKAGE.rglob("*.pyx"))


def _module(pyx: Path) -> str:
    return ".".join(pyx.relative_to(PACKAGE.parent).with_suffix("").parts)


def _cimported(source: Path) -> list[Path]:
    """The package's .pxd files a .pyx/.pxd cimports, directly or through another."""
    seen: list[Path] = []
    todo = [source]
    while todo:
        text = todo.pop().read_text(encoding="utf-8")
        for name in re.findall(r"^\s*from\s+(slitcli(?:\.\w+)+)\s+cimport", text, re.M):
            pxd = PACKAGE.parent.joinpath(*name.split(".")).with_suffix(".pxd")
            if pxd.exists() and pxd not in seen:
                seen.append(pxd)
                todo.append(pxd)
    return seen


def test_there_are_compiled_kernels():
    assert len(SOURCES) >= 10


@pytest.mark.parametrize("pyx", SOURCES, ids=_module)
def test_each_cython_module_is_built_and_current(pyx):
    module = importlib.import_module(_module(pyx))
    built = Path(module.__file__)
    assert built.suffix in (".so", ".pyd"), f"{module.__name__} loads from {built}"
    newest = max(p.stat().st_mtime for p in [pyx, *_cimported(pyx)])
    assert built.stat().st_mtime >= newest, (
        f"{built.name} is older than its sources: run `make venv` to rebuild")
