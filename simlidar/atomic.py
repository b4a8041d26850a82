"""Claiming a name in an output folder: locked temporaries, renames that never replace by
accident, and the removal of temporaries left by dead runs.

A run builds under ``out/.<name>.<kind>-<random>`` (``kind``: ``partial``, ``old``, ``fetch``)
and holds an exclusive ``flock`` on the file of the same name plus ``.lock`` for as long as the
temporary exists. The random part comes from ``tempfile`` (no two processes pick the same, even
with equal PIDs in containers sharing a volume). A temporary whose lock can be taken belongs to
a dead run: :func:`clean_stale` removes it, and never touches a live run's (its lock is held).

Installing is one ``renameat2`` call (Linux): ``RENAME_NOREPLACE`` without ``--force``, so a
dataset that appeared under the final name while this run worked is refused, never replaced;
``RENAME_EXCHANGE`` with ``--force``, so the old dataset and the new one swap in one step and
the old one is then removed under this run's lock. Where ``renameat2`` is unavailable the
fallback is ``os.rename`` after an existence check (a narrow race, documented).

Files are written the same way (:func:`write_files`, :func:`write_file`): in a locked temporary
folder beside them, each renamed into place only when every one is complete.

A kill -9 leaves a temporary for the next run to remove; SIGTERM and SIGINT need not:
inside :func:`stopped_by_signals` they raise :class:`Interrupted`, so that the ``finally``
clauses remove the temporaries as on an error, and :func:`uninterrupted` keeps such a signal
from cutting a temporary's making or removal in half.
"""

import ctypes
import errno
import fcntl
import os
import re
import shutil
import signal
import tempfile
import threading
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from simlidar.errors import DatasetError, SimlidarError

_AT_FDCWD = -100
_RENAME_NOREPLACE, _RENAME_EXCHANGE = 1, 2
_TEMP = re.compile(r"^\.(?P<name>.+)\.(?P<kind>partial|old|fetch)-[A-Za-z0-9_]+$")
_LEGACY = re.compile(r"^\.(?P<name>.+)\.(partial|old)-\d+(-\d+)?$")  # simlidar <= 0.1.0: pid


def _libc():
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return libc if hasattr(libc, "renameat2") else None
    except OSError:
        return None


_LIBC = _libc()

_STOP_SIGNALS = (signal.SIGTERM, signal.SIGINT)
# the main thread's state (only it runs Python's signal handlers): how deep it is inside
# uninterrupted() blocks, and the signal that arrived there (one: the rest are ignored), raised
# at the end
_holding = 0
_held: list["_Stop"] = []


class Interrupted(SimlidarError):
    """SIGTERM or SIGINT arrived inside :func:`stopped_by_signals`."""


class _Stop(BaseException):
    """What the handlers of :func:`stopped_by_signals` raise, its argument the signal's name:
    a BaseException as KeyboardInterrupt is, so that no ``except Exception`` on its way
    swallows it (tqdm's does, around starting its monitor thread)."""


def _is_main_thread() -> bool:
    return threading.current_thread() is threading.main_thread()


@contextmanager
def stopped_by_signals(what: str) -> Iterator[None]:
    """Inside the block, SIGTERM and SIGINT raise :class:`Interrupted` ("<what>: stopped by
    SIGTERM; ..."): the ``finally`` clauses that remove temporaries run as on an error, where
    SIGTERM would end the process with them in place and SIGINT show a KeyboardInterrupt
    traceback. Signals after the first are ignored, so that a second Ctrl-C cannot cut the
    removal short; one that arrives inside :func:`uninterrupted` waits for its end. The
    previous handlers come back when the block ends. Only the main thread may set handlers:
    elsewhere the block runs unchanged."""
    if not _is_main_thread():
        yield
        return
    stopping = []

    def stop(signum: int, _frame) -> None:
        if stopping:
            return
        stopping.append(signum)
        if _holding:
            _held.append(_Stop(signal.Signals(signum).name))
        else:
            raise _Stop(signal.Signals(signum).name)

    previous = [(number, signal.signal(number, stop)) for number in _STOP_SIGNALS]
    try:
        yield
    except _Stop as stopped:
        raise Interrupted(
            f"{what}: stopped by {stopped.args[0]}; the files it was writing are removed"
        ) from None
    finally:
        for number, handler in previous:
            signal.signal(number, handler)


@contextmanager
def uninterrupted() -> Iterator[None]:
    """Hold the error of a signal that :func:`stopped_by_signals` catches until the block ends
    (a temporary made and its name kept, or removed whole), then raise it. Changes nothing
    outside such a block, nor in another thread than the main one."""
    global _holding
    if not _is_main_thread():
        yield
        return
    _holding += 1
    try:
        yield
    finally:
        _holding -= 1
        if not _holding and _held:
            raise _held.pop()


class Temporary:
    """A locked temporary folder ``out/.<name>.<kind>-<random>``; ``release()`` unlocks it
    and removes the folder if it is still there."""

    def __init__(self, out: Path, name: str, kind: str = "partial"):
        fd, lock = tempfile.mkstemp(prefix=f".{name}.{kind}-", suffix=".lock", dir=out)
        self.lock_path = Path(lock)
        self.path = self.lock_path.with_suffix("")
        self._fd = fd
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)  # new file: nobody else holds it
        self.path.mkdir()

    def release(self) -> None:
        with uninterrupted():
            shutil.rmtree(self.path, ignore_errors=True)
            self.lock_path.unlink(missing_ok=True)
            os.close(self._fd)


def _rename(src: Path, dst: Path, flags: int) -> None:
    if _LIBC is None:
        if flags == _RENAME_NOREPLACE and (dst.exists() or dst.is_symlink()):
            raise OSError(errno.EEXIST, os.strerror(errno.EEXIST), str(dst))
        os.rename(src, dst)  # exchange unavailable: the caller moved the old one aside
        return
    if _LIBC.renameat2(_AT_FDCWD, os.fsencode(src), _AT_FDCWD, os.fsencode(dst), flags) != 0:
        code = ctypes.get_errno()
        if code in (errno.EINVAL, errno.ENOSYS):  # a file system without these flags
            raise _Unsupported()
        raise OSError(code, os.strerror(code), str(dst))


class _Unsupported(Exception):
    pass


def install(temp: Temporary, final: Path, force: bool) -> None:
    """Move ``temp``'s folder to ``final``: refused if ``final`` exists (also if it appeared
    after the run started), unless ``force``: then swapped in one step, the old removed."""
    global _LIBC
    if not (final.exists() or final.is_symlink()):
        try:
            _rename(temp.path, final, _RENAME_NOREPLACE)
            return
        except _Unsupported:
            _LIBC = None
            return install(temp, final, force)
        except OSError as exc:
            if exc.errno not in (errno.EEXIST, errno.ENOTEMPTY):
                raise
    if not force:
        raise DatasetError(
            f"{final} already exists (it appeared while this run was writing): "
            "nothing replaced; pass --force to overwrite it"
        )
    if _LIBC is not None:
        try:
            _rename(temp.path, final, _RENAME_EXCHANGE)  # temp.path now holds the old one
            return  # release() removes it, still under this run's lock
        except _Unsupported:
            _LIBC = None
    old = Temporary(final.parent, final.name, "old")
    try:
        old.path.rmdir()
        os.rename(final, old.path)
        os.rename(temp.path, final)
    finally:
        old.release()


def _is_dead(lock: Path) -> bool:
    try:
        fd = os.open(lock, os.O_RDWR)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        return False  # a live run holds it
    else:
        return True  # unlocked: its run is gone (we now hold it until close)
    finally:
        os.close(fd)


def clean_stale(out: Path) -> tuple[list[Path], list[Path]]:
    """Remove the temporaries of dead runs in ``out``; return (removed, unknown): unknown ones
    carry no lock (written by simlidar 0.1.0 or earlier, named by PID) and are left alone."""
    removed, unknown = [], []
    if not out.is_dir():
        return removed, unknown
    for entry in sorted(out.iterdir()):
        if entry.suffix == ".lock" and _TEMP.match(entry.stem):
            if _is_dead(entry):
                folder = entry.with_suffix("")
                shutil.rmtree(folder, ignore_errors=True)
                entry.unlink(missing_ok=True)
                removed.append(folder)
        elif entry.is_dir() and _LEGACY.match(entry.name):
            unknown.append(entry)
    return removed, unknown


def claim_folder(out: Path) -> bool:
    """Make ``out`` an output folder: create it if needed (True when this call created it),
    check that it is writable, and remove dead runs' temporaries from it with a one-line
    warning each (those of simlidar 0.1.0, which carry no lock, are only reported)."""
    created = not out.exists()
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise DatasetError(f"--out {out}: cannot create the folder ({exc.strerror})") from None
    if not out.is_dir() or not os.access(out, os.W_OK | os.X_OK):
        raise DatasetError(f"--out {out}: expected a writable folder")
    removed, unknown = clean_stale(out)
    for folder in removed:
        warnings.warn(f"removed {folder}, left by a run that did not finish", stacklevel=3)
    if unknown:
        names = " ".join(str(u) for u in unknown)
        warnings.warn(
            f"{len(unknown)} temporary folder(s) of older simlidar runs in {out}; if "
            f"none is running there, remove them with: rm -rf {names}",
            stacklevel=3,
        )
    return created


def write_files(
    paths: list[str | Path], write, mode: int | None = None, what: str = ""
) -> list[Path]:
    """Write the files ``paths`` of one folder all or none: ``write(temporaries)`` writes a
    temporary of each, of the same name, in a locked temporary folder beside them
    (:class:`Temporary`; a killed run's is removed by the next :func:`claim_folder` there), and
    only when it returns are they renamed into place, in order. A full disk while writing
    leaves none of them; on any error the temporaries are removed, and an OSError becomes a
    DatasetError naming the first path and the cause. A link at a path is replaced, never
    written through.

    mode : the files' permission bits; None: what the writer's ``open`` gave (0666 less the
        umask, as every other output)
    what : what the files are, for the error ("the checkpoint": "cannot write the checkpoint")
    """
    paths = [Path(p) for p in paths]
    folder = paths[0].parent
    if any(p.parent != folder for p in paths):
        raise ValueError(f"{[str(p) for p in paths]}: expected files of one folder")
    try:
        work = Temporary(folder, paths[0].name)
    except OSError as exc:
        raise DatasetError(
            f"{paths[0]}: cannot write{what and ' '}{what} ({exc.strerror or exc})"
        ) from None
    try:
        temporaries = [work.path / p.name for p in paths]
        write(temporaries)
        for temporary in temporaries if mode is not None else []:
            temporary.chmod(mode)
        for temporary, path in zip(temporaries, paths):
            os.replace(temporary, path)
    except OSError as exc:
        raise DatasetError(
            f"{paths[0]}: cannot write{what and ' '}{what} ({exc.strerror or exc})"
        ) from None
    finally:
        work.release()
    return paths


def write_file(path: str | Path, write, mode: int | None = None, what: str = "") -> Path:
    """Write the one file ``path`` through ``write(temporary)``: :func:`write_files`."""
    return write_files([path], lambda temporaries: write(temporaries[0]), mode, what)[0]


def temporary_of(name: str) -> str | None:
    """The name whose temporary (its folder or its lock file) the entry ``name`` is, if it is
    one (``.suite.json.partial-x1y2.lock``: ``suite.json``)."""
    match = _TEMP.match(name.removesuffix(".lock"))
    return match["name"] if match else None


@contextmanager
def building(out: str | Path, name: str, force: bool = False) -> Iterator[Path]:
    """A hidden locked folder ``out/.<name>.partial-<random>``
    to build a dataset in; it becomes ``out/<name>`` when the block ends without error and is
    removed on any error (with ``out`` too, if this call created it and it is left empty). An
    existing ``out/<name>`` stops the build before anything is written, unless ``force``: then
    it is replaced only at the end, in one step.

    Used by the converters (``simlidar.convert``); ``simlidar.generator.generate`` builds
    several at once with the same parts.
    """
    out = Path(out)
    final = out / name
    if final.exists() and not force:
        raise DatasetError(f"{final} already exists: pass --force to overwrite it")
    created = claim_folder(out)
    claim = Temporary(out, name)
    try:
        yield claim.path
        install(claim, final, force)
    finally:
        claim.release()
        if created and out.is_dir() and not any(out.iterdir()):
            out.rmdir()
