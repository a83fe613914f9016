"""`slitcli detect` over many inputs and chunks (slitcli.multi), serially in this process."""

from __future__ import annotations

import random
from pathlib import Path

import pandas as pd
import pytest
from bagwriter import write_bag
from click.testing import CliRunner

from slitcli.cli import cli
from slitcli.detect import run_detect
from slitcli.errors import SlitcliError
from slitcli.io.sequence import read_image
from slitcli.multi import (
    INDEX_COLUMNS,
    output_names,
    plan_chunks,
    read_inputs_file,
    run_detect_many,
)
from slitcli.rig import paper_rig
from slitcli.sim.scene import load_scene
from slitcli.sim.sequence import render_sequence

ROOT = Path(__file__).resolve().parent.parent
SCENES = {"corridor": 3, "distractors": 2, "overhang": 3}


@pytest.fixture(scope="module")
def seqs(tmp_path_factory):
    """Three tiny rendered sequences, a bag of the first, and their serial tables."""
    base = tmp_path_factory.mktemp("many")
    rig = paper_rig()
    out = {}
    for name, n in SCENES.items():
        out[name] = base / "in" / name
        render_sequence(load_scene(ROOT / "sample_data" / f"{name}.yaml"), rig, out[name],
                        frames=n)
    seq = out["corridor"]
    left = sorted((seq / "left").iterdir())
    pairs = [(read_image(p), read_image(seq / "right" / p.name)) for p in left]
    out["bag"] = write_bag(base / "in" / "corridor.bag", pairs, ros=1,
                           t0_ns=1_700_000_000_000_000_000, dt_ns=100_000_000)
    ref = {}
    for name, src in out.items():
        ref[name] = base / "ref" / name
        run_detect(src, ref[name], rig_path=seq / "rig.yaml" if name == "bag" else None)
    return out, ref


def test_output_names_are_unique_and_first_come_first_named():
    names = output_names(["a/run", "b/run.bag", "c/run", "d/other", "e/run-2"])
    # the third 'run' takes -3 because -2 is taken; the input really named run-2 comes later
    # and then finds its own name taken
    assert names == ["run", "run-2", "run-3", "other", "run-2-2"]
    assert len(set(names)) == len(names)


@pytest.mark.parametrize("seed", range(6))
def test_chunks_cover_every_frame_once_in_order(seed):
    rng = random.Random(seed)
    n = [rng.randrange(0, 40) for _ in range(rng.randrange(1, 6))]
    k = rng.randrange(1, 12)
    chunks = plan_chunks(n, k)
    for i, m in enumerate(n):
        mine = [c.frames for c in chunks if c.input == i]
        assert [f for r in mine for f in r] == list(range(m))
        assert all(0 < len(r) <= k for r in mine) or m == 0
        assert len(mine) == max(1, -(-m // k))
    whole = plan_chunks(n, None)
    assert [len(c.frames) for c in whole] == n


def test_many_inputs_give_each_serial_table_and_an_index(seqs, tmp_path):
    src, ref = seqs
    names = ["corridor", "distractors", "overhang"]
    out = tmp_path / "out"
    s = run_detect_many([src[n] for n in names], out)
    for n in names:
        assert (out / n / "ranges.csv").read_bytes() == (ref[n] / "ranges.csv").read_bytes()
    index = pd.read_csv(out / "index.csv", keep_default_na=False)
    assert tuple(index.columns) == INDEX_COLUMNS
    assert list(index["output"]) == names and list(index["frames"]) == [3, 2, 3]
    assert set(index["status"]) == {"done"} and s.computed == 8 and s.chunks_resumed == 0


@pytest.mark.parametrize("chunk", [1, 2, 5])
def test_chunks_give_the_serial_table_and_resume(seqs, tmp_path, chunk):
    src, ref = seqs
    out = tmp_path / "out"
    rig = src["corridor"] / "rig.yaml"
    s = run_detect_many([src["bag"], src["overhang"]], out, chunk_frames=chunk, rig_path=rig)
    assert (out / "corridor" / "ranges.csv").read_bytes() == \
        (ref["bag"] / "ranges.csv").read_bytes()
    # one chunk's frames lost: only those are computed again, the others are kept
    parts = out / "overhang" / ".slitcli" / "detect" / "parts"
    lost = [f for f in range(3) if f // chunk == 0]
    for f in lost:
        (parts / f"{f:06d}.rows.csv").unlink()
    (out / "overhang" / "ranges.csv").unlink()
    again = run_detect_many([src["bag"], src["overhang"]], out, chunk_frames=chunk,
                            rig_path=rig)
    assert again.computed == len(lost)
    assert again.chunks_resumed == s.chunks - 1
    assert (out / "overhang" / "ranges.csv").read_bytes() == \
        (ref["overhang"] / "ranges.csv").read_bytes()


def test_one_input_keeps_the_single_layout(seqs, tmp_path):
    src, ref = seqs
    out = tmp_path / "one"
    res = CliRunner().invoke(cli, ["detect", str(src["overhang"]), "-o", str(out)])
    assert res.exit_code == 0, res.output
    assert (out / "ranges.csv").read_bytes() == (ref["overhang"] / "ranges.csv").read_bytes()
    assert not (out / "index.csv").exists()
    # chunked, still one input: the same layout and bytes
    out2 = tmp_path / "one_chunked"
    res = CliRunner().invoke(cli, ["detect", str(src["overhang"]), "-o", str(out2),
                                   "--chunk-frames", "2"])
    assert res.exit_code == 0, res.output
    assert sorted(p.name for p in out2.iterdir()) == sorted(p.name for p in out.iterdir())
    assert (out2 / "ranges.csv").read_bytes() == (ref["overhang"] / "ranges.csv").read_bytes()


def test_inputs_file_and_a_failing_input(seqs, tmp_path):
    src, ref = seqs
    lst = tmp_path / "runs.txt"
    broken = tmp_path / "broken"
    broken.mkdir()
    lst.write_text(f"# two runs\n{src['distractors']}\n\n{broken}  # empty folder\n")
    assert read_inputs_file(lst) == [src["distractors"], broken]
    out = tmp_path / "out"
    res = CliRunner().invoke(cli, ["detect", "--inputs", str(lst), "-o", str(out)])
    assert res.exit_code == 2
    assert "broken" in res.stderr and "Traceback" not in res.stderr
    assert "2/2 inputs" in res.stderr
    assert (out / "distractors" / "ranges.csv").read_bytes() == \
        (ref["distractors"] / "ranges.csv").read_bytes()
    index = pd.read_csv(out / "index.csv", keep_default_na=False)
    assert list(index["status"]) == ["done", "failed"] and index["message"][1] != ""


def test_bad_many_inputs_are_refused(seqs, tmp_path):
    src, _ = seqs
    with pytest.raises(SlitcliError, match="given twice"):
        run_detect_many([src["overhang"], src["overhang"]], tmp_path / "o")
    busy = tmp_path / "busy"
    busy.mkdir()
    (busy / "notes.txt").write_text("mine")
    with pytest.raises(SlitcliError, match="not empty"):
        run_detect_many([src["overhang"], src["distractors"]], busy)
    with pytest.raises(SlitcliError, match="chunk_frames"):
        run_detect_many([src["overhang"]], tmp_path / "o2", chunk_frames=0)
    with pytest.raises(SlitcliError, match="sub-range"):
        run_detect(src["overhang"], tmp_path / "o3", frames=range(2, 9))
    empty = tmp_path / "list.txt"
    empty.write_text("# nothing\n")
    res = CliRunner().invoke(cli, ["detect", "--inputs", str(empty), "-o", str(tmp_path / "x")])
    assert res.exit_code == 2 and "--inputs" in res.stderr
