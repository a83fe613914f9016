"""Progress on stderr (stdout is for data): a tqdm bar, silent when stderr is not a TTY."""

from __future__ import annotations

import sys

from tqdm import tqdm


def progress_bar(total: int, desc: str, *, unit: str = "frame") -> tqdm:
    """A tqdm bar on stderr; disabled when stderr is not a terminal (logs, CI, pipes)."""
    return tqdm(total=total, desc=desc, unit=unit, file=sys.stderr,
                disable=not sys.stderr.isatty(), leave=False, dynamic_ncols=True)
