"""What every command shares: one-line errors with the right exit code, option types, and
options made from the settings' dataclass fields (:mod:`simlidar.settings`).

User mistakes end in one line on stderr: exit code 2 for a bad option value (usage, including a
bad model recipe given to --model), 1 for anything else (a bad scene recipe, a path that is not
a dataset, an existing dataset, ...). ``--debug`` shows the traceback instead.
"""

import re
import sys
from pathlib import Path

import click

from simlidar.errors import ConfigError, SimlidarError

_NO_ARGS = getattr(click.exceptions, "NoArgsIsHelpError", ())  # click >= 8.2


class Group(click.Group):
    """Turns library errors into one-line messages with the right exit code."""

    def invoke(self, ctx: click.Context):
        try:
            return super().invoke(ctx)
        except ConfigError as exc:
            if ctx.meta.get("debug"):
                raise
            raise click.UsageError(str(exc)) from None  # exit 2, one line
        except (SimlidarError, OSError) as exc:  # OSError: permissions, full disk, ...
            if ctx.meta.get("debug"):
                raise
            click.echo(f"Error: {exc}", err=True)
            ctx.exit(1)

    def main(self, args=None, prog_name=None, complete_var=None, standalone_mode=True, **extra):
        """As click's, but a usage error is the one line "Error: ..." (exit 2), without
        click's usage and "Try --help" lines: the message already names the option."""
        if not standalone_mode:
            return super().main(args, prog_name, complete_var, False, **extra)
        try:
            code = super().main(args, prog_name, complete_var, False, **extra)
        except _NO_ARGS as exc:  # `simlidar` alone: the help, as click shows it
            exc.show()
            sys.exit(exc.exit_code)
        except click.UsageError as exc:
            click.echo(f"Error: {exc.format_message()}", err=True)
            sys.exit(exc.exit_code)
        except click.ClickException as exc:
            exc.show()
            sys.exit(exc.exit_code)
        except click.Abort:
            click.echo("Aborted!", err=True)
            sys.exit(1)
        sys.exit(code if isinstance(code, int) else 0)


# the characters of a command's first sentence that ``simlidar --help`` shows: all of it
SHORT_HELP_LIMIT = 1000


class LazyGroup(Group):
    """A :class:`Group` whose commands are imported when one is asked for (click's lazy
    loading: ``list_commands`` and ``get_command``), so that ``simlidar generate`` does not
    import the benchmark commands' module and ``simlidar train`` not the generator's.

    lazy : command name -> module of ``simlidar.cli`` that defines it under that name
    """

    def __init__(self, *args, lazy: dict[str, str], **kwargs):
        self._commands: dict[str, click.Command] = {}
        self.lazy = dict(lazy)
        super().__init__(*args, **kwargs)

    @property
    def commands(self) -> dict[str, click.Command]:
        """Every command, each module imported (for introspection: the help and the CLI
        resolve one command at a time)."""
        for name in self.lazy:
            self._load(name)
        return self._commands

    @commands.setter
    def commands(self, value) -> None:
        self._commands = dict(value)

    def add_command(self, cmd: click.Command, name: str | None = None) -> None:
        self._commands[name or cmd.name] = cmd

    def list_commands(self, ctx) -> list[str]:
        return sorted({*self._commands, *self.lazy})

    def get_command(self, ctx, cmd_name: str) -> click.Command | None:
        return self._load(cmd_name) if cmd_name in self.lazy else self._commands.get(cmd_name)

    def format_commands(self, ctx, formatter) -> None:
        """The commands, each with the first sentence of its help whole, wrapped to the
        terminal (click's own cut it at one line's width with "...")."""
        rows = []
        for name in self.list_commands(ctx):
            command = self.get_command(ctx, name)
            if command is not None and not command.hidden:
                rows.append((name, command.get_short_help_str(limit=SHORT_HELP_LIMIT)))
        if rows:
            with formatter.section("Commands"):
                formatter.write_dl(rows)

    def _load(self, name: str) -> click.Command:
        if name not in self._commands:
            import importlib

            module = importlib.import_module(f"simlidar.cli.{self.lazy[name]}")
            self._commands[name] = getattr(module, name)
        return self._commands[name]


_INTEGER = re.compile(r"[+-]?[0-9]+")
_DECIMAL = re.compile(
    r"[+-]?(?:(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?|inf|infinity|nan)", re.IGNORECASE
)


def plain_number(text: str, integer: bool = False) -> bool:
    """Whether ``text`` is a number written as people type one: ASCII digits, a sign, a point,
    an exponent (``inf``, ``nan`` for decimals). Python's ``int`` and ``float`` also take
    other scripts' digits (``float("٠.٥")`` is 0.5) and ``1_000``: a value that reads as
    something else where it is stored or shown."""
    return (_INTEGER if integer else _DECIMAL).fullmatch(text.strip()) is not None


def _refuse_unplain(kind: click.ParamType, value, integer: bool, param, ctx) -> None:
    """Every numeric option's first check (:func:`plain_number`): a usage error naming the
    value."""
    if isinstance(value, str) and not plain_number(value, integer):
        what = "a whole number" if integer else "a number"
        kind.fail(f"{value!r} is not {what} in ASCII digits (0-9)", param, ctx)


class IntegerRange(click.IntRange):
    """click's IntRange, for ASCII digits only (:func:`plain_number`)."""

    def convert(self, value, param, ctx):
        _refuse_unplain(self, value, True, param, ctx)
        return super().convert(value, param, ctx)


class NoiseLevels(click.ParamType):
    """A comma-separated list of noise levels (each as GeneratorConfig's ``noise`` accepts it),
    e.g. ``0.1,0.2,0.33,0.5``."""

    name = "LEVELS"

    def convert(self, value, param, ctx):
        if isinstance(value, list):
            return value
        levels = []
        for part in str(value).split(","):
            try:
                if not plain_number(part):
                    raise ValueError(part)
                level = float(part)
            except ValueError:
                self.fail(f"{part!r} is not a number; expected levels like 0.1,0.2", param, ctx)
            from simlidar.generator.config import GeneratorConfig
            from simlidar.settings import rule_of

            rule = rule_of(GeneratorConfig, "noise")  # the one rule of a noise level
            if not rule.accepts(level):
                self.fail(f"{level:g}: expected noise levels, each {rule.expected()}", param, ctx)
            levels.append(level)
        if len(set(levels)) != len(levels):
            self.fail(f"{value!r} repeats a level; expected distinct levels", param, ctx)
        return levels


DEFAULT_OUT = Path("data")  # where generate, convert and fetch write datasets


class Workers(click.ParamType):
    """A number of worker processes >= 1, or ``auto``: the cores this process may run on."""

    name = "N|auto"

    def convert(self, value, param, ctx):
        if isinstance(value, int) and not isinstance(value, bool):
            number = value
        elif str(value).strip().lower() == "auto":
            from simlidar.processes import usable_cores

            return usable_cores()
        else:
            try:
                if not plain_number(str(value), integer=True):
                    raise ValueError(value)
                number = int(str(value))
            except ValueError:
                self.fail(f"{value!r} is not a whole number; expected N >= 1 or auto", param, ctx)
        if number < 1:
            self.fail(f"{number} is below 1; expected N >= 1 or auto", param, ctx)
        return number


class Scheduler(click.ParamType):
    """A Dask scheduler's address (``tcp://HOST:PORT``) or ``local``, checked to be reachable
    (and Dask installed) before anything is written."""

    name = "ADDRESS|local"

    def convert(self, value, param, ctx):
        from simlidar.cluster import check_scheduler

        try:
            check_scheduler(str(value))
        except ConfigError as exc:  # the address, then why (no "--scheduler" twice)
            self.fail(str(exc).replace(f"--scheduler {value}: ", f"{value}: ", 1), param, ctx)
        return str(value)


def scheduler_option(what: str):
    """``--scheduler ADDRESS|local``: run ``what`` as tasks on a Dask cluster."""
    return click.option(
        "--scheduler",
        type=Scheduler(),
        default=None,
        help=f"Run {what} on a Dask cluster: a scheduler's address (tcp://HOST:8786; the output "
        "folder must be on a file system every worker shares), or local: a LocalCluster of "
        '--workers processes here. Needs pip install "simlidar[cluster]".',
    )


class FiniteRange(click.FloatRange):
    """A FloatRange for ASCII numbers only (:func:`plain_number`) that also refuses nan (which
    compares False with both bounds)."""

    def convert(self, value, param, ctx):
        _refuse_unplain(self, value, False, param, ctx)
        number = super().convert(value, param, ctx)
        if number != number:
            self.fail(
                f"{value!r} is not a number in the range {self._describe_range()}.", param, ctx
            )
        return number


class OutFolder(click.Path):
    """An --out folder: not an empty string, which would silently mean the current folder."""

    def __init__(self):
        super().__init__(file_okay=False, path_type=Path)

    def convert(self, value, param, ctx):
        if value == "":
            self.fail("'' is empty; expected a folder name ('.': the current one)", param, ctx)
        return super().convert(value, param, ctx)


def batch_options(largest: int, default: int, what: str):
    """``--batch-size`` (1 .. ``largest`` ``what`` ray-cast together) and ``--workers`` (N or
    auto), generate's and stream's: neither changes the files."""

    def decorate(command):
        command = click.option(
            "--workers",
            type=Workers(),
            default="1",
            show_default=True,
            help="Processes that simulate (auto: every core this process may use); the files "
            "are the same for every count.",
        )(command)
        return click.option(
            "--batch-size",
            type=IntegerRange(1, largest),
            default=default,
            show_default=True,
            help=f"{what} ray-cast together (does not change the data).",
        )(command)

    return decorate


scenes_option = click.option(
    "--scenes",
    type=click.Path(path_type=Path),
    default=None,
    help="Scene catalog folder (default: the one shipped with simlidar).",
)


def load_scene_catalog(scenes):
    from simlidar.scene.recipe import load_catalog

    return load_catalog(scenes)


def click_type(rule):
    """The click type that accepts what a setting's rule accepts (None: click's default)."""
    from simlidar.settings import Choice, Range

    if isinstance(rule, Choice):
        return click.Choice([str(v) for v in rule.values])
    if not isinstance(rule, Range):
        return None
    kind = IntegerRange if rule.integer else FiniteRange
    return kind(rule.low, rule.high, min_open=rule.low_open, max_open=rule.high_open)


def setting_option(cls, name: str, *decls: str, **overrides):
    """A click option made from the settings field ``cls.<name>`` (:mod:`simlidar.settings`):
    its default, its help text and a type accepting what the field accepts; ``overrides``
    replace any of them (e.g. ``default=None`` where the value comes from elsewhere)."""
    from simlidar.settings import default_of, help_of, rule_of

    flags = decls or (f"--{name.replace('_', '-')}",)
    options = {
        "type": click_type(rule_of(cls, name)),
        "default": default_of(cls, name),
        "show_default": True,
        "help": help_of(cls, name),
    }
    options.update(overrides)
    if options["default"] is None:
        options["show_default"] = False
    return click.option(*flags, **options)


def need_torch(command: str) -> None:
    """Refuse ``simlidar <command>`` in one line where PyTorch is not installed."""
    try:
        import torch  # noqa: F401
    except ImportError:
        raise SimlidarError(
            f"simlidar {command} needs PyTorch: pip install 'simlidar[torch]' (or torch itself)"
        ) from None
