"""The benchmark scripts' arguments (``benchmark/*.py``, argparse): the CLI's rule that a bad
value is one line naming it and what was expected, exit code 2, and that a SimlidarError
while a script runs is one line and exit code 1, never a traceback."""

import argparse
import math
import shlex
import sys
from collections.abc import Callable
from pathlib import Path

from simlidar.errors import SimlidarError


def integers(
    low: int, high: int | None = None, one: bool = False
) -> Callable[[str], tuple[int, ...] | int]:
    """An argparse type: a comma-separated list of integers in [low, high] (``"4,8,16"``), or
    with ``one`` a single integer."""
    return _listed(int, "integer", low, high, one)


def numbers(
    low: float, high: float | None = None, one: bool = False
) -> Callable[[str], tuple[float, ...] | float]:
    """An argparse type: a comma-separated list of finite numbers in [low, high]
    (``"0,0.3,1"``), or with ``one`` a single number."""
    return _listed(float, "number", low, high, one)


def _listed(kind: type, noun: str, low, high, one: bool) -> Callable:
    """:func:`integers` and :func:`numbers`: ``kind`` parses each comma-separated part."""
    bounds = f"in [{low}, {high}]" if high is not None else f">= {low}"
    article = "an" if noun[0] in "aeiou" else "a"
    expected = f"{article} {noun} {bounds}" if one else f"comma-separated {noun}s {bounds}"

    def parse(text: str):
        try:
            values = tuple(kind(part) for part in text.split(","))
        except ValueError:
            values = ()
        if (
            not values
            or (one and len(values) > 1)
            or not all(math.isfinite(v) for v in values if kind is float)
            or any(v < low or (high is not None and v > high) for v in values)
        ):
            raise argparse.ArgumentTypeError(f"{text!r}: expected {expected}")
        return values[0] if one else values

    return parse


def choices(known: tuple[str, ...]) -> Callable[[str], tuple[str, ...]]:
    """An argparse type: a comma-separated list of some of ``known``."""

    def parse(text: str) -> tuple[str, ...]:
        values = tuple(text.split(","))
        unknown = [v for v in values if v not in known]
        if unknown:
            raise argparse.ArgumentTypeError(
                f"{unknown[0]!r}: expected comma-separated values of {list(known)}"
            )
        return values

    return parse


def in_folder(text: str) -> Path:
    """An argparse type: a file to write whose folder exists (checked before any work, as the
    file is written at the end)."""
    path = Path(text)
    if not text or not path.parent.is_dir() or path.is_dir():
        raise argparse.ArgumentTypeError(f"{text!r}: expected a file in an existing folder")
    return path


def command_line(script: str, argv: list[str] | None) -> str:
    """The command that made a script's results, as written into them: ``python
    benchmark/<script>`` and its arguments (``argv``, or the process's), less ``--no-train``,
    which writes what training would."""
    given = argv if argv is not None else sys.argv[1:]
    # quoted where the shell needs it (an empty argument, a space), else as given
    return f"python benchmark/{script}" + "".join(
        f" {shlex.quote(a)}" for a in given if a != "--no-train"
    )


def run(main: Callable[[], int | None]) -> None:
    """Run a script's ``main`` and exit with its code; a SimlidarError is one line on stderr
    and exit code 1."""
    try:
        code = main()
    except SimlidarError as exc:
        print(f"error: {exc}", file=sys.stderr)
        code = 1
    sys.exit(code or 0)
