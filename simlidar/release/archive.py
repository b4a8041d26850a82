"""Publishing and downloading datasets: ``simlidar pack`` and ``simlidar fetch``.

``pack`` writes a reproducible ``.tar.gz`` (sorted members, no owners, no timestamps) and its
``.sha256``. ``fetch`` downloads an archive, checks its checksum, extracts it safely, verifies
the dataset and only then moves it into place; a failure at any step removes what it wrote and
says which step failed.

A fetched archive installs only under the dataset's own name: the one folder it holds must be
named as its ``croissant.json`` names the dataset (a file its SHA256SUMS covers), and as the
URL's ``<name>.tar.gz`` where the URL ends in one. ``--force`` replaces only a folder that is a
simlidar dataset of that name (its SHA256SUMS, split files and ``croissant.json`` naming it),
and in one step (:func:`simlidar.atomic.install`): a kill leaves the old dataset or the new one,
never neither.

Nothing is read before it is bounded: the download by :func:`archive_limit` and the free disk
space, whether or not the server sends a length; the archive's headers and members as it is
extracted (:mod:`simlidar.release.untar`). SIGTERM and SIGINT remove the work folder as an
error does.
"""

import gzip
import http.client
import json
import os
import re
import tarfile
import time
import urllib.error
import urllib.parse
import urllib.request
from pathlib import Path

from simlidar.atomic import (
    Temporary,
    claim_folder,
    install,
    stopped_by_signals,
    uninterrupted,
    write_files,
)
from simlidar.dataset.schema import SPLITS
from simlidar.dataset.shards import find_split_files
from simlidar.errors import ConfigError, DatasetError
from simlidar.release.checksums import SUMS, is_os_litter, is_sha256, sha256_file
from simlidar.release.croissant import CROISSANT
from simlidar.release.untar import (
    MAX_MEMBERS,
    PATH_MAX,
    ROOM_EVERY,
    FetchError,
    check_room,
    safe_extract,
)
from simlidar.release.verify import verify
from simlidar.resources import size_text

DEFAULT_MAX_BYTES = 20 * 2**30  # refuse archives that unpack to more than this
MAX_TIMEOUT_S = 86_400.0  # one day: the longest wait for the server that makes sense
TIMEOUT_S = 30.0  # the default wait for the server
# a download slower than this over any --timeout window fails (curl's --speed-limit): each wait
# is bounded by the timeout, and this bounds the whole, so a server trickling a byte a second
# cannot hold a fetch for hours
MIN_RATE_BPS = 1024
_CHUNK = 1 << 16
_PLAIN_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,99}")


def _checked(path: Path) -> None:
    problems = verify(path)
    if problems:
        more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
        raise DatasetError(f"{problems[0]}{more}")


def pack(path: str | Path, out: str | Path | None = None) -> tuple[Path, Path]:
    """Verify a dataset directory and write ``<dir name>.tar.gz`` and its ``.sha256``.

    The directory name already carries the dataset version (``...-v1.0.0``). Operating-system
    litter (``.DS_Store``, ``Thumbs.db``, ``desktop.ini``, ``._*``) is left out. Returns the
    paths of the archive and of its checksum file.
    """
    path = Path(path)
    _checked(path)
    out = Path(out) if out is not None else path.parent
    if out.resolve() == path.resolve() or path.resolve() in out.resolve().parents:
        raise DatasetError(f"--out {out}: expected a folder outside the dataset {path}")
    links = [p.name for p in path.iterdir() if p.is_symlink()]
    if links:  # never pack what a link points at (a secret of the packer's, say)
        raise DatasetError(f"{path / links[0]}: a symbolic link; expected only regular files")
    claim_folder(out)  # also removes the temporaries of packs that were killed
    archive = out / f"{path.name}.tar.gz"
    checksum = archive.with_name(archive.name + ".sha256")
    files = sorted(p for p in path.iterdir() if p.is_file() and not is_os_litter(p.name))

    def write(temporaries: list[Path]) -> None:
        tmp, tmp_sum = temporaries
        with (
            open(tmp, "wb") as raw,
            gzip.GzipFile(filename="", mode="wb", fileobj=raw, mtime=0) as gz,
            tarfile.open(fileobj=gz, mode="w", format=tarfile.PAX_FORMAT) as tar,
        ):
            tar.addfile(_info(path.name, tarfile.DIRTYPE, 0))
            for file in files:
                with open(file, "rb", opener=_no_follow) as f:
                    size = os.fstat(f.fileno()).st_size
                    tar.addfile(_info(f"{path.name}/{file.name}", tarfile.REGTYPE, size), f)
        tmp_sum.write_text(f"{sha256_file(tmp)}  {archive.name}\n")

    # both complete before either is in place (a full disk leaves neither), readable by all
    write_files([archive, checksum], write, mode=0o644)
    return archive, checksum


def _no_follow(name: str, flags: int) -> int:
    """``open``'s opener that refuses a link swapped in after the check (ELOOP)."""
    return os.open(name, flags | os.O_NOFOLLOW)


def _info(name: str, kind: bytes, size: int) -> tarfile.TarInfo:
    """A tar member without owner, group or time, so that the archive is reproducible."""
    info = tarfile.TarInfo(name)
    info.type, info.size, info.mtime = kind, size, 0
    info.mode = 0o755 if kind == tarfile.DIRTYPE else 0o644
    info.uid = info.gid = 0
    info.uname = info.gname = ""
    return info


def archive_limit(max_bytes: int) -> int:
    """The most bytes a ``.tar.gz`` whose members unpack to at most ``max_bytes`` can take: the
    download's bound. Deflate adds at most n/4096 + n/16384 + 18 bytes to n bytes it cannot
    compress (zlib's ``deflateBound``), under ``max_bytes // 1024``; tar adds a 512-byte
    header, up to 511 bytes of padding and, for a long name, a header of 512 bytes and its up
    to PATH_MAX bytes to each of at most MAX_MEMBERS members, then 10 KiB of end blocks."""
    return max_bytes + max_bytes // 1024 + MAX_MEMBERS * (2 * 512 + PATH_MAX + 512) + 10 * 1024


def check_url(url: str) -> str:
    """``url`` if it is an http(s) URL with a host; a FetchError naming it otherwise (``file://``
    and ``ftp://`` are not downloads, ``http://[::1`` does not parse)."""
    try:
        parts = urllib.parse.urlsplit(url)
        parts.port  # noqa: B018 (raises ValueError for a port out of range)
    except ValueError as exc:
        raise FetchError("download", f"{url!r}: not a URL ({exc})") from None
    if parts.scheme.lower() not in ("http", "https") or not parts.hostname:
        raise FetchError("download", f"{url!r}: expected an http:// or https:// URL with a host")
    return url


def _download(url: str, target: Path, timeout: float, progress: bool, limit: int) -> None:
    """Write what ``url`` sends into ``target``: at most ``limit`` bytes (a longer length the
    server announces is refused before reading), while the disk keeps MIN_FREE_BYTES free."""
    from tqdm import tqdm

    try:
        with urllib.request.urlopen(url, timeout=timeout) as response:
            expected = response.headers.get("Content-Length")
            expected = int(expected) if expected is not None else None
            if expected is not None and expected > limit:
                raise FetchError(
                    "download",
                    f"{url}: the server announces {expected} bytes, more than the limit {limit}",
                )
            size = "of unknown size" if expected is None else f"of {size_text(expected)}"
            check_room(target.parent, expected or 0, "download", f"{url}: a download {size}")
            received, room_checked = 0, 0
            with (
                open(target, "wb") as f,
                tqdm(
                    total=expected,
                    unit="B",
                    unit_scale=True,
                    desc="download",
                    disable=not progress,
                    leave=False,
                ) as bar,
            ):
                window_start, window_bytes = time.monotonic(), 0
                while block := response.read1(_CHUNK):  # returns what one wait brought
                    received += len(block)
                    if received > limit:  # without a length: http.client stops at one
                        raise FetchError(
                            "download", f"{url}: more than the limit of {limit} bytes received"
                        )
                    if received - room_checked >= ROOM_EVERY:
                        rest = expected - received if expected is not None else 0
                        more = (
                            "no length given" if expected is None else f"{size_text(rest)} to come"
                        )
                        what = f"{url}: {size_text(received)} received, {more}"
                        check_room(target.parent, rest, "download", what)
                        room_checked = received
                    f.write(block)
                    window_bytes += len(block)
                    bar.update(len(block))
                    elapsed = time.monotonic() - window_start
                    if elapsed >= timeout:
                        if window_bytes < MIN_RATE_BPS * elapsed:
                            raise FetchError(
                                "download",
                                f"{url}: {window_bytes} bytes in {elapsed:.0f} s, slower than "
                                f"{MIN_RATE_BPS} bytes/s",
                            )
                        window_start, window_bytes = time.monotonic(), 0
    except urllib.error.HTTPError as exc:
        raise FetchError("download", f"{url}: HTTP {exc.code} {exc.reason}") from None
    except urllib.error.URLError as exc:
        reason = exc.reason
        if isinstance(reason, TimeoutError):
            reason = f"no answer within {timeout:g} s"
        raise FetchError("download", f"{url}: {reason}") from None
    except TimeoutError:
        raise FetchError("download", f"{url}: no answer within {timeout:g} s") from None
    except ValueError as exc:  # not a URL urllib can open
        raise FetchError("download", f"{url}: {exc}") from None
    except (OSError, http.client.HTTPException) as exc:  # e.g. IncompleteRead
        raise FetchError("download", f"{url}: {exc.__class__.__name__}: {exc}") from None
    if expected is not None and received != expected:
        raise FetchError("download", f"{url}: got {received} of {expected} bytes")


def _sidecar_sha256(url: str, timeout: float) -> str:
    try:
        with urllib.request.urlopen(url + ".sha256", timeout=timeout) as response:
            text = response.read(4096).decode("ascii", "replace")
    except (urllib.error.URLError, OSError) as exc:
        raise FetchError(
            "checksum",
            f"no --sha256 given and {url}.sha256 is not available ({getattr(exc, 'reason', exc)})",
        ) from None
    digest = text.split()[0] if text.split() else ""
    if len(digest) != 64:
        raise FetchError("checksum", f"{url}.sha256 does not hold a sha256 ({text[:40]!r})")
    return digest.lower()


def _own_name(folder: Path, url: str) -> str:
    """The name a verified extracted dataset installs under: its folder's, which must be the
    name its ``croissant.json`` gives and, where the URL ends in ``<name>.tar.gz``, that one
    (an archive cannot choose to land on another folder of ``--out``)."""
    name = folder.name
    if not _PLAIN_NAME.fullmatch(name):
        raise FetchError("install", f"the archive's folder {name!r}: expected a dataset name")
    claimed = _croissant_name(folder)
    if claimed != name:
        raise FetchError(
            "install",
            f"the archive's folder {name!r}: its {CROISSANT} names the dataset {claimed!r}",
        )
    path = urllib.parse.urlsplit(url).path.rsplit("/", 1)[-1]
    if path.endswith(".tar.gz") and path.removesuffix(".tar.gz") != name:
        raise FetchError(
            "install",
            f"the archive's folder {name!r}: expected {path.removesuffix('.tar.gz')!r}, "
            "the name the URL gives",
        )
    return name


def _croissant_name(folder: Path) -> str | None:
    """The dataset name that ``folder``'s ``croissant.json`` gives; None if it has none."""
    file = folder / CROISSANT
    try:
        if file.is_symlink() or not file.is_file() or file.stat().st_size > 1 << 24:
            return None
        name = json.loads(file.read_text(encoding="utf-8")).get("name")
    except (OSError, ValueError, AttributeError):
        return None
    return name if isinstance(name, str) else None


def _is_dataset_named(path: Path, name: str) -> bool:
    """Whether ``path`` is a simlidar dataset directory named ``name`` (what ``--force`` may
    replace): a real folder holding SHA256SUMS, the split files and a Croissant naming it."""
    if path.is_symlink() or not path.is_dir():
        return False
    try:
        has_splits = all(find_split_files(path, split) for split in SPLITS)
    except DatasetError:
        has_splits = True  # a dataset with broken shards is still a dataset
    return has_splits and (path / SUMS).is_file() and _croissant_name(path) == name


def check_timeout(timeout: float) -> float:
    """``timeout`` if it is a number of seconds in (0, MAX_TIMEOUT_S]; ConfigError otherwise
    (inf, NaN or 1e300 would overflow the socket's timer)."""
    if not (isinstance(timeout, int | float) and 0 < timeout <= MAX_TIMEOUT_S):
        raise ConfigError(f"timeout={timeout!r}: expected seconds in (0, {MAX_TIMEOUT_S:g}]")
    return float(timeout)


def _work_name(url: str) -> str:
    """What the temporary folder of a download is named after: the archive's file name if it
    is a plain one, else ``download``."""
    name = urllib.parse.urlsplit(url).path.rsplit("/", 1)[-1].removesuffix(".tar.gz")
    return name if _PLAIN_NAME.fullmatch(name) else "download"


def fetch(
    url: str,
    sha256: str | None = None,
    out: str | Path = ".",
    timeout: float = TIMEOUT_S,
    force: bool = False,
    max_bytes: int = DEFAULT_MAX_BYTES,
    progress: bool = True,
) -> Path:
    """Download, check, extract and verify a dataset archive; return the installed folder.

    The work happens in a locked temporary folder ``out/.<archive name>.fetch-<random>``
    (:mod:`simlidar.atomic`), removed at the end whatever happens, SIGTERM and SIGINT included
    (then an :class:`simlidar.atomic.Interrupted` error); those of runs killed otherwise are
    removed by the next run in ``out`` (a warning each). ``out`` itself is removed again if
    this call created it and nothing was installed.

    url : the archive's address (http or https; ``simlidar pack`` makes such archives)
    sha256 : the archive's expected SHA-256 (64 hex digits); None: the ``<url>.sha256``
        file published beside it
    out : the folder that receives the dataset directory (made if missing)
    timeout : seconds a connection may stay silent
    force : replace an installed dataset directory of the same name (else an error names it)
    max_bytes : the most bytes the archive's members may hold once unpacked; the download
        may take :func:`archive_limit` of it
    progress : a progress bar on stderr
    """
    if sha256 is not None and not is_sha256(sha256):
        raise FetchError("checksum", f"--sha256 {sha256!r}: expected 64 hexadecimal digits")
    timeout = check_timeout(timeout)
    check_url(url)
    with stopped_by_signals(f"fetch {url}"):
        return _fetch(url, sha256, Path(out), timeout, force, max_bytes, progress)


def _fetch(url, sha256, out, timeout, force, max_bytes, progress) -> Path:
    """:func:`fetch`'s work, its arguments checked."""
    created, work = False, None
    try:
        with uninterrupted():  # made and kept in ``work``, so that the end removes it
            created = claim_folder(out)
            work = Temporary(out, _work_name(url), "fetch")
        archive = work.path / "archive.tar.gz"
        _download(url, archive, timeout, progress, archive_limit(max_bytes))
        expected = (sha256 or _sidecar_sha256(url, timeout)).lower()
        actual = sha256_file(archive)
        if actual != expected:
            raise FetchError("checksum", f"sha256 {actual} does not match {expected}")
        folder = safe_extract(archive, work.path / "extracted", max_bytes)
        try:
            _checked(folder)
        except DatasetError as exc:
            raise FetchError("verify", str(exc)) from None
        name = _own_name(folder, url)
        final = out / name
        if final.exists() or final.is_symlink():
            if not _is_dataset_named(final, name):
                raise FetchError(
                    "install",
                    f"{final} exists and is not a simlidar dataset named {name!r}: nothing "
                    "replaced (--force replaces only a dataset of the same name); move it away "
                    "or choose another --out",
                )
            if not force:
                raise FetchError("install", f"{final} already exists: pass --force to replace")
        with uninterrupted():
            claim = Temporary(out, name)
        try:
            claim.path.rmdir()
            folder.rename(claim.path)
            try:
                install(claim, final, force)  # one step; with --force the old one leaves
            except DatasetError as exc:
                raise FetchError("install", str(exc)) from None
        finally:
            claim.release()
        return final
    finally:
        with uninterrupted():
            if work is not None:
                work.release()
            if created and out.is_dir() and not any(out.iterdir()):
                out.rmdir()
