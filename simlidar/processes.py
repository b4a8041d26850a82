"""Worker processes: how many to start, that they end with the process that started them, and
that each runs BLAS on one thread.

A forked worker waiting for its next job reads a pipe whose other end it holds itself (a fork
copies every open file), so it never sees end-of-file when its parent dies: without care a
``kill -9`` of ``generate --workers N`` leaves N processes waiting forever.
:func:`die_with_parent`, run as a pool's initializer, asks Linux to kill the worker when its
parent dies (``prctl(PR_SET_PDEATHSIG, SIGKILL)``) and, where that is unavailable, watches
the parent from a thread.
"""

import ctypes
import multiprocessing
import os
import signal
import threading
import time
import warnings
from concurrent.futures import ProcessPoolExecutor

_PR_SET_PDEATHSIG = 1  # <linux/prctl.h>
WATCH_SECONDS = 0.5  # how often a worker without PR_SET_PDEATHSIG looks for its parent


def usable_cores() -> int:
    """The cores this process may run on (its CPU affinity; all of them where unknown)."""
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def capped_workers(requested: int, work: int, unit: str) -> int:
    """``requested`` worker processes, capped at ``work`` (how many ``unit`` there are to do,
    e.g. batches) and at the usable cores; a one-line warning says so when capped. A process
    more than either only costs memory and start-up time (999 workers for 3 batches of 32
    samples took 5 GB and 66 s)."""
    cores = usable_cores()
    usable = max(1, min(requested, work, cores))
    if usable < requested:
        warnings.warn(
            f"--workers {requested}: starting {usable} worker process(es), as many as there "
            f"are {unit} to do ({work}) and cores to run on ({cores})",
            stacklevel=2,
        )
    return usable


def die_with_parent(parent: int) -> None:
    """Make this process (a worker forked by process ``parent``) end when its parent ends.

    Linux sends the signal when the *thread* that forked the worker ends: fork workers from a
    thread that outlives them (the pool's owner does). Called in the worker, first thing."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        armed = libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0) == 0
    except (OSError, AttributeError):  # not Linux
        armed = False
    if os.getppid() != parent:  # the parent died before the request: nobody will signal
        os.kill(os.getpid(), signal.SIGKILL)
    if not armed:
        threading.Thread(target=_watch, args=(parent,), daemon=True).start()


def one_blas_thread() -> None:
    """numpy's BLAS on one thread in a worker (a forked one or a cluster task's). A process
    left to itself spreads the scene transforms' matrix products over every core, spinning
    more than it gains (``--workers 1`` spends 1.4 cores' time for 10 % less wall time); N
    workers doing that on N cores fight for them (``--workers 2`` was 1.3x the samples/s of 1,
    1.8x with this)."""
    from threadpoolctl import threadpool_limits

    threadpool_limits(1, user_api="blas")


def _watch(parent: int) -> None:
    while os.getppid() == parent:  # an orphan is adopted by another process
        time.sleep(WATCH_SECONDS)
    os.kill(os.getpid(), signal.SIGKILL)


def _start_worker(parent: int) -> None:
    """A forked worker's initializer: it ends with its parent ``parent``, whatever kills that,
    and runs BLAS on one thread."""
    die_with_parent(parent)
    one_blas_thread()


def forked_pool(workers: int) -> ProcessPoolExecutor:
    """``workers`` forked processes that die with this one and run BLAS on one thread (they
    see what this process held when each was forked)."""
    return ProcessPoolExecutor(
        workers,
        mp_context=multiprocessing.get_context("fork"),
        initializer=_start_worker,
        initargs=(os.getpid(),),
    )
