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
        # a signal during numba's first compilation is lost in llvmlite's ctypes callback
        # (cli/main.py raises from the handler): wait until a first frame is staged
        deadline = time.monotonic() + 120
        while not list(tmp_path.glob(".slitcli-render-*/left/*.png")) \
                and time.monotonic() < deadline:
            time.sleep(0.05)
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
