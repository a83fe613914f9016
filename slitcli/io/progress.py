"""Progress and run summaries, one convention for every command.

Library runners take ``on_progress(done, total)``: called with ``done == 0`` once the
total is known, then after every frame (finished frames of a resumed run count as done
at once). They return a :class:`RunSummary`. The command line draws a tqdm bar on stderr
(:func:`progress_bar`, silent when stderr is not a terminal) and prints the summary's
one line on stdout.
"""

from __future__ import annotations

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


def progress_bar(total: int, desc: str, *, unit: str = "frame") -> Any:
    """A tqdm bar on stderr; disabled when stderr is not a terminal (logs, CI, pipes)."""
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit=unit, file=sys.stderr,
                disable=not sys.stderr.isatty(), leave=False, dynamic_ncols=True)


@contextmanager
def progress(desc: str) -> Iterator[Progress]:
    """A bar on stderr driven by ``on_progress(done, total)`` callbacks."""
    with progress_bar(0, desc) as bar:
        def update(done: int, total: int) -> None:
            if bar.total != total:
                bar.total = total
                bar.refresh()
            bar.update(done - bar.n)

        yield update


__all__ = ["Progress", "RunSummary", "progress", "progress_bar"]
