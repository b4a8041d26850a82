"""The stream benchmark's runs (docs/streams.md, "Running them"): networks and the estimate on
a stream dataset, cell by cell, resumable, and their report. ``simlidar bench --suite stream``
(:mod:`simlidar.bench.stream_suite`), ``benchmark/stream_bench.py`` and
``benchmark/stream_estimate.py`` run them.

* **Cells.** One (model, seed) cell a line of ``cells.jsonl``, appended as it finishes; a run
  started again skips the pairs already there. A model is run as its recipe says: a window
  model of ``models`` frame-based (trained on the rotation windows, answering at each frame's
  end), a stream network's recipe (a ``[stream]`` table) on whole streams
  (:mod:`simlidar.bench.stream_sequences`), a spiking recipe of ``event_models`` event-driven
  on arrival-coded windows (:mod:`simlidar.bench.stream_task`). A recipe's noise augmentation
  is switched off (a stream carries no noise to draw anew).
* **The estimate.** One (family, seed) learner a line of ``estimate-fits.jsonl``
  (:mod:`simlidar.bench.stream_estimate`), and ``estimate.json``: per delay, each family's seed
  mean and the best.

The report of a run's files is :mod:`simlidar.bench.stream_report`.
"""

import json
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import torch

from simlidar.bench import stream_sequences
from simlidar.bench.latency import DELAYS_MS
from simlidar.bench.stream_task import (
    decision_answers,
    frame_answers,
    latency_record,
    read_cells,
    scored_windows,
    stream_views,
    training_windows,
)
from simlidar.errors import ConfigError
from simlidar.models.registry import load_recipe

CELLS = "cells.jsonl"
FITS = "estimate-fits.jsonl"
ESTIMATE = "estimate.json"
FRAME, WINDOW, EVENT, SEQUENCE = "frame", "window", "event", "sequence"
SUFFIX = {FRAME: "", SEQUENCE: "", WINDOW: "-window", EVENT: "-event"}  # of a cell's model


def plans(
    models: Sequence[str], event_models: Sequence[str] = (), window_models: Sequence[str] = ()
) -> list[tuple[str, str, dict]]:
    """(model, mode, recipe) of each model to run, every recipe read (an unknown one refused)
    before anything runs: a stream network's recipe is a ``sequence``, another of ``models``
    a ``frame`` model; one of ``window_models`` a ``window`` model (frame-based, answering at
    its window's end), one of ``event_models`` an ``event`` model (a stream network's recipe
    in either is refused)."""
    out = []
    for model in models:
        recipe = load_recipe(model)
        out.append((model, SEQUENCE if "stream" in recipe else FRAME, recipe))
    for option, names, mode in (
        ("--window-models", window_models, WINDOW),
        ("--event-models", event_models, EVENT),
    ):
        for model in names:
            recipe = load_recipe(model)
            if "stream" in recipe:
                raise ConfigError(
                    f"{option} {recipe['name']}: a stream network's recipe; "
                    "expected a window model: give it to --models"
                )
            out.append((model, mode, recipe))
    return out


def _reads(mode: str, recipe: dict):
    """What a plan reads: a window coding ("arrival" event-driven, "tof") or a StreamSpec."""
    if mode == SEQUENCE:
        return stream_sequences.check_recipe(recipe)
    return "arrival" if mode == EVENT else "tof"


def read_inputs(dataset: Path, planned: list) -> dict:
    """The train and test inputs every plan reads, each read once."""
    inputs = {}
    for _, mode, recipe in planned:
        what = _reads(mode, recipe)
        if what in inputs:
            continue
        if mode == SEQUENCE:
            inputs[what] = tuple(
                stream_sequences.sequences(dataset, s, what) for s in ("train", "test")
            )
        else:
            inputs[what] = tuple(stream_views(dataset, s, what) for s in ("train", "test"))
    return inputs


def cell_name(recipe: dict, mode: str) -> str:
    return recipe["name"] + SUFFIX[mode]


def sequence_cell(
    dataset: Path,
    recipe: dict,
    seed: int,
    epochs: int | None,
    validation: float,
    data,
    command: str,
) -> dict:
    """One (model, seed) cell of a stream network.

    dataset : the stream dataset's directory; recipe : the network's loaded recipe
    seed, epochs, validation : the training seed, epochs (None: the recipe's) and fraction of
        the training streams held out whole
    data : the train and test :class:`~simlidar.bench.stream_sequences.Sequences`
    command : what made the cell, recorded in it
    """
    train_data, test_data = data
    start = time.perf_counter()
    result = stream_sequences.fit(recipe, train_data, seed, epochs, validation)
    seconds = time.perf_counter() - start
    held = np.setdiff1d(np.arange(len(train_data.labels)), result.trained)
    test_accuracy, _ = stream_sequences.step_score(
        result.model, test_data, np.arange(len(test_data.labels))
    )
    answers = stream_sequences.sequence_answers(result.model, test_data)
    return {
        "model": recipe["name"],
        "mode": SEQUENCE,
        "command": command,
        "coding": train_data.spec.input,
        "stream": train_data.spec.table(),
        "seed": seed,
        "dataset": dataset.name,
        "streams_trained": len(result.trained),
        "streams_validated": len(held),
        "epochs": result.epochs,
        "best_epoch": result.best_epoch,
        "stopped": result.stopped,
        "validation_curve": [score[0] for score in result.validation if score is not None],
        "train_seconds": round(seconds, 1),
        "threads": torch.get_num_threads(),
        # the accuracy over the test streams' steps from each one's reference step on (a
        # window model's window accuracy, step by step)
        "test_window_accuracy": test_accuracy,
        **latency_record(answers, test_data),
    }


def window_cell(
    dataset: Path,
    recipe: dict,
    seed: int,
    epochs: int | None,
    validation: float,
    views,
    mode: str,
    command: str,
) -> dict:
    """One (model, seed) cell of a window model.

    dataset : the stream dataset's directory; recipe : the model's loaded recipe
    seed, epochs, validation : the training seed, epochs (None: the recipe's) and fraction of
        the training streams held out whole
    views : the train and test StreamViews of the mode's coding
    mode : "frame" (answers at the frame ends, time-of-flight windows), "window" (the same, at
        the windows' ends) or "event" (a spiking network's first output spike in each
        arrival-coded window)
    command : what made the cell, recorded in it
    """
    from simlidar.bench.train import train

    recipe = dict(recipe, training=dict(recipe["training"]))
    recipe["training"]["noise_augment"] = False
    recipe["training"]["validation"] = validation
    train_views, test_views = views
    rows = training_windows(train_views, seed, validation, list(train_views.classes))
    start = time.perf_counter()
    result = train(
        recipe,
        dataset,
        seed=seed,
        epochs=epochs,
        progress=False,
        rows=rows,
        test=scored_windows(test_views),
    )
    seconds = time.perf_counter() - start
    if mode == EVENT:
        answers = decision_answers(result.model, test_views)
    else:
        answers = frame_answers(
            result.model, test_views, result.spec, result.silent_from, clock=mode
        )
    return {
        "model": cell_name(recipe, mode),
        "mode": mode,
        "command": command,
        "coding": test_views.coding,
        "seed": seed,
        "dataset": dataset.name,
        "streams_trained": len(rows.trained),
        "windows_trained": len(rows.y_train),
        "windows_validated": len(rows.y_val),
        "epochs": result.epochs,
        "best_epoch": result.best_epoch,
        "train_seconds": round(seconds, 1),
        "threads": torch.get_num_threads(),
        "test_window_accuracy": result.test_accuracy,
        **latency_record(answers, test_views),
    }


def run_cells(
    dataset: Path,
    out: Path,
    planned: list,
    seeds: Sequence[int],
    command: str,
    epochs: Callable[[str], int | None] = lambda name: None,
    validation: float = 0.1,
    note: Callable[[str], None] = print,
) -> list[dict]:
    """Every (model, seed) cell of ``planned`` (:func:`plans`) not yet in ``out``'s
    cells.jsonl, appended as each finishes; every cell of the file returned.

    dataset : the stream dataset's directory (its name is each cell's ``dataset``)
    seeds : the training seeds of every model
    command : what made the cells, recorded in each
    epochs : a model's epoch count by the name it is planned under (None: its recipe's)
    validation : the fraction of the training streams held out whole
    note : called with a line as each cell finishes
    """
    path = out / CELLS
    cells = read_cells(path, dataset.name)
    done = {(c["model"], c["seed"]) for c in cells}
    todo = [
        (m, mode, r, s)
        for m, mode, r in planned
        for s in seeds
        if (cell_name(r, mode), s) not in done
    ]
    if not todo:
        return cells
    inputs = read_inputs(dataset, planned)  # before anything is written
    out.mkdir(parents=True, exist_ok=True)
    for model, mode, recipe, seed in todo:
        data = inputs[_reads(mode, recipe)]
        count = epochs(model)
        if mode == SEQUENCE:
            record = sequence_cell(dataset, recipe, seed, count, validation, data, command)
        else:
            record = window_cell(dataset, recipe, seed, count, validation, data, mode, command)
        with path.open("a") as f:
            f.write(json.dumps(record) + "\n")
        cells.append(record)
        acc = dict(zip(DELAYS_MS, record["accuracy_after"]["accuracy"]))
        note(
            f"{record['model']} seed {seed}: 10 ms {acc[10]:.3f}, 50 ms {acc[50]:.3f}, "
            f"end {record['accuracy_after']['end_accuracy']:.3f} "
            f"({record['train_seconds']} s)"
        )
    return cells


def summarise_estimate(fits: list[dict], command: str) -> dict:
    """Per delay: each family's seed mean and seeds, the estimate and its family."""
    table = {}
    for k, d in enumerate(DELAYS_MS):
        means = {}
        for family in sorted({f["family"] for f in fits}):
            got = [f["accuracy"][k] for f in fits if f["family"] == family]
            means[family] = {"mean": float(np.mean(got)), "seeds": len(got)}
        best = max(means, key=lambda name: means[name]["mean"])
        table[f"{d:g}"] = {"families": means, "estimate": means[best]["mean"], "best": best}
    return {"command": command, "clock": "sensor time from t_reference_us", "delays": table}


def run_estimate(
    dataset: Path,
    out: Path,
    families: Sequence[str],
    seeds: Sequence[int],
    command: str,
    note: Callable[[str], None] = print,
) -> dict:
    """Every (family, seed) learner of the estimate not yet in ``out``'s estimate-fits.jsonl,
    appended as each finishes; then estimate.json from every fit of the file (returned).

    dataset : the stream dataset's directory
    families, seeds : the learner families (:data:`~simlidar.bench.stream_estimate.FAMILIES`)
        and the seeds of each
    command : what made the learners, recorded in estimate.json
    note : called with a line as each learner finishes
    """
    from simlidar.bench.bound import BoundConfig, train_learner
    from simlidar.bench.stream_estimate import any_time, family_parts, known, view_at

    for family in families:
        family_parts(family)  # a bad name refused before any work
    path = out / FITS
    fits = read_cells(path, dataset.name)
    done = {(f["family"], f["seed"]) for f in fits}
    todo = [f for f in families if any((f, s) not in done for s in seeds)]
    if todo:
        train, test = known(dataset, "train"), known(dataset, "test")  # before writing
        out.mkdir(parents=True, exist_ok=True)
    for family in todo:
        model, view = family_parts(family)
        tests = [view_at(test, d, view) for d in DELAYS_MS]
        for seed in seeds:
            if (family, seed) in done:
                continue
            draw = any_time(train, np.random.default_rng(seed), view)
            scores, record = train_learner(
                draw(),
                train.labels,
                train.classes,
                seed,
                BoundConfig(model=model),
                draw,
                height=train.delays.shape[1],
            )
            accuracy = [float((scores(x).argmax(1) == test.labels).mean()) for x in tests]
            cell = {
                "dataset": dataset.name,
                "family": family,
                "seed": seed,
                "delays_ms": list(DELAYS_MS),
                "accuracy": accuracy,
                **record,
            }
            with path.open("a") as f:
                f.write(json.dumps(cell) + "\n")
            fits.append(cell)
            shown = ", ".join(f"{d:g} ms {a:.3f}" for d, a in zip(DELAYS_MS, accuracy))
            note(f"{family} seed {seed}: {shown}")
    if not fits:
        raise ConfigError(f"{path}: no learner of the estimate; expected a family and a seed")
    summary = summarise_estimate(fits, command)
    if todo or not (out / ESTIMATE).exists():
        (out / ESTIMATE).write_text(json.dumps(summary, indent=1) + "\n")
    return summary
