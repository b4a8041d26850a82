"""Watching a command that runs a model's own code (``simlidar train``, ``bench`` and
``evaluate``): the
console command runs it again in a child process, which reports its exit code on a pipe just
before it ends (:class:`simlidar.cli.Entry`). A model's code may end the process
(``os._exit``, a signal) or leave a thread running that the interpreter would wait for; the
parent names the first in one line and ends the second."""

import os
import select
import signal
import subprocess
import sys
import threading

import click

# the commands that run a model's own code, each in a watched child process (Entry): the
# parent, a second Python with click, adds about 0.25 s of wall time to a run (a bench that
# stops at a bad --models: 3.62 s against 3.37, medians of 8), against a model's seconds
WATCHED = frozenset({"train", "bench", "evaluate"})
# set in the watched child: "<parent pid>:<its end of the pipe to report on>:<program name>"
WATCH_ENV = "SIMLIDAR_WATCHED_BY"
# after the child has reported its exit code, how long its interpreter may take to end before
# the parent ends it (what keeps it then is not the run: an atexit hook or a process that a
# model started): ten times the 0.8-1.1 s that the interpreter took to end after a tiny bench
ENDING_S = 10.0
# how often the parent looks whether the child has ended, while a process that the child
# started holds the pipe open (no end of file then): at most this late
POLL_S = 0.5


def command(args: list[str]) -> str | None:
    """The command of a command line (the group's own options take no values)."""
    return next((arg for arg in args if not arg.startswith("-")), None)


def _program() -> str:
    """What click calls this program in help and usage lines: ``python -m simlidar.cli``, or
    the console command's file name."""
    package = getattr(sys.modules["__main__"], "__package__", None)
    return f"python -m {package}" if package else os.path.basename(sys.argv[0])


def watch(command: str) -> int:
    """Run this command line in a watched child process and wait for it (:class:`Entry`); the
    exit code to end with."""
    read, write = os.pipe()
    child = subprocess.Popen(
        [sys.executable, "-m", "simlidar.cli", *sys.argv[1:]],
        env={**os.environ, WATCH_ENV: f"{os.getpid()}:{write}:{_program()}"},
        pass_fds=(write,),
    )
    os.close(write)
    passed = []

    def pass_on(signum, _frame):
        passed.append(signum)
        child.send_signal(signum)

    # a terminal's Ctrl-C reaches the child too, which stops and reports; SIGTERM and SIGHUP
    # (kill, timeout) reach this process alone
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    for signum in (signal.SIGTERM, signal.SIGHUP):
        signal.signal(signum, pass_on)
    reported = _reported(read, child)
    if reported is not None:
        try:
            child.wait(timeout=ENDING_S)
        except subprocess.TimeoutExpired:  # the run is over: what keeps the process is not
            child.kill()
            child.wait()
        return reported
    code = child.wait()
    if -code in passed:  # stopped as asked: end as one process would have
        signal.signal(-code, signal.SIG_DFL)
        os.kill(os.getpid(), -code)
    how = f"was killed by {signal.Signals(-code).name}" if code < 0 else f"exited with code {code}"
    rerun = "; a rerun skips the cells already written" if command == "bench" else ""
    # on a line of its own: the child may have died in the middle of its progress bar's line
    click.echo(
        f"\nError: simlidar {command} ended before it finished: its process {how} and no "
        "message (a model's code that called os._exit, say, or the kernel, out of memory); "
        "expected a finished run or a one-line error. What it wrote is whole (each file is "
        f"written in one step){rerun}",
        err=True,
    )
    return 1


def _reported(read: int, child: subprocess.Popen) -> int | None:
    """The exit code the child reported on the pipe ``read``, or None once it has ended without
    one. A process the child started may hold the pipe's other end open: it is not waited
    for."""
    received = b""
    while True:
        if select.select([read], [], [], POLL_S)[0]:
            chunk = os.read(read, 64)
            received += chunk
            if not chunk or received.endswith(b"\n"):
                break
        elif child.poll() is not None:
            break
    os.close(read)
    text = received.decode("ascii", "replace").strip()
    return int(text) if text.isdigit() else None


def reporting(watcher: str) -> tuple[int, str]:
    """In the watched child: (the pipe's end to report the exit code on, the program's name
    from the parent). The pipe is not inherited by what this process starts, and this
    process ends when its parent does."""
    from simlidar.processes import die_with_parent

    parent, fd, program = watcher.split(":", 2)
    die_with_parent(int(parent))
    os.set_inheritable(int(fd), False)
    return int(fd), program


def report(pipe: int, code: int) -> None:
    """Tell the watching parent, on the pipe ``pipe``, that this process ends with ``code``."""
    try:
        os.write(pipe, f"{code}\n".encode())
    except OSError:  # the parent is gone, and this process with it
        pass


def end(code, pipe: int) -> None:
    """End the watched child with ``code`` (a SystemExit's), reported on the pipe ``pipe``
    first; without waiting for threads left running (a model's), which a warning names."""
    if code is None:
        code = 0
    elif not isinstance(code, int):  # as Python ends on sys.exit("message")
        click.echo(str(code), err=True)
        code = 1
    report(pipe, code)
    left = [
        thread.name
        for thread in threading.enumerate()
        if thread is not threading.main_thread() and not thread.daemon and thread.is_alive()
    ]
    if left:
        click.echo(
            f"Warning: {len(left)} thread(s) still running ({', '.join(map(repr, left))}), "
            "started by a model's code: the run is over, and the process ends without "
            "waiting for them",
            err=True,
        )
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    sys.exit(code)
