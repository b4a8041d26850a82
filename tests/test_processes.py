"""Worker processes (simlidar.processes): as many as there is work and cores for, and none
outliving the run that started them.

Attack list (issue 35, item 4):

* ``generate --workers 999`` for 3 batches: forked 999 processes (5 GB, 66 s); now at most
  min(batches, cores), said in one line on stderr.
* ``kill -9`` of a real ``simlidar generate --workers 2`` process while its workers run: the
  workers, blocked on a pipe whose other end they hold themselves, lived on as orphans; now
  every child is gone within a deadline (polled, not slept).
* a worker forked just as its parent is killed (before it asked for the parent-death signal):
  it ends by itself.
"""

import os
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import pytest

from simlidar.processes import capped_workers, usable_cores

DEADLINE_S = 30.0


def _children(pid: int) -> list[int]:
    """The live processes whose parent is ``pid``, from /proc."""
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit() and _state(int(entry.name)) not in (None, "Z"):
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
                found.append(int(entry.name))
    return found


def _state(pid: int) -> str | None:
    """A process's state letter (``Z``: a zombie, dead), None when it is gone."""
    try:
        return (Path("/proc") / str(pid) / "stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return None


def _wait_for(condition, what: str):
    deadline = time.monotonic() + DEADLINE_S
    while time.monotonic() < deadline:
        value = condition()
        if value:
            return value
        time.sleep(0.05)
    raise AssertionError(f"not within {DEADLINE_S} s: {what}")


def test_workers_are_capped_at_the_batches_and_the_cores(tmp_path, monkeypatch, cli):
    import simlidar.processes as gen

    sizes = []
    real = gen.ProcessPoolExecutor

    def counted(workers, **kwargs):
        sizes.append(workers)
        assert workers <= usable_cores(), f"{workers} processes for {usable_cores()} cores"
        return real(workers, **kwargs)

    monkeypatch.setattr(gen, "ProcessPoolExecutor", counted)
    args = ["generate", "--classes", "4", "--train-size", "64", "--test-size", "32"]
    args += ["--batch-size", "32", "--out", str(tmp_path), "--workers", "999"]
    done = cli(*args)
    assert done.exit_code == 0, done.output
    batches, cores = 3, usable_cores()  # train 2 + test 1
    expected = min(batches, cores)
    assert sizes == ([expected] if expected > 1 else []) + [1]  # and the preview's process
    (line,) = [w for w in done.stderr.splitlines() if w.startswith("Warning:")]
    assert line == (
        f"Warning: --workers 999: starting {expected} worker process(es), as many as there "
        f"are batches to do ({batches}) and cores to run on ({cores})"
    )
    quiet = cli(*args[:-1], "1", "--force")
    assert quiet.exit_code == 0 and "Warning" not in quiet.stderr


def test_a_count_within_the_work_and_the_cores_is_kept_silently():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert capped_workers(1, 10, "batches") == 1
        assert capped_workers(usable_cores(), 10**6, "batches") == usable_cores()
    with pytest.warns(UserWarning, match=r"--workers 5: starting 1 worker process\(es\)"):
        assert capped_workers(5, 0, "batches") == 1  # nothing to do: one process, no pool


def test_a_killed_run_leaves_no_worker_behind(tmp_path):
    """kill -9 of `simlidar generate --workers 2` as soon as its workers exist."""
    args = [sys.executable, "-m", "simlidar.cli", "generate", "--workers", "2"]
    args += ["--train-size", "200000", "--test-size", "64", "--batch-size", "64"]
    args += ["--out", str(tmp_path / "data")]
    run = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, cwd=tmp_path)
    workers: list[int] = []
    try:
        wanted = min(2, usable_cores())
        if wanted > 1:
            workers = _wait_for(
                lambda: (found := _children(run.pid)) and len(found) >= wanted and found,
                "the run's 2 workers started",
            )
        else:
            time.sleep(3)  # one core: generate runs without a pool
            assert _children(run.pid) == []
        run.kill()  # SIGKILL: no cleanup runs in the parent
        run.wait()
        _wait_for(
            lambda: all(_state(pid) in (None, "Z") for pid in workers),
            f"workers {workers} of the killed run ended",
        )
    finally:
        run.kill()
        for pid in workers:  # ours: a failed run must not leave them spinning
            if _state(pid) not in (None, "Z"):
                os.kill(pid, signal.SIGKILL)
        run.stderr.close()


def test_a_worker_whose_parent_is_already_gone_ends_itself():
    """die_with_parent in a process whose parent is not the one it was forked by."""
    code = (
        "import os, sys; from simlidar.processes import die_with_parent; "
        "die_with_parent(os.getppid() + 1); sys.exit(3)"
    )
    done = subprocess.run([sys.executable, "-c", code], timeout=60)
    assert done.returncode == -signal.SIGKILL
    code = code.replace("os.getppid() + 1", "os.getppid()")  # its real parent: nothing happens
    assert subprocess.run([sys.executable, "-c", code], timeout=60).returncode == 3
