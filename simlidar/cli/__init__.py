"""The ``simlidar`` command line, one module per stage (``docs/architecture.md``). The only
package that imports click.

User mistakes end in one line on stderr: exit code 2 for a bad option value (usage, including a
bad model recipe given to --model), 1 for anything else (a bad scene recipe, a path that is not
a dataset, an existing dataset, ...). ``--debug`` shows the traceback instead.

``simlidar train`` and ``bench`` run a model's own code (an outside builder's), which may end
the process (``os._exit``, a signal) or leave a thread running that the interpreter would wait
for: the console command runs them in a child process that it watches (:class:`Entry`).
"""

import os
import sys
import warnings

import click

from simlidar import __version__
from simlidar.cli import watch
from simlidar.cli.options import LazyGroup

# every command: its name -> the module of simlidar.cli that defines it under that name,
# imported only when the command runs (or its help is shown)
COMMANDS = {
    **dict.fromkeys(("generate", "sweep", "profiles", "sensors", "scenes"), "generate"),
    **dict.fromkeys(("info", "preview", "card", "verify", "pack", "fetch"), "release"),
    **dict.fromkeys(("train", "bench"), "bench"),
    "report": "report",
    "evaluate": "evaluate",
    "convert": "convert",
    "stream": "stream",
}


class Entry(LazyGroup):
    """The group as the console command and ``python -m simlidar.cli`` call it (``main()``, no
    arguments): a command that runs a model's code (:data:`~simlidar.cli.watch.WATCHED`) runs
    in a child process, the same command line again, which reports its exit code on a pipe just
    before it ends. A child that ends without reporting (a model's code called ``os._exit``,
    the kernel killed it) is named in one line, exit code 1: it used to end the run with no
    word, even with exit code 0. A child that has reported ends without waiting for threads
    left running (a model's), and the parent ends it if it is still there
    :data:`~simlidar.cli.watch.ENDING_S` later.

    Calls with arguments (a script's ``main([...])``) and click's ``CliRunner`` (which calls
    ``main.main``) run in their own process, as before."""

    def __call__(self, *args, **kwargs):
        watcher = os.environ.pop(watch.WATCH_ENV, None)
        command = watch.command(sys.argv[1:])
        if watcher is None and not args and not kwargs and command in watch.WATCHED:
            sys.exit(watch.watch(command))
        if watcher is None:
            return super().__call__(*args, **kwargs)
        pipe, program = watch.reporting(watcher)
        try:
            super().__call__(prog_name=program)  # as the parent's help and usage name it
            code = 0
        except SystemExit as exc:
            code = exc.code
        except BaseException:  # a traceback (--debug): Python prints it and exits with 1
            watch.report(pipe, 1)
            raise
        watch.end(code, pipe)


def _version(ctx: click.Context, _param, value: bool) -> None:
    """``--version``: the package's version and the machine's ray-casting path (Embree's
    shared buffers, or the slower fallback: :mod:`simlidar.sensor.embree`)."""
    if not value or ctx.resilient_parsing:
        return
    from simlidar.sensor.embree import ray_casting

    click.echo(f"simlidar, version {__version__}")
    click.echo(f"ray casting: {ray_casting()}")
    ctx.exit()


@click.group(cls=Entry, lazy=COMMANDS)
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
