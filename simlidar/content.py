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


def shipped_or_path(name_or_path: str | Path, folder: str, kind: str, other: str = "") -> Path:
    """The file a user named: a bare name (no ``/`` and no ``.toml``) is ``<folder>/<name>.toml``
    of the shipped content ``folder`` (a ConfigError ``<kind> '<name>': expected one of [...]
    or a .toml file<other>`` when there is none); anything else is a path, read as such. The one
    rule for profiles, sensors, model recipes and suites."""
    text = str(name_or_path)
    if "/" in text or text.endswith(".toml"):
        return Path(text)
    path = content_dir(folder) / f"{text}.toml"
    if not path.is_file():
        names = sorted(p.stem for p in content_dir(folder).glob("*.toml"))
        raise ConfigError(f"{kind} {text!r}: expected one of {names} or a .toml file{other}")
    return path


def read_text(path: Path, max_bytes: int, error=ConfigError, where: str | None = None) -> str:
    """The text of a file from elsewhere: a regular file (or a link to one) of at most
    ``max_bytes`` bytes of UTF-8; never reads more than ``max_bytes`` + 1 bytes, and never
    opens a named pipe or a device (which could hang or never end). Any problem is an
    ``error`` (a :class:`~simlidar.errors.SimlidarError` class) starting with ``where``
    (default: the path): not found, not a regular file, too large, not UTF-8."""
    where = where or str(path)
    try:
        mode = path.stat().st_mode
        if not stat.S_ISREG(mode):
            kind = file_kind(mode)
            target = f" ({path.resolve()})" if path.is_symlink() else ""
            raise error(f"{where}: expected a regular file, got {kind}{target}")
        with path.open("rb") as f:
            data = f.read(max_bytes + 1)
    except FileNotFoundError:
        raise error(f"{where}: file not found") from None
    except (OSError, ValueError) as exc:  # ValueError: a NUL character in the path
        raise error(f"{where}: cannot read the file ({exc})") from None
    if len(data) > max_bytes:
        size = max(len(data), path.stat().st_size)
        raise error(f"{where}: expected a file of at most {max_bytes} bytes, got {size} bytes")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise error(
            f"{where}: expected UTF-8 text, got byte 0x{data[exc.start]:02x} at offset {exc.start}"
        ) from None


def read_toml(path: Path, max_bytes: int, error=ConfigError, where: str | None = None) -> dict:
    """Parse a TOML file read by :func:`read_text` (the same checks and errors); not TOML, or
    nested too deeply, is an ``error`` too."""
    where = where or str(path)
    text = read_text(path, max_bytes, error, where)
    try:
        return tomllib.loads(text)
    except RecursionError:
        raise error(f"{where}: not valid TOML (arrays or tables nested too deeply)") from None
    except ValueError as exc:  # TOMLDecodeError, or an integer of more than 4300 digits
        raise error(f"{where}: not valid TOML ({exc})") from None


def read_named_toml(path: Path, where: str, max_bytes: int) -> dict:
    """:func:`read_toml` of a content file (a profile, a sensor) whose stem becomes part of
    dataset names, so the name is checked first; ConfigError starting with ``where``."""
    if not _NAME.match(path.stem):
        raise ConfigError(
            f"{where}: file name {path.stem!r}: expected lower-case letters, "
            "digits, '_', '-' or '.' (it becomes part of dataset names)"
        )
    return read_toml(path, max_bytes, ConfigError, where)


def key_error(where: str, key: str, expected: str, got) -> ConfigError:
    """The one-line error for a bad ``key`` of a content file: what was expected, what came."""
    return ConfigError(f"{where}: key '{key}': expected {expected}, got {shown(got)}")


def check_keys(where: str, data: dict, keys, optional=()) -> None:
    """Refuse a content file's table ``data`` holding a key not in ``keys``, or missing one of
    ``keys`` that is not ``optional``: a one-line ConfigError starting with ``where``."""
    for key in data:
        if key not in keys:
            raise key_error(where, key, f"one of {sorted(keys)}", key)
    for key in keys:
        if key not in data and key not in optional:
            raise ConfigError(f"{where}: key '{key}' is missing")


# Characters of a content file's free text: the text is stored in every file made from the
# content and quoted in its errors (the rpm error quotes a sensor's model and manual), so it is
# one short line. The longest shipped: 19 (the HDL-64E S2's model), 82 (the HDL-32E's manual
# citation), 16 (a receiver's dual_when_strongest_is_last).
TEXT_CHARS = {"model": 100, "manual": 200, "dual_when_strongest_is_last": 100}


def checked_text(where: str, key: str, value) -> str:
    """``value`` of a content file's free-text ``key`` (a model's name, a citation): a string
    that is not blank, of at most ``TEXT_CHARS[key]`` characters, printable on one line; a
    one-line ConfigError naming the key otherwise."""
    limit = TEXT_CHARS[key]
    if not (
        isinstance(value, str) and len(value) <= limit and value.strip() and value.isprintable()
    ):
        raise key_error(
            where, key, f"a non-empty line of text of at most {limit} characters", value
        )
    return value


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
