"""The command line loads a command's module only when that command is looked up."""

from __future__ import annotations

import importlib
import subprocess
import sys
import textwrap

import click

from slitcli.cli.main import COMMANDS, cli


def _run(code: str) -> str:
    res = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True,
                         text=True, timeout=300)
    assert res.returncode == 0, res.stderr[-2000:]
    return res.stdout.strip()


def test_the_table_names_each_command_its_module_and_its_help():
    """Every command a module registers is in the table, under that module, with the
    help line the command itself gives."""
    for module in sorted({m for m, _ in COMMANDS.values()}):
        importlib.import_module(module)
    loaded = {name: cmd for name, cmd in dict.items(cli.commands)}
    assert set(loaded) == set(COMMANDS)
    for name, (module, short) in COMMANDS.items():
        cmd = loaded[name]
        assert cmd.callback is not None or isinstance(cmd, click.Group)
        where = cmd.callback.__module__ if cmd.callback else None
        assert where in (module, None), name
        assert cmd.get_short_help_str(10**6) == short, name


def test_help_lists_every_command_without_importing_one():
    out = _run("""
        import sys
        from click.testing import CliRunner
        from slitcli.cli import cli
        res = CliRunner().invoke(cli, ["--help"])
        assert res.exit_code == 0, res.output
        mods = sorted(m for m in sys.modules if m.startswith("slitcli.cli.") and
                      m != "slitcli.cli.main")
        heavy = sorted(m for m in ("numpy", "numba", "pandas", "cv2") if m in sys.modules)
        listed = [line.split()[0] for line in res.output.split("Commands:")[1].splitlines()
                  if line.startswith("  ") and not line.startswith("   ")]
        print(mods, heavy, listed)
        """)
    assert out == f"[] [] {sorted(COMMANDS)!r}"


def test_one_command_imports_its_own_module_only():
    out = _run("""
        import sys
        from click.testing import CliRunner
        from slitcli.cli import cli
        res = CliRunner().invoke(cli, ["rig", "--help"])
        assert res.exit_code == 0, res.output
        print(sorted(m for m in sys.modules if m.startswith("slitcli.cli.")))
        """)
    assert out == "['slitcli.cli.main', 'slitcli.cli.rig']"


def test_an_unknown_command_is_a_usage_error_naming_it():
    res = subprocess.run([sys.executable, "-m", "slitcli", "detcet"], capture_output=True,
                         text=True, timeout=300)
    assert res.returncode == 2
    assert "detcet" in res.stderr and "Traceback" not in res.stderr
