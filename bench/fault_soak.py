"""Fault soak (issue 26): N kill -9 at random moments of each command, then a re-run.

For each of `render`, `laser --overlay`, `stereo`, `detect --save-images` and
`detect --jobs 2` on a small copy of the sample corridor (or a rendered 4-frame scene):
an uninterrupted reference run, then ``--kills`` runs each killed with SIGKILL at a
uniformly random moment (each resuming the previous one), then a final run. Reports per
command how many kills landed mid-run, whether the final outputs equal the reference
byte for byte, temporary debris left, and processes of any run still alive 5 s after
its kill.

    python bench/fault_soak.py --kills 10 --frames 6 --seed 1
"""

from __future__ import annotations

import argparse
import random
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))

from fault_helpers import debris, new_tag, start, tree_bytes, wait_gone
from test_faults import COMMANDS, reference, workspace


def soak(command: str, kills: int, frames: int, seed: int) -> dict:
    args = COMMANDS[command]
    with tempfile.TemporaryDirectory() as tmp:
        root = workspace(Path(tmp), frames)
        t0 = time.monotonic()
        want = reference(root, args)
        # the wall time of a fresh run as a process (start-up included): kill moments are
        # drawn uniformly within it, so most land mid-run even as the resumes get shorter
        scratch = [a if a != "OUT" else "SCRATCH" for a in args]
        t1 = time.monotonic()
        start(scratch, root, new_tag()).communicate(timeout=1200)
        run_s = time.monotonic() - t1
        rng = random.Random(f"{seed} {command}")
        landed, survivors = 0, 0
        for _ in range(kills):
            if command == "render" and (root / "OUT").exists():
                break  # finished before its kill: OUT is final
            tag = new_tag()
            proc = start(args, root, tag)
            try:
                proc.wait(timeout=rng.uniform(0.3, run_s))
            except Exception:
                proc.kill()
                landed += 1
            proc.communicate(timeout=600)
            survivors += len(wait_gone(tag, 5.0))
        tag = new_tag()
        if command == "render" and (root / "OUT").exists():
            # a render that finished before its kill is final (a re-run refuses an existing OUT)
            args = [*args, "--overwrite"]
        proc = start(args, root, tag)
        _, err = proc.communicate(timeout=1200)
        survivors += len(wait_gone(tag, 5.0))
        return {"command": command, "kills": kills, "landed_mid_run": landed,
                "final_exit": proc.returncode, "identical": tree_bytes(root / "OUT") == want,
                "files": len(want), "debris": len(debris(root / "OUT")),
                "survivors": survivors, "run_s": round(run_s, 1),
                "seconds": round(time.monotonic() - t0, 1),
                "stderr": err.strip()[-300:] if proc.returncode else ""}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kills", type=int, default=10)
    ap.add_argument("--frames", type=int, default=6)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--commands", nargs="*", default=list(COMMANDS))
    a = ap.parse_args()
    for c in a.commands:
        r = soak(c, a.kills, a.frames, a.seed)
        print(" ".join(f"{k}={v}" for k, v in r.items()), flush=True)


if __name__ == "__main__":
    main()
