"""The one exception family of the library.

Every error a user can cause is a :class:`SimlidarError` whose message names the bad value and
what was expected; the CLI prints it on one line and exits with code 2 for a
:class:`ConfigError` (a bad option value) and 1 for the others.
"""


class SimlidarError(Exception):
    """Base class of every error the library raises on purpose."""


class ConfigError(SimlidarError):
    """A configuration value is out of range or of the wrong kind."""


class RecipeError(SimlidarError):
    """A scene recipe file is malformed: the message names the file and the key."""


class DatasetError(SimlidarError):
    """A path is not a simlidar dataset, or a dataset cannot be written where asked."""


class ResultsError(SimlidarError):
    """Benchmark results cannot be read or merged: a cell that does not follow the published
    cell schema, or cells of several runs that disagree (``simlidar report``)."""


class TrainingError(SimlidarError):
    """A model's training or scoring produced what no result may hold: a loss, an output or a
    weight that is NaN or infinite. Nothing of the run is kept."""


class ResourceError(SimlidarError):
    """The machine cannot hold what was asked: more memory or disk space than there is."""


def shown(value, limit: int = 100) -> str:
    """``repr(value)`` for a one-line error message, cut to ``limit`` characters."""
    try:
        text = repr(value)
    except (ValueError, RecursionError):  # an integer of too many digits, a deep structure
        return "a value too large or too deeply nested to print"
    return text if len(text) <= limit else f"{text[:limit]}... ({len(text)} characters)"


def first_line(exc: BaseException) -> str:
    """The first line of ``exc``'s message for a one-line error (its type's name when it has
    none): h5py's and the OS's errors can run to several lines."""
    return str(exc).splitlines()[0] if str(exc) else type(exc).__name__


def raised(exc: BaseException) -> str:
    """``"ValueError: <the first line of its message>"`` (the name alone without a message): how
    a one-line error says what the user's code raised."""
    return f"{type(exc).__name__}: {first_line(exc)}" if str(exc) else type(exc).__name__
