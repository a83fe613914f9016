"""``python -m slitcli``: the command line."""

from slitcli.cli import main

main()
