"""io/atomic.py: short temporary names, sweeping dead processes' debris, OS errors named."""

from __future__ import annotations

import errno
import os
import subprocess
import sys
from pathlib import Path

import pytest
from robust_helpers import invoke, one_error_line

from slitcli.io import atomic
from slitcli.io.atomic import (
    atomic_directory,
    os_error_message,
    sweep_temp,
    temp_name,
    write_text_atomic,
)


@pytest.mark.parametrize("length", [242, 250, 255])
def test_longest_file_names_can_be_written(tmp_path, length):
    name = "n" * (length - 4) + ".csv"
    write_text_atomic(tmp_path / name, "a\n")
    assert (tmp_path / name).read_text() == "a\n"
    assert os.listdir(tmp_path) == [name]
    assert len(temp_name().encode()) <= 32


def test_longest_folder_name_for_atomic_directory(tmp_path):
    with atomic_directory(tmp_path / ("d" * 255)) as tmp:
        (tmp / "x").write_text("1")
    assert (tmp_path / ("d" * 255) / "x").read_text() == "1"


def _dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test_sweep_removes_only_dead_processes_temp_names(tmp_path):
    dead = _dead_pid()
    stale_file = tmp_path / f".slitcli-{dead}-0123abcd.tmp"
    stale_file.write_text("half")
    stale_dir = tmp_path / f".slitcli-{dead}-89abcdef.tmp"
    (stale_dir / "left").mkdir(parents=True)
    live = tmp_path / f".slitcli-{os.getppid()}-00000000.tmp"  # the parent: alive
    live.write_text("busy")
    own = tmp_path / temp_name()
    own.write_text("mine")
    others = [tmp_path / n for n in (".slitcli-outputs", f".slitcli-{dead}-xyz.tmp",
                                     f"slitcli-{dead}-0123abcd.tmp", ".000043.png.ab12.tmp")]
    for p in others:
        p.write_text("keep")
    removed = sweep_temp(tmp_path)
    assert sorted(removed) == sorted([stale_file, stale_dir])
    assert live.exists() and own.exists() and all(p.exists() for p in others)
    assert sweep_temp(tmp_path / "missing") == []


def test_atomic_directory_sweeps_its_parent(tmp_path):
    debris = tmp_path / f".slitcli-{_dead_pid()}-0badf00d.tmp"
    (debris / "gt").mkdir(parents=True)
    with atomic_directory(tmp_path / "OUT") as tmp:
        (tmp / "a").write_text("1")
    assert sorted(os.listdir(tmp_path)) == ["OUT"]


@pytest.mark.parametrize("code, fix", [(errno.ENOSPC, "free some space"),
                                       (errno.EROFS, "read-only"),
                                       (errno.EACCES, "permissions"),
                                       (errno.EDQUOT, "quota")])
def test_environment_errors_name_the_final_path(tmp_path, monkeypatch, code, fix):
    def failing(self, data):
        raise OSError(code, os.strerror(code), str(self))

    monkeypatch.setattr(Path, "write_bytes", failing)
    target = tmp_path / "rig.yaml"
    line = one_error_line(invoke(["rig", "init", target]), names=f"{target}: ")
    assert fix in line and ".tmp" not in line
    assert os.listdir(tmp_path) == []  # nothing half-written, no temporary left


def test_disk_full_inside_a_rendered_folder_names_the_output_path(tmp_path, monkeypatch):
    from robust_helpers import scene_dict, write_yaml

    calls = {"n": 0}
    real = atomic.write_bytes_atomic

    def full_after_three(path, data):
        calls["n"] += 1
        if calls["n"] > 3:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))
        real(path, data)

    monkeypatch.setattr(atomic, "write_bytes_atomic", full_after_three)
    scene = write_yaml(tmp_path / "s.yaml", {**scene_dict(), "robot": {"frames": 1}})
    line = one_error_line(invoke(["render", scene, tmp_path / "OUT"], seconds=120),
                          names=str(tmp_path / "OUT"))
    assert "No space left" in line and ".slitcli-" not in line
    # no OUT; only the render's resumable staging (issue 26 item 22)
    assert sorted(n for n in os.listdir(tmp_path) if not n.startswith(".slitcli-render-")) \
        == ["s.yaml"]


def test_unknown_os_errors_stay_internal():
    assert os_error_message(OSError(errno.EBADF, "Bad file descriptor")) is None
    msg = os_error_message(OSError(errno.ENOSPC, "No space left on device", "/x/y"))
    assert msg is not None and msg.startswith("/x/y: No space left on device;")


@pytest.mark.parametrize("code", [errno.EROFS, errno.ENOSPC])
def test_creating_the_temporary_is_reported_at_the_final_path(tmp_path, monkeypatch, code):
    def refuse(*args, **kwargs):
        raise OSError(code, os.strerror(code), str(args[0]))

    monkeypatch.setattr(atomic.os, "open", refuse)
    with pytest.raises(OSError) as info:
        write_text_atomic(tmp_path / "a.csv", "x")
    assert info.value.filename == str(tmp_path / "a.csv")
    real_mkdir = Path.mkdir

    def mkdir(self, *args, **kwargs):
        if self.name.startswith(".slitcli-"):
            refuse(str(self))
        real_mkdir(self, *args, **kwargs)

    monkeypatch.setattr(Path, "mkdir", mkdir)
    with pytest.raises(OSError) as info, atomic_directory(tmp_path / "OUT"):
        pass
    assert info.value.filename == str(tmp_path / "OUT")
