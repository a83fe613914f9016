"""Options every command shares: ``--config FILE`` and the ``-o/--out`` spelling.

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

CONFIG_HELP = ("YAML file of option values (keys: option names without dashes, e.g. "
               "'max-dt: 0.05'); options given on the command line override it. "
               "See docs/config.md.")


class AliasOption(click.Option):
    """An option whose old spellings (``hidden_aliases``) work but are not shown in --help."""

    def __init__(self, *args: Any, hidden_aliases: tuple[str, ...] = (), **kw: Any) -> None:
        super().__init__(*args, **kw)
        self.hidden_aliases = tuple(hidden_aliases)

    def get_help_record(self, ctx: click.Context) -> tuple[str, str] | None:
        shown = [o for o in self.opts if o not in self.hidden_aliases]
        saved = self.opts
        self.opts = shown
        try:
            return super().get_help_record(ctx)
        finally:
            self.opts = saved


def out_option(help_text: str, *, required: bool = True, file: bool = False,
               old: tuple[str, ...] = (), **kw: Any) -> Any:
    """``-o/--out`` with one spelling everywhere; ``old`` spellings (``--output``) still work."""
    path_type = click.Path(dir_okay=False, path_type=Path) if file else \
        click.Path(path_type=Path)
    return click.option("-o", "--out", *old, "out", cls=AliasOption, hidden_aliases=old,
                        required=required, type=kw.pop("type", path_type), help=help_text,
                        **kw)


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
            raise SlitcliError(f"{path}: unknown key '{k}' for '{command_path}'; {hint}")
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


def _config_callback(ctx: click.Context, _param: click.Parameter, value: Path | None) -> None:
    if value is None:
        return
    defaults = load_config(value, ctx)
    ctx.default_map = {**(ctx.default_map or {}), **defaults}


def config_option() -> click.Option:
    """The ``--config FILE`` option (eager: read before the other options take defaults)."""
    return click.Option(["--config"], type=click.Path(dir_okay=False, path_type=Path),
                        default=None, is_eager=True, expose_value=False,
                        callback=_config_callback, help=CONFIG_HELP)


def install_config_option(group: click.Group) -> None:
    """Give every command under ``group`` the ``--config`` option (once)."""
    for command in group.commands.values():
        if isinstance(command, click.Group):
            install_config_option(command)
        elif not any(p.name == "config" for p in command.params):
            command.params.append(config_option())


def pick_out(argument: Path | None, option: Path | None, metavar: str) -> Path:
    """The output path of a command that takes it as an argument (old) or as ``-o``."""
    if argument is not None and option is not None and argument != option:
        raise click.UsageError(f"give the output once: {metavar} ({argument}) or -o/--out "
                               f"({option}), not both")
    out = option if option is not None else argument
    if out is None:
        raise click.UsageError(f"missing the output: give -o/--out {metavar}")
    return out
