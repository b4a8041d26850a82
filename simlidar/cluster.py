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

import secrets
from collections.abc import Callable, Iterator
from contextlib import contextmanager

from simlidar.errors import ConfigError, DatasetError

LOCAL = "local"  # --scheduler local: a LocalCluster on this machine
CONNECT_SECONDS = 10  # how long to wait for a scheduler before calling it unreachable


def _dask():
    try:
        from dask import distributed
    except ImportError:
        raise ConfigError(
            "--scheduler needs Dask's distributed scheduler; expected it installed: "
            'pip install "simlidar[cluster]"'
        ) from None
    return distributed


@contextmanager
def connect(address: str, workers: int = 2) -> Iterator:
    """A ``dask.distributed.Client`` of the scheduler at ``address`` (``tcp://HOST:PORT``), or
    of a new LocalCluster of ``workers`` processes when ``address`` is ``local``; closed (and
    the local cluster stopped) on exit. ConfigError, one line, when the scheduler cannot be
    reached."""
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
            client = distributed.Client(address, timeout=CONNECT_SECONDS)
    except (OSError, TimeoutError, ValueError, TypeError) as exc:
        if cluster is not None:
            cluster.close()
        cause = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise ConfigError(
            f"--scheduler {address}: cannot reach a Dask scheduler ({cause}); expected the "
            f"address of a running scheduler (tcp://HOST:8786) or {LOCAL!r}"
        ) from None
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
    DatasetError naming the task (``names``) when its workers kept dying."""
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
