"""Stream suites (issue 60, item 5): ``simlidar bench --suite`` of a suite with ``task =
"stream"`` makes its dataset, runs its networks and estimate, writes the report, keeps what is
done; its file and options are checked."""

import json
import re
from pathlib import Path

import pytest

from simlidar.bench.stream_report import report_table, summary
from simlidar.bench.stream_suite import is_stream_suite, load_stream_suite
from simlidar.bench.stream_task import read_cells
from simlidar.bench.suite import load_suite
from simlidar.errors import ConfigError

ROOT = Path(__file__).resolve().parents[2]
TINY = """name = "tiny-stream"
task = "stream"
models = ["mlp", "gru_rotations"]
window_models = ["mlp"]
estimate = ["mlp-latest"]
seeds = [0]
estimate_seeds = [0]
validation = 0.25

[generate]
train_size = 12
test_size = 8

[budget]
epochs = 1
"""


def test_the_shipped_stream_suite_reads():
    suite = load_stream_suite("stream")
    assert is_stream_suite("stream") and not is_stream_suite("quick")
    assert suite.models == ("cnn", "mlp", "gru_rotations", "lif_stream")
    assert suite.event_models == ("snn_simlidar_tuned",) and len(suite.seeds) == 5
    assert suite.window_models == ("cnn",)
    assert suite.generate == {"train_size": 1500, "test_size": 600}
    assert suite.epochs_of("cnn") == 30 and suite.epochs_of("lif_stream") is None
    with pytest.raises(ConfigError, match="key 'task': expected 'window' here"):
        load_suite("stream")  # the window suites' loader names what it is


@pytest.mark.parametrize(
    "change, words",
    [
        (('models = ["mlp", "gru_rotations"]', 'models = ["mlp", "nope"]'), "model recipe 'nope'"),
        (('estimate = ["mlp-latest"]', 'estimate = ["svm-latest"]'), "family 'svm-latest'"),
        (("seeds = [0]", "seeds = [-1]"), "key 'seeds': expected integers in [0, 2**63)"),
        (("validation = 0.25", "validation = 0.9"), "key 'validation': expected a fraction"),
        (("train_size = 12", "train_size = 0"), "[generate] train_size=0"),
        (("train_size = 12", "trains = 12"), "key 'generate.trains': expected one of"),
        (("[budget]\nepochs = 1", "[budget.cnn]\nepochs = 1"), "budget.cnn': expected a model"),
        (("[budget]\nepochs = 1", "[budget]\nepochs = 0"), "budget.epochs': expected a"),
        (('task = "stream"\n', 'task = "stream"\nboard_power_w = 5\n'), "key 'board_power_w'"),
    ],
)
def test_a_bad_stream_suite_is_named(tmp_path, change, words):
    path = tmp_path / "bad.toml"
    path.write_text(TINY.replace(*change))
    with pytest.raises(ConfigError, match=re.escape(words)):
        load_stream_suite(path)


def test_a_stream_suite_runs_keeps_and_refuses(tmp_path, cli):
    suite = tmp_path / "tiny.toml"
    suite.write_text(TINY)
    out = tmp_path / "bench"
    first = cli("bench", "--suite", suite, "--out", out)
    assert first.exit_code == 0, first.output
    assert "3 models in" in first.output
    cells = [json.loads(line) for line in (out / "cells.jsonl").read_text().splitlines()]
    assert [(c["model"], c["mode"], c["epochs"]) for c in cells] == [
        ("mlp", "frame", 1),
        ("gru_rotations", "sequence", 1),
        ("mlp-window", "window", 1),
    ]
    # the same network and seed, answering at its windows' ends: the same answers, sooner
    frame, window = cells[0], cells[2]
    assert frame["test_window_accuracy"] == window["test_window_accuracy"]
    assert window["first_answer_after_reference_ms"]["max"] < 15.0
    assert frame["first_answer_after_reference_ms"]["min"] > 40.0
    assert cells[0]["command"] == f"simlidar bench --suite {suite} --out {out} --threads 1"
    assert json.loads((out / "estimate.json").read_text())["delays"]["10"]["best"] == "mlp-latest"
    report = (out / "report.md").read_text()
    assert "| gru_rotations | 1 |" in report and "| estimate | 1 |" in report
    data = out / "data" / "simlidar-stream-4c-10rot-w32-v1.0.0"
    assert (data / "train.h5").is_file()
    again = cli("bench", "--suite", suite, "--out", out, "--json")
    assert again.exit_code == 0, again.output
    assert f"kept {data}" in again.output  # nothing made or trained anew
    assert len((out / "cells.jsonl").read_text().splitlines()) == 3
    other = tmp_path / "other.toml"
    other.write_text(TINY.replace("train_size = 12", "train_size = 14"))
    refused = cli("bench", "--suite", other, "--out", out)
    assert refused.exit_code == 1 and "Traceback" not in refused.output
    assert "already exists and was made with another configuration" in refused.output
    option = cli("bench", "--suite", suite, "--out", out, "--remeasure")
    assert option.exit_code == 2
    assert "--remeasure: not an option of a stream suite" in option.output


def test_the_docs_results_table_is_the_committed_one():
    """docs/streams.md's table is what the committed cells and estimate give (written by
    ``benchmark/stream_bench.py --no-train --doc``), not retyped."""
    results = ROOT / "benchmark/results/stream"
    cells = read_cells(results / "cells.jsonl", "simlidar-stream-4c-10rot-w32-v1.0.0")
    estimate = json.loads((results / "estimate.json").read_text())
    text = (ROOT / "docs/streams.md").read_text()
    block = text.split("<!-- stream-results:start -->\n")[1].split("<!-- stream-results:end -->")[0]
    assert block.strip("\n") == "\n".join(report_table(summary(cells), estimate))
    # the report too: its header, its rule, a row a model and the estimate's
    assert (results / "report.md").read_text().count("\n| ") == len(summary(cells)) + 3


def test_the_docs_speed_table_is_the_committed_one():
    """docs/streams.md's speed table is what ``benchmark/stream_speed.py`` writes from its
    committed figures (``--doc``), not retyped; the receiver's rows included."""
    import subprocess
    import sys

    figures = ROOT / "benchmark/results/stream-speed/2026-11-28.json"
    assert "receiver" in json.loads(figures.read_text())
    made = subprocess.run(
        [sys.executable, str(ROOT / "benchmark/stream_speed.py"), "--from-json", str(figures)],
        capture_output=True, text=True, check=True,
    )  # fmt: skip
    text = (ROOT / "docs/streams.md").read_text()
    block = text.split("<!-- stream-speed:start -->\n")[1].split("<!-- stream-speed:end -->")[0]
    assert block.strip("\n") == made.stdout.strip("\n")
