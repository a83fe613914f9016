"""Library errors name library parameters; the command line maps them to its flags once.

The library (everything under ``slitcli/`` except ``slitcli/cli/``) must not write CLI
flags into its error messages: it names parameters in backticks (```bin_deg```) and
passes ``param=``; :func:`slitcli.cli.user_message` turns them into flags.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import click
import pytest
from click.testing import CliRunner

from slitcli.cli import PARAM_FLAGS, cli, user_message
from slitcli.errors import SlitcliError

LIB = Path(__file__).resolve().parents[1] / "slitcli"
ERROR_TYPES = {"SlitcliError", "ValueError"}
# a CLI flag: two dashes then a lower-case word, not inside a word or a longer dash run
FLAG = re.compile(r"(?<![\w-])--[a-z][a-z0-9-]*")


def _library_files() -> list[Path]:
    return sorted(p for p in LIB.rglob("*.py") if (LIB / "cli") not in p.parents)


def _error_calls(tree: ast.AST):
    """The ``SlitcliError(...)`` / ``ValueError(...)`` calls of a module."""
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            f = node.func
            name = f.id if isinstance(f, ast.Name) else f.attr if isinstance(f, ast.Attribute) \
                else None
            if name in ERROR_TYPES and node.args:
                yield node


def _literal_text(node: ast.AST) -> str:
    """The string literal parts of a message expression (f-string pieces, concatenations)."""
    return "".join(n.value for n in ast.walk(node)
                   if isinstance(n, ast.Constant) and isinstance(n.value, str))


def _flags_in(source: str) -> list[tuple[int, str]]:
    return [(call.lineno, flag) for call in _error_calls(ast.parse(source))
            for flag in FLAG.findall(_literal_text(call.args[0]))]


def test_the_scan_finds_flags_where_they_are():
    # the detector itself: a flag in a plain, f-string or concatenated message is found;
    # a backticked parameter, a negative number or an en-dash range is not
    src = ('raise SlitcliError("--bin-deg 20 is out of range")\n'
           'raise SlitcliError(f"{x}: pass " "--period-s SECONDS", param="period_s")\n'
           'raise ValueError(f"`bin_deg` {v} must be > -1 and in 0.05--10")\n'
           'raise errors.SlitcliError(f"{p}: use --format")\n')
    assert _flags_in(src) == [(1, "--bin-deg"), (2, "--period-s"), (4, "--format")]


def test_library_error_messages_name_parameters_not_flags():
    files = _library_files()
    calls = 0
    found = []
    for path in files:
        tree = ast.parse(path.read_text(encoding="utf-8"))
        calls += sum(1 for _ in _error_calls(tree))
        found += [f"{path.relative_to(LIB.parent)}:{line}: {flag}"
                  for line, flag in _flags_in(path.read_text(encoding="utf-8"))]
    assert calls >= 200, f"only {calls} error calls found in {len(files)} files"  # scan works
    assert found == [], "library messages naming CLI flags (use `param` + param=):\n" + \
        "\n".join(found)


def _option_names() -> set[str]:
    """Every option string of every command (lazy groups included)."""
    names: set[str] = set()

    def walk(cmd: click.Command, ctx: click.Context) -> None:
        for p in cmd.params:
            if isinstance(p, click.Option):
                names.update(p.opts)
                names.update(p.secondary_opts)
        if isinstance(cmd, click.Group):
            for sub in cmd.list_commands(ctx):
                child = cmd.get_command(ctx, sub)
                if child is not None:
                    walk(child, click.Context(child, parent=ctx, info_name=sub))

    walk(cli, click.Context(cli, info_name="slitcli"))
    return names


def test_every_mapped_flag_is_a_real_option():
    options = _option_names()
    missing = [f"{name} -> {flag}" for name, value in PARAM_FLAGS.items()
               for flag in value.split("/") if flag.startswith("-") and flag not in options]
    assert missing == []


def test_every_laser_parameter_error_names_its_option():
    """Each LaserParams field is a `laser` / `detect` option, so an error about it names
    the option (not the library's name)."""
    from dataclasses import fields

    from slitcli.laser.params import LaserParams

    names = [f.name for f in fields(LaserParams)]
    assert [n for n in names if PARAM_FLAGS.get(n) != "--" + n.replace("_", "-")] == []


@pytest.mark.parametrize("message,param,expected", [
    ("`num_disparities` 40 must be a multiple of 16 for `matcher` bm (OpenCV)",
     ("num_disparities", "matcher"), "--num-disparities 40 must be a multiple of 16 for "
     "--matcher bm (OpenCV)"),
    ("`window_w_px` 8: the window width must be odd", "window_w_px",
     "--window 8: the window width must be odd"),
    ("`mode` 'best' is unknown", "mode", "--fusion 'best' is unknown"),
    # a parameter without an option keeps its library name, unquoted
    ("`support_radius_px` must be >= 1 px", "support_radius_px",
     "support_radius_px must be >= 1 px"),
    # only the parameters the error names are rewritten
    ("`fps` 200 is out of range; not `dpi`", "fps", "--fps 200 is out of range; not `dpi`"),
])
def test_user_message_maps_the_named_parameters(message, param, expected):
    assert user_message(SlitcliError(message, param=param)) == expected


def _one_error_line(res) -> str:
    lines = [x for x in res.stderr.splitlines() if x.strip()]
    assert res.exit_code == 2 and len(lines) == 1, res.stderr
    assert "Traceback" not in res.stderr and "`" not in lines[0]
    return lines[0]


def test_stereo_cli_names_its_flags(tmp_path):
    seq = tmp_path / "seq"
    seq.mkdir()
    res = CliRunner().invoke(cli, ["stereo", str(seq), "-o", str(tmp_path / "out"),
                                   "--matcher", "bm", "--num-disparities", "40"])
    line = _one_error_line(res)
    assert "--num-disparities 40 must be a multiple of 16 for --matcher bm" in line
    assert "num_disparities" not in line


def test_export_cli_names_its_flags(tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    res = CliRunner().invoke(cli, ["export", str(run), "-o", str(tmp_path / "s.bag"),
                                   "--camera-frame-id", "left camera"])
    line = _one_error_line(res)
    assert "--camera-frame-id 'left camera' must be a non-empty name without spaces" in line


def test_calibrate_cli_names_its_flags(tmp_path):
    for d in ("l", "r"):
        (tmp_path / d).mkdir()
    res = CliRunner().invoke(cli, ["calibrate", "stereo", str(tmp_path / "l"),
                                   str(tmp_path / "r"), "--board", "2x6", "--square-m",
                                   "0.025", "-o", str(tmp_path / "rig.yaml")])
    line = _one_error_line(res)
    assert "--board 2x6: a board needs at least 3x3 inner corners" in line


@pytest.mark.parametrize("args,expected", [
    (["--colour-error", "2"], "laser parameter --colour-error = 2.0 is out of range"),
    (["--max-hue-deg", "0"], "laser parameter --max-hue-deg = 0.0 is out of range"),
    (["--max-texture-ratio", "nan"], "laser parameter --max-texture-ratio = nan is out of range"),
    (["--min-texture-ratio", "7"], "laser parameter --min-texture-ratio = 7.0 is out of range"),
])
def test_laser_cli_names_its_flags(tmp_path, args, expected):
    """An out-of-range laser tuning value is named by its option, in one line, before
    any frame is read (the folder is empty)."""
    seq = tmp_path / "seq"
    seq.mkdir()
    res = CliRunner().invoke(cli, ["laser", str(seq), "-o", str(tmp_path / "out"), *args])
    line = _one_error_line(res)
    assert expected in line
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("command", ["detect", "stereo", "laser"])
@pytest.mark.parametrize("value", ["two", "0", "-1"])
def test_a_bad_thread_setting_is_refused_before_anything_is_written(tmp_path, command,
                                                                     value):
    seq = Path(__file__).resolve().parent.parent / "sample_data" / "sequences" / "corridor"
    out = tmp_path / "out"
    res = CliRunner().invoke(cli, [command, str(seq), "-o", str(out)],
                             env={"SLITCLI_THREADS": value})
    assert res.exit_code == 2, res.output
    lines = [x for x in res.output.splitlines() if x.strip()]
    assert len(lines) == 1 and "SLITCLI_THREADS" in lines[0], res.output
    assert not out.exists()
