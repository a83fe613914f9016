"""Progress and run summaries, one convention for every command.

Library runners take ``on_progress(done, total)``: called with ``done == 0`` once the
total is known, then after every frame (finished frames of a resumed run count as done
at once). They return a :class:`RunSummary`. The command line draws a tqdm bar on stderr
(:func:`progress_bar`, silent when stderr is not a terminal) and prints the summary's
one line on stdout.

Interruption (Ctrl-C, SIGTERM) is acted on between frames: the command line installs
:func:`on_signal`, which only records the signal while a progress bar is open (a frame
loop runs); the bar's next update, or its end, raises ``KeyboardInterrupt`` or
:class:`Terminated` there, in plain Python, so the clean-up and the one line on stderr
always happen. Raising from the handler itself could land inside a compiled library's
or a ctypes callback, where the exception is swallowed and the run goes on. Outside a frame
loop the handler raises at once; a second signal ends the process at once.
"""

from __future__ import annotations

import os
import signal
import sys
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any

Progress = Callable[[int, int], None]


@dataclass(frozen=True)
class RunSummary:
    """What a run over frames did.

    Attributes
    ----------
    command : str
        ``laser``, ``stereo``, ``detect``...
    frames : int
        Frames in the input.
    resumed : int
        Frames finished by an earlier run and not computed again.
    seconds : float
        Wall time of this run.
    outputs : tuple of Path
        The tables (and folders) written.
    counts : mapping str -> number
        Command-specific counts (``laser_bins``, ``valid_fraction``...).
    notes : tuple of str
        What the user should know about the input (e.g. bag images left unpaired);
        parameters named in backticks as in :class:`slitcli.errors.SlitcliError`.
    """

    command: str
    frames: int
    resumed: int
    seconds: float
    outputs: tuple[Path, ...]
    counts: Mapping[str, float] = field(default_factory=lambda: MappingProxyType({}))
    notes: tuple[str, ...] = ()

    @property
    def computed(self) -> int:
        """Frames computed in this run."""
        return self.frames - self.resumed

    @property
    def frames_per_s(self) -> float:
        done = self.computed
        return done / self.seconds if self.seconds > 0 and done else float("nan")

    def line(self, details: str = "") -> str:
        """One line for the terminal: frames, what was found, speed, where it went."""
        extra = f", {details}" if details else ""
        # nothing computed (every frame already done): there is no speed to report
        speed = f"{self.frames_per_s:.1f} frames/s" if self.computed else "nothing to compute"
        return (f"{self.command}: {self.frames} frames ({self.resumed} already done){extra}, "
                f"{speed} -> "
                f"{', '.join(str(p) for p in self.outputs)}")


class Terminated(BaseException):
    """SIGTERM arrived: unwinds like Ctrl-C, so temporary outputs are removed."""


@dataclass
class _SignalState:
    """The one process-wide record a signal handler can leave (signals are per process):
    the signal received and not yet acted on, and how many frame loops are open."""

    pending: int | None = None
    frame_loops: int = 0


_SIGNALS = _SignalState()


def reset_signals() -> None:
    """Forget a signal recorded by an earlier command of this process (tests run many)."""
    _SIGNALS.pending = None
    _SIGNALS.frame_loops = 0


def _interrupt_error(signum: int) -> BaseException:
    return Terminated() if signum == signal.SIGTERM else KeyboardInterrupt()


def on_signal(signum: int, frame: object) -> None:
    """SIGINT / SIGTERM handler: record; raise at once only outside a frame loop.

    A second signal while the first is being handled ends the process at once
    (``os._exit``, status 128 + signal): the user insists, and the next run removes
    the temporary files left.
    """
    if _SIGNALS.pending is not None:
        word = "terminated" if signum == signal.SIGTERM else "interrupted"
        os.write(2, f"slitcli: {word} again: stopped at once (the next run removes the "
                    "temporary files)\n".encode())
        os._exit(128 + signum)
    _SIGNALS.pending = signum
    if _SIGNALS.frame_loops == 0:
        raise _interrupt_error(signum)


def check_interrupt() -> None:
    """Raise the recorded signal's error (``KeyboardInterrupt`` or :class:`Terminated`),
    if one arrived; frame loops call this between frames."""
    if _SIGNALS.pending is not None:
        raise _interrupt_error(_SIGNALS.pending)


@contextmanager
def frame_loop() -> Iterator[None]:
    """While open, a signal is only recorded (:func:`on_signal`); it is raised by the
    next :func:`check_interrupt`, or when the loop ends."""
    _SIGNALS.frame_loops += 1
    try:
        yield
    finally:
        _SIGNALS.frame_loops -= 1
    check_interrupt()


def progress_bar(total: int, desc: str, *, unit: str = "frame") -> Any:
    """A tqdm bar on stderr; disabled when stderr is not a terminal (logs, CI, pipes).

    Used as a context manager it is a :func:`frame_loop`: every ``update`` first raises
    a signal that arrived (:func:`check_interrupt`), and so does its end.
    """
    from tqdm import tqdm

    class _FrameBar(tqdm):  # type: ignore[misc]
        def update(self, n: float | None = 1) -> bool | None:
            check_interrupt()
            return super().update(n)

        def __enter__(self) -> _FrameBar:
            _SIGNALS.frame_loops += 1
            return super().__enter__()

        def __exit__(self, *exc: Any) -> None:
            _SIGNALS.frame_loops -= 1
            super().__exit__(*exc)
            if exc[0] is None:
                check_interrupt()

    return _FrameBar(total=total, desc=desc, unit=unit, file=sys.stderr,
                     disable=not sys.stderr.isatty(), leave=False, dynamic_ncols=True)


@contextmanager
def progress(desc: str) -> Iterator[Progress]:
    """A bar on stderr driven by ``on_progress(done, total)`` callbacks."""
    with progress_bar(0, desc) as bar:
        def update(done: int, total: int) -> None:
            check_interrupt()
            if bar.total != total:
                bar.total = total
                bar.refresh()
            bar.update(done - bar.n)

        yield update


__all__ = ["Progress", "RunSummary", "Terminated", "check_interrupt", "frame_loop", "on_signal",
           "progress", "progress_bar", "reset_signals"]
