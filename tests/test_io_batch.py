"""Resumable batches (slitcli.io.batch): what a re-run reuses and what it refuses."""

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import cv2
import pytest
from fault_helpers import small_sequence

from slitcli import __version__
from slitcli.detect import run_detect
from slitcli.errors import SlitcliError
from slitcli.io.batch import FrameBatch, check_jobs, max_jobs
from slitcli.io.progress import RunSummary
from slitcli.laser.batch import run_laser
from slitcli.stereo.run import run_stereo


def test_same_manifest_resumes_and_keeps_finished_parts(tmp_path):
    b = FrameBatch(tmp_path, "detect", {"fusion": "paper"})
    b.part_path(0).write_text("0,1\n")
    again = FrameBatch(tmp_path, "detect", {"fusion": "paper"})
    assert again.is_done(0) and not again.is_done(1)


def test_other_settings_are_refused_unless_overwrite(tmp_path):
    FrameBatch(tmp_path, "detect", {"fusion": "paper"}).part_path(0).write_text("0,1\n")
    with pytest.raises(SlitcliError, match=r"changed: fusion.*pass `overwrite`"):
        FrameBatch(tmp_path, "detect", {"fusion": "conservative"})
    b = FrameBatch(tmp_path, "detect", {"fusion": "conservative"}, overwrite=True)
    assert not b.is_done(0)


def test_results_of_another_slitcli_version_are_not_reused(tmp_path):
    b = FrameBatch(tmp_path, "detect", {"fusion": "paper"})
    b.part_path(0).write_text("0,1\n")
    path = tmp_path / ".slitcli" / "detect" / "manifest.json"
    m = json.loads(path.read_text())
    assert m["slitcli_version"] == __version__
    path.write_text(json.dumps({**m, "slitcli_version": "0.0.1"}))
    with pytest.raises(SlitcliError, match="changed: slitcli_version"):
        FrameBatch(tmp_path, "detect", {"fusion": "paper"})
    assert not FrameBatch(tmp_path, "detect", {"fusion": "paper"}, overwrite=True).is_done(0)


# ---------------------------------------------------------------- run lock (issue 26 item 2)
@pytest.mark.parametrize("left", ["lock", "working folder", "parts and a temporary"])
def test_a_run_killed_before_its_manifest_is_resumed_not_refused(tmp_path, left):
    """kill -9 between taking the folder's lock and writing the manifest leaves
    ``.slitcli`` with the lock and the command's working folder but no settings: no
    results, so a re-run starts there (a foreign folder or another command's is still
    refused)."""
    out = tmp_path / "out"
    work = out / ".slitcli" / "detect"
    (out / ".slitcli").mkdir(parents=True)
    (out / ".slitcli" / "lock").write_text("999999\n")
    if left != "lock":
        (work / "parts").mkdir(parents=True)
    if left == "parts and a temporary":
        (work / "parts" / "000000.rows.csv").write_text("stale\n")
        (work / ".manifest.json.tmp-999999").write_text("{")
    b = FrameBatch(out, "detect", {"fusion": "paper"})
    assert not b.is_done(0) and (work / "manifest.json").exists()
    b.close()
    # the same leftovers are not this command's: refused
    other = tmp_path / "other"
    shutil.copytree(out, other)
    (other / ".slitcli" / "detect" / "manifest.json").unlink()
    with pytest.raises(SlitcliError, match="was not written by slitcli stereo"):
        FrameBatch(other, "stereo", {"matcher": "nssd"})


def test_the_lock_is_reentrant_within_a_process_and_released_on_close(tmp_path):
    a = FrameBatch(tmp_path, "detect", {"fusion": "paper"})
    b = FrameBatch(tmp_path, "detect", {"fusion": "paper"})  # same process: allowed
    assert (tmp_path / ".slitcli" / "lock").read_text() == str(os.getpid())
    b.close()
    a.close()


def test_another_process_holding_out_is_named(tmp_path):
    holder = subprocess.Popen(
        [sys.executable, "-c", "import sys, time; from slitcli.io.lock import lock_output; "
         f"held = lock_output({str(tmp_path)!r}); print('held', flush=True); time.sleep(60)"],
        stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        with pytest.raises(SlitcliError, match=rf"in use by slitcli pid {holder.pid}; wait"):
            FrameBatch(tmp_path, "detect", {"fusion": "paper"})
    finally:
        holder.kill()
        holder.wait()
    # the kernel dropped the dead holder's lock; its pid is still in the file
    FrameBatch(tmp_path, "detect", {"fusion": "paper"}).close()


# ---------------------------------------------------------------- jobs (item 24)
def test_jobs_are_bounded_by_the_cpus():
    check_jobs(1)
    check_jobs(max_jobs())
    assert max_jobs() == 2 * (os.cpu_count() or 1)
    for bad in (0, max_jobs() + 1, 10**9):
        with pytest.raises(SlitcliError, match=rf"`jobs` {bad} is out of range; give 1 to "):
            check_jobs(bad)


def test_no_nan_speed_when_every_frame_was_done():
    line = RunSummary("detect", 4, 4, 0.01, (Path("o/ranges.csv"),)).line()
    assert "nan" not in line and "nothing to compute" in line
    assert "2.0 frames/s" in RunSummary("detect", 4, 0, 2.0, ()).line()


# ---------------------------------------------------------------- stale temporaries (19)
def test_stale_temporaries_of_dead_processes_are_swept_and_nothing_else(tmp_path):
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True).stdout.strip()
    stale = [tmp_path / f".slitcli-{dead}-0123abcd.tmp",
             tmp_path / "disparity" / f".slitcli-{dead}-89abcdef.tmp",
             tmp_path / ".slitcli" / "stereo" / "parts" / f".slitcli-{dead}-00000000.tmp"]
    kept = [tmp_path / "notes.txt", tmp_path / "disparity" / ".slitcli-x.tmp",
            tmp_path / f".slitcli-{os.getpid()}-0123abcd.tmp"]
    for p in stale + kept:
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text("x")
    (tmp_path / ".slitcli" / "stereo" / "manifest.json").write_text("{}")
    FrameBatch(tmp_path, "stereo", {"a": 1}, overwrite=True, subfolders=("disparity",))
    assert not any(p.exists() for p in stale)
    assert all(p.exists() for p in kept)


# ---------------------------------------------------------------- per-frame identity (3, 21)
def _copy(src: Path, dst: Path) -> Path:
    shutil.copytree(src, dst)
    return dst


def _run(command: str, seq: Path, out: Path):
    if command == "detect":
        s = run_detect(seq, out)
        return s, (out / "ranges.csv").read_bytes()
    if command == "stereo":
        s = run_stereo(seq, out)
        return s, (out / "stereo_ranges.csv").read_bytes()
    s = run_laser(seq, out)
    return s, (out / "laser.csv").read_bytes()


@pytest.mark.parametrize("command", ["detect", "stereo", "laser"])
def test_changed_frames_are_recomputed_and_the_others_kept(tmp_path, command):
    """Swapping two frames, editing times.csv and replacing one image recompute exactly
    the frames concerned; the table then equals a fresh run on the edited input."""
    seq = small_sequence(tmp_path / "seq", 3)
    out = tmp_path / "out"
    assert _run(command, seq, out)[0].resumed == 0
    left, right = seq / "left", seq / "right"
    for side in (left, right):  # swap frames 0 and 1
        a, b = (side / "000000.png").read_bytes(), (side / "000001.png").read_bytes()
        (side / "000000.png").write_bytes(b)
        (side / "000001.png").write_bytes(a)
    assert _run(command, seq, out)[0].resumed == 1
    (seq / "times.csv").write_text("frame,time_s\n0,0\n1,0.2\n2,7.25\n")
    assert _run(command, seq, out)[0].resumed == 2  # the time is part of every identity
    for side in (left, right):  # replace frame 0's images
        (side / "000000.png").write_bytes((side / "000002.png").read_bytes())
    summary, table = _run(command, seq, out)
    assert summary.resumed == 2
    fresh = _run(command, _copy(seq, tmp_path / "seq2"), tmp_path / "fresh")[1]
    assert table == fresh
    assert _run(command, seq, out)[0].resumed == 3


def test_two_images_of_one_frame_are_refused_naming_both(tmp_path):
    seq = small_sequence(tmp_path / "seq", 2)
    img = cv2.imread(str(seq / "left" / "000001.png"))
    cv2.imwrite(str(seq / "left" / "000001.jpg"), img)
    with pytest.raises(SlitcliError, match=r"000001\.jpg.*000001\.png|000001\.png.*000001\.jpg"):
        run_detect(seq, tmp_path / "out")
    assert not (tmp_path / "out").exists()
