"""The published cell schema (simlidar/bench/cell.schema.json) and `simlidar report`, which
merges the cells of several benchmark runs into one report.

Attack list, one test (or parameter) each:
* the schema itself: not draft 2020-12, a required key that a committed cell lacks, a key every
  committed cell has left optional, `stopped` values other than the code's;
* every committed cell of every `simlidar bench` run under benchmark/results/ must validate; the
  benchmark scripts' own cells (another format) must be refused, not silently taken as cells;
* hand-broken cells: a missing required key, accuracy 1.5, a string where a number is, a
  negative seed or count, a bad digest, a boolean where an integer is, an early accuracy 2, a
  `stopped` word of no rule, NaN (valid for Python's json, invisible to a schema's ranges);
  the outside models' optional keys (`spec`, `device`, `threads`, `stepped`) of the wrong type;
* merging the committed paper run with a folder a tiny `simlidar bench` made: one report with
  both, the paper's row, a model trained on other data shown once per run rather than averaged;
* a folder whose dataset of the same name holds other data (the tiny bench on a small dataset
  named as the paper's): refused in one line, exit 1, nothing written;
* a dataset without a digest (null) beside another folder's cells of that name: refused;
* two different cells of the same (dataset, model, seed) in two folders: refused naming both;
  identical copies, and a folder given twice: kept once;
* the seeds of one model split over two folders (same recipe, rules and data): one row;
* a broken cell among good ones, a folder without cells, a path that is no folder, a cell that
  is not JSON: one line, exit 1, nothing written;
* --out: a non-empty folder that no report wrote, an input folder (refused, untouched), a
  file and '' (exit 2, as every --out), an earlier report (replaced).
"""

import json
import math
import os
from pathlib import Path

import pytest

from simlidar.bench.merge import SCHEMA, check_cell, read_cell
from simlidar.bench.outdir import MAX_JSON_BYTES
from simlidar.bench.run import run_suite
from simlidar.bench.suite import load_suite
from simlidar.bench.train import STOPS
from simlidar.errors import ResultsError
from simlidar.generator.config import GeneratorConfig
from simlidar.generator.generate import generate
from simlidar.generator.profiles import load_profile

ROOT = Path(__file__).resolve().parents[2]
RESULTS = ROOT / "benchmark" / "results"
PAPER = RESULTS / "paper"
# benchmark/results/<folder>/cells written by the benchmark scripts in their own format, not by
# simlidar bench (no suite.json): the schema is not theirs
SCRIPT_CELLS = {
    "paper-table": "benchmark/paper_table.py",
    "scan-timing": "benchmark/scan_timing.py",
    "early-tradeoff": "benchmark/early_tradeoff.py",
    "early-objectives": "benchmark/early_objectives.py",
    "early-objectives-crops": "benchmark/early_objectives.py",
    "sweep-decisions": "benchmark/sweep_decisions.py",
    "sweep-decisions-scnn": "benchmark/sweep_decisions.py",
    "weather": "benchmark/weather.py",
}
TINY = """
name = "tiny"
description = "a tiny run to merge with the paper's"
models = [{models}]
seeds = [0]
datasets = ["{dataset}"]

[budget]
epochs = 1
"""


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


def folder_of(root: Path, cells: dict, suite: str | None = "copied") -> Path:
    """A run folder holding ``cells`` (file stem -> cell) and, with ``suite``, a suite.json."""
    (root / "cells").mkdir(parents=True)
    for stem, cell in cells.items():
        (root / "cells" / f"{stem}.json").write_text(json.dumps(cell))
    if suite is not None:
        (root / "suite.json").write_text(json.dumps({"name": suite}))
    return root


def refused(result, text: str, code: int = 1) -> str:
    """The one error line of a refused command, which must hold ``text``."""
    assert result.exit_code == code, result.output
    assert "Traceback" not in result.output
    errors = [line for line in result.output.splitlines() if line.startswith("Error")]
    assert len(errors) == 1 and text in errors[0], result.output
    return errors[0]


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
    (lambda c: c.update(stepped={"decision_step_mean": "x"}), "key 'stepped'"),
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
    stepped = json.loads(
        (
            ROOT
            / "benchmark/results/outside/cells"
            / "simlidar-32c-noise0.1-paper-v2.0.0__snntorch_lif__seed0.json"
        ).read_text()
    )
    outside = dict(
        spiking,
        spec=stepped["spec"],
        device="cuda",
        threads=2,
        stepped=stepped["stepped"],
        my_field=[1, 2],  # outside models add fields of their own
    )
    check_cell(outside, "outside.json")
    for bad, words in [
        (dict(outside, spec={**stepped["spec"], "readout": "count"}), "key 'spec.readout'"),
        (dict(outside, stepped={**stepped["stepped"], "steps": 0}), "key 'stepped.steps'"),
    ]:
        with pytest.raises(ResultsError, match=words):
            check_cell(bad, "x")
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


@pytest.fixture(scope="module")
def tiny_runs(tmp_path_factory, catalog):
    """Two folders that a tiny `simlidar bench` wrote on small datasets of the paper profile:
    ``mine``, the spiking network and the CNN on 8 classes (a dataset name of its own), and
    ``clash``, the CNN on 32 classes at noise 0.1, a dataset named as the paper suite's but
    holding other data (64 / 32 samples, not 3000 / 600)."""
    root = tmp_path_factory.mktemp("tiny")
    paper = load_profile("paper")
    made = {}
    for name, classes, train, test in (("mine", 8, 48, 16), ("clash", 32, 64, 32)):
        config = GeneratorConfig.from_profile(
            paper, classes=classes, train_size=train, test_size=test
        )
        (made[name],) = generate(config, [0.1], catalog, root / "data", progress=False)
    assert made["clash"].path.name == "simlidar-32c-noise0.1-paper-v2.0.0"
    runs = {}
    for name, models in (("mine", '"snn_simlidar", "cnn"'), ("clash", '"cnn"')):
        suite = root / f"{name}.toml"
        suite.write_text(TINY.format(models=models, dataset=made[name].path))
        run_suite(load_suite(suite), root / name, progress=False)
        runs[name] = root / name
    return runs


def test_the_paper_run_and_a_tiny_bench_merge_into_one_report(tiny_runs, tmp_path, cli):
    out = tmp_path / "merged"
    result = cli("report", PAPER, tiny_runs["mine"], "--out", out)
    assert result.exit_code == 0, result.output
    assert f"86 cells of 2 runs in {out}" in result.output
    results = json.loads((out / "results.json").read_text())
    assert [s["cells"] for s in results["merged_from"]] == [84, 2]
    assert [s["suite"] for s in results["merged_from"]] == ["paper", "tiny"]
    assert results["suite"]["name"] == "paper + tiny"
    cells = results["cells"]
    assert len(cells) == 86 and not any("per_sample" in c for c in cells)
    for cell in cells:
        check_cell(cell, "merged")  # still cells of the schema
    mine = [c for c in cells if c["origin"] == str(tiny_runs["mine"])]
    assert {c["dataset"] for c in mine} == {"simlidar-8c-noise0.1-paper-v2.0.0"}
    # the paper's cnn and snn_simlidar trained on the 32-class data at noise 0.1, the tiny
    # run's on 8 classes: each shown once per run, never averaged into one row
    assert {c["model"] for c in mine} == {"snn_simlidar (tiny)", "cnn (tiny)"}
    text = (out / "report.md").read_text()
    assert text.startswith("# Benchmark report: suite paper + tiny")
    # the tiny run's splits are not the paper's size: the paper's SNN goes to the note
    assert "| *paper: SNN 256-400-32* |" not in text
    assert "**Not comparable with the paper's figures.**" in text
    assert "The paper's SNN 256-400-32, on its own data: 99.83 % at noise 0.1" in text
    assert "| cnn (paper) | 100.00 ± 0.00 (3) | 96.28 ± 0.42 (3) |" in text
    assert "| cnn (tiny) | " in text and "| snn_simlidar (tiny) | " in text
    assert "| snn_simlidar_tuned | 99.28 ± 0.25 (3) | 95.83 ± 0.33 (3) |" in text  # one run's
    assert (
        "cnn, snn_simlidar are shown once per run (paper, tiny): their cells differ in "
        "training rules and datasets at noise 0.1 (simlidar-32c-noise0.1-paper-v2.0.0, "
        "simlidar-8c-noise0.1-paper-v2.0.0)." in text
    )
    assert "## simlidar-8c-noise0.1-paper-v2.0.0" in text
    assert "## simlidar-32c-noise0.5-paper-v2.0.0" in text
    for picture in ("accuracy_vs_noise.png", "decisions.png", "confusion.png"):
        assert (out / picture).stat().st_size > 1000 and f"]({picture})" in text
    assert sorted(p.name for p in out.parent.iterdir()) == ["merged"]  # no temporaries left

    # a second report into the same --out replaces the first
    again = cli("report", tiny_runs["mine"], "--out", out)
    assert again.exit_code == 0, again.output
    assert len(json.loads((out / "results.json").read_text())["cells"]) == 2
    assert "cnn (paper)" not in (out / "report.md").read_text()


def test_a_folder_whose_dataset_holds_other_data_is_refused(tiny_runs, tmp_path, cli):
    out = tmp_path / "new" / "merged"
    line = refused(
        cli("report", PAPER, tiny_runs["clash"], "--out", out),
        "dataset simlidar-32c-noise0.1-paper-v2.0.0: ",
    )
    assert "were made from different data of that name" in line
    assert str(PAPER / "cells") in line and str(tiny_runs["clash"] / "cells") in line
    assert not (tmp_path / "new").exists()  # nothing written, not even --out's parent


def test_a_cell_without_a_data_digest_is_refused_beside_another_folders(tmp_path, cli):
    name = "simlidar-32c-noise0.1-paper-v2.0.0__cnn__seed0"
    blind = paper_cell()
    blind["inputs"]["splits_sha256"] = None
    blind["seed"] = 7
    check_cell(blind, "null digest")  # a dataset without SHA256SUMS: valid on its own
    a = folder_of(tmp_path / "a", {name: paper_cell()})
    b = folder_of(tmp_path / "b", {name.replace("seed0", "seed7"): blind})
    line = refused(cli("report", a, b, "--out", tmp_path / "out"), "records no data digest")
    assert "seed7.json" in line and "seed0.json" in line
    assert not (tmp_path / "out").exists()
    assert cli("report", b, "--out", tmp_path / "out").exit_code == 0  # alone it is fine


def test_two_different_cells_of_one_dataset_model_and_seed_are_refused(tmp_path, cli):
    name = "simlidar-32c-noise0.1-paper-v2.0.0__cnn__seed0"
    a = folder_of(tmp_path / "a", {name: paper_cell()})
    b = folder_of(tmp_path / "b", {name: dict(paper_cell(), accuracy=0.5)})
    line = refused(
        cli("report", a, b, "--out", tmp_path / "out"),
        "cell (simlidar-32c-noise0.1-paper-v2.0.0, cnn, seed 0) is in",
    )
    assert f"{a / 'cells' / name}.json and in {b / 'cells' / name}.json" in line
    assert "(key 'accuracy')" in line and not (tmp_path / "out").exists()
    copy = folder_of(tmp_path / "copy", {name: paper_cell()})  # identical: kept once
    merged = cli("report", a, copy, a, "--out", tmp_path / "out")
    assert merged.exit_code == 0, merged.output
    assert "1 cells of 2 runs" in merged.output


def test_one_models_seeds_from_two_folders_share_one_row(tmp_path, cli):
    cells = {p.stem: json.loads(p.read_text()) for p in (PAPER / "cells").glob("*__cnn__*")}
    first = {k: v for k, v in cells.items() if not k.endswith("seed2")}
    second = {k: v for k, v in cells.items() if k.endswith("seed2")}
    a = folder_of(tmp_path / "a", first, suite="paper")
    b = folder_of(tmp_path / "b", second, suite="paper")
    result = cli("report", a, b, "--out", tmp_path / "out")
    assert result.exit_code == 0, result.output
    text = (tmp_path / "out" / "report.md").read_text()
    # the committed report's row, from two folders
    row = "| cnn | 100.00 ± 0.00 (3) | 96.28 ± 0.42 (3) | 86.22 ± 1.55 (3) | 70.83 ± 0.50 (3) |"
    assert row in text and row in (PAPER / "report.md").read_text()
    assert "shown once per run" not in text
    assert "suite a + b" in text.splitlines()[0]  # two runs of one suite: named by folder


def test_bad_folders_and_cells_are_refused_in_one_line_with_nothing_written(tmp_path, cli):
    name = "simlidar-32c-noise0.1-paper-v2.0.0__cnn__seed0"
    good = folder_of(tmp_path / "good", {name: paper_cell()})
    out = tmp_path / "out"
    broken = folder_of(
        tmp_path / "broken", {name.replace("cnn", "x"): dict(paper_cell(), accuracy=1.5)}
    )
    line = refused(cli("report", good, broken, "--out", out), "key 'accuracy': 1.5 is greater")
    assert line.startswith(f"Error: {broken / 'cells'}")
    empty = tmp_path / "empty"
    empty.mkdir()
    refused(cli("report", good, empty, "--out", out), "no finished cells (cells/*.json)")
    refused(cli("report", tmp_path / "missing", "--out", out), "not a folder; expected a benchmark")
    junk = folder_of(tmp_path / "junk", {})
    (junk / "cells" / "x.json").write_text("{not json")
    refused(cli("report", junk, "--out", out), "x.json: cannot be read (Expecting property name")
    (junk / "cells" / "x.json").write_text("[1, 2]")
    refused(cli("report", junk, "--out", out), "x.json: the cell: [1, 2] is not of type 'object'")
    assert not out.exists()

    # --out: a folder of other files is refused and left as it was; a file too; '' is usage
    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    refused(
        cli("report", good, "--out", other), "not empty and not a folder written by simlidar report"
    )
    assert [p.name for p in other.iterdir()] == ["notes.txt"]
    refused(
        cli("report", good, "--out", good), "not empty and not a folder written by simlidar report"
    )
    (tmp_path / "file").write_text("x")
    refused(cli("report", good, "--out", tmp_path / "file"), "is a file", code=2)  # as every --out
    refused(cli("report", good, "--out", ""), "'' is empty", code=2)
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "broken", "empty", "file", "good", "junk", "other",
    ]  # fmt: skip


def test_the_committed_outside_models_merge_with_the_paper_run(tmp_path, cli):
    """docs/benchmark.md's leaderboard: the snnTorch and Norse examples' run on the paper
    suite's data beside every shipped model, with the paper's row (both runs' splits are the
    paper's size)."""
    out = tmp_path / "leaderboard"
    result = cli("report", PAPER, ROOT / "benchmark/results/outside", "--out", out)
    assert result.exit_code == 0, result.output
    text = (out / "report.md").read_text()
    assert "| *paper: SNN 256-400-32* | 99.83 | 96.16 | 82.66 | 68.16 |" in text
    assert "| snntorch_lif | 98.50 (1) §" in text and "| norse_lif | 99.17 (1) §" in text
    assert "| snn_simlidar_tuned | 99.28 ± 0.25 (3) |" in text


def test_two_versions_of_one_model_are_refused_naming_the_recipe_that_changed(tmp_path, cli):
    name = "simlidar-32c-noise0.1-paper-v2.0.0__cnn__seed0"
    other = paper_cell()
    other["inputs"] = dict(other["inputs"], recipe_sha256="f" * 64)
    other["accuracy"] = 0.5  # what the other recipe scored: a consequence, not the cause
    a = folder_of(tmp_path / "a", {name: paper_cell()})
    b = folder_of(tmp_path / "b", {name: other})
    line = refused(cli("report", a, b, "--out", tmp_path / "out"), "which differ (recipe)")
    assert "accuracy" not in line and not (tmp_path / "out").exists()


HOSTILE_CELLS = [  # (what stands in cells/x.json, the words of the refusal)
    (lambda p: p.write_text("[" * 100_000 + "]" * 100_000), "JSON nested too deeply"),
    (lambda p: os.mkfifo(p), "expected a regular file, got a named pipe"),
    (lambda p: p.symlink_to("/dev/zero"), "expected a regular file, got a character device"),
    (lambda p: p.write_bytes(b" " * (MAX_JSON_BYTES + 1)), "expected a file of at most"),
    (
        lambda p: p.write_text(json.dumps(dict(paper_cell(), model="x" * 100_000))),
        "key 'model': 'xxxxx",
    ),
    (lambda p: p.write_text(json.dumps(dict(paper_cell(), accuracy=math.nan))), "NaN"),
]


@pytest.mark.parametrize("making, words", HOSTILE_CELLS)
def test_a_hostile_cell_file_is_refused_in_one_line_without_reading_it_whole(
    making, words, tmp_path, cli
):
    """A cell nested past the parser's depth, a named pipe (which would hang the report), a
    link to an endless device, an oversized file and a 100,000-character model name (which
    the pictures' legend would try to draw) are each one line, nothing written."""
    folder = folder_of(tmp_path / "run", {})
    making(folder / "cells" / "x.json")
    line = refused(cli("report", folder, "--out", tmp_path / "out"), words)
    assert line.startswith(f"Error: {folder / 'cells' / 'x.json'}: ") and len(line) < 400
    assert not (tmp_path / "out").exists()


def test_a_suite_json_that_is_a_pipe_is_never_opened(tmp_path, cli):
    name = "simlidar-32c-noise0.1-paper-v2.0.0__cnn__seed0"
    folder = folder_of(tmp_path / "run", {name: paper_cell()}, suite=None)
    os.mkfifo(folder / "suite.json")  # opening it would wait for a writer for ever
    result = cli("report", folder, "--out", tmp_path / "out")
    assert result.exit_code == 0, result.output
