"""Where a cell runs: the torch device (``--device``) and the number of threads
(``--threads``), both recorded by every cell.

A cell's result depends on its thread count (float sums are split differently), so the count is
fixed by the run, not left to torch's default, and a cell run on a cluster worker uses the same
count as one run in place (``simlidar bench`` and ``simlidar bench --scheduler`` give the same
cells).
"""

from collections.abc import Iterator
from contextlib import contextmanager

from simlidar.errors import ConfigError
from simlidar.resources import check_threads_room

DEVICES = ("auto", "cpu", "cuda")
# one thread a cell: 0.19 times the wall time of two for a CNN cell on this project's shared
# 2-core machine (docs/benchmark.md, "Devices and threads"), and what two cells side by side want
DEFAULT_THREADS = 1
MAX_THREADS = 1024


def resolve_device(name: str):
    """The torch device of ``--device``: ``auto`` (CUDA where torch sees a GPU, else the CPU),
    ``cpu``, ``cuda`` or ``cuda:N``; ConfigError for a device this machine does not have."""
    import torch

    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if name == "cpu":
        return torch.device("cpu")
    if name == "cuda" or (name.startswith("cuda:") and name[5:].isdigit()):
        if not torch.cuda.is_available():
            raise ConfigError(
                f"--device {name}: torch sees no CUDA device here; expected auto or cpu"
            )
        if ":" in name and int(name[5:]) >= torch.cuda.device_count():
            raise ConfigError(
                f"--device {name}: this machine has {torch.cuda.device_count()} CUDA device(s)"
            )
        return torch.device(name)
    raise ConfigError(f"--device {name!r}: expected one of {list(DEVICES)} or cuda:N")


def check_threads(threads: int) -> int:
    """``threads`` if it is an integer in [1, MAX_THREADS] that this process can make
    (:func:`~simlidar.resources.check_threads_room`); ConfigError or ResourceError otherwise."""
    if isinstance(threads, bool) or not isinstance(threads, int) or not 1 <= threads <= MAX_THREADS:
        raise ConfigError(f"threads={threads!r}: expected an integer in [1, {MAX_THREADS}]")
    check_threads_room(threads, f"--threads {threads}")
    return threads


@contextmanager
def threads(count: int) -> Iterator[int]:
    """Run the block with ``count`` torch threads and at most ``count`` numba threads (the
    spiking layers' kernels), restoring both after."""
    import torch

    check_threads(count)
    before = torch.get_num_threads()
    numba_before = _numba_threads()
    torch.set_num_threads(count)
    _set_numba_threads(count)
    try:
        yield count
    finally:
        torch.set_num_threads(before)
        if numba_before is not None:
            _set_numba_threads(numba_before)


def _numba_threads() -> int | None:
    try:
        import numba
    except ImportError:
        return None
    return numba.get_num_threads()


def _set_numba_threads(count: int) -> None:
    try:
        import numba
    except ImportError:
        return
    numba.set_num_threads(max(1, min(count, numba.config.NUMBA_NUM_THREADS)))
