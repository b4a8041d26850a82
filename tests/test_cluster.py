"""Generation and benchmark cells on a real Dask LocalCluster (2 worker processes, loopback):
the same bytes as one process, also after a worker is killed mid-shard (issue "Scale out").

Attack list (issue 35, item 5), each a real server on loopback:

* ``--scheduler`` at a plain HTTP server (``http.server``): Dask's handshake waited for ever
  (> 10 min, no output); now one line naming the address within the connect timeout.
* ``--scheduler`` at a raw TCP service that speaks first (an SSH banner): its bytes read as a
  frame count, an 82-line MemoryError traceback; now one line naming the address.
* a closed port and an unknown scheme: one line, nothing written.
"""

import json
import os
import signal
import socket
import threading
import time
from contextlib import contextmanager
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer

import pytest
from distributed import Client, LocalCluster

from simlidar.errors import ConfigError, DatasetError
from simlidar.generator.config import GeneratorConfig
from simlidar.generator.generate import generate
from simlidar.generator.on_cluster import _cluster_shard
from simlidar.generator.shard import Shard


@pytest.fixture(scope="module")
def cluster():
    with (
        LocalCluster(
            n_workers=2, threads_per_worker=1, host="127.0.0.1", dashboard_address=None
        ) as cluster,
        Client(cluster) as client,
    ):
        yield cluster.scheduler_address, client


def _files(path):
    return {p.name: p.read_bytes() for p in sorted(path.iterdir())}


def test_the_cluster_writes_the_bytes_of_one_process(
    cluster, sharded, datasets, catalog, small_config, tmp_path
):
    address, _ = cluster
    written = generate(
        small_config,
        [0.1, 0.5],
        catalog,
        tmp_path,
        batch_size=16,
        progress=False,
        shard_samples=40,
        scheduler=address,
    )
    assert _files(written[0].path) == _files(sharded)  # 2 noise levels, 5 shard files each
    (alone,) = generate(
        small_config, [0.5], catalog, tmp_path / "one", progress=False, shard_samples=40
    )
    assert _files(written[1].path) == _files(alone.path)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        [written[0].path.name, written[1].path.name, "one"]
    )


def _slow_appends():
    """In a worker process: every batch a shard writer appends takes 0.2 s more, so that a
    shard is being written for seconds and the test's poll cannot miss it however loaded the
    machine is (the bytes are the same)."""
    import time

    from simlidar.dataset.writer import SplitWriter

    append = SplitWriter.append

    def slow(self, *args, **kwargs):
        time.sleep(0.2)
        return append(self, *args, **kwargs)

    slow.original = append
    SplitWriter.append = slow


def _full_speed():
    """Undo :func:`_slow_appends` in a worker that has it."""
    from simlidar.dataset.writer import SplitWriter

    SplitWriter.append = getattr(SplitWriter.append, "original", SplitWriter.append)


def test_a_worker_killed_mid_shard_changes_nothing(cluster, catalog, tmp_path):
    address, client = cluster
    config = GeneratorConfig(train_size=1600, test_size=400)
    (alone,) = generate(config, [0.2], catalog, tmp_path / "one", progress=False, shard_samples=400)
    out = tmp_path / "cluster"
    out.mkdir()
    done, errors = [], []
    client.run(_slow_appends)  # the restarted worker (after the kill) writes at full speed

    def run():
        try:
            done.extend(
                generate(
                    config,
                    [0.2],
                    catalog,
                    out,
                    batch_size=8,
                    progress=False,
                    shard_samples=400,
                    scheduler=address,
                )
            )
        except Exception as exc:  # reported by the assertion below
            errors.append(exc)

    thread = threading.Thread(target=run)
    thread.start()
    killed = None
    deadline = time.monotonic() + 60
    while killed is None and thread.is_alive() and time.monotonic() < deadline:
        if any(out.glob(".*/.train-*.h5.partial-*")):  # a shard half written
            busy = [w for w, keys in client.processing().items() if keys]
            if busy:
                pids = client.run(os.getpid, workers=busy[:1])
                killed = pids[busy[0]]
                os.kill(killed, signal.SIGKILL)
        time.sleep(0.005)
    thread.join(timeout=120)
    assert killed is not None, "no worker was caught writing a shard"
    assert not errors, errors
    assert _files(done[0].path) == _files(alone.path)
    assert [p.name for p in out.iterdir()] == [alone.path.name]  # no temporaries left
    client.wait_for_workers(2, timeout=60)  # the nanny restarted it, for the tests after
    client.run(_full_speed)


def test_a_worker_without_the_output_folder_says_so(small_config, catalog, tmp_path):
    shard = Shard("train", 0, 1, 0, 8, "train.h5")
    where = (None, catalog.fingerprint())
    with pytest.raises(DatasetError, match="not found on worker .*; expected the output folder"):
        _cluster_shard(small_config, [0.1], where, shard, [str(tmp_path / "absent")], 8)
    with pytest.raises(DatasetError, match="expected 0+, the caller's"):
        _cluster_shard(small_config, [0.1], (None, "0" * 64), shard, [str(tmp_path)], 8)


def test_an_unreachable_scheduler_is_one_line_and_writes_nothing(
    catalog, tmp_path, monkeypatch, cli
):
    import simlidar.cluster

    monkeypatch.setattr(simlidar.cluster, "CONNECT_SECONDS", 1)
    result = cli("generate", "--scheduler", "tcp://127.0.0.1:9", "--out", str(tmp_path / "d"))
    assert result.exit_code == 2
    assert (
        "Invalid value for '--scheduler': tcp://127.0.0.1:9: cannot reach a Dask scheduler"
        in result.output
    )
    assert (
        "expected the address of a running scheduler (tcp://HOST:8786) or 'local'" in result.output
    )
    assert not (tmp_path / "d").exists()
    with pytest.raises(ConfigError, match="cannot reach a Dask scheduler"):
        generate(
            GeneratorConfig(train_size=32, test_size=32),
            [0.1],
            catalog,
            tmp_path,
            scheduler="nonsense://x",
        )


def test_bench_cells_on_the_cluster_equal_cells_run_here(cluster, datasets, tmp_path, cli):
    """Both runs at their defaults: a plain bench used torch's default thread count (2 here)
    while a cluster task ran on one thread, and the CNN's cells differed (issue 35, item 9);
    both now run the cells on --threads (default 1) and record it."""
    address, _ = cluster
    args = ["bench", "--suite", "quick", "--models", "mlp,cnn", "--dataset", str(datasets[0.1])]
    args += ["--epochs", "2"]
    here = cli(*args, "--out", str(tmp_path / "here"), "--json")
    there = cli(*args, "--out", str(tmp_path / "there"), "--json", "--scheduler", address)
    assert here.exit_code == 0 and there.exit_code == 0, there.output
    cells = sorted((tmp_path / "here" / "cells").iterdir())
    assert [c.name for c in cells] == sorted(
        p.name for p in (tmp_path / "there" / "cells").iterdir()
    )
    for cell in cells:
        a = json.loads(cell.read_text())
        b = json.loads((tmp_path / "there" / "cells" / cell.name).read_text())
        assert a["accuracy"] == b["accuracy"] and a["validation_curve"] == b["validation_curve"]
        assert a["threads"] == b["threads"] == 1


class _QuietHandler(SimpleHTTPRequestHandler):
    def log_message(self, *args):  # its log would mix with the command's stderr
        pass


@contextmanager
def _http_server():
    """A plain HTTP server on a free loopback port: its address as tcp://127.0.0.1:PORT."""
    server = ThreadingHTTPServer(("127.0.0.1", 0), _QuietHandler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"tcp://127.0.0.1:{server.server_address[1]}"
    finally:
        server.shutdown()
        server.server_close()


@contextmanager
def _banner_server():
    """A raw TCP service that speaks first, as SSH does, and then waits."""
    listener = socket.create_server(("127.0.0.1", 0))
    listener.settimeout(0.2)
    stop = threading.Event()
    held = []

    def serve():
        while not stop.is_set():
            try:
                conn, _ = listener.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            conn.sendall(b"SSH-2.0-OpenSSH_9.6p1 Ubuntu-3ubuntu13\r\n")
            held.append(conn)  # kept open, as a real service keeps it

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    try:
        yield f"tcp://127.0.0.1:{listener.getsockname()[1]}"
    finally:
        stop.set()
        thread.join()
        listener.close()
        for conn in held:
            conn.close()


@pytest.mark.parametrize(
    "server, cause",
    [
        (_http_server, "no Dask answer within 2 s"),
        (_banner_server, "it answered, but not in Dask's protocol (MemoryError)"),
    ],
    ids=["http", "banner"],
)
def test_a_service_that_is_not_a_scheduler_is_one_line_naming_it(
    server, cause, catalog, tmp_path, monkeypatch, cli
):
    import simlidar.cluster

    monkeypatch.setattr(simlidar.cluster, "CONNECT_SECONDS", 2)
    with server() as address:
        out = tmp_path / "d"
        args = ["generate", "--scheduler", address, "--out", str(out)]
        result = []  # run on a thread: a run that hangs fails the test instead of hanging it
        thread = threading.Thread(target=lambda: result.append(cli(*args)))
        thread.daemon = True
        thread.start()
        thread.join(60)
        assert result, f"--scheduler {address}: no answer within 60 s"
        (done,) = result
        assert done.exit_code == 2, done.output
        assert done.output.count("\n") == 1 and "Traceback" not in done.output
        assert done.output.startswith(
            f"Error: Invalid value for '--scheduler': {address}: cannot reach a Dask scheduler "
            f"({cause}); expected"
        )
        assert "expected the address of a running scheduler (tcp://HOST:8786)" in done.output
        assert not out.exists()
        with pytest.raises(ConfigError, match=f"--scheduler {address}: cannot reach a Dask"):
            generate(
                GeneratorConfig(train_size=32, test_size=32), [0.1], catalog, out, scheduler=address
            )
