"""``SHA256SUMS``: the checksum of every file of a dataset directory (``sha256sum -c`` format)."""

import hashlib
import stat
from pathlib import Path

from simlidar.atomic import write_file
from simlidar.dataset.storage import entry_problem
from simlidar.errors import DatasetError

SUMS = "SHA256SUMS"
_BLOCK = 1 << 20
# Files that file managers drop into any folder they show (macOS Finder, Windows Explorer):
# never part of a dataset, ignored by the checksums and left out of archives. Compared in
# lower case (Windows names are case-insensitive); ``._*`` are macOS AppleDouble files.
OS_LITTER = frozenset({".ds_store", "thumbs.db", "desktop.ini"})


def is_os_litter(name: str) -> bool:
    """Whether a file name is operating-system litter (:data:`OS_LITTER` or ``._*``)."""
    return name.lower() in OS_LITTER or name.startswith("._")


def is_sha256(text: str) -> bool:
    """Whether ``text`` is a hex sha256 digest (64 hexadecimal digits, any case)."""
    return len(text) == 64 and all(c in "0123456789abcdefABCDEF" for c in text)


def sha256_file(path: str | Path) -> str:
    """Hex sha256 of a file, read in 1 MiB blocks."""
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        while block := f.read(_BLOCK):
            digest.update(block)
    return digest.hexdigest()


def dataset_files(path: Path) -> list[str]:
    """Names of the files a dataset directory's checksums cover: its regular files (never a
    link, whatever it points to) but SHA256SUMS itself and operating-system litter
    (:func:`is_os_litter`)."""
    return sorted(
        p.name
        for p in path.iterdir()
        if _is_regular(p) and p.name != SUMS and not is_os_litter(p.name)
    )


def _is_regular(path: Path) -> bool:
    """A regular file itself, not a link to one (``lstat``)."""
    try:
        return stat.S_ISREG(path.lstat().st_mode)
    except OSError:
        return False


def stray_entries(path: Path) -> list[str]:
    """Problems of the entries of a dataset directory that are not regular files: a link (it
    would be read, hashed and packed as the file it points to), a folder (a dataset has none:
    ``payload/run_me.sh`` would travel with it unchecked), a pipe, a socket, a device
    (:func:`~simlidar.dataset.storage.entry_problem`, which the readers apply to split files).
    Operating-system litter is allowed as a regular file only."""
    return [p for p in map(entry_problem, sorted(path.iterdir())) if p is not None]


def write_sums(path: Path, names: list[str] | None = None) -> None:
    """(Re)write SHA256SUMS; with ``names``, refresh only those lines and keep the others. The
    file is replaced, never written through (a link stays what it pointed to); a file that is
    not a regular file of ``path`` is never hashed (DatasetError)."""
    sums = read_sums(path) if names is not None and (path / SUMS).exists() else {}
    for name in names if names is not None else dataset_files(path):
        if not _is_regular(path / name):
            raise DatasetError(f"{path / name}: expected a regular file (not a link) to hash")
        sums[name] = sha256_file(path / name)
    text = "".join(f"{digest}  {name}\n" for name, digest in sorted(sums.items()))
    write_text(path / SUMS, text)


def write_text(path: Path, text: str) -> Path:
    """Replace the file ``path`` with ``text`` (:func:`simlidar.atomic.write_file`: a
    temporary renamed over it, so a link there is replaced, never written through), with the
    mode of a file written in place (0666 less the umask: 0644 as a rule)."""
    return write_file(path, lambda tmp: tmp.write_text(text))


def read_sums(path: Path) -> dict[str, str]:
    """``{file name: hex digest}`` from SHA256SUMS; malformed lines raise ValueError."""
    sums = {}
    try:
        text = (path / SUMS).read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        message = f"{path / SUMS}: not UTF-8 text ({exc.reason} at byte {exc.start})"
        raise ValueError(f"{message}; expected '<sha256>  <file name>' lines") from None
    for number, line in enumerate(text.splitlines(), 1):
        digest, sep, name = line.partition("  ")
        if not sep or len(digest) != 64 or not name or "/" in name:
            raise ValueError(f"{path / SUMS}: line {number} is not '<sha256>  <file name>'")
        sums[name] = digest
    return sums


def check_sums(path: Path) -> list[str]:
    """Problems with the checksums of a dataset directory (empty when all match), and with
    its entries: every one a regular file listed in SHA256SUMS (:func:`stray_entries`)."""
    stray = stray_entries(path)
    if not (path / SUMS).is_file() or not _is_regular(path / SUMS):
        return stray + [f"{path / SUMS}: missing"] * (not (path / SUMS).is_symlink())
    try:
        sums = read_sums(path)
    except ValueError as exc:
        return stray + [str(exc)]
    problems = []
    for name, digest in sums.items():
        if (path / name).is_symlink():
            continue  # named by stray_entries; never hashed through
        if not (path / name).is_file():
            problems.append(f"{path / name}: listed in {SUMS} but missing")
        elif sha256_file(path / name) != digest:
            problems.append(f"{path / name}: sha256 does not match {SUMS}")
    for name in dataset_files(path):
        if name not in sums:
            problems.append(f"{path / name}: not listed in {SUMS}")
    return stray + problems
