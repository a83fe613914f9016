"""Command ``warm-up``: compile the numba kernels ahead of the first run."""

from __future__ import annotations

import click

from slitcli.cli.main import cli


@cli.command("warm-up", short_help="Compile the numba kernels for this machine ahead of the "
             "first run.")
@click.option("--workers", type=click.IntRange(1, 64), default=None,
              help="Processes compiling in parallel [default: the cores available].")
@click.option("--list", "list_only", is_flag=True,
              help="Only list the kernels found in the package sources, one a line.")
def warmup_cmd(workers: int | None, list_only: bool) -> None:
    """Compile every numba kernel the pipelines use, for this machine, into the cache.

    slitcli's hot kernels are compiled by numba on first use (about a minute of CPU)
    and cached in __pycache__ beside their sources. This command runs the render,
    laser, stereo (plain and semi-global), detect and DWA pipelines on a one-frame
    scene in parallel processes so that the compiling happens now; later runs load
    the machine code in milliseconds. `make venv` runs it; run it yourself after
    `pip install slitcli`. Progress on stderr (one line per job), the summary on stdout:
    kernels ready out of those in the sources, and the ones no pipeline reached (they
    compile on first use). A second run only loads the cache (seconds). See
    docs/install.md.

    \b
    Examples:
      slitcli warm-up
      slitcli warm-up --workers 1
      slitcli warm-up --list
    """
    from slitcli.warmup import kernel_inventory, warm_up

    if list_only:
        for name in kernel_inventory():
            click.echo(name)
        return
    report = warm_up(workers=workers, on_progress=lambda line: click.echo(line, err=True))
    click.echo(report.summary_line())
