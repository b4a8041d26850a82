"""Outside builders that misbehave as processes do, run through ``simlidar bench`` (and
``train``) as the console command runs them: ``python -m simlidar.cli`` in a real process, whose
watched child runs the model's code (issue 58, finding 6).

Attack list:

* a builder that calls ``os._exit(0)``: bench ended with exit code 0, nothing written and no
  word; a model killed in training (SIGKILL, as the out-of-memory killer does) left a bare
  ``Killed``. Now one line on stderr, on a line of its own after the progress bar, exit code 1,
  nothing half-written.
* a builder that changes the working directory: a relative ``--out`` landed in the builder's
  folder, and the next message blamed the builder's file ("not found"). Now every path of the
  run is absolute before a model's code runs; the output lands where it was asked.
* a builder that starts a non-daemon thread that sleeps for ever: bench printed its results,
  then hung. Now the process ends, with a warning naming the thread; one that registers an
  atexit hook that never returns is ended by the watching parent.
* SIGTERM or SIGKILL to the command: the child (the model's run) ends with it, never left
  running as an orphan.
* a run killed while it wrote a cell or a checkpoint: its locked temporaries stayed in
  ``cells/`` and ``checkpoints/`` for good; now the next run into the folder removes them.
"""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from outside_builders import PLAIN_MODEL

BUILDERS = """
import atexit
import os
import signal
import threading
import time

from torch import nn
"""
BUILDERS += (
    PLAIN_MODEL
    + """

def exits(input_shape, classes, generator=None):  # when built, before anything is written
    os._exit(0)


class Killed(Plain):  # passes the probe, killed in its first training step
    calls = 0

    def forward(self, x):
        self.calls += 1
        if self.calls > 1:
            os.kill(os.getpid(), signal.SIGKILL)
        return super().forward(x)


def killed(input_shape, classes, generator=None):
    return Killed(input_shape[1] * input_shape[2], classes)


def moves(input_shape, classes, generator=None):
    os.chdir(ELSEWHERE)
    return build(input_shape, classes)


def lingers(input_shape, classes, generator=None):
    threading.Thread(target=time.sleep, args=(3600,), name="forever").start()
    return build(input_shape, classes)


def holds(input_shape, classes, generator=None):
    atexit.register(time.sleep, 3600)
    return build(input_shape, classes)


def sleeps(input_shape, classes, generator=None):
    with open(STARTED, "w") as started:  # the run's child is in the model's code
        started.write(str(os.getpid()))
    time.sleep(3600)
"""
)
SUITE = 'name = "misbehaving"\nmodels = ["cnn"]\nseeds = [0]\ndatasets = [{path}]\n'
SUITE += "[budget]\nepochs = 1\n"
TIMEOUT_S = 120  # a tiny bench takes a few seconds; a hang is what this catches


@pytest.fixture
def work(tmp_path, datasets):
    """A folder with the builders (b.py) and a suite (s.toml) naming the small noise-0.1
    dataset by a path relative to it: the commands run in it, with relative paths."""
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    code = BUILDERS.replace("ELSEWHERE", repr(str(elsewhere)))
    (tmp_path / "b.py").write_text(code.replace("STARTED", repr(str(tmp_path / "started"))))
    relative = os.path.relpath(datasets[0.1], tmp_path)
    (tmp_path / "s.toml").write_text(SUITE.format(path=repr(relative)))
    return tmp_path


def _run(work: Path, *args, code: str | None = None) -> subprocess.CompletedProcess:
    """``simlidar <args>`` as the console command runs it, in ``work``; with ``code``, through
    ``python -c code`` (which calls ``main()``) instead of ``-m simlidar.cli``."""
    launch = ["-c", code] if code else ["-m", "simlidar.cli"]
    return subprocess.run(
        [sys.executable, *launch, *map(str, args)],
        cwd=work,
        capture_output=True,
        text=True,
        timeout=TIMEOUT_S,
    )


def _left(folder: Path) -> list[str]:
    """Every path under ``folder`` (none if there is none), relative to it, sorted."""
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*"))


@pytest.mark.parametrize(
    "command, how, written",
    [
        ("bench --models b.py:exits", "exited with code 0", []),
        ("bench --models b.py:killed", "was killed by SIGKILL", ["cells", "suite.json"]),
        ("train --model b.py:exits", "exited with code 0", []),
    ],
)
def test_a_model_that_ends_its_process_is_named_in_one_line(work, datasets, command, how, written):
    name, *args = command.split()
    args += ["--dataset", datasets[0.1]] if name == "train" else ["--suite", "s.toml"]
    done = _run(work, name, *args, "--out", "out")
    assert done.returncode == 1, done.stderr
    assert "Traceback" not in done.stderr
    last = done.stderr.replace("\r", "\n").splitlines()[-1]  # not glued to the progress bar
    assert last.startswith(
        f"Error: simlidar {name} ended before it finished: its process {how} and no message "
        "(a model's code that called os._exit, say, or the kernel, out of memory); expected"
    ), done.stderr
    assert last.endswith("; a rerun skips the cells already written") == (name == "bench")
    assert _left(work / "out") == written  # bench's claim; no cell, checkpoint or temporary


def test_a_model_that_changes_the_working_directory_moves_no_path(work):
    """Relative --out, recipe path, dataset (the suite's) and builder file: the builder's
    os.chdir in the first model's check moved --out into its folder, and the second model's
    recipe lookups failed there."""
    (work / "r").mkdir()
    (work / "r" / "mine.toml").write_text(
        'model = "../b.py:build"\n[training]\noptimizer = "adam"\nlr = 1e-2\n'
        "batch_size = 32\nepochs = 1\n"
    )
    done = _run(
        work, "bench", "--suite", "s.toml", "--models", "b.py:moves,r/mine.toml", "--out", "out"
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith(f"2 cells in {work / 'out'}: results.json, report.md\n")
    cells = sorted(p.name for p in (work / "out" / "cells").iterdir())
    assert [c.split("__")[1] for c in cells] == ["b.moves", "mine"]
    assert list((work / "elsewhere").iterdir()) == []  # nothing landed where it moved to


def test_a_thread_a_model_leaves_running_does_not_keep_the_run(work):
    done = _run(work, "bench", "--suite", "s.toml", "--models", "b.py:lingers", "--out", "out")
    assert done.returncode == 0, done.stderr
    assert (work / "out" / "results.json").is_file() and "1 cells in" in done.stdout
    warning = done.stderr.strip().splitlines()[-1]
    assert warning == (
        "Warning: 2 thread(s) still running ('forever', 'forever'), started by a model's code: "
        "the run is over, and the process ends without waiting for them"
    )


def test_a_run_that_does_not_end_after_it_finished_is_ended(work):
    """An atexit hook that never returns (the thread check cannot see it): the parent ends the
    child once ENDING_S (here 1 s) have passed since it reported, with the code it reported."""
    code = "import simlidar.cli as cli; cli.watch.ENDING_S = 1.0; cli.main()"
    start = time.monotonic()
    args = ["bench", "--suite", "s.toml", "--models", "b.py:holds", "--out", "out", "--json"]
    done = _run(work, *args, code=code)
    assert done.returncode == 0, done.stderr
    assert (work / "out" / "results.json").is_file() and done.stdout.startswith('{"suite"')
    assert time.monotonic() - start < TIMEOUT_S / 2


def _state(pid: int) -> str | None:
    """A process's state letter (``Z``: a zombie, dead), None when it is gone."""
    try:
        return (Path("/proc") / str(pid) / "stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return None


@pytest.mark.parametrize("stop", [signal.SIGTERM, signal.SIGKILL])
def test_a_stopped_command_leaves_no_model_running(work, stop):
    """SIGTERM is passed on to the child, and the command ends by it as one process would;
    SIGKILL of the command ends the child with it (the parent-death signal)."""
    args = ["-m", "simlidar.cli", "bench", "--suite", "s.toml", "--models", "b.py:sleeps"]
    command = subprocess.Popen(
        [sys.executable, *args, "--out", "out"],
        cwd=work,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    started = work / "started"
    try:
        deadline = time.monotonic() + TIMEOUT_S
        while not (started.is_file() and started.read_text()):
            assert time.monotonic() < deadline and command.poll() is None, "never built"
            time.sleep(0.05)
        child = int(started.read_text())
        assert child != command.pid  # the model runs in a child of the command
        command.send_signal(stop)
        assert command.wait(timeout=TIMEOUT_S) == -stop
        while _state(child) not in (None, "Z"):
            assert time.monotonic() < deadline, f"the child {child} outlived the command"
            time.sleep(0.05)
        assert "Error" not in command.stderr.read()  # stopped as asked: no error to report
    finally:
        command.kill()
        command.wait()
        command.stderr.close()


def test_a_rerun_removes_what_a_run_killed_while_writing_left(tmp_path, datasets):
    """A cell's and a checkpoint's temporaries of a killed run (their locks free) go when the
    folder is claimed again; a live run's (its lock held) stay."""
    from simlidar.atomic import Temporary
    from simlidar.bench.outdir import claim
    from simlidar.bench.suite import load_suite

    suite_file = tmp_path / "s.toml"
    suite_file.write_text(SUITE.format(path=repr(str(datasets[0.1]))))
    suite, out = load_suite(suite_file), tmp_path / "out"
    claim(out, suite)
    (out / "checkpoints").mkdir()
    dead = [out / "cells" / ".a.json.partial-x1", out / "checkpoints" / ".a.pt.partial-y2"]
    for folder in dead:
        folder.mkdir()
        (folder / "half").write_bytes(b"{")
        folder.with_name(folder.name + ".lock").touch()
    live = Temporary(out / "cells", "b.json")
    try:
        claim(out, suite)
        assert _left(out / "checkpoints") == []
        assert _left(out / "cells") == sorted([live.path.name, live.lock_path.name])
    finally:
        live.release()
