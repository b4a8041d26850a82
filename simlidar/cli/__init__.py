"""The ``simlidar`` command line, one module per stage (``docs/architecture.md``). The only
package that imports click.

User mistakes end in one line on stderr: exit code 2 for a bad option value (usage, including a
bad model recipe given to --model), 1 for anything else (a bad scene recipe, a path that is not
a dataset, an existing dataset, ...). ``--debug`` shows the traceback instead.
"""

import warnings

import click

from simlidar import __version__
from simlidar.cli.options import LazyGroup

# every command: its name -> the module of simlidar.cli that defines it under that name,
# imported only when the command runs (or its help is shown)
COMMANDS = {
    **dict.fromkeys(("generate", "sweep", "profiles", "sensors", "scenes"), "generate"),
    **dict.fromkeys(("info", "preview", "card", "verify", "pack", "fetch"), "release"),
    **dict.fromkeys(("train", "bench"), "bench"),
    "report": "report",
    "convert": "convert",
}


def _version(ctx: click.Context, _param, value: bool) -> None:
    """``--version``: the package's version and the machine's ray-casting path (Embree's
    shared buffers, or the slower fallback: :mod:`simlidar.sensor.embree`)."""
    if not value or ctx.resilient_parsing:
        return
    from simlidar.sensor.embree import ray_casting

    click.echo(f"simlidar, version {__version__}")
    click.echo(f"ray casting: {ray_casting()}")
    ctx.exit()


@click.group(cls=LazyGroup, lazy=COMMANDS)
@click.option(
    "--version",
    is_flag=True,
    expose_value=False,
    is_eager=True,
    callback=_version,
    help="Show the version and the ray-casting path, and exit.",
)
@click.option("--debug", is_flag=True, help="Show tracebacks instead of one-line errors.")
@click.pass_context
def main(ctx: click.Context, debug: bool) -> None:
    """simlidar: synthetic LiDAR temporal-pulse datasets (Sim LiDAR) and benchmarks."""
    ctx.meta["debug"] = debug
    if not debug:  # warnings as one line each, without the source line
        warnings.showwarning = lambda message, *args, **kwargs: click.echo(
            f"Warning: {message}", err=True
        )
