"""One line on stderr when a process compiles a numba kernel (a cache miss).

Kernels are compiled at set-up (:mod:`slitcli.warmup`); one that was not (a new
signature, an edited kernel file, a ``pip install`` without ``slitcli warm-up``) is
compiled on first use, which takes seconds to a minute. The command line installs this
notice first thing, so a user never waits on a silent terminal. Imported at every start
of the command line: it imports nothing beyond the standard library until numba loads.
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
        _install_listener(echo)
        return
    sys.meta_path.insert(0, _AfterNumbaImport(echo))


def announce_in_worker() -> None:
    """In a worker process (``--jobs N``): the notice on stderr, if the process that
    started it asked for notices (:func:`announce_compiles`)."""
    if os.environ.get(_WANTED) and not os.environ.get(_ANNOUNCED):
        announce_compiles(lambda line: print(line, file=sys.stderr, flush=True))


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


class _AfterNumbaImport:
    """A meta-path finder that runs :func:`_install_listener` right after ``numba`` loads."""

    def __init__(self, echo: Callable[[str], None]) -> None:
        self.echo = echo

    def find_spec(self, name: str, path: Any = None, target: Any = None) -> Any:
        if name != "numba":
            return None
        sys.meta_path.remove(self)
        from importlib.util import find_spec

        spec = find_spec(name)
        if spec is None or spec.loader is None:
            return spec
        inner, echo = spec.loader, self.echo

        class _Loader:
            def create_module(self, spec_: Any) -> Any:
                return inner.create_module(spec_)

            def exec_module(self, module: Any) -> None:
                inner.exec_module(module)
                _install_listener(echo)

        spec.loader = _Loader()
        return spec


__all__ = ["announce_compiles", "announce_in_worker"]
