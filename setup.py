"""Build of slitcli's compiled kernels: every ``slitcli/**/*.pyx`` becomes a C extension.

The project's metadata lives in ``pyproject.toml``; this file only lists the extensions,
which setuptools cannot glob from ``pyproject.toml``. Cython translates each ``.pyx`` (and
inlines the ``cdef inline`` functions of the ``.pxd`` files it cimports) to C; the C
compiler builds it for the processor of the machine that installs slitcli
(``-march=native``; set ``SLITCLI_PORTABLE_BUILD=1`` for a wheel that other x86-64
machines can run). Floating-point contraction (fused multiply-add) stays off, so that a
kernel's arithmetic is the IEEE operations its source spells, in that order. A module
adds flags of its own in a header line, e.g. ``# cflags: -fno-math-errno
-fno-trapping-math`` (flags that change no value but let the compiler vectorise more),
read here and passed after the defaults.
"""

from __future__ import annotations

import os
from pathlib import Path

from Cython.Build import cythonize
from setuptools import Extension, setup

#: Cython settings of every kernel module: no Python semantics that cost a branch per
#: array access (the kernels index within bounds they compute themselves)
DIRECTIVES = {
    "language_level": 3,
    "boundscheck": False,
    "wraparound": False,
    "initializedcheck": False,
    "cdivision": True,
    "embedsignature": True,
}


def _own_flags(source: Path) -> list[str]:
    """The ``# cflags: ...`` header line of a kernel module (its first 20 lines)."""
    with source.open(encoding="utf-8") as text:
        for _, line in zip(range(20), text, strict=False):
            if line.startswith("# cflags:"):
                return line.split(":", 1)[1].split()
    return []


def _extensions() -> list[Extension]:
    flags = ["-O3", "-g0", "-ffp-contract=off", "-Wno-unreachable-code"]
    if not os.environ.get("SLITCLI_PORTABLE_BUILD"):
        flags.append("-march=native")
    sources = sorted(Path("slitcli").rglob("*.pyx"))
    extensions = [Extension(".".join(src.with_suffix("").parts), [str(src)],
                            extra_compile_args=flags + _own_flags(src),
                            define_macros=[("NPY_NO_DEPRECATED_API", "NPY_1_7_API_VERSION")])
                  for src in sources]
    if not extensions:
        return []
    return cythonize(extensions, compiler_directives=DIRECTIVES, nthreads=os.cpu_count() or 1,
                     quiet=True)


setup(ext_modules=_extensions(),
      options={"build_ext": {"parallel": os.cpu_count() or 1}})
