"""The published cell schema (simlidar/bench/cell.schema.json).

Attack list, one test (or parameter) each:
* the schema itself: not draft 2020-12, a required key that a committed cell lacks, a key every
  committed cell has left optional, `stopped` values other than the code's;
* every committed cell of every `simlidar bench` run under benchmark/results/ must validate; the
  benchmark scripts' own cells (another format) must be refused, not silently taken as cells;
* hand-broken cells: a missing required key, accuracy 1.5, a string where a number is, a
  negative seed or count, a bad digest, a boolean where an integer is, an early accuracy 2, a
  `stopped` word of no rule, NaN (valid for Python's json, invisible to a schema's ranges);
  the outside models' optional keys (`spec`, `device`, `threads`, `stepped`) of the wrong type;
"""

import json
import math
from pathlib import Path

import pytest

from simlidar.bench.merge import SCHEMA, check_cell, read_cell
from simlidar.bench.train import STOPS
from simlidar.errors import ResultsError

ROOT = Path(__file__).resolve().parents[2]
RESULTS = ROOT / "benchmark" / "results"
PAPER = RESULTS / "paper"
# benchmark/results/<folder>/cells written by the benchmark scripts in their own format, not by
# simlidar bench (no suite.json): the schema is not theirs
SCRIPT_CELLS = {
    "paper-table": "benchmark/paper_table.py",
    "scan-timing": "benchmark/scan_timing.py",
    "early-tradeoff": "benchmark/early_tradeoff.py",
}


def schema() -> dict:
    return json.loads(SCHEMA.read_text())


def bench_cells() -> list[Path]:
    """Every committed cell of a simlidar bench run (a folder with suite.json)."""
    return sorted(
        path
        for folder in RESULTS.iterdir()
        if (folder / "suite.json").is_file()
        for path in (folder / "cells").glob("*.json")
    )


def paper_cell(name: str = "simlidar-32c-noise0.1-paper-v2.0.0__cnn__seed0") -> dict:
    return json.loads((PAPER / "cells" / f"{name}.json").read_text())


def test_the_schema_is_draft_2020_12_and_requires_what_every_committed_cell_has():
    from jsonschema import Draft202012Validator

    document = schema()
    assert document["$schema"] == "https://json-schema.org/draft/2020-12/schema"
    Draft202012Validator.check_schema(document)
    cells = [json.loads(path.read_text()) for path in bench_cells()]
    assert len(cells) >= 240  # paper, physical, physical-ablation
    every = set.intersection(*(set(cell) for cell in cells))
    assert set(document["required"]) == every
    assert document["additionalProperties"] is True
    assert tuple(document["properties"]["stopped"]["enum"]) == STOPS
    for key in ("spec", "device", "threads", "stepped"):  # the outside models' keys, optional
        assert key in document["properties"] and key not in document["required"]


def test_every_committed_bench_cell_follows_the_schema():
    checked = 0
    for folder in sorted(p for p in RESULTS.iterdir() if (p / "cells").is_dir()):
        if (folder / "suite.json").is_file():
            for path in sorted((folder / "cells").glob("*.json")):
                read_cell(path)  # raises on the first problem, naming the file
                checked += 1
        else:  # a benchmark script's cells: named here, and not taken for bench cells
            assert folder.name in SCRIPT_CELLS, f"{folder}: cells of neither bench nor a script"
            first = next((folder / "cells").glob("*.json"))
            with pytest.raises(ResultsError, match="the cell: '[a-z_]+' is a required property"):
                read_cell(first)
    assert checked == len(bench_cells()) >= 240


BROKEN = [  # (what is done to a good cell, the words of the refusal)
    (lambda c: c.pop("accuracy"), "the cell: 'accuracy' is a required property"),
    (lambda c: c.update(accuracy=1.5), "key 'accuracy': 1.5 is greater than the maximum of 1"),
    (lambda c: c.update(params="115200"), "key 'params': '115200' is not of type 'integer'"),
    (lambda c: c.update(latency_ms="fast"), "key 'latency_ms': 'fast' is not of type 'number'"),
    (lambda c: c.update(seed=-1), "key 'seed': -1 is less than the minimum of 0"),
    (lambda c: c["confusion"][0].__setitem__(3, -2), "key 'confusion.0.3': -2 is less than"),
    (lambda c: c.update(classes=True), "key 'classes': True is not of type 'integer'"),
    (lambda c: c["inputs"].update(splits_sha256="abc"), "key 'inputs.splits_sha256'"),
    (lambda c: c["inputs"].pop("rules"), "key 'inputs': 'rules' is a required property"),
    (lambda c: c.update(stopped="bored"), "key 'stopped': 'bored' is not one of"),
    (lambda c: c["synaptic_operations"].update(dense=-1), "key 'synaptic_operations.dense'"),
    (lambda c: c.update(validation_curve=[0.5, 7]), "key 'validation_curve.1': 7 is greater"),
    (lambda c: c.update(threads="4"), "key 'threads': '4' is not of type 'integer'"),
    (lambda c: c.update(device=3), "key 'device': 3 is not of type 'string'"),
    (lambda c: c.update(spec=[1]), "key 'spec': [1] is not of type 'object'"),
    (lambda c: c.update(stepped={"decision_step_mean": "x"}), "key 'stepped.decision_step_mean'"),
]


@pytest.mark.parametrize("breaking, words", BROKEN)
def test_hand_broken_cells_are_refused(breaking, words):
    cell = paper_cell()
    check_cell(cell, "good.json")  # the cell before it was broken passes
    breaking(cell)
    with pytest.raises(ResultsError) as caught:
        check_cell(cell, "broken.json")
    message = str(caught.value)
    assert message.startswith("broken.json: ") and words in message, message
    assert "\n" not in message and message.endswith(
        "expected a cell as simlidar/bench/cell.schema.json describes"
    )


def test_spiking_cells_and_the_outside_models_keys_are_typed_not_forbidden(tmp_path):
    spiking = paper_cell("simlidar-32c-noise0.5-paper-v2.0.0__snn_simlidar__seed1")
    check_cell(spiking, "snn.json")
    outside = dict(
        spiking,
        spec={"output": "spikes", "encoding": "latency", "steps": 25, "readout": "count"},
        device="cuda",
        threads=2,
        stepped={"decision_step_mean": 7.5, "input_spikes_mean": 120.0, "no_decision": None},
        my_field=[1, 2],  # outside models add fields of their own
    )
    check_cell(outside, "outside.json")
    broken = dict(spiking, early={**spiking["early"], "accuracy": 2})
    with pytest.raises(ResultsError, match="key 'early.accuracy': 2 is greater"):
        check_cell(broken, "x")
    (tmp_path / "nan.json").write_text(
        json.dumps(dict(spiking, accuracy="@")).replace('"@"', "NaN")
    )
    with pytest.raises(ResultsError, match="nan.json: cannot be read .NaN is not a number"):
        read_cell(tmp_path / "nan.json")
    no_cap = dict(spiking, budget={"epochs": 2, "max_seconds": math.inf})  # json writes Infinity
    (tmp_path / "inf.json").write_text(json.dumps(no_cap))
    assert read_cell(tmp_path / "inf.json")["budget"]["max_seconds"] == math.inf
