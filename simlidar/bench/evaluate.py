"""A saved model scored on any dataset, measured as a benchmark cell is (``simlidar evaluate``;
docs/benchmark.md, "Scoring a saved model").

A checkpoint is a file from elsewhere until it is checked (:func:`read_checkpoint`): read with
``weights_only=True`` (no pickled code), its parts checked for the types
:func:`~simlidar.bench.checkpoints.save_checkpoint` writes, its recipe as
:func:`~simlidar.models.registry.load_recipe` checks a recipe file. A recipe names the code
that builds its model: simlidar's own builders run; an outside builder runs only when the
user names it too (:func:`check_builder`), as a checkpoint could name any module. The dataset
must then fit the model (:func:`check_fit`): the same coding of "no return" (the dataset
profile's), and, where the checkpoint records its training data (``trained_on``), the same
input shape, class names and timing; the weights themselves must fit the model built for the
dataset's input shape and classes.
"""

import hashlib
import io
import math
import re
import time
import zipfile
from pathlib import Path

import numpy as np
import torch

from simlidar import __version__
from simlidar.bench.cells import splits_sha256
from simlidar.bench.checkpoints import data_record, load_checkpoint
from simlidar.bench.checks import check_output, check_weights
from simlidar.bench.measure import measure
from simlidar.bench.outdir import machine
from simlidar.bench.scoring import predictions
from simlidar.dataset.loaders import load_split, spike_threshold
from simlidar.dataset.reader import dataset_splits
from simlidar.dataset.version import GENERATOR
from simlidar.errors import ConfigError, DatasetError, first_line, raised, shown
from simlidar.models.protocol import spec_of
from simlidar.models.registry import BUILDERS, is_outside, load_recipe
from simlidar.models.training_config import TrainingConfig
from simlidar.release.verify import check_trainable
from simlidar.resources import check_memory

EXPECTED = "expected a checkpoint written by simlidar train or bench"
MAX_NAME = 255  # a name in a cell (schema: maxLength), which the summary prints
SPLIT = "test"  # the split scored: measure() reads the test split


def read_checkpoint(path: Path) -> tuple[dict, str]:
    """(content, sha256 of the file) of the checkpoint ``path``, checked before any of it is
    used (:func:`check_content`); a DatasetError naming the file otherwise: a missing file or
    one that is no ``torch.save`` archive, one that needs more than tensors and plain values
    to load (``weights_only=True`` refuses pickled code), or one of other parts."""
    where = f"checkpoint {path}"
    if not path.is_file():  # a folder, a named pipe (which would hang), nothing
        raise DatasetError(f"{where}: not a file; {EXPECTED} (.pt)")
    check_memory(path.stat().st_size, f"{where}: the file")
    content = path.read_bytes()
    if not zipfile.is_zipfile(io.BytesIO(content)):
        raise DatasetError(f"{where}: not a torch.save archive (a zip file); {EXPECTED}")
    try:
        data = torch.load(io.BytesIO(content), weights_only=True, map_location="cpu")
    except Exception as exc:  # a file from elsewhere: whatever fails, it is not a checkpoint
        raise DatasetError(f"{where}: cannot be read ({raised(exc)}); {EXPECTED}") from None
    check_content(data, where)
    return data, hashlib.sha256(content).hexdigest()


def check_content(data, where: str) -> None:
    """Refuse a checkpoint's content (``data``) unlike what ``save_checkpoint`` writes: a
    DatasetError starting with ``where``, naming the part."""

    def refuse(part: str, expected: str, got) -> DatasetError:
        return DatasetError(f"{where}: {part}: expected {expected}, got {shown(got, 60)}")

    if not isinstance(data, dict) or not {"state_dict", "recipe"} <= data.keys():
        found = sorted(map(str, data)) if isinstance(data, dict) else type(data).__name__
        raise refuse("content", "a dict with state_dict and recipe", found)
    weights = data["state_dict"]
    if not isinstance(weights, dict) or not all(
        isinstance(k, str) and isinstance(v, torch.Tensor) for k, v in weights.items()
    ):
        raise refuse("state_dict", "names and tensors", type(weights).__name__)
    recipe = data["recipe"]
    if not isinstance(recipe, dict):
        raise refuse("recipe", "a dict", type(recipe).__name__)
    for key, kind in (("model", str), ("name", str), ("training", dict), ("architecture", dict)):
        if not isinstance(recipe.get(key), kind):
            raise refuse(f"recipe key {key!r}", f"a {kind.__name__}", recipe.get(key))
    for key in ("model", "name"):
        if not 0 < len(recipe[key]) <= MAX_NAME or not recipe[key].isprintable():
            raise refuse(f"recipe key {key!r}", f"a printable name of 1 to {MAX_NAME}", recipe[key])
    for key, kind in (("base", str), ("spec", dict)):  # optional: a file builder's folder
        if key in recipe and not isinstance(recipe[key], kind):
            raise refuse(f"recipe key {key!r}", f"a {kind.__name__}", recipe[key])
    try:
        TrainingConfig.from_table(recipe["training"], f"{where}: recipe")
        if "spec" in recipe:
            spec_of(None, recipe["spec"], f"{where}: recipe")
    except ConfigError as exc:
        raise DatasetError(str(exc)) from None
    silent = data.get("silent_from", 1.0)
    if not isinstance(silent, float | int) or not (0 <= silent <= 1 or silent == math.inf):
        raise refuse("silent_from", "a delay in [0, 1] or inf", silent)
    history = data.get("history", [])
    if not isinstance(history, list) or not all(_epoch_ok(h) for h in history):
        raise refuse("history", "a list of epochs (finite seconds, accuracies in [0, 1])", history)
    if "trained_on" in data:
        _check_trained_on(data["trained_on"], refuse)


def _epoch_ok(epoch) -> bool:
    """Whether one epoch of a checkpoint's history holds what a cell would record of it."""
    if not isinstance(epoch, dict):
        return False
    seconds, accuracy = epoch.get("seconds", 0.0), epoch.get("val_accuracy")
    return (
        isinstance(seconds, float | int)
        and math.isfinite(seconds)
        and seconds >= 0
        and (accuracy is None or (isinstance(accuracy, float | int) and 0 <= accuracy <= 1))
    )


def _check_trained_on(record, refuse) -> None:
    """A checkpoint's record of its training data (:func:`data_record`), checked for types."""
    good = (
        isinstance(record, dict)
        and isinstance(record.get("input_shape"), list)
        and all(isinstance(n, int) and n > 0 for n in record["input_shape"])
        and isinstance(record.get("class_names"), list)
        and all(isinstance(n, str) for n in record["class_names"])
        and isinstance(record.get("timing"), str)
        and isinstance(record.get("profile"), str | None)
    )
    if not good:
        raise refuse("trained_on", "input_shape, class_names, timing and profile", record)


def builder_code(recipe: dict) -> str:
    """The code an outside builder of ``recipe`` runs: a module's dotted name and function, or
    a file's resolved path and function (relative to the recipe's folder, ``base``, or else to
    the working directory, as :func:`~simlidar.models.registry.builder` finds it)."""
    where, function = recipe["model"].rsplit(":", 1)
    if not where.endswith(".py"):
        return recipe["model"]
    path = Path(where)
    if not path.is_absolute() and "base" in recipe:
        path = Path(recipe["base"]) / path
    return f"{path.resolve()}:{function}"


def check_builder(recipe: dict, model: str | None, where: str) -> None:
    """Allow the checkpoint's recipe to build its model: one of simlidar's builders, or the
    outside builder that ``model`` (``--model``: a builder or a recipe naming one) names too,
    the same module or file. A checkpoint could name any module (``os:system``), whose import
    would run it: without ``model`` none is imported. A DatasetError (the checkpoint) or a
    ConfigError (``--model``) otherwise."""
    name = recipe["model"]
    if name in BUILDERS:
        if model is not None:
            raise ConfigError(
                f"--model {model}: the checkpoint's model is simlidar's own {name!r}; expected "
                "no --model (it names the code of an outside model's checkpoint)"
            )
        return
    if not is_outside(name):
        raise DatasetError(
            f"{where}: recipe key 'model': expected one of {sorted(BUILDERS)} or an outside "
            f"builder 'package.module:function' or 'path/to/file.py:function', got {name!r}"
        )
    if model is None:
        raise DatasetError(
            f"{where}: its model is built by outside code, {builder_code(recipe)}, which "
            "evaluate runs only when you name it: a checkpoint from elsewhere could name any "
            f"module; expected --model {name} (or the recipe that names it)"
        )
    named = load_recipe(model)  # the user's choice: imported as train --model does
    if not is_outside(named["model"]) or builder_code(named) != builder_code(recipe):
        got = builder_code(named) if is_outside(named["model"]) else named["model"]
        raise ConfigError(
            f"--model {model}: names {got}; expected the checkpoint's own builder, "
            f"{builder_code(recipe)}"
        )


def check_fit(data: dict, dataset: Path, where: str) -> list[str]:
    """Refuse a dataset that the checkpoint's model cannot read as its training data did: a
    DatasetError naming both. Compared: the coding of no return (``silent_from``: the
    profile's rule; delays mean something else under another), and from a checkpoint that
    records its training data (``trained_on``, :func:`data_record`) the input shape, the class
    names and the timing. Returns warnings: another profile of the same coding, or a
    checkpoint that records no training data (its weights' shapes are then what is checked:
    input shape and class count, by :func:`build`)."""
    attrs = dataset_splits(dataset)[SPLIT].attrs
    trained, here = float(data.get("silent_from", 1.0)), spike_threshold(attrs)
    if trained != here:
        raise DatasetError(
            f"{where}: its model was trained on data where {_coding(trained)}; in dataset "
            f"{dataset} {_coding(here)}; expected a dataset whose profile codes no return as "
            "the training data's did (docs/profiles.md)"
        )
    record, found = data.get("trained_on"), data_record(dataset)
    if record is None:
        return [
            f"{where} does not record the data it was trained on: its weights' shapes (input "
            "shape, class count) and the coding of no return were checked, not the class "
            "names or the timing (flash or scan)"
        ]
    for key, what in (("input_shape", "inputs"), ("class_names", "classes"), ("timing", "timing")):
        if record[key] != found[key]:
            raise DatasetError(
                f"{where}: its model was trained on {what} {shown(record[key], 80)}; dataset "
                f"{dataset} has {shown(found[key], 80)}; expected a dataset of the same {what}"
            )
    if record.get("profile") != found["profile"]:
        return [
            f"{where} was trained on profile {record.get('profile') or 'physical'}, dataset "
            f"{dataset} is of profile {found['profile'] or 'physical'} (the same coding of no "
            "return): figures across profiles compare other pulse rules"
        ]
    return []


def _coding(silent_from: float) -> str:
    if silent_from == math.inf:
        return "every pixel is an input spike (input_spikes = all, the paper profile)"
    return f"delays of {silent_from:g} and above are no return, no input spike"


_MISMATCH = re.compile(
    r"size mismatch for (?P<name>\S+): copying a param with shape torch\.Size\(\[(?P<saved>[^\]]*)"
    r"\]\) from checkpoint, the shape in current model is torch\.Size\(\[(?P<built>[^\]]*)\]\)"
)


def build(path: Path, data: dict, dataset: Path, where: str) -> torch.nn.Module:
    """The checkpoint's model built for the dataset's input shape and classes, its weights
    loaded (:func:`~simlidar.bench.checkpoints.load_checkpoint`); a DatasetError naming the
    first weight that does not fit, or what the builder raised."""
    info = dataset_splits(dataset)[SPLIT]
    shape, classes = (1, info.height, info.width), len(info.attrs["class_names"])
    fits = f"dataset {dataset} (inputs {' x '.join(map(str, shape))}, {classes} classes)"
    try:
        model, _ = load_checkpoint(path, shape, classes)
    except RuntimeError as exc:  # load_state_dict: other shapes or other parameters
        found = _MISMATCH.search(str(exc))
        detail = first_line(exc)
        if found:
            detail = (
                f"weight {found['name']} is ({found['saved']}) in the checkpoint, "
                f"({found['built']}) in the model built for this dataset"
            )
        raise DatasetError(
            f"{where} does not fit {fits}: {detail}; expected a dataset of the input shape "
            "and classes its model was trained on"
        ) from None
    except Exception as exc:  # a builder refusing the shape, or a checkpoint's odd architecture
        message = str(exc) if isinstance(exc, ConfigError) else raised(exc)
        raise DatasetError(f"{where}: its model cannot be built for {fits}: {message}") from None
    return model


def evaluate(path: Path, dataset: Path, model: str | None = None, threads: int = 1) -> dict:
    """Score the checkpoint ``path`` on the test split of ``dataset`` and measure it as a
    benchmark cell (:func:`~simlidar.bench.measure.measure`): accuracy, confusion, early
    decisions, NeuroBench's metrics, latency; returns a record of the cell's keys that apply,
    plus ``evaluated`` (the checkpoint, its sha256, the split and the dataset's fingerprint,
    warnings). Checks as the module says; the dataset must be one ``simlidar verify`` accepts.

    model : the outside builder (or its recipe) that the checkpoint names, when it names one
        (:func:`check_builder`)
    threads : the torch threads the caller runs it on (recorded; the latency depends on it)
    """
    start = time.perf_counter()
    path, dataset = Path(path), Path(dataset)
    where = f"checkpoint {path}"
    data, digest = read_checkpoint(path)
    recipe = data["recipe"]
    check_builder(recipe, model, where)
    check_trainable(dataset)  # a sound dataset, or a one-line error (as train)
    warnings = check_fit(data, dataset, where)
    network = build(path, data, dataset, where)
    attrs = dataset_splits(dataset)[SPLIT].attrs
    x, y = load_split(dataset, SPLIT)
    spec = spec_of(network, recipe.get("spec"), where)
    check_weights(network, where)
    # its output's kind and shape on two samples, as train checks a model before training; a
    # forward that raises is one line (outside code)
    check_output(network, spec, torch.from_numpy(x[:2])[:, None], len(attrs["class_names"]),
                 where, spike_threshold(attrs))  # fmt: skip
    timing = {}
    begun = time.perf_counter()
    predicted = predictions(
        network, torch.from_numpy(x)[:, None], spec=spec, silent_from=spike_threshold(attrs)
    ).numpy()
    timing["scoring"] = time.perf_counter() - begun
    # no suite, so no board power for the conventional energy estimate
    figures = measure(network, recipe, dataset, None, predicted,
                      timing, spec)  # fmt: skip
    history = data.get("history", [])
    record = {
        "dataset": dataset.resolve().name,  # "." named by its folder's name
        "source": attrs.get("source", GENERATOR),
        "noise": float(attrs["noise"]),
        "model": recipe["name"],
        "kind": "spiking" if spec.spiking else "conventional",
        "spec": spec.table(),
        "family": recipe["model"],
        "classes": len(attrs["class_names"]),
        "test_size": len(y),
        "epochs": len(history),
        "epochs_run": len(history),
        "validation_curve": [h.get("val_accuracy") for h in history],
        **({"train_seconds": round(history[-1].get("seconds", 0.0), 2)} if history else {}),
        **figures,
        "threads": threads,
        "machine": machine(),
        "simlidar_version": __version__,
        "seconds": round(time.perf_counter() - start, 2),
        "evaluated": {
            "checkpoint": str(path),
            "checkpoint_sha256": digest,
            "split": SPLIT,
            "splits_sha256": splits_sha256(dataset),
            "warnings": warnings,
        },
    }
    return record


def summary(record: dict) -> list[str]:
    """The lines ``simlidar evaluate`` prints of a record of :func:`evaluate`."""
    from simlidar.bench.early import format_early
    from simlidar.bench.stepped import format_stepped

    correct = int(np.trace(np.array(record["confusion"])[:, :-1]))
    silent = sum(row[-1] for row in record["confusion"])
    trained = f"{record['epochs']} epochs trained" if record["epochs"] else "no history"
    lines = [
        f"{record['model']} ({record['family']}, {record['kind']}; {trained}) on "
        f"{record['dataset']} ({record['classes']} classes, noise {record['noise']:g}), "
        f"{record['evaluated']['split']} split: accuracy {record['accuracy']:.4f} ({correct} of "
        f"{record['test_size']}{f'; no decision on {silent}' if silent else ''})"
    ]
    if "early" in record:
        lines.append(format_early(record["early"]))
    if "stepped" in record:
        lines.append(f"  {format_stepped(record['stepped'])}")
    ops = record["synaptic_operations"]
    lines.append(
        f"  NeuroBench: {record['params']:,} parameters, footprint {record['footprint']:,} "
        f"bytes, connection sparsity {_figure(record['connection_sparsity'])}, activation "
        f"sparsity {_figure(record['activation_sparsity'])}; synaptic operations per sample: "
        f"effective MACs {_figure(ops['effective_macs'], '{:,.0f}')}, effective ACs "
        f"{_figure(ops['effective_acs'], '{:,.0f}')}, dense {_figure(ops['dense'], '{:,.0f}')}"
    )
    energy = ""
    if "energy_pj_mac" in record:
        energy = f"; {record['macs']:,} MACs a sample: {record['energy_pj_mac']:,.0f} pJ"
    elif "energy_pj_ops" in record:
        energy = f"; {record['energy_pj_ops']:,.0f} pJ a sample by its operations"
    lines.append(
        f"  latency {record['latency_ms']:.3g} ms at batch 1 (median of "
        f"{record['latency_runs']} runs, {record['threads']} thread(s)), "
        f"{record['throughput_per_s']:,.0f} samples/s at batch {record['throughput_batch']}"
        f"{energy}"
    )
    return lines


def _figure(value, form: str = "{:.4f}") -> str:
    return "none" if value is None else form.format(value)
