"""Helpers of the fault tests: small sequences, processes tagged through the environment,
output trees compared byte for byte, temporary debris found."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time
import uuid
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CORRIDOR = ROOT / "sample_data" / "sequences" / "corridor"
TAG = "SLITCLI_FAULT_TAG"


def small_sequence(dst: Path, frames: int) -> Path:
    """The first ``frames`` pairs of the sample corridor (with its rig and times)."""
    for sub in ("left", "right"):
        (dst / sub).mkdir(parents=True)
        for p in sorted((CORRIDOR / sub).glob("*.png"))[:frames]:
            shutil.copyfile(p, dst / sub / p.name)
    shutil.copyfile(CORRIDOR / "rig.yaml", dst / "rig.yaml")
    lines = (CORRIDOR / "times.csv").read_text().splitlines()
    (dst / "times.csv").write_text("\n".join(lines[:frames + 1]) + "\n")
    return dst


def start(args: list[str], cwd: Path, tag: str) -> subprocess.Popen:
    """``python -m slitcli ARGS`` with every descendant carrying ``tag`` in its environment."""
    env = {**os.environ, TAG: tag}
    return subprocess.Popen([sys.executable, "-m", "slitcli", *args], cwd=cwd, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def new_tag() -> str:
    return uuid.uuid4().hex


def tagged_pids(tag: str) -> list[int]:
    """Live processes (not zombies) whose environment holds ``tag`` (read from /proc)."""
    found = []
    needle = f"{TAG}={tag}".encode()
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/environ", "rb") as f:
                env = f.read()
            with open(f"/proc/{entry}/stat", "rb") as f:
                state = f.read().rsplit(b")", 1)[1].split()[0]
        except OSError:
            continue
        if needle in env.split(b"\0") and state != b"Z":
            found.append(int(entry))
    return found


def wait_gone(tag: str, seconds: float) -> list[int]:
    """Poll until no tagged process is left or ``seconds`` pass; what is left."""
    deadline = time.monotonic() + seconds
    while (left := tagged_pids(tag)) and time.monotonic() < deadline:
        time.sleep(0.1)
    return left


def tree_bytes(folder: Path) -> dict[str, bytes]:
    """Every visible output file under ``folder`` (not the ``.slitcli`` resume state)."""
    out = {}
    for p in sorted(folder.rglob("*")):
        rel = p.relative_to(folder)
        if rel.parts[0] == ".slitcli" or not p.is_file():
            continue
        out[str(rel)] = p.read_bytes()
    return out


def debris(*folders: Path) -> list[Path]:
    """slitcli temporary names (``.slitcli-<pid>-<hex>.tmp``, render staging) anywhere
    under or beside the given folders."""
    found = []
    for folder in folders:
        for p in [*folder.rglob(".slitcli-*"), *folder.parent.glob(".slitcli-*")]:
            if p.name != ".slitcli-outputs":
                found.append(p)
    return sorted(set(found))
