"""What a benchmark cell measures on its trained model (:func:`measure`), and measuring every
finished cell of a run again from its checkpoint (:func:`remeasure`)."""

import time
from pathlib import Path

import numpy as np
import torch

from simlidar.bench import metrics
from simlidar.bench.checkpoints import load_checkpoint
from simlidar.bench.early import early_decisions
from simlidar.bench.outdir import claim, collect, read_cell, write_json
from simlidar.bench.scoring import predictions
from simlidar.bench.stepped import stepped_decisions
from simlidar.bench.suite import Suite
from simlidar.dataset.loaders import load_split, spike_threshold
from simlidar.dataset.reader import dataset_splits
from simlidar.errors import DatasetError
from simlidar.models.protocol import STEPPED_SPIKES, ModelSpec, encode, spec_of
from simlidar.models.training_config import TrainingConfig

METRICS = "neurobench-2.3.0-definitions/v1"  # what measure() computes; a cell records it


def decision_record(
    model: torch.nn.Module,
    dataset: Path,
    spec: ModelSpec,
    silent_from: float,
    x: torch.Tensor,
    y: np.ndarray,
    per_sample: bool = False,
) -> dict:
    """How early a spiking network decides on the test split ``x`` (N, 1, H, W), ``y``:
    ``{"stepped": ...}`` for a network of stepped spikes (:func:`stepped_decisions`),
    ``{"early": ...}`` for one the event-driven evaluator runs (:func:`early_decisions`),
    ``{}`` for any other; with ``per_sample``, each with its ``per_sample`` part.

    model : the trained network
    dataset : the dataset directory whose test split ``x``, ``y`` are: the event-driven
        evaluator reads the split from it
    spec : the model's declaration (:func:`simlidar.models.protocol.spec_of`)
    silent_from : the data's no-return threshold: delays at or above it are no input spike
        (:func:`simlidar.dataset.loaders.spike_threshold`)
    """
    if spec.output == STEPPED_SPIKES:
        return {"stepped": stepped_decisions(model, x, y, spec, silent_from, per_sample)}
    if getattr(model, "event_driven", False):
        return {"early": early_decisions(model, dataset, per_sample=per_sample)}
    return {}


def measure(
    model: torch.nn.Module,
    recipe: dict,
    dataset: Path,
    board_power_w: float | None,
    predicted: np.ndarray,
    timing: dict,
    spec: ModelSpec | None = None,
) -> dict:
    """Everything a cell measures on its trained model (on the CPU) besides training:
    accuracy, confusion, footprint, latency, NeuroBench's workload metrics, early decisions;
    ``timing`` gets the seconds of each part, and is recorded. ``spec``: what the model
    declares (default: :func:`~simlidar.models.protocol.spec_of` the model, the recipe's
    ``[spec]`` over it).

    dataset : the dataset directory whose test split is measured
    board_power_w : the suite's board power (``Suite.board_power_w``), which gives a
        conventional model's energy estimate (power x latency); None: no estimate
    predicted : (N,) the model's class of each test sample (-1: no decision), for the accuracy
        and the confusion matrix
    """
    attrs = dataset_splits(dataset)["test"].attrs
    x, y = load_split(dataset, "test")
    x = torch.from_numpy(x)[:, None]
    classes = len(attrs["class_names"])
    spec = spec or spec_of(model, recipe.get("spec"))
    record = {
        "accuracy": float(np.mean(predicted == y)),
        "input_shape": list(x.shape[1:]),
        **metrics.footprint(model),
        "metrics": METRICS,
        "lr_schedule": TrainingConfig.from_table(recipe["training"]).lr_schedule,
    }
    start = time.perf_counter()
    silent_from = spike_threshold(attrs)
    if spec.spiking or spec.output == STEPPED_SPIKES:
        for key, found in decision_record(model, dataset, spec, silent_from, x, y, True).items():
            record["per_sample"] = found.pop("per_sample")
            record[key] = found
        timing[f"{'stepped' if 'stepped' in record else 'early'}_decisions"] = (
            time.perf_counter() - start
        )
        start = time.perf_counter()
    if spec.output == STEPPED_SPIKES:
        figures = metrics.stepped_figures(model, x, lambda b: encode(b, spec, silent_from))
    elif spec.spiking:
        figures = metrics.spiking_figures(model, x, record.get("early"))
    else:
        figures = metrics.conventional_figures(model, x, board_power_w)
    timing["latency_and_counts"] = time.perf_counter() - start
    record.update(figures)
    record["confusion"] = metrics.confusion_matrix(y, predicted, classes).tolist()
    record["timing_seconds"] = {k: round(v, 2) for k, v in timing.items()}
    return record


def remeasure(out: Path, suite: Suite, progress: bool = True) -> dict:
    """Measure every finished cell of ``out`` again from its checkpoint (no training): the
    figures of :func:`measure` are replaced, the training record is kept. A checkpoint whose
    test predictions do not give the cell's recorded accuracy is refused (it is not the cell's
    model; one sample may differ, as float rounding differs with the thread count). Writes
    results.json and the report; returns the results."""
    from tqdm import tqdm

    from simlidar.bench.report import write_report

    if not (out / "suite.json").is_file():
        raise DatasetError(
            f"--out {out}: no benchmark run to re-measure; expected a directory "
            "written by simlidar bench"
        )
    claim(out, suite)  # the suite must own the directory
    cells = sorted((out / "cells").glob("*.json"))
    missing = [c.stem for c in cells if not (out / "checkpoints" / f"{c.stem}.pt").is_file()]
    if missing:
        raise DatasetError(
            f"--out {out}: cell {missing[0]} has no checkpoint "
            f"(checkpoints/{missing[0]}.pt; {len(missing)} cells lack one); "
            "expected every cell's weights, as bench saves them"
        )
    for path in tqdm(cells, desc="re-measure", unit="cell", disable=not progress):
        record = read_cell(path)
        dataset = _dataset_of(out, suite, record["dataset"])
        model, data = load_checkpoint(
            out / "checkpoints" / f"{path.stem}.pt", tuple(record["input_shape"]), record["classes"]
        )
        x, y = load_split(dataset, "test")
        spec = spec_of(model, data["recipe"].get("spec"))
        silent_from = float(data.get("silent_from", 1.0))
        predicted = predictions(
            model, torch.from_numpy(x)[:, None], spec=spec, silent_from=silent_from
        )
        predicted = predicted.numpy()
        if abs(float(np.sum(predicted == y)) - record["accuracy"] * len(y)) > 1.5:
            raise DatasetError(
                f"--out {out}: checkpoint of cell {path.stem} scores "
                f"{np.mean(predicted == y):.4f}, the cell {record['accuracy']:.4f}; "
                "expected the cell's own model"
            )
        timing = {k: v for k, v in record.get("timing_seconds", {}).items() if k == "train"}
        record.update(
            measure(model, data["recipe"], dataset, suite.board_power_w, predicted, timing, spec)
        )
        write_json(path, record, indent=None)
    results = collect(out, suite)
    write_report(results, out)
    return results


def _dataset_of(out: Path, suite: Suite, name: str) -> Path:
    """The directory of a cell's dataset: generated under ``<out>/datasets`` or one of the
    suite's."""
    for path in [out / "datasets" / name, *suite.datasets]:
        if path.name == name and path.is_dir():
            return path
    raise DatasetError(
        f"--out {out}: dataset {name} of a cell is not there; expected it under "
        f"{out / 'datasets'} or among the suite's datasets"
    )
