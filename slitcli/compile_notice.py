"""What the command line does when numba loads: a notice for compiles, a cheaper BLAS check.

One line on stderr when a process compiles a numba kernel (a cache miss). Kernels are
compiled at set-up (:mod:`slitcli.warmup`); one that was not (a new signature, an
edited kernel file, a ``pip install`` without ``slitcli warm-up``) is compiled on first
use, which takes seconds to a minute. The command line installs this notice first
thing, so a user never waits on a silent terminal.

numba's first kernel call (also a cache load) imports its array-math registry, which
checks for a BLAS by importing ``scipy.linalg.cython_blas``: with SciPy installed (the
dev extras' scikit-image brings it) that imports all of ``scipy.linalg``, about a
fifth of a one-frame ``slitcli detect``, for a check that no slitcli kernel needs.
:func:`_preload_cython_blas` loads that one extension module instead, so numba's check
passes the same way and its ``np.dot`` still calls SciPy's BLAS (docs/notes/startup.md).

Imported at every start of the command line: it imports nothing beyond the standard
library until numba loads.
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable
from typing import Any

_ANNOUNCED = "SLITCLI_COMPILE_ANNOUNCED"
_WANTED = "SLITCLI_COMPILE_NOTICE"


def announce_compiles(echo: Callable[[str], None]) -> None:
    """Call ``echo`` once, with one line, when this process first compiles a kernel.

    A cache hit says nothing: only a real compile (numba's ``numba:compile`` event, which
    fires on a cache miss) does. Installed when numba is first imported, so a command
    that never uses numba does not pay for importing it. Worker processes inherit the
    environment flag and stay quiet once the parent has spoken.
    """
    os.environ[_WANTED] = "1"  # worker processes started by this one announce too
    if "numba" in sys.modules:
        _after_numba(echo)
        return
    sys.meta_path.insert(0, _AfterImport("numba", lambda _numba: _after_numba(echo)))


def announce_in_worker() -> None:
    """In a worker process (``--jobs N``): the notice on stderr, if the process that
    started it asked for notices (:func:`announce_compiles`)."""
    if os.environ.get(_WANTED) and not os.environ.get(_ANNOUNCED):
        announce_compiles(lambda line: print(line, file=sys.stderr, flush=True))


def _after_numba(echo: Callable[[str], None]) -> None:
    _install_listener(echo)
    _preload_cython_blas()


def _preload_cython_blas() -> None:
    """Load ``scipy.linalg.cython_blas`` without running ``scipy/linalg/__init__.py``.

    numba (``numba.np.arraymath``, imported with its registries on the first kernel
    call) sets its BLAS flag by ``import scipy.linalg.cython_blas``; Python would run
    the package's ``__init__``, which imports all of ``scipy.linalg`` (0.2-0.35 s of
    CPU). With the extension module already in ``sys.modules`` numba's import finds it
    there: the same module, the same BLAS functions for numba's ``np.dot``, without the
    rest. When ``scipy.linalg`` is imported later, the module is set as its attribute,
    as a normal import would. Does nothing when SciPy is absent (numba's check then fails
    quickly), when ``scipy.linalg`` or numba's registries are already loaded, or when the
    module cannot be found or loaded (numba then imports it the usual way).
    """
    name = "scipy.linalg.cython_blas"
    scipy = sys.modules.get("scipy")  # numba's import checks SciPy's version when present
    if (scipy is None or "numba.np.arraymath" in sys.modules or "scipy.linalg" in sys.modules
            or name in sys.modules):
        return
    from importlib.machinery import PathFinder
    from importlib.util import module_from_spec

    try:
        spec = PathFinder.find_spec(name, [os.path.join(d, "linalg") for d in scipy.__path__])
        if spec is None or spec.loader is None:
            return
        module = module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    except (ImportError, OSError):
        sys.modules.pop(name, None)
        return
    sys.meta_path.insert(0, _AfterImport("scipy.linalg",
                                         lambda linalg: setattr(linalg, "cython_blas", module)))


def _install_listener(echo: Callable[[str], None]) -> None:
    from numba.core import event

    class _FirstCompile(event.Listener):
        def on_start(self, event_: Any) -> None:
            if os.environ.get(_ANNOUNCED):
                return
            os.environ[_ANNOUNCED] = "1"
            echo("slitcli: compiling numba kernels for this machine (once after install or "
                 "update; up to a minute). `slitcli warm-up` compiles them all ahead.")

        def on_end(self, event_: Any) -> None:
            pass

    event.register("numba:compile", _FirstCompile())


class _AfterImport:
    """A meta-path finder that calls ``then(module)`` right after module ``name`` loads
    (once: it removes itself when ``name`` is first looked up)."""

    def __init__(self, name: str, then: Callable[[Any], None]) -> None:
        self.name = name
        self.then = then

    def find_spec(self, name: str, path: Any = None, target: Any = None) -> Any:
        if name != self.name:
            return None
        sys.meta_path.remove(self)
        from importlib.util import find_spec

        spec = find_spec(name)
        if spec is None or spec.loader is None:
            return spec
        inner, then = spec.loader, self.then

        class _Loader:
            def create_module(self, spec_: Any) -> Any:
                return inner.create_module(spec_)

            def exec_module(self, module: Any) -> None:
                inner.exec_module(module)
                then(module)

        spec.loader = _Loader()
        return spec


__all__ = ["announce_compiles", "announce_in_worker"]
