"""benchmark/loader_speed.py runs at tiny sizes: it prints the three ways' seconds and ratios
and writes them as JSON (the figures are for people, not for asserts), and refuses a bad
argument in one line, writing nothing."""

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "benchmark" / "loader_speed.py"
ROW = r"  (.+?) +(\d+\.\d+) s  ratio +(\d+\.\d+)"


def run(*args, cwd=None) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, str(SCRIPT), *map(str, args)],
        capture_output=True,
        text=True,
        cwd=cwd,
        timeout=300,
    )


def checked(done, figures: Path, samples: int, whole: bool) -> dict:
    """The printed table and the JSON agree, every time and ratio positive."""
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert lines[0].startswith("train split of ")
    assert f": {samples} samples of 16 x 16, " in lines[0]
    assert ("read whole" if whole else "chunk cache") in lines[0]
    rows = [re.fullmatch(ROW, line) for line in lines[1:]]
    assert all(rows) and len(rows) == 3, lines
    assert [r[1] for r in rows] == [
        "load_split",
        "PulseDataset, ds[i] in order",
        "PulseDataset, DataLoader shuffled (batch 64)",
    ]
    record = json.loads(figures.read_text())
    assert record["samples"] == samples and record["read_whole"] is whole
    assert record["split_bytes"] == samples * (16 * 16 * 4 + 8)
    for way, row in zip(("load_split", "in_order", "shuffled"), rows):
        assert record["seconds"][way] > 0 and record["ratio_to_load_split"][way] > 0
        assert record["ratio_to_load_split"][way] == pytest.approx(
            record["seconds"][way] / record["seconds"]["load_split"]
        )
        assert float(row[2]) == pytest.approx(record["seconds"][way], abs=1e-4)
    assert record["ratio_to_load_split"]["load_split"] == 1.0
    assert record["command"].startswith("python benchmark/loader_speed.py ")
    return record


def test_it_times_a_generated_dataset(tmp_path):
    figures = tmp_path / "loader.json"
    done = run("--samples", 64, "--rounds", 1, "--json", figures)
    record = checked(done, figures, 64, whole=True)
    assert record["data"].startswith("a generated dataset, simlidar-32c-noise0.2-paper-")
    assert record["memory_budget_bytes"] == 512 * 2**20


def test_it_times_a_given_dataset_through_the_chunk_cache(datasets, tmp_path):
    figures = tmp_path / "loader.json"
    done = run("--data", datasets[0.1], "--budget-mib", 0, "--rounds", 1, "--json", figures)
    record = checked(done, figures, 96, whole=False)
    assert record["data"] == str(datasets[0.1]) and record["memory_budget_bytes"] == 0


@pytest.mark.parametrize(
    "args, words",
    [
        (["--rounds", "0"], "argument --rounds: '0': expected an integer in [1, 1000]"),
        (["--samples", "8"], "argument --samples: '8': expected an integer in"),
        (["--budget-mib", "-1"], "argument --budget-mib: '-1': expected an integer in"),
        (["--split", "val"], "argument --split: invalid choice: 'val'"),
        (["--json", "no/x.json"], "argument --json: 'no/x.json': expected a file in"),
        (["--data", "/nonexistent/x"], "/nonexistent/x: expected a dataset directory"),
    ],
)
def test_a_bad_argument_is_one_line(args, words, tmp_path):
    done = run(*args, cwd=tmp_path)
    assert done.returncode in (1, 2) and "Traceback" not in done.stderr, done.stderr
    (line,) = [x for x in done.stderr.splitlines() if "error: " in x]
    assert words in line, line
    assert not any(tmp_path.iterdir())
