"""Extracting a dataset archive from elsewhere (``simlidar fetch``), everything bounded before
it is read: tar's extension headers by their declared sizes before tarfile reads them into
memory (:class:`_BoundedHeader`), the members by their count, names and sizes as the list is
read, and the disk by the room it keeps free. Every refusal is a :class:`FetchError` naming
its step."""

import os
import tarfile
import threading
import zlib
from pathlib import Path

from simlidar.errors import DatasetError, shown
from simlidar.resources import free_disk, size_text

# the most members an archive may hold: a dataset is a handful of files (two splits, card,
# Croissant, preview, SHA256SUMS) plus its shards, a few hundred at the default 250,000 samples
# a shard; past this the archive is refused before more of its member list is read (300,000
# empty members took 206 MB and 26 s)
MAX_MEMBERS = 10_000
# Linux's PATH_MAX (<linux/limits.h>, with the final NUL): no longer path can be opened, so no
# longer member name or link target can be extracted, and a GNU long-name header may declare
# no more
PATH_MAX = 4096
NAME_MAX = 255  # the longest name of one folder level (ext4, XFS, btrfs)
# the most bytes one pax header may declare (tarfile reads it whole, then parses it): a path
# and a link path of PATH_MAX each, times to the nanosecond, owner names and the extended
# attributes bsdtar stores for a file from macOS take a few KiB
MAX_PAX_BYTES = 1 << 16
# the most pax records all members together may carry, each counted as its text and the
# _PAX_RECORD_BYTES of Python objects tarfile keeps it in; global records count once for each
# member, as tarfile copies them into each. A dataset's archive carries none (pack) or a few
# per member (GNU tar's times: about 400 bytes so counted; 4 MB for MAX_MEMBERS members).
# Without it, 10,000 members each after a pax header of 64 KiB of short records held 3.4 GB
# for 168 s, and one global header of 64 KiB before 10,000 empty members (an archive of
# 110 KB) 1 GB for 22 s
MAX_PAX_TOTAL = 1 << 24
# a record's Python objects besides its text, rounded up: measured 75 bytes (a dict entry, the
# headers of two strings), 34 for a global record's copy
_PAX_RECORD_BYTES = 100
# the most extension headers before one member: GNU tar writes at most a long name and a long
# link, pax writers a global and an extended header; tarfile follows a chain by recursion
MAX_HEADER_CHAIN = 8
# what a download or an extraction leaves free on its disk, checked every ROOM_EVERY bytes: a
# disk filled to its last byte fails the other programs writing there (logs, a database's
# journal) before this one notices; the gap between the two bounds how far below the reserve
# a download can go between checks
MIN_FREE_BYTES = 1 << 26
ROOM_EVERY = 1 << 23


class FetchError(DatasetError):
    """A step of ``fetch`` failed; the message names the step."""

    def __init__(self, step: str, message: str):
        super().__init__(f"fetch failed at {step}: {message}")
        self.step = step


def check_room(folder: Path, nbytes: int, step: str, what: str) -> None:
    """Refuse, as a FetchError of ``step``, to write ``nbytes`` more into ``folder`` when that
    would leave less than MIN_FREE_BYTES free on its disk; ``what`` says what they are."""
    free = free_disk(folder)
    if nbytes + MIN_FREE_BYTES > free:
        raise FetchError(
            step,
            f"{what}, {size_text(free)} free in {folder}; expected room for it and "
            f"{size_text(MIN_FREE_BYTES)} to spare (free some space, or choose another --out)",
        )


# the extension headers tarfile reads into memory whole: what each is, and the most it may declare
_HEADER_BOUNDS = {
    tarfile.GNUTYPE_LONGNAME: ("GNU long-name", PATH_MAX),
    tarfile.GNUTYPE_LONGLINK: ("GNU long-link", PATH_MAX),
    tarfile.XHDTYPE: ("pax", MAX_PAX_BYTES),
    tarfile.XGLTYPE: ("pax global", MAX_PAX_BYTES),
    tarfile.SOLARIS_XHDTYPE: ("Solaris pax", MAX_PAX_BYTES),
}


def _sparse() -> FetchError:
    return FetchError("extract", "a sparse file; expected only files and folders")


class _BoundedHeader(tarfile.TarInfo):
    """A tar member whose headers are checked before tarfile acts on them: an extension header
    (long name, long link, pax) declaring more than its bound in ``_HEADER_BOUNDS``, or a chain
    of more than MAX_HEADER_CHAIN of them, is refused before its payload is read (tarfile reads
    a header's whole declared size into memory: a 74-byte archive declaring 1 GiB took 1 GiB),
    and so are sparse files, whose maps tarfile reads without a bound."""

    _chain = threading.local()  # how many headers deep the current member's reading is

    @classmethod
    def fromtarfile(cls, tar):
        depth = getattr(cls._chain, "depth", 0)
        if depth >= MAX_HEADER_CHAIN:
            raise FetchError(
                "extract",
                f"more than {MAX_HEADER_CHAIN} extension headers before one member; expected a "
                "few (a long name, a long link, pax headers)",
            )
        cls._chain.depth = depth + 1
        try:
            return super().fromtarfile(tar)
        finally:
            cls._chain.depth = depth

    @classmethod
    def frombuf(cls, buf, encoding, errors):
        info = super().frombuf(buf, encoding, errors)
        if info.type == tarfile.GNUTYPE_SPARSE:
            raise _sparse()
        what, bound = _HEADER_BOUNDS.get(info.type, ("", None))
        if bound is not None and info.size > bound:
            raise FetchError(
                "extract", f"a {what} header of {info.size} bytes; expected at most {bound}"
            )
        return info

    # where tarfile reads the sparse maps that pax headers announce (private to tarfile; the
    # test of a sparse map of 1,000,000 entries fails if a new Python renames them)
    def _proc_gnusparse_00(self, *args):
        raise _sparse()

    _proc_gnusparse_01 = _proc_gnusparse_10 = _proc_gnusparse_00


def _check_name(name: str) -> None:
    """Refuse a member name that no file system call would take: longer than PATH_MAX bytes,
    or with a level longer than NAME_MAX."""
    size = len(name.encode("utf-8", "surrogateescape"))
    longest = max((len(p.encode("utf-8", "surrogateescape")) for p in name.split("/")), default=0)
    if size >= PATH_MAX or longest > NAME_MAX:
        raise FetchError(
            "extract",
            f"member {shown(name)}: a name of {size} bytes, a level of {longest}; expected "
            f"under {PATH_MAX} and at most {NAME_MAX}",
        )


def safe_extract(archive: Path, target: Path, max_bytes: int) -> Path:
    """Extract a dataset archive into ``target``; return the one top-level folder.

    Refused, each before more of the archive is read: extension headers past their bounds
    (:class:`_BoundedHeader`), more than :data:`MAX_MEMBERS` members, names longer than
    PATH_MAX or NAME_MAX, more than ``max_bytes`` unpacked. Then absolute paths, ``..``, links
    and anything but files and folders, more than one top-level folder, and more than the
    disk can hold with MIN_FREE_BYTES to spare.
    """
    damaged = (tarfile.TarError, OSError, EOFError, zlib.error)
    try:
        tar = tarfile.open(archive, "r:gz", tarinfo=_BoundedHeader)
    except damaged as exc:
        raise FetchError("extract", f"not a .tar.gz archive ({exc})") from None
    with tar:
        members, total, pax = [], 0, 0
        try:
            for member in tar:  # read lazily: stop at a bound, before the next member is read
                members.append(member)
                if len(members) > MAX_MEMBERS:
                    raise FetchError(
                        "extract",
                        f"more than {MAX_MEMBERS} members; expected a dataset's few files",
                    )
                _check_name(member.name)
                pax += sum(
                    len(k) + len(v) + _PAX_RECORD_BYTES for k, v in member.pax_headers.items()
                )
                if pax > MAX_PAX_TOTAL:
                    raise FetchError(
                        "extract",
                        f"pax records of more than {MAX_PAX_TOTAL} bytes in the first "
                        f"{len(members)} members; expected a few per member",
                    )
                total += member.size
                if total > max_bytes:
                    raise FetchError(
                        "extract", f"{total} bytes unpacked, more than the limit {max_bytes}"
                    )
        except damaged as exc:
            raise FetchError("extract", f"damaged archive ({exc})") from None
        tops = set()
        for m in members:
            parts = Path(m.name).parts  # "./a/b" -> ("a", "b"); "./" -> ()
            if not parts:
                continue
            if m.name.startswith("/") or os.path.isabs(m.name) or ".." in parts:
                raise FetchError("extract", f"member {shown(m.name)} would land outside the target")
            if not (m.isfile() or m.isdir()):
                raise FetchError("extract", f"member {shown(m.name)} is a link or special file")
            tops.add(parts[0])
        if len(tops) != 1:
            raise FetchError("extract", f"expected one top-level folder, got {shown(sorted(tops))}")
        check_room(target.parent, total, "extract", f"{size_text(total)} to unpack")
        try:
            tar.extractall(target, members=members, filter="data")
        except damaged as exc:
            raise FetchError("extract", f"{exc.__class__.__name__}: {exc}") from None
    return target / tops.pop()
