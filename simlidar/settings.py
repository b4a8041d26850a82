"""Settings declared once: a frozen dataclass field carries its default, its accepted values
and its help text, and everything else is derived from it: the check that refuses a bad value
(one line naming the key and what was expected), the command line option (``simlidar.cli``)
and the documentation's tables.

    classes: int = setting(32, "32: layout x object ...", Range(2, None, "an integer"))

:func:`check` runs every field's rule; a class calls it from ``__post_init__`` and adds the
checks that involve several fields.
"""

import math
from dataclasses import MISSING, dataclass, field, fields

from simlidar.content import finite_number
from simlidar.errors import ConfigError, shown


@dataclass(frozen=True)
class Range:
    """Accepted numbers ``low`` .. ``high`` (None: unbounded), each end open or closed.

    unit : how the message names a value, with its article ("an integer", "a level",
        "degrees"); "an integer" also refuses a non-integer (and a bool)
    note : said after the range in the message, e.g. "(0: no validation)"
    finite : refuse infinities even where the range is unbounded
    """

    low: float | None
    high: float | None
    unit: str = "a number"
    low_open: bool = False
    high_open: bool = False
    note: str = ""
    finite: bool = False

    @property
    def integer(self) -> bool:
        return self.unit == "an integer"

    def accepts(self, value) -> bool:
        if isinstance(value, bool) or not isinstance(value, int | float):
            return False
        if self.integer:  # any int, compared with the bounds exactly
            if not isinstance(value, int):
                return False
        elif not (finite_number(value) or (not self.finite and value in (-math.inf, math.inf))):
            return False  # NaN, an infinity where refused, an int too large for a float
        if self.low is not None and (value <= self.low if self.low_open else value < self.low):
            return False
        return self.high is None or (value < self.high if self.high_open else value <= self.high)

    def expected(self) -> str:
        low, high = self.low, self.high
        if high is None:
            text = f"{self.unit} {'>' if self.low_open else '>='} {_as_written(low)}"
        elif low is None:
            text = f"{self.unit} {'<' if self.high_open else '<='} {_as_written(high)}"
        else:
            text = (
                f"{self.unit} in {'(' if self.low_open else '['}{_as_written(low)}, "
                f"{_as_written(high)}{')' if self.high_open else ']'}"
            )
        return f"{text} {self.note}" if self.note else text


def _as_written(value: float) -> str:
    """A bound as people write it: 2**63, 1000000000, 0.5."""
    if value == 2**63:
        return "2**63"
    return str(int(value)) if float(value).is_integer() else f"{value:g}"


@dataclass(frozen=True)
class Choice:
    """One of ``values`` (strings, or True/False for a flag)."""

    values: tuple

    def accepts(self, value) -> bool:
        return any(value is v if isinstance(v, bool) else value == v for v in self.values)

    def expected(self) -> str:
        if set(self.values) == {True, False}:
            return "true or false"
        return f"one of {list(self.values)}"


def setting(default=MISSING, help: str = "", rule: Range | Choice | None = None, **kw):
    """A dataclass field with its help text and accepted values; no ``default``: required."""
    metadata = {"help": help, "rule": rule}
    if "default_factory" in kw:
        return field(metadata=metadata, **kw)
    return field(default=default, metadata=metadata, **kw)


def rule_of(cls, name: str) -> Range | Choice | None:
    return next(f.metadata.get("rule") for f in fields(cls) if f.name == name)


def help_of(cls, name: str) -> str:
    return next(f.metadata.get("help", "") for f in fields(cls) if f.name == name)


def default_of(cls, name: str):
    f = next(f for f in fields(cls) if f.name == name)
    return f.default_factory() if f.default_factory is not MISSING else f.default


def check_value(cls, name: str, value, say) -> None:
    """Refuse ``value`` for ``cls``'s field ``name`` unless its rule accepts it:
    ``say(name, expected)`` makes the ConfigError's text."""
    rule = rule_of(cls, name)
    if rule is not None and not rule.accepts(value):
        raise ConfigError(say(name, rule.expected()))


def check(obj, say=None) -> None:
    """Check every field of the dataclass instance ``obj`` against its rule (in field order).

    say : (name, expected) -> the message; default ``"<name>=<value>: expected <expected>"``
        (the value as :func:`~simlidar.errors.shown` prints it)
    """
    for f in fields(obj):
        value = getattr(obj, f.name)
        check_value(
            type(obj),
            f.name,
            value,
            say or (lambda name, expected, v=value: f"{name}={shown(v)}: expected {expected}"),
        )
