"""Where the declarative content folders (``scenes/``, ``profiles/``, ``sensors/``, ``baselines/``,
``benchmark/``) live.

In a wheel they are packaged as ``simlidar/_content/<name>``; in a source checkout (and an
editable install) they are the top-level folders beside the package.
"""

import math
import re
import stat
import tomllib
from pathlib import Path

from simlidar.errors import ConfigError, shown

_PACKAGE = Path(__file__).resolve().parent


def content_dir(name: str) -> Path:
    """Return the folder of the shipped content ``name`` (``"scenes"``, ``"baselines"``, ...)."""
    packaged = _PACKAGE / "_content" / name
    if packaged.is_dir():
        return packaged
    return _PACKAGE.parent / name


_NAME = re.compile(r"^[a-z0-9][a-z0-9_.-]{0,63}$")
# A name that is used as a file name inside a folder (a scene catalog's layouts, objects and
# surfaces): no folder part, no dots, so "../x/open_road" can never name a file elsewhere
PLAIN_NAME = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_-]{0,63}$")
PLAIN_NAME_RULE = "letters, digits, '_' or '-' (at most 64; a file name without folders)"

_FILE_KINDS = (
    (stat.S_ISREG, "a regular file"),
    (stat.S_ISDIR, "a folder"),
    (stat.S_ISLNK, "a link"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISFIFO, "a named pipe"),
    (stat.S_ISSOCK, "a socket"),
)


def file_kind(mode: int) -> str:
    """What a ``stat`` mode says an entry is, with its article: "a regular file", "a folder",
    "a link" (from ``lstat``), "a named pipe", ..."""
    return next((name for test, name in _FILE_KINDS if test(mode)), "a special file")


def read_named_toml(path: Path, where: str, what: str, max_bytes: int) -> dict:
    """The parsed TOML of a content file (a profile, a sensor) whose stem becomes part of
    dataset names; ConfigError starting with ``where`` for a bad name, a missing, oversized,
    unreadable or non-TOML file. ``what`` names the kind of file in the size message."""
    if not _NAME.match(path.stem):
        raise ConfigError(
            f"{where}: file name {path.stem!r}: expected lower-case letters, "
            "digits, '_', '-' or '.' (it becomes part of dataset names)"
        )
    try:
        if not path.is_file():
            raise ConfigError(f"{where}: file not found")
        if path.stat().st_size > max_bytes:
            raise ConfigError(
                f"{where}: {path.stat().st_size} bytes: expected {what} of at most "
                f"{max_bytes} bytes"
            )
        return tomllib.loads(path.read_bytes()[:max_bytes].decode("utf-8"))
    except UnicodeDecodeError:
        raise ConfigError(f"{where}: expected a UTF-8 TOML text file") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{where}: not valid TOML ({exc})") from None
    except OSError as exc:
        raise ConfigError(f"{where}: cannot read ({exc.strerror})") from None


def key_error(where: str, key: str, expected: str, got) -> ConfigError:
    """The one-line error for a bad ``key`` of a content file: what was expected, what came."""
    return ConfigError(f"{where}: key '{key}': expected {expected}, got {shown(got)}")


def finite_number(value) -> bool:
    """A TOML int or float that is finite (booleans are not numbers here); an integer too
    large for a float (``1`` followed by 400 zeros) is not: every user of such a number takes
    it as a float."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return False
    try:
        return math.isfinite(value)
    except OverflowError:  # an int beyond 1.8e308
        return False
