"""The command line: parses options, builds parameter dataclasses, calls the library.

Every command calls one library function. The library's own :class:`SlitcliError`
becomes exit status 2 with one line on stderr (its parameter names turned into this
command line's flags, :func:`slitcli.cli.main.user_message`); click's usage errors
too; any other exception is an internal error (exit 1, one line; the traceback with
``--debug``). Command modules import nothing heavy at import time, so ``--help`` is
quick.
"""

# The subcommands register themselves on `cli` when their modules are imported.
from slitcli.cli import (
    calibrate,
    detect,
    dwa,
    export,
    figures,
    laser,
    report,
    rig,
    sim,
    stereo,
)
from slitcli.cli.main import PARAM_FLAGS, bag_options, cli, main, user_message

__all__ = [
    "PARAM_FLAGS",
    "bag_options",
    "calibrate",
    "cli",
    "detect",
    "dwa",
    "export",
    "figures",
    "laser",
    "main",
    "report",
    "rig",
    "sim",
    "stereo",
    "user_message",
]
