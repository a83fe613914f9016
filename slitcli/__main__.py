"""``python -m slitcli``: the command line."""

from slitcli.cli import run

run()
