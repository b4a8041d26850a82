"""Publishing and downloading datasets: ``simlidar pack`` and ``simlidar fetch``.

``pack`` writes a reproducible ``.tar.gz`` (sorted members, no owners, no timestamps) and its
``.sha256``. ``fetch`` downloads an archive, checks its checksum, extracts it safely, verifies
the dataset and only then moves it into place; a failure at any step removes what it wrote and
says which step failed.
"""

import gzip
import http.client
import os
import re
import shutil
import tarfile
import tempfile
import urllib.error
import urllib.parse
import urllib.request
from pathlib import Path

from simlidar.atomic import Temporary, claim_folder
from simlidar.errors import ConfigError, DatasetError
from simlidar.release.checksums import is_os_litter, is_sha256, sha256_file
from simlidar.release.verify import verify

DEFAULT_MAX_BYTES = 20 * 2**30  # refuse archives that unpack to more than this
MAX_TIMEOUT_S = 86_400.0  # one day: the longest wait for the server that makes sense
TIMEOUT_S = 30.0  # the default wait for the server
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
    out.mkdir(parents=True, exist_ok=True)
    archive = out / f"{path.name}.tar.gz"
    files = sorted(p for p in path.iterdir() if p.is_file() and not is_os_litter(p.name))
    fd, name = tempfile.mkstemp(prefix=f".{archive.name}.partial-", dir=out)  # unique
    tmp = Path(name)
    try:
        with os.fdopen(fd, "wb") as raw:
            os.fchmod(raw.fileno(), 0o644)  # mkstemp's 0600 would keep a published one private
            with (
                gzip.GzipFile(filename="", mode="wb", fileobj=raw, mtime=0) as gz,
                tarfile.open(fileobj=gz, mode="w", format=tarfile.PAX_FORMAT) as tar,
            ):
                tar.addfile(_info(path.name, tarfile.DIRTYPE, 0))
                for file in files:
                    size = file.stat().st_size
                    with open(file, "rb") as f:
                        tar.addfile(_info(f"{path.name}/{file.name}", tarfile.REGTYPE, size), f)
        tmp.replace(archive)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    checksum = archive.with_name(archive.name + ".sha256")
    checksum.write_text(f"{sha256_file(archive)}  {archive.name}\n")
    return archive, checksum


def _info(name: str, kind: bytes, size: int) -> tarfile.TarInfo:
    """A tar member without owner, group or time, so that the archive is reproducible."""
    info = tarfile.TarInfo(name)
    info.type, info.size, info.mtime = kind, size, 0
    info.mode = 0o755 if kind == tarfile.DIRTYPE else 0o644
    info.uid = info.gid = 0
    info.uname = info.gname = ""
    return info


class FetchError(DatasetError):
    """A step of ``fetch`` failed; the message names the step."""

    def __init__(self, step: str, message: str):
        super().__init__(f"fetch failed at {step}: {message}")
        self.step = step


def _download(url: str, target: Path, timeout: float, progress: bool) -> None:
    from tqdm import tqdm

    try:
        with urllib.request.urlopen(url, timeout=timeout) as response:  # noqa: S310
            expected = response.headers.get("Content-Length")
            expected = int(expected) if expected is not None else None
            received = 0
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
                while block := response.read(_CHUNK):
                    f.write(block)
                    received += len(block)
                    bar.update(len(block))
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
        with urllib.request.urlopen(url + ".sha256", timeout=timeout) as response:  # noqa: S310
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


def safe_extract(archive: Path, target: Path, max_bytes: int) -> Path:
    """Extract a dataset archive into ``target``; return the one top-level folder.

    Refused: absolute paths, ``..``, links and anything but files and folders, more than one
    top-level folder, and more than ``max_bytes`` unpacked.
    """
    try:
        tar = tarfile.open(archive, "r:gz")
    except (tarfile.TarError, OSError) as exc:
        raise FetchError("extract", f"not a .tar.gz archive ({exc})") from None
    with tar:
        try:
            members = tar.getmembers()
        except (tarfile.TarError, OSError, EOFError) as exc:
            raise FetchError("extract", f"damaged archive ({exc})") from None
        tops, total = set(), 0
        for m in members:
            parts = Path(m.name).parts  # "./a/b" -> ("a", "b"); "./" -> ()
            if not parts:
                continue
            if m.name.startswith("/") or os.path.isabs(m.name) or ".." in parts:
                raise FetchError("extract", f"member {m.name!r} would land outside the target")
            if not (m.isfile() or m.isdir()):
                raise FetchError("extract", f"member {m.name!r} is a link or special file")
            tops.add(parts[0])
            total += m.size
        if len(tops) != 1:
            raise FetchError("extract", f"expected one top-level folder, got {sorted(tops)}")
        if total > max_bytes:
            raise FetchError("extract", f"{total} bytes unpacked, more than the limit {max_bytes}")
        try:
            tar.extractall(target, filter="data")
        except (OSError, tarfile.TarError) as exc:
            raise FetchError("extract", f"{exc.__class__.__name__}: {exc}") from None
    return target / tops.pop()


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
    (:mod:`simlidar.atomic`), removed at the end whatever happens; those of killed runs
    are removed by the next run in ``out`` (a warning each). ``out`` itself is removed again if
    this call created it and nothing was installed.
    """
    if sha256 is not None and not is_sha256(sha256):
        raise FetchError("checksum", f"--sha256 {sha256!r}: expected 64 hexadecimal digits")
    timeout = check_timeout(timeout)
    out = Path(out)
    created = claim_folder(out)
    work = None
    try:
        work = Temporary(out, _work_name(url), "fetch")
        archive = work.path / "archive.tar.gz"
        _download(url, archive, timeout, progress)
        expected = (sha256 or _sidecar_sha256(url, timeout)).lower()
        actual = sha256_file(archive)
        if actual != expected:
            raise FetchError("checksum", f"sha256 {actual} does not match {expected}")
        folder = safe_extract(archive, work.path / "extracted", max_bytes)
        try:
            _checked(folder)
        except DatasetError as exc:
            raise FetchError("verify", str(exc)) from None
        final = out / folder.name
        if final.exists():
            if not force:
                raise FetchError("install", f"{final} already exists: pass --force to replace")
            shutil.rmtree(final)
        folder.rename(final)
        return final
    finally:
        if work is not None:
            work.release()
        if created and out.is_dir() and not any(out.iterdir()):
            out.rmdir()
