"""SIGTERM is handled like Ctrl-C: one line, exit 143 (130), no output, no temporary left."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest
from robust_helpers import scene_dict, write_yaml


def _wait_for_temp_folder(proc, folder, seconds: float = 120.0) -> None:
    """Poll until the command has created its temporary output folder (it is then mid-run)."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if any(n.startswith(".slitcli-") for n in os.listdir(folder)):
            return
        if proc.poll() is not None:
            pytest.fail(f"ended before writing: {proc.returncode}")
        time.sleep(0.05)
    proc.kill()
    pytest.fail("no temporary folder appeared")


@pytest.mark.parametrize("sig, code, word", [(signal.SIGTERM, 143, "terminated"),
                                             (signal.SIGINT, 130, "interrupted")])
def test_signal_mid_render_cleans_up(tmp_path, sig, code, word):
    write_yaml(tmp_path / "s.yaml", {**scene_dict(), "robot": {"frames": 500}})
    proc = subprocess.Popen([sys.executable, "-m", "slitcli", "render", "s.yaml", "OUT"],
                            cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        _wait_for_temp_folder(proc, tmp_path)
        # early in the run: the signal may land inside a C call, where an exception
        # raised by the handler would be swallowed (the run went on); it is raised at
        # the next frame boundary (io/progress.on_signal)
        time.sleep(0.5)
        os.kill(proc.pid, sig)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == code, err[-2000:]
    lines = [x for x in err.splitlines() if x.strip()]
    assert len(lines) == 1 and lines[0].startswith("slitcli: ") and word in lines[0], err
    # no temporary and no OUT; only the render's resumable staging (issue 26 item 22)
    assert sorted(n for n in os.listdir(tmp_path) if not n.startswith(".slitcli-render-")) \
        == ["s.yaml"]


def test_debris_of_a_killed_render_is_swept_by_the_next_run(tmp_path):
    write_yaml(tmp_path / "s.yaml", {**scene_dict(), "robot": {"frames": 500}})
    write_yaml(tmp_path / "one.yaml", {**scene_dict(), "robot": {"frames": 1}})
    proc = subprocess.Popen([sys.executable, "-m", "slitcli", "render", "s.yaml", "OUT"],
                            cwd=tmp_path, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        _wait_for_temp_folder(proc, tmp_path)
        time.sleep(0.5)
        proc.kill()  # SIGKILL: no handler runs, the temporary folder stays
        proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert any(n.startswith(".slitcli-") for n in os.listdir(tmp_path))
    done = subprocess.run([sys.executable, "-m", "slitcli", "render", "one.yaml", "OUT"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert sorted(os.listdir(tmp_path)) == ["OUT", "one.yaml", "s.yaml"]


def _signal_inside_a_ctypes_callback(sig: int) -> None:
    """Send ``sig`` to this process from inside a C call's Python callback (libc qsort's
    comparison), where an exception raised by a signal handler is swallowed: what a
    compiled library that calls back into Python does to a Ctrl-C that lands in it."""
    import ctypes

    libc = ctypes.CDLL(None)
    cmp = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.POINTER(ctypes.c_int),
                           ctypes.POINTER(ctypes.c_int))
    sent = []

    def compare(a, b):
        if not sent:
            sent.append(True)
            os.kill(os.getpid(), sig)
        return a[0] - b[0]

    values = (ctypes.c_int * 4)(4, 3, 2, 1)
    libc.qsort(values, 4, ctypes.sizeof(ctypes.c_int), cmp(compare))


@pytest.mark.parametrize("sig, error", [(signal.SIGINT, KeyboardInterrupt),
                                        (signal.SIGTERM, "Terminated")])
def test_signal_in_a_frame_loop_is_raised_at_the_next_frame(sig, error):
    """Inside a frame loop the handler only records the signal, so a signal arriving in
    a section that swallows exceptions (a ctypes callback) is not lost: the next
    frame's progress update raises it, in plain Python."""
    from slitcli.io import progress

    error = progress.Terminated if error == "Terminated" else error
    previous = {s: signal.signal(s, progress.on_signal) for s in (signal.SIGINT,
                                                                  signal.SIGTERM)}
    progress.reset_signals()
    try:
        with pytest.raises(error), progress.progress("test") as on_progress:
            on_progress(0, 3)
            _signal_inside_a_ctypes_callback(sig)  # frame 1: the signal is recorded
            on_progress(1, 3)  # the next frame boundary raises it
            pytest.fail("the frame loop went on after the signal")
    finally:
        progress.reset_signals()
        for s, h in previous.items():
            signal.signal(s, h)


def test_signal_outside_a_frame_loop_is_raised_at_once():
    """Outside a frame loop nothing checks between frames: the handler raises."""
    from slitcli.io import progress

    previous = signal.signal(signal.SIGINT, progress.on_signal)
    progress.reset_signals()
    try:
        with pytest.raises(KeyboardInterrupt):
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(5)
            pytest.fail("not interrupted")
    finally:
        progress.reset_signals()
        signal.signal(signal.SIGINT, previous)
