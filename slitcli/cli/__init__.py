"""The command line: parses options, builds parameter dataclasses, calls the library.

Every command calls one library function. The library's own :class:`SlitcliError`
becomes exit status 2 with one line on stderr (its parameter names turned into this
command line's flags, :func:`slitcli.cli.main.user_message`); click's usage errors
too; any other exception is an internal error (exit 1, one line; the traceback with
``--debug``). A command's module is imported when the command is looked up
(:data:`slitcli.cli.main.COMMANDS`), so ``slitcli --help`` imports none of them and
``slitcli detect`` imports the detect command's.
"""

from slitcli.cli.main import PARAM_FLAGS, bag_options, cli, main, user_message

__all__ = ["PARAM_FLAGS", "bag_options", "cli", "main", "user_message"]
