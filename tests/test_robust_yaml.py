"""Rig and scene files that try to hurt: exit 2, one short line naming file and key, fast."""

from __future__ import annotations

import pytest
from robust_helpers import invoke, one_error_line, rig_dict, scene_dict, write_yaml

from slitcli.errors import SlitcliError
from slitcli.io.yamlfile import MAX_DEPTH, brief, finite_float, load_yaml_text

# A "billion laughs": 683 bytes that expand to 10^9 strings if aliases are followed.
LAUGHS = "a: &a [" + ", ".join(['"lol"'] * 9) + "]\n" + "".join(
    f"{chr(98 + i)}: &{chr(98 + i)} [{', '.join(['*' + chr(97 + i)] * 9)}]\n" for i in range(8))


def test_alias_bomb_is_refused_at_once(tmp_path):
    path = tmp_path / "rig.yaml"
    path.write_text("slitcli_rig: 1\n" + LAUGHS)
    # invoke() fails the test if the command is still running after 20 s (a hang guard)
    line = one_error_line(invoke(["rig", "show", path]), names=str(path))
    assert "alias" in line and len(path.read_bytes()) < 1000


@pytest.mark.parametrize("depth", [MAX_DEPTH + 1, 1000, 200_000])
def test_deep_nesting_is_refused_not_a_recursion_error(tmp_path, depth):
    path = tmp_path / "scene.yaml"
    path.write_text("slitcli_scene: 1\nobjects: " + "[" * depth + "]" * depth + "\n")
    line = one_error_line(invoke(["render", path, tmp_path / "out"]), names=str(path))
    assert "nests deeper" in line and not (tmp_path / "out").exists()


def test_nesting_within_the_bound_is_read():
    text = "a: " + "[" * (MAX_DEPTH - 1) + "1" + "]" * (MAX_DEPTH - 1)
    value = load_yaml_text(text, "t")["a"]
    for _ in range(MAX_DEPTH - 2):
        value = value[0]
    assert value == [1]


@pytest.mark.parametrize("text, needle", [
    ("a: 1\na: 2\n", "repeats the key 'a' at line 2"),
    ("a: {b: 1, b: 2}\n", "repeats the key 'b'"),
    ("a: &x 1\nb: *x\n", "alias"),
    ("a: [1,\n", "not valid YAML"),
])
def test_loader_refusals_name_the_line(text, needle):
    with pytest.raises(SlitcliError, match=needle):
        load_yaml_text(text, "f.yaml")


def test_brief_bounds_every_echo():
    assert brief(10**5000).startswith("<integer of about 5001 digits")
    assert len(brief("x" * 10**6)) <= 60
    assert brief(list(range(10**4))) == "<list of 10000 items>"
    assert finite_float(10**400) is None and finite_float(True) is None
    assert finite_float(float("nan")) is None and finite_float(3) == 3.0


def _raw(**change) -> dict:
    """The raw block of the paper rig as an ideal pair, with ``change`` applied."""
    from slitcli.calibrate.rectify import ideal_raw, rig_with_raw
    from slitcli.rig import paper_rig

    raw = rig_with_raw(ideal_raw(paper_rig())).to_dict()["raw"]
    raw.update(change)
    return raw


def _rig_case(tmp_path, change):
    d = rig_dict()
    change(d)
    return write_yaml(tmp_path / "rig.yaml", d)


RIG_CASES = [
    ("huge int", lambda d: d["left"].update(fx_px=10**400), "left.fx_px"),
    ("huge int in raw", lambda d: d.update(raw=_raw(image_size_px=[10**30, 240])),
     "raw.image_size_px"),
    ("long distortion", lambda d: d.update(raw=_raw(D1=[0.0] * 1000)), "raw.D1"),
    ("huge int matrix", lambda d: d.update(raw=_raw(T=[10**400, 0, 0])), "raw.T"),
    ("true as version", lambda d: d.update(slitcli_rig=True), "slitcli_rig"),
    ("sheet below floor", lambda d: d["laser"].update(offset_m=0.9), "laser.offset_m"),
    ("absurd size", lambda d: d.update(image_size_px=[10**9, 10**9]), "image_size_px"),
    ("absurd area", lambda d: d.update(image_size_px=[16000, 16000]), "image_size_px"),
    ("absurd focal", lambda d: d["left"].update(fx_px=1e300), "left.fx_px"),
    ("huge name", lambda d: d.update(name="n" * 10**5), "'name'"),
    ("nan", lambda d: d.update(baseline_m=float("nan")), "baseline_m"),
    ("huge list echoed", lambda d: d.update(image_size_px=list(range(3000))), "image_size_px"),
]


@pytest.mark.parametrize("change, key", [c[1:] for c in RIG_CASES], ids=[c[0] for c in RIG_CASES])
def test_bad_rig_values_name_the_key(tmp_path, change, key):
    path = _rig_case(tmp_path, change)
    one_error_line(invoke(["rig", "show", path]), names=key)


def test_rig_file_that_is_a_folder_or_too_big(tmp_path):
    (tmp_path / "dir.yaml").mkdir()
    one_error_line(invoke(["rig", "show", tmp_path / "dir.yaml"]), names="dir.yaml")
    (tmp_path / "dir.yaml").rmdir()
    (tmp_path / "dir.yaml").symlink_to("/dev/zero")
    one_error_line(invoke(["rig", "show", tmp_path / "dir.yaml"]), names="not a regular file")
    big = tmp_path / "big.yaml"
    with big.open("wb") as f:
        f.truncate(20 * 1024 * 1024)
    one_error_line(invoke(["rig", "show", big]), names="bytes")


def test_dangling_rig_link_is_named(tmp_path):
    link = tmp_path / "rig.yaml"
    link.symlink_to(tmp_path / "gone.yaml")
    one_error_line(invoke(["rig", "show", link]), names="symbolic link to a missing file")


def _scene_case(tmp_path, change):
    d = scene_dict()
    change(d)
    return write_yaml(tmp_path / "scene.yaml", d)


SCENE_CASES = [
    ("seed -1", lambda d: d.update(seed=-1), "'seed'"),
    ("huge seed", lambda d: d.update(seed=10**30), "'seed'"),
    ("size 3e299", lambda d: d["objects"][0].update(size_m=[3e299, 1, 1]), "objects[0].size_m"),
    ("huge int size", lambda d: d["objects"][0].update(size_m=[10**400, 1, 1]),
     "objects[0].size_m"),
    ("radius 1e300", lambda d: d.update(highlights=[{"position_xyz_m": [1, 0, 0.5],
                                                      "radius_m": 1e300}]),
     "highlights[0].radius_m"),
    ("light dir zero", lambda d: d.update(image={"light_dir_xyz": [0, 0, 0]}),
     "image.light_dir_xyz"),
    ("frames 1e11 float", lambda d: d["robot"].update(frames=1e11), "robot.frames"),
    ("frames 1e11 int", lambda d: d["robot"].update(frames=10**11), "robot.frames"),
    ("poses of 5", lambda d: d.update(robot={"motion": "poses", "poses": [[0, 0, 0, 1, 2]]}),
     "robot.poses[0]"),
    ("version true", lambda d: d.update(slitcli_scene=True), "slitcli_scene"),
    ("surface seed", lambda d: d["objects"][0].update(surface={"seed": -5}),
     "objects[0].surface.seed"),
    ("speed", lambda d: d["robot"].update(speed_mps=1e200), "robot.speed_mps"),
    ("frame rate", lambda d: d["robot"].update(frame_rate_hz=1e-300), "robot.frame_rate_hz"),
    ("objects", lambda d: d.update(objects=[{"type": "box"} for _ in range(5001)]), "objects"),
]


@pytest.mark.parametrize("change, key", [c[1:] for c in SCENE_CASES],
                         ids=[c[0] for c in SCENE_CASES])
def test_bad_scene_values_name_the_key(tmp_path, change, key):
    path = _scene_case(tmp_path, change)
    one_error_line(invoke(["render", path, tmp_path / "out"]), names=key)
    assert not (tmp_path / "out").exists()


def test_duplicate_scene_key_is_refused(tmp_path):
    path = tmp_path / "scene.yaml"
    path.write_text("slitcli_scene: 1\nseed: 1\nseed: 2\n")
    one_error_line(invoke(["render", path, tmp_path / "out"]), names="repeats the key 'seed'")


@pytest.mark.parametrize("seed", ["-1", "-9999999999999", str(2**64)])
def test_render_seed_option_out_of_range(tmp_path, seed):
    path = write_yaml(tmp_path / "scene.yaml", scene_dict())
    one_error_line(invoke(["render", path, tmp_path / "out", "--seed", seed]), names="--seed")


def test_render_frames_option_bounded(tmp_path):
    path = write_yaml(tmp_path / "scene.yaml", scene_dict())
    one_error_line(invoke(["render", path, tmp_path / "out", "--frames", str(10**11)]),
                   names="--frames")
