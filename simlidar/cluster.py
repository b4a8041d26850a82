"""Independent tasks on a Dask distributed cluster: ``--scheduler ADDRESS`` of ``generate``
(one task per shard file) and ``bench`` (one task per cell).

Dask is an optional extra (``pip install "simlidar[cluster]"``), imported only here and only
when a scheduler is asked for. ``local`` starts a ``LocalCluster`` of worker processes (one
thread each) on this machine, on loopback. A task runs where the scheduler puts it and writes
its own files to the output path, which every worker must see (a shared file system); what the
caller gets back is small (names, sizes). A task whose worker dies (killed, out of memory) is
run again by the scheduler on another worker (Dask's ``allowed-failures``, 3 by default); a
task that raises is retried ``retries`` times and then ends the run with its error.
"""

import asyncio
import secrets
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager

from simlidar.errors import ConfigError, DatasetError, first_line

LOCAL = "local"  # --scheduler local: a LocalCluster on this machine
CONNECT_SECONDS = 10  # how long to wait for a scheduler's answer before calling it unreachable


def _dask():
    try:
        from dask import distributed
    except ImportError:
        raise ConfigError(
            "--scheduler needs Dask's distributed scheduler; expected it installed: "
            'pip install "simlidar[cluster]"'
        ) from None
    return distributed


def _handshake(distributed, address: str, seconds: float) -> None:
    """Open a connection to ``address`` and exchange Dask's handshake, all within ``seconds``;
    a ConfigError saying why not otherwise. Dask's own ``Client`` bounds the connection but not the
    handshake's reply: a plain HTTP server there kept it waiting for ever, and a service that
    speaks first (an SSH banner) made it read its bytes as a frame count and fail with a
    MemoryError. Run on a thread of its own, so that a caller's event loop does not matter."""

    async def probe():
        comm = await asyncio.wait_for(distributed.comm.connect(address, timeout=seconds), seconds)
        await comm.close()

    failure: list[BaseException] = []

    def run():
        try:
            asyncio.run(probe())
        except BaseException as exc:  # handed to the caller below
            failure.append(exc)

    thread = threading.Thread(target=run, name="simlidar-scheduler-probe", daemon=True)
    thread.start()
    thread.join(seconds + 5)  # wait_for has ended it by then; never wait without end
    if thread.is_alive():
        raise _unreachable(address, TimeoutError())
    if failure:
        raise _unreachable(address, failure[0])


def _unreachable(address: str, exc: BaseException) -> ConfigError:
    """The one line for a scheduler that did not answer as one: the address and why."""
    if isinstance(exc, TimeoutError):
        cause = f"no Dask answer within {CONNECT_SECONDS} s"
    elif isinstance(exc, OSError | ValueError | TypeError) and str(exc):
        cause = first_line(exc)
    else:  # garbage read as Dask's frames: MemoryError, a decoding error, ...
        cause = f"it answered, but not in Dask's protocol ({type(exc).__name__})"
    return ConfigError(
        f"--scheduler {address}: cannot reach a Dask scheduler ({cause}); expected the "
        f"address of a running scheduler (tcp://HOST:8786) or {LOCAL!r}"
    )


@contextmanager
def connect(address: str, workers: int = 2) -> Iterator:
    """A ``dask.distributed.Client`` of the scheduler at ``address`` (``tcp://HOST:PORT``), or
    of a new LocalCluster of ``workers`` processes when ``address`` is ``local``; closed (and
    the local cluster stopped) on exit. ConfigError, one line naming the address, when no
    Dask scheduler answers there within ``CONNECT_SECONDS`` (nothing, or another service)."""
    distributed = _dask()
    cluster = None
    try:
        if address == LOCAL:
            cluster = distributed.LocalCluster(
                n_workers=workers,
                threads_per_worker=1,
                processes=True,
                host="127.0.0.1",
                dashboard_address=None,
            )
            client = distributed.Client(cluster)
        else:
            _handshake(distributed, address, CONNECT_SECONDS)
            client = distributed.Client(address, timeout=CONNECT_SECONDS)
    except (OSError, TimeoutError, ValueError, TypeError) as exc:
        if cluster is not None:
            cluster.close()
        raise _unreachable(address, exc) from None
    try:
        yield client
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def check_scheduler(address: str) -> None:
    """Fail early, in one line (ConfigError), when Dask is missing or the scheduler at
    ``address`` cannot be reached (``local`` needs Dask only)."""
    _dask()
    if address != LOCAL:
        with connect(address):
            pass


def run_tasks(
    client,
    function: Callable,
    tasks: list[tuple],
    names: list[str],
    on_done: Callable[[int, object], None] = lambda index, result: None,
    retries: int = 1,
) -> list:
    """Run ``function(*task)`` for every task on the cluster; ``on_done(index, result)`` as
    each finishes (in any order); the results in task order. The first task that fails for
    good cancels the others and raises: its own error (a SimlidarError stays one line), or a
    DatasetError naming the task (``names``) when its workers kept dying.

    client : a ``dask.distributed.Client`` (:func:`connect`)
    function : what a worker runs; what it returns comes back to the caller, so it should be
        small (names, sizes)
    tasks : each task's positional arguments to ``function``
    names : each task's name in an error, in task order
    on_done : called here, in the calling process, as each task finishes (a progress bar)
    retries : the times a task that raises is run again before its error ends the run (a dead
        worker's task is run again by the scheduler's own rule, Dask's ``allowed-failures``)
    """
    distributed = _dask()
    run = secrets.token_hex(4)  # keys unique to this run: a shared scheduler may hold others'
    futures = [
        client.submit(function, *task, key=f"simlidar-{run}-{i}", pure=False, retries=retries)
        for i, task in enumerate(tasks)
    ]
    position = {future.key: i for i, future in enumerate(futures)}
    results: list = [None] * len(tasks)
    try:
        for future in distributed.as_completed(futures):
            index = position[future.key]
            try:
                results[index] = future.result()
            except distributed.KilledWorker:
                raise DatasetError(
                    f"{names[index]}: the workers running it died again and again (killed, or "
                    "out of memory); nothing of it was kept: run the command again"
                ) from None
            on_done(index, results[index])
    except BaseException:
        client.cancel(futures)
        raise
    return results
