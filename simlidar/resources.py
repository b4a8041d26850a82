"""What the machine can hold: the memory this process may still allocate and the free space
of a folder's file system, and the checks that refuse a size taken from a file or a suite
before anything is allocated or written (a one-line :class:`ResourceError` naming both
figures), instead of a MemoryError traceback, the kernel's out-of-memory killer or a disk that
fills an hour into a run."""

import os
import resource
import shutil
from pathlib import Path

from simlidar.errors import ResourceError


def size_text(nbytes: float) -> str:
    """Bytes as people read them: 812 B, 1.5 MiB, 19.1 GiB."""
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if abs(nbytes) < 1024 or unit == "PiB":
            return f"{nbytes:.0f} {unit}" if unit == "B" else f"{nbytes:.1f} {unit}"
        nbytes /= 1024
    raise AssertionError("unreachable")


def _meminfo_kib(*keys: str) -> int | None:
    """The sum of /proc/meminfo's ``keys`` (kiB); None where the file says nothing."""
    try:
        lines = Path("/proc/meminfo").read_text().splitlines()
    except OSError:
        return None
    values = {}
    for line in lines:
        key, _, rest = line.partition(":")
        if key in keys and rest.split():
            values[key] = int(rest.split()[0])
    return sum(values.values()) if len(values) == len(keys) else None


def _cgroup_room() -> int | None:
    """Bytes left under this process's cgroup (v2) memory limit; None without one."""
    try:
        group = Path("/proc/self/cgroup").read_text().splitlines()[0].split(":", 2)[2]
        folder = Path("/sys/fs/cgroup") / group.lstrip("/")
        limit = (folder / "memory.max").read_text().strip()
        if limit == "max":
            return None
        return max(0, int(limit) - int((folder / "memory.current").read_text()))
    except (OSError, IndexError, ValueError):
        return None


def _address_space_room() -> int | None:
    """Bytes of address space left under ``ulimit -v`` (RLIMIT_AS); None without a limit."""
    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    if soft == resource.RLIM_INFINITY:
        return None
    try:
        status = Path("/proc/self/status").read_text().splitlines()
        used = next(int(line.split()[1]) * 1024 for line in status if line.startswith("VmSize:"))
    except (OSError, StopIteration, ValueError, IndexError):
        used = 0
    return max(0, soft - used)


def available_memory() -> int | None:
    """Bytes this process can still allocate: the least of the memory the kernel calls
    available (with free swap), the room under its cgroup's limit and under ``ulimit -v``;
    None where none of them is known."""
    kib = _meminfo_kib("MemAvailable", "SwapFree")
    if kib is not None:
        kib *= 1024
    elif hasattr(os, "sysconf") and "SC_AVPHYS_PAGES" in os.sysconf_names:
        kib = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    known = [v for v in (kib, _cgroup_room(), _address_space_room()) if v is not None]
    return min(known) if known else None


def check_memory(nbytes: int, what: str) -> None:
    """Refuse to allocate ``nbytes`` for ``what`` (e.g. "/data/x/train.h5: 'delays' (20000000,
    16, 16) float32") when this process cannot hold them: a ResourceError naming both sizes."""
    room = available_memory()
    if room is not None and nbytes > room:
        raise ResourceError(
            f"{what}: {size_text(nbytes)} to hold in memory, {size_text(room)} available; "
            "expected data that fits (a smaller split, or a machine with more memory)"
        )


def free_disk(folder: str | Path) -> int:
    """Free bytes of the file system of ``folder`` (or of its nearest existing parent: a
    folder that a command is about to create)."""
    folder = Path(folder).absolute()
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    return shutil.disk_usage(folder).free


def check_disk(folder: str | Path, nbytes: int, what: str) -> None:
    """Refuse to write about ``nbytes`` for ``what`` into ``folder`` when its file system has
    less free space: a ResourceError naming both sizes, before anything is written."""
    free = free_disk(folder)
    if nbytes > free:
        raise ResourceError(
            f"{what}: about {size_text(nbytes)} to write into {folder}, {size_text(free)} "
            "free there; expected enough free disk space (free some, or write elsewhere "
            "with --out)"
        )


def thread_stack_bytes() -> int:
    """The address space a new thread reserves for its stack: glibc's default, the soft
    ``ulimit -s`` (8 MiB where that is unlimited), as OpenMP's threads (torch's) take it."""
    soft, _ = resource.getrlimit(resource.RLIMIT_STACK)
    return 8 * 2**20 if soft == resource.RLIM_INFINITY else soft


def check_threads_room(count: int, what: str) -> None:
    """Refuse ``count`` threads when they cannot be made under ``ulimit -v``: a ResourceError
    naming both sizes. OpenMP aborts the process on a thread it cannot create ("libgomp:
    Thread creation failed"), which no caller can catch. A thread is counted as twice its
    stack: torch's threads took about 16 MiB of address space each with 8 MiB stacks (measured
    on this project's machines: 150 then 200 threads left 122 and 9 MiB of a 4 GiB limit, 250
    aborted)."""
    room = _address_space_room()
    need = 2 * count * thread_stack_bytes()
    if room is not None and need > room:
        raise ResourceError(
            f"{what}: {count} threads reserve {size_text(need)} of address space for their "
            f"stacks, {size_text(room)} is left under ulimit -v; expected fewer threads"
        )
