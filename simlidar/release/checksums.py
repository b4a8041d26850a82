"""``SHA256SUMS``: the checksum of every file of a dataset directory (``sha256sum -c`` format)."""

import hashlib
from pathlib import Path

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
    """Names of the files a dataset directory's checksums cover: all but SHA256SUMS itself
    and operating-system litter (:func:`is_os_litter`)."""
    return sorted(
        p.name
        for p in path.iterdir()
        if p.is_file() and p.name != SUMS and not is_os_litter(p.name)
    )


def write_sums(path: Path, names: list[str] | None = None) -> None:
    """(Re)write SHA256SUMS; with ``names``, refresh only those lines and keep the others."""
    sums = read_sums(path) if names is not None and (path / SUMS).exists() else {}
    for name in names if names is not None else dataset_files(path):
        sums[name] = sha256_file(path / name)
    lines = [f"{digest}  {name}\n" for name, digest in sorted(sums.items())]
    (path / SUMS).write_text("".join(lines))


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
    """Problems with the checksums of a dataset directory (empty when all match)."""
    if not (path / SUMS).is_file():
        return [f"{path / SUMS}: missing"]
    try:
        sums = read_sums(path)
    except ValueError as exc:
        return [str(exc)]
    problems = []
    for name, digest in sums.items():
        if not (path / name).is_file():
            problems.append(f"{path / name}: listed in {SUMS} but missing")
        elif sha256_file(path / name) != digest:
            problems.append(f"{path / name}: sha256 does not match {SUMS}")
    for name in dataset_files(path):
        if name not in sums:
            problems.append(f"{path / name}: not listed in {SUMS}")
    return problems
