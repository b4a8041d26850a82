"""``simlidar evaluate``: a saved model scored on its own dataset gives train's accuracy to the
sample, on another noise level other figures in the same cell format; the checkpoint is read
as a file from elsewhere and the dataset must fit it.

Bad input covered (each one line, no traceback, nothing written): a missing file, a file that
is no checkpoint, a zip that torch cannot read, a checkpoint of other parts or NaN weights, a
checkpoint whose recipe names outside code (never imported unless ``--model`` names the same
builder), a dataset of another class count, input shape, coding of no return (profile) or,
where the checkpoint records its training data, timing; an ``--out`` that exists; an
install without torch.
"""

import json
import sys
import zipfile
from pathlib import Path

import pytest
import torch
from outside_builders import PLAIN_MODEL

from simlidar.bench.checkpoints import data_record
from simlidar.bench.merge import SCHEMA
from simlidar.generator.config import GeneratorConfig
from simlidar.generator.generate import generate
from simlidar.generator.profiles import load_profile

SNN = """
model = "snn"
[architecture]
hidden = [64]
[training]
optimizer = "adam"
lr = 3e-3
batch_size = 32
epochs = 4
"""
PLAIN = "\nfrom torch import nn\n" + PLAIN_MODEL


@pytest.fixture(scope="module")
def trained(tmp_path_factory, datasets, cli):
    """Two models trained by ``simlidar train --json`` on the noise-0.1 dataset: a small dense
    SNN (a recipe file) and the shipped MLP; {name: train's JSON record}."""
    folder = tmp_path_factory.mktemp("trained")
    recipe = folder / "tiny_snn.toml"
    recipe.write_text(SNN)
    records = {}
    for name, model in (("snn", recipe), ("mlp", "mlp")):
        args = ["train", "--model", model, "--dataset", datasets[0.1], "--out", folder]
        result = cli(*args, "--epochs", "4", "--json")
        assert result.exit_code == 0, result.output
        records[name] = json.loads(result.stdout)
    return records


@pytest.fixture(scope="module")
def others(tmp_path_factory, catalog):
    """Small datasets that the models of ``trained`` do not fit: 8 classes, 8 columns, the
    paper profile (every pixel a spike), and one that they fit by shape but not by timing
    (scan): {what: path}."""
    out = tmp_path_factory.mktemp("others")
    configs = {
        "classes": GeneratorConfig(classes=8, train_size=16, test_size=16),
        "width": GeneratorConfig(width=8, train_size=32, test_size=32),
        "profile": GeneratorConfig(train_size=32, test_size=32, profile=load_profile("paper")),
        "timing": GeneratorConfig(train_size=32, test_size=32, timing="scan"),
    }
    return {
        what: generate(config, [0.1], catalog, out / what, progress=False)[0].path
        for what, config in configs.items()
    }


def _evaluate(cli, checkpoint, dataset, *more):
    result = cli("evaluate", checkpoint, "--dataset", dataset, "--json", *more)
    assert result.exit_code == 0, result.output
    return json.loads(result.stdout), result


def _one_line(result, code: int, *words: str) -> None:
    assert result.exit_code == code, result.output
    assert "Traceback" not in result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("Error: "), lines
    for word in words:
        assert word in lines[0], lines[0]


def test_its_own_dataset_gives_trains_accuracy_to_the_sample(trained, datasets, cli):
    for train_record in trained.values():
        record, result = _evaluate(cli, train_record["checkpoint"], datasets[0.1])
        size = record["test_size"]
        assert size == 64
        assert round(record["accuracy"] * size) == round(train_record["test_accuracy"] * size)
        assert record["validation_curve"] == train_record["validation_curve"]
        assert record["epochs_run"] == train_record["epochs_run"] == 4
        assert record["spec"] == train_record["spec"]
        # train records what the model depends on in its data: nothing left unchecked
        saved = torch.load(train_record["checkpoint"], weights_only=True)
        assert saved["trained_on"] == data_record(datasets[0.1])
        assert result.stderr == "" and record["evaluated"]["warnings"] == []
    snn, _ = _evaluate(cli, trained["snn"]["checkpoint"], datasets[0.1])
    early = trained["snn"]["early"]  # train's event-driven figures, measured again
    for key in ("accuracy", "input_spikes_mean", "hidden_spikes_mean", "decision_time_ns_mean"):
        assert snn["early"][key] == pytest.approx(early[key]), key
    assert snn["early"]["accuracy"] == snn["accuracy"]  # equal by construction (measure)


def test_another_noise_level_gives_other_figures_in_the_cell_format(trained, datasets, cli):
    from jsonschema import Draft202012Validator

    schema = json.loads(SCHEMA.read_text())
    required = schema.pop("required")  # a cell's; evaluate records those that apply
    validator = Draft202012Validator(schema)
    records = {
        noise: _evaluate(cli, trained["snn"]["checkpoint"], datasets[noise])[0]
        for noise in (0.1, 0.5)
    }
    clear, noisy = records[0.1], records[0.5]
    assert (clear["noise"], noisy["noise"]) == (0.1, 0.5)
    assert clear.keys() == noisy.keys()
    assert clear["early"]["input_spikes_total_mean"] != noisy["early"]["input_spikes_total_mean"]
    assert clear["confusion"] != noisy["confusion"]
    # what a checkpoint cannot tell (docs/benchmark.md): the seed, how training stopped and
    # under which budget, the training data's size and fingerprints
    absent = {"seed", "train_size", "best_epoch", "stopped", "stopped_by_time",
              "validation_size", "budget", "inputs"}  # fmt: skip
    for record in records.values():
        validator.validate(record)  # every key it has, typed as a cell's
        assert set(required) - set(record) == absent
        assert record["metrics"] == "neurobench-2.3.0-definitions/v1"
        assert record["synaptic_operations"]["effective_acs"] > 0  # spiking: from the early run
        assert len(record["per_sample"]["decision_time_ns"]) == 64
        assert record["evaluated"]["split"] == "test"
        assert len(record["evaluated"]["checkpoint_sha256"]) == 64
    conventional, _ = _evaluate(cli, trained["mlp"]["checkpoint"], datasets[0.5])
    validator.validate(conventional)
    assert conventional["kind"] == "conventional" and conventional["macs"] == 256 * 400 + 400 * 32
    assert "early" not in conventional


def test_the_summary_and_the_file(trained, datasets, cli, tmp_path):
    checkpoint = trained["snn"]["checkpoint"]
    text = cli("evaluate", checkpoint, "--dataset", datasets[0.5])
    assert text.exit_code == 0, text.output
    lines = text.stdout.splitlines()
    assert lines[0].startswith("tiny_snn (snn, spiking; 4 epochs trained) on simlidar-32c-")
    assert "noise 0.5), test split: accuracy 0." in lines[0]
    assert lines[1].startswith("  event-driven: accuracy")
    assert lines[2].startswith("  NeuroBench: 18,432 parameters, footprint 73,728 bytes")
    assert lines[3].startswith("  latency ")
    out = tmp_path / "deeper" / "eval.json"
    both = cli("evaluate", checkpoint, "--dataset", datasets[0.5], "--json", "--out", out)
    assert both.exit_code == 0, both.output
    assert json.loads(out.read_text()) == json.loads(both.stdout)
    before = out.read_bytes()
    again = cli("evaluate", checkpoint, "--dataset", datasets[0.5], "--out", out)
    _one_line(again, 1, f"--out {out}: already exists")
    assert out.read_bytes() == before


def test_files_that_are_no_checkpoint_are_one_line(trained, datasets, cli, tmp_path):
    dataset = datasets[0.1]
    for path, words in (
        (tmp_path / "missing.pt", "not a file"),
        (tmp_path, "not a file"),
        (Path(dataset) / "README.md", "not a torch.save archive"),
    ):
        _one_line(cli("evaluate", path, "--dataset", dataset), 1, str(path), words)
    archive = tmp_path / "photos.zip"
    with zipfile.ZipFile(archive, "w") as z:
        z.writestr("a.txt", "not a tensor")
    _one_line(cli("evaluate", archive, "--dataset", dataset), 1, "cannot be read (")
    pickled = tmp_path / "code.pt"  # a checkpoint holding an object: weights_only refuses it
    torch.save({"state_dict": {}, "recipe": {}, "hook": zipfile.ZipInfo("x")}, pickled)
    _one_line(cli("evaluate", pickled, "--dataset", dataset), 1, "UnpicklingError")
    odd = tmp_path / "odd.pt"
    torch.save([1, 2, 3], odd)
    _one_line(cli("evaluate", odd, "--dataset", dataset), 1, "content: expected a dict")
    data = torch.load(trained["mlp"]["checkpoint"], weights_only=True)
    for change, words in (
        (lambda d: d["recipe"].update(training={"lr": -1}), "'training.lr': expected"),
        (lambda d: d.update(history=[{"seconds": float("nan")}]), "history: expected"),
        (lambda d: d.update(silent_from=7.0), "silent_from: expected"),
        (lambda d: d["recipe"].update(name="\x1b[2Jx"), "recipe key 'name'"),
    ):
        copy = {**data, "recipe": dict(data["recipe"])}
        change(copy)
        torch.save(copy, odd)
        _one_line(cli("evaluate", odd, "--dataset", dataset), 1, words)
    weights = {**data["state_dict"], "net.1.bias": torch.full((400,), float("nan"))}
    torch.save({**data, "state_dict": weights}, odd)
    _one_line(cli("evaluate", odd, "--dataset", dataset), 1, "'net.1.bias' holds nan")


def test_outside_code_runs_only_when_named(trained, datasets, cli, tmp_path):
    dataset = datasets[0.1]
    marker = tmp_path / "ran"
    evil = tmp_path / "evil.py"
    evil.write_text(f"open({str(marker)!r}, 'w').close()\ndef build(*a, **k):\n    pass\n")
    data = torch.load(trained["mlp"]["checkpoint"], weights_only=True)
    hostile = tmp_path / "hostile.pt"
    for model in (f"{evil}:build", "os:system"):
        torch.save({**data, "recipe": {**data["recipe"], "model": model}}, hostile)
        result = cli("evaluate", hostile, "--dataset", dataset)
        _one_line(result, 1, "built by outside code", f"expected --model {model}")
    assert not marker.exists()  # never imported
    other = tmp_path / "other.py"
    other.write_text(PLAIN)
    (tmp_path / "code").mkdir()
    mine = tmp_path / "code" / "mine.py"
    mine.write_text(PLAIN)
    made = cli("train", "--model", f"{mine}:build", "--dataset", dataset, "--out", tmp_path,
               "--epochs", "2", "--validation", "0", "--json")  # fmt: skip
    assert made.exit_code == 0, made.output
    checkpoint = json.loads(made.stdout)["checkpoint"]
    _one_line(cli("evaluate", checkpoint, "--dataset", dataset), 1, f"expected --model {mine}")
    named = cli("evaluate", checkpoint, "--dataset", dataset, "--model", f"{other}:build")
    _one_line(named, 2, f"names {other.resolve()}:build", f"builder, {mine.resolve()}:build")
    record, _ = _evaluate(cli, checkpoint, dataset, "--model", f"{mine}:build")
    accuracy = json.loads(made.stdout)["test_accuracy"]
    assert round(record["accuracy"] * 64) == round(accuracy * 64)
    assert record["family"] == f"{mine}:build" and record["macs"] == 256 * 32
    shipped = cli("evaluate", trained["mlp"]["checkpoint"], "--dataset", dataset, "--model", "mlp")
    _one_line(shipped, 2, "simlidar's own 'mlp'; expected no --model")


def test_a_dataset_that_does_not_fit_is_one_line(trained, others, cli, tmp_path):
    """Refused by the checkpoint's record of its data (train's), and, for a checkpoint without
    one, by the first weight that does not fit."""
    checkpoint = trained["mlp"]["checkpoint"]
    for what, words in (
        ("classes", "its model was trained on classes ['tunnel/none'"),
        ("width", "its model was trained on inputs [1, 16, 16]"),
        ("profile", "every pixel is an input spike"),
    ):
        result = cli("evaluate", checkpoint, "--dataset", others[what])
        _one_line(result, 1, f"checkpoint {checkpoint}", str(others[what]), words)
    data = torch.load(checkpoint, weights_only=True)
    del data["trained_on"]
    older = tmp_path / "older.pt"
    torch.save(data, older)
    for what, words in (
        ("classes", "(inputs 1 x 16 x 16, 8 classes): weight "),
        ("width", "(inputs 1 x 16 x 8, 32 classes): weight "),
    ):
        _one_line(cli("evaluate", older, "--dataset", others[what]), 1, str(older), words)
    assert "weight net.1.weight is (400, 256) in the checkpoint, (400, 128) in the model" in (
        cli("evaluate", older, "--dataset", others["width"]).output
    )


def test_a_checkpoint_without_its_datas_record_runs_with_a_warning(
    trained, datasets, cli, tmp_path
):
    """A checkpoint written before train recorded its data (or by other code): scored, with
    the one warning saying what was not checked."""
    data = torch.load(trained["mlp"]["checkpoint"], weights_only=True)
    del data["trained_on"]
    older = tmp_path / "older.pt"
    torch.save(data, older)
    record, result = _evaluate(cli, older, datasets[0.1])
    assert "does not record the data it was trained on" in result.stderr
    assert record["evaluated"]["warnings"] == [result.stderr.strip()[len("warning: ") :]]
    assert (
        record["accuracy"]
        == _evaluate(cli, trained["mlp"]["checkpoint"], datasets[0.1])[0]["accuracy"]
    )


def test_a_checkpoint_that_records_its_data_is_held_to_it(trained, datasets, others, cli, tmp_path):
    data = torch.load(trained["snn"]["checkpoint"], weights_only=True)
    recorded = tmp_path / "recorded.pt"
    torch.save({**data, "trained_on": data_record(datasets[0.1])}, recorded)
    _, result = _evaluate(cli, recorded, datasets[0.5])
    assert result.stderr == ""  # the same inputs, classes, timing and profile: no warning
    timing = cli("evaluate", recorded, "--dataset", others["timing"])
    _one_line(timing, 1, "trained on timing 'flash'", "has 'scan'")
    renamed = data_record(datasets[0.1])
    renamed["class_names"][3] = "tree"
    torch.save({**data, "trained_on": renamed}, recorded)
    _one_line(cli("evaluate", recorded, "--dataset", datasets[0.5]), 1, "trained on classes [")
    profile = {**data_record(datasets[0.1]), "profile": "physical-like"}
    torch.save({**data, "trained_on": profile}, recorded)
    _, result = _evaluate(cli, recorded, datasets[0.5])
    assert "trained on profile physical-like" in result.stderr


def test_without_torch_it_is_one_line(datasets, cli, monkeypatch):
    monkeypatch.setitem(sys.modules, "torch", None)  # import torch raises ImportError
    result = cli("evaluate", "any.pt", "--dataset", datasets[0.1])
    _one_line(result, 1, "simlidar evaluate needs PyTorch")
