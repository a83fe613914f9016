"""``--config FILE`` (the option itself: :mod:`slitcli.cli.main`) and output arguments.

``--config FILE`` reads a YAML mapping of option values (keys: the option's long name
without the leading dashes, ``max-dt`` or ``max_dt``) and hands it to click as the
command's ``default_map``: values on the command line override the file. Keys that are
not options of the command are refused, naming the key and the file.
"""

from __future__ import annotations

import difflib
from pathlib import Path
from typing import Any

import click

from slitcli.errors import SlitcliError


def _option_keys(command: click.Command) -> dict[str, str]:
    """Config keys of a command's options -> the parameter name click stores them under."""
    keys: dict[str, str] = {}
    for p in command.params:
        if not isinstance(p, click.Option) or p.name in (None, "config") or p.hidden:
            continue
        for opt in (*p.opts, *p.secondary_opts):
            if opt.startswith("--"):
                keys[opt[2:]] = p.name
                keys[opt[2:].replace("-", "_")] = p.name
        keys[p.name] = p.name
    return keys


def load_config(path: Path, ctx: click.Context) -> dict[str, Any]:
    """The ``default_map`` of a config file for the context's command.

    Unknown keys and values the option's type refuses are errors naming the file and
    the key.
    """
    from slitcli.io.yamlfile import read_yaml

    data = read_yaml(path, kind="config file",
                     missing_hint="give an existing YAML file of option values")
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise SlitcliError(f"{path}: a config file is a mapping of option names to values "
                           f"(e.g. 'max-dt: 0.05'), not a {type(data).__name__}")
    command, command_path = ctx.command, ctx.command_path
    keys = _option_keys(command)
    params = {p.name: p for p in command.params}
    out: dict[str, Any] = {}
    for k, v in data.items():
        name = keys.get(str(k))
        if name is None:
            close = difflib.get_close_matches(str(k), sorted(keys), n=1)
            hint = f"did you mean '{close[0]}'?" if close else \
                f"see '{command_path} --help' for its options"
            raise SlitcliError(f"{path}: '{k}' is not an option of '{command_path}'; {hint}")
        if name in out:
            raise SlitcliError(f"{path}: key '{k}' sets the same option as another key; "
                               "keep one")
        if isinstance(v, dict):
            raise SlitcliError(f"{path}: key '{k}' must be a value or a list, not a mapping")
        value = tuple(v) if isinstance(v, list) else v
        try:
            params[name].type_cast_value(ctx, value)
        except click.BadParameter as e:
            raise SlitcliError(f"{path}: key '{k}' = {v!r}: {e.format_message()}") from None
        out[name] = value
    return out


def pick_out(argument: Path | None, option: Path | None, metavar: str) -> Path:
    """The output path of a command that takes it as an argument (old) or as ``-o``."""
    if argument is not None and option is not None and argument != option:
        raise click.UsageError(f"give the output once: {metavar} ({argument}) or -o/--out "
                               f"({option}), not both")
    out = option if option is not None else argument
    if out is None:
        raise click.UsageError(f"missing the output: give -o/--out {metavar}")
    return out
