"""Shared checks of the robustness tests: bad input is exit 2 and one line, quickly."""

from __future__ import annotations

import contextlib
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import yaml
from click.testing import CliRunner, Result

from slitcli.cli import cli
from slitcli.rig import paper_rig

ROOT = Path(__file__).resolve().parent.parent


class Hang(Exception):
    """The command ran past its time limit."""


@contextlib.contextmanager
def time_limit(seconds: int) -> Iterator[None]:
    """Raise :class:`Hang` in the main thread after ``seconds`` (SIGALRM)."""

    def on_alarm(signum, frame):
        raise Hang(f"still running after {seconds} s")

    previous = signal.signal(signal.SIGALRM, on_alarm)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


def invoke(args: list[str], *, seconds: int = 20) -> Result:
    """Run slitcli in-process with a time limit (a hang fails the test, never blocks it)."""
    with time_limit(seconds):
        return CliRunner().invoke(cli, [str(a) for a in args])


def one_error_line(result: Result, *, names: str | None = None) -> str:
    """Assert exit 2, exactly one non-empty stderr line, no traceback, no internal error."""
    assert result.exit_code == 2, (result.exit_code, result.output, result.exception)
    lines = [x for x in result.stderr.splitlines() if x.strip()]
    assert len(lines) == 1, result.stderr
    line = lines[0]
    assert line.startswith("slitcli: error: "), line
    assert "Traceback" not in result.stderr and "internal error" not in result.stderr
    assert len(line) < 600, f"message of {len(line)} characters"
    if names is not None:
        assert names in line, line
    return line


def run_slitcli(args: list[str], *, timeout: float = 60,
                cwd: Path | None = None) -> subprocess.CompletedProcess:
    """slitcli in a child process (for crashes that would take the test process down)."""
    return subprocess.run([sys.executable, "-m", "slitcli", *map(str, args)],
                          capture_output=True, text=True, timeout=timeout, cwd=cwd)


def child_one_error_line(proc: subprocess.CompletedProcess, *, names: str) -> str:
    """:func:`one_error_line` for a child process."""
    assert proc.returncode == 2, (proc.returncode, proc.stderr[-2000:])
    lines = [x for x in proc.stderr.splitlines() if x.strip()]
    assert len(lines) == 1, proc.stderr[-2000:]
    assert lines[0].startswith("slitcli: error: ") and names in lines[0], lines[0]
    return lines[0]


def rig_dict() -> dict:
    """The paper rig as the mapping of a rig file."""
    return paper_rig().to_dict()


def scene_dict() -> dict:
    """A small valid scene: one box ahead, two frames. The tests that use it check
    plumbing (exit status, files, messages), which no draw of its seed changes, so one
    seed suffices."""
    return {"slitcli_scene": 1, "name": "probe", "seed": 3,
            "objects": [{"type": "box", "centre_xy_m": [1.5, 0.0], "size_m": [0.3, 0.4, 0.5]}],
            "robot": {"frames": 2}}


def write_yaml(path: Path, data: object) -> Path:
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path
