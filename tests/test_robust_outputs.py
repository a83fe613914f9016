"""--overwrite replaces only slitcli's own outputs; an output is never one of the inputs."""

from __future__ import annotations

import pandas as pd
import pytest
from robust_helpers import invoke, one_error_line, scene_dict, write_yaml

from slitcli.io.atomic import OWNED_LIST

SCENE = {**scene_dict(), "robot": {"frames": 1}}


def _render(scene, out, *extra):
    return invoke(["render", scene, out, *extra], seconds=120)


def test_render_overwrite_keeps_unrelated_files_and_refuses_its_input(tmp_path):
    """Plumbing of --overwrite; one seed pair suffices: seed 11 only has to differ
    from the scene's seed 3, so that the replaced image has other bytes (the sensor
    noise of a 1-frame render is drawn from the seed: two seeds giving equal PNGs
    would need every one of the image's pixel noise draws to agree)."""
    out = tmp_path / "OUT"
    scene = write_yaml(tmp_path / "s.yaml", SCENE)
    assert _render(scene, out).exit_code == 0
    first = (out / "left" / "000000.png").read_bytes()
    (out / "notes.txt").write_text("mine")
    mine = write_yaml(out / "my_scene.yaml", {**SCENE, "seed": 11})
    r = _render(mine, out, "--overwrite")
    assert r.exit_code == 0, r.output
    assert (out / "notes.txt").read_text() == "mine" and mine.exists()
    assert (out / "left" / "000000.png").read_bytes() != first  # another seed: replaced
    owned = set((out / OWNED_LIST).read_text().split())
    assert owned == {"gt", "left", "right", "rig.yaml", "scene.yaml", "times.csv"}
    # the scene slitcli wrote into OUT is an output: reading it back and overwriting refuses
    before = (out / "scene.yaml").read_bytes()
    one_error_line(_render(out / "scene.yaml", out, "--overwrite"), names="scene.yaml")
    assert (out / "scene.yaml").read_bytes() == before


def test_render_overwrite_refuses_an_entry_it_did_not_write(tmp_path):
    out = tmp_path / "OUT"
    (out / "left").mkdir(parents=True)
    (out / "left" / "holiday.png").write_bytes(b"x")
    scene = write_yaml(tmp_path / "s.yaml", SCENE)
    one_error_line(_render(scene, out, "--overwrite"), names="was not written by slitcli")
    assert (out / "left" / "holiday.png").read_bytes() == b"x"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["OUT", "s.yaml"]  # no debris


def test_render_into_the_folder_of_its_input_keeps_the_input(tmp_path):
    scene = write_yaml(tmp_path / "s.yaml", SCENE)
    before = scene.read_bytes()
    assert _render(scene, tmp_path, "--overwrite").exit_code == 0
    assert scene.read_bytes() == before and (tmp_path / "left" / "000000.png").exists()


def test_simulate_dwa_overwrite_keeps_unrelated_files_and_its_world(tmp_path):
    out = tmp_path / "OUT"
    args = ["simulate-dwa", "--scenario", "paper", "--sensing-range", "2", "-o", out]
    assert invoke(args, seconds=120).exit_code == 0
    (out / "notes.txt").write_text("mine")
    assert invoke([*args, "--overwrite"], seconds=120).exit_code == 0
    assert (out / "notes.txt").read_text() == "mine"
    world = out / "world.yaml"
    before = world.read_bytes()
    one_error_line(invoke(["simulate-dwa", world, "-o", out, "--overwrite"]), names="world.yaml")
    assert world.read_bytes() == before
    mine = out / "mine.yaml"
    mine.write_bytes(before)
    r = invoke(["simulate-dwa", mine, "-o", out, "--overwrite"], seconds=120)
    assert r.exit_code == 0, r.output
    assert mine.read_bytes() == before and (out / "notes.txt").exists()
    assert not (out / "metrics.csv").read_text().count("range_0.6m")  # old cases removed


def _table(path):
    rows = [(f, 0.2 * f, float(b), 1.5) for f in range(3) for b in (-10, 0, 10)]
    pd.DataFrame(rows, columns=["frame", "time_s", "bearing_deg", "fused_range_m"]).to_csv(
        path, index=False)
    return path


@pytest.mark.parametrize("spelling", ["same", "dot", "link"])
def test_dwa_output_equal_to_input_is_refused(tmp_path, spelling):
    table = _table(tmp_path / "x.csv")
    before = table.read_bytes()
    out = {"same": table, "dot": tmp_path / "." / "sub" / ".." / "x.csv",
           "link": tmp_path / "link.csv"}[spelling]
    if spelling == "link":
        out.symlink_to(table)
    one_error_line(invoke(["dwa", table, "--goal", "3,0", "-o", out, "--overwrite"]),
                   names="is also this command's input")
    assert table.read_bytes() == before


def test_dwa_existing_output_needs_overwrite(tmp_path):
    table = _table(tmp_path / "x.csv")
    out = tmp_path / "cmds.csv"
    out.write_text("precious")
    one_error_line(invoke(["dwa", table, "--goal", "3,0", "-o", out]), names="--overwrite")
    assert out.read_text() == "precious"
    assert invoke(["dwa", table, "--goal", "3,0", "-o", out, "--overwrite"]).exit_code == 0
    assert out.read_text().startswith("frame,")


def test_rig_import_output_equal_to_input_is_refused(tmp_path):
    assert invoke(["rig", "init", tmp_path / "paper.yaml"]).exit_code == 0
    assert invoke(["rig", "export", tmp_path / "paper.yaml", "--format", "kalibr", "-o",
                   tmp_path]).exit_code == 0
    chain = tmp_path / "camchain.yaml"
    before = chain.read_bytes()
    one_error_line(invoke(["rig", "import", chain, "-o", chain]), names="input")
    one_error_line(invoke(["rig", "import", chain, "-o", tmp_path / "paper.yaml"]),
                   names="--overwrite")
    one_error_line(invoke(["rig", "import", chain, "--base", tmp_path / "paper.yaml", "-o",
                           tmp_path / "paper.yaml", "--overwrite"]), names="input")
    assert chain.read_bytes() == before
    assert invoke(["rig", "import", chain, "-o", tmp_path / "paper.yaml",
                   "--overwrite"]).exit_code == 0
