"""Where a cell runs (simlidar.bench.hardware): threads the process can make, or one line."""

import resource

import pytest

from simlidar.bench.hardware import threads
from simlidar.errors import ResourceError
from simlidar.resources import thread_stack_bytes


def test_more_threads_than_the_address_space_holds_is_one_line_not_an_openmp_abort(
    datasets, tmp_path, limited_python
):
    """Under ``ulimit -v`` 4 GiB, 300 torch threads made libgomp abort the process ("Thread
    creation failed", which no handler catches); now they are refused before any is made,
    with nothing written, and a count that fits trains."""
    command = ["-m", "simlidar.cli", "train", "--model", "mlp", "--dataset", datasets[0.1]]
    limit = 4 * 2**30
    result = limited_python([*command, "--threads", 300, "--out", tmp_path / "r"], limit)
    assert result.returncode == 1 and "Traceback" not in result.stderr, result.stderr
    assert "libgomp" not in result.stderr, result.stderr
    (line,) = result.stderr.strip().splitlines()
    assert line.startswith("Error: --threads 300: 300 threads reserve"), line
    assert line.endswith("left under ulimit -v; expected fewer threads"), line
    assert not (tmp_path / "r").exists()
    fits = [*command, "--threads", 2, "--epochs", 1, "--out", tmp_path / "ok"]
    assert limited_python(fits, limit).returncode == 0


def test_the_thread_check_counts_twice_the_stack_a_thread(monkeypatch):
    import simlidar.resources

    stack = thread_stack_bytes()
    assert stack == resource.getrlimit(resource.RLIMIT_STACK)[0] or stack == 8 * 2**20
    monkeypatch.setattr(simlidar.resources, "_address_space_room", lambda: 2 * 3 * stack)
    with threads(3):  # exactly what three threads take
        pass
    with pytest.raises(ResourceError, match="--threads 4: 4 threads reserve"):
        with threads(4):
            pass
