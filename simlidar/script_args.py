"""The benchmark scripts' arguments (``benchmark/*.py``, argparse): the CLI's rule that a bad
value is one line naming it and what was expected, exit code 2, and that a SimlidarError
while a script runs is one line and exit code 1, never a traceback."""

import argparse
import sys
from collections.abc import Callable

from simlidar.errors import SimlidarError


def integers(
    low: int, high: int | None = None, one: bool = False
) -> Callable[[str], tuple[int, ...] | int]:
    """An argparse type: a comma-separated list of integers in [low, high] (``"4,8,16"``), or
    with ``one`` a single integer."""
    bounds = f"in [{low}, {high}]" if high is not None else f">= {low}"
    expected = f"an integer {bounds}" if one else f"comma-separated integers {bounds}"

    def parse(text: str) -> tuple[int, ...] | int:
        try:
            values = tuple(int(part) for part in text.split(","))
        except ValueError:
            values = ()
        if (
            not values
            or (one and len(values) > 1)
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


def run(main: Callable[[], int | None]) -> None:
    """Run a script's ``main`` and exit with its code; a SimlidarError is one line on stderr
    and exit code 1."""
    try:
        code = main()
    except SimlidarError as exc:
        print(f"error: {exc}", file=sys.stderr)
        code = 1
    sys.exit(code or 0)
