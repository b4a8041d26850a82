"""Run a suite: train and score every (dataset, model, seed) cell, write results and report.

Output directory layout::

    <out>/suite.json          which suite (name, sha256 of its file) owns the directory
    <out>/datasets/...        datasets generated on the fly by the suite
    <out>/cells/<id>.json     one finished cell (written atomically): a rerun skips it
    <out>/checkpoints/<id>.pt its kept weights (save_checkpoint; not published: re-measuring)
    <out>/results.json        every finished cell plus suite, versions, machine, time taken
    <out>/report.md, *.png    tables beside the paper's numbers, and pictures
"""

import json
import os
import platform
import re
import shutil
import socket
import time
from pathlib import Path

import numpy as np
import torch

from simlidar import __version__
from simlidar.atomic import clean_stale, temporary_of, write_file
from simlidar.bench import metrics
from simlidar.bench.cells import (
    cell_id,
    cell_inputs,
    finished,
    recorded_rules,
    training_rules,
)
from simlidar.bench.early import early_decisions
from simlidar.bench.hardware import DEFAULT_THREADS, check_threads, resolve_device, threads
from simlidar.bench.stepped import stepped_decisions
from simlidar.bench.suite import Suite
from simlidar.bench.train import (
    predictions,
    save_checkpoint,
    train,
    validation_count,
)
from simlidar.content import content_dir
from simlidar.dataset.loaders import load_split, spike_threshold
from simlidar.dataset.reader import dataset_splits
from simlidar.dataset.version import GENERATOR
from simlidar.errors import ConfigError, DatasetError
from simlidar.models.protocol import STEPPED_SPIKES, ModelSpec, encode, spec_of
from simlidar.models.registry import load_recipe
from simlidar.models.training import TrainingConfig
from simlidar.release.verify import check_trainable
from simlidar.resources import check_memory

_NUMBERS = re.compile(r"\[[-0-9.eE+,\s]*\]")  # a list of numbers spread over lines


def write_json(path: Path, data, indent: int | None = 1) -> None:
    """Write atomically; with ``indent``, lists of numbers stay on one line each. Strict JSON:
    a non-finite number (which Python would write as a bare ``Infinity``, which JSON parsers
    refuse) is refused in one line instead; the values are made finite where they come in."""
    try:
        text = json.dumps(data, indent=indent, allow_nan=False)
    except ValueError as exc:
        raise DatasetError(f"{path}: {exc}; expected finite numbers, nothing written") from None
    if indent is not None:
        text = _NUMBERS.sub(
            lambda m: "[" + ", ".join(m[0][1:-1].replace(",", " ").split()) + "]", text
        )
    write_file(path, lambda tmp: tmp.write_text(text + "\n"))


def machine() -> dict:
    """CPU model, cores, torch version and threads: what the timings depend on."""
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {
        "cpu": cpu,
        "cores": os.cpu_count(),
        "torch": torch.__version__,
        "torch_threads": torch.get_num_threads(),
        "python": platform.python_version(),
        "platform": platform.platform(),
    }


def claim(out: Path, suite: Suite) -> None:
    """Make ``out`` the suite's output directory, or refuse one that belongs to another suite
    (nothing in it is touched).

    A directory belongs to a suite's name and its data (``[generate]`` or ``datasets``): the
    suite file may change otherwise (models, seeds, budgets, description), as every cell
    carries the rules it was trained by and a cell made under other rules is refused by
    :func:`finished`. ``suite.json`` then records the file's new sha256.
    """
    marker = out / "suite.json"
    if marker.is_file():
        try:
            owner = json.loads(marker.read_text())
        except (OSError, ValueError):
            owner = {}
        if owner.get("sha256") != suite.sha256:
            if owner.get("name") != suite.name or owner.get("data_sha256") != suite.data_sha256:
                other = "data" if owner.get("name") == suite.name else "suite"
                raise DatasetError(
                    f"--out {out}: belongs to suite {owner.get('name', '?')!r} (data sha256 "
                    f"{str(owner.get('data_sha256'))[:12]}), not to {suite.name!r} (data sha256 "
                    f"{suite.data_sha256[:12]}): another {other}; expected a new --out "
                    "directory (bench replaces nothing), or this one's own suite"
                )
            write_json(marker, _ownership(suite))  # the same suite and data, the file edited
        (out / "cells").mkdir(exist_ok=True)  # removed by hand: its cells are run again
        return
    # what a claim that failed midway left: cells/, suite.json's temporaries (a killed
    # write's; .suite.json.partial, a fixed name, from simlidar before write_file)
    litter = {"cells", ".suite.json.partial"}
    if out.exists() and any(
        (p.name not in litter and temporary_of(p.name) != marker.name)
        or (p.name == "cells" and p.is_dir() and any(p.iterdir()))
        for p in out.iterdir()
    ):
        raise DatasetError(
            f"--out {out}: not empty and not a benchmark output directory; "
            "expected a new or empty directory"
        )
    created = not out.exists()
    try:
        (out / "cells").mkdir(parents=True, exist_ok=True)
        clean_stale(out)  # a killed claim's temporary of suite.json (a live one's stays)
        (out / ".suite.json.partial").unlink(missing_ok=True)
        write_json(marker, _ownership(suite))
    except BaseException:  # undo, so that a rerun can claim the folder (write_json left none)
        shutil.rmtree(out if created else out / "cells", ignore_errors=True)
        raise


def _ownership(suite: Suite) -> dict:
    return {
        "name": suite.name,
        "sha256": suite.sha256,
        "data_sha256": suite.data_sha256,
        "path": _shown(suite),
    }


def _shown(suite: Suite) -> str:
    """The suite file as a reader can find it: ``benchmark/<name>.toml`` for a shipped suite
    (not this machine's install path), the path as given otherwise."""
    shipped = content_dir("benchmark") / suite.path.name
    if shipped.is_file() and shipped.resolve() == suite.path.resolve():
        return f"benchmark/{suite.path.name}"
    return str(suite.path)


def resolve_datasets(suite: Suite, out: Path, dataset: Path | None, progress: bool) -> list[Path]:
    """The dataset directories of the run: ``dataset`` if given, the suite's paths, or the
    suite's generated datasets (made under ``<out>/datasets`` the first time)."""
    if dataset is not None:
        paths = [dataset]
    elif suite.generate is None:
        paths = list(suite.datasets)
    else:
        from simlidar.generator.generate import generate, generated_name
        from simlidar.scene.recipe import load_catalog

        root = out / "datasets"
        paths = [root / generated_name(suite.generate.with_noise(n)) for n in suite.noise]
        missing = [n for n, path in zip(suite.noise, paths) if not path.is_dir()]
        for path in paths:
            if not path.is_dir() and (path.exists() or path.is_symlink()):
                raise DatasetError(
                    f"--out {out}: {path} is in the way of the suite's dataset of that name "
                    "(not a folder); expected nothing there: remove it (bench replaces nothing)"
                )
        try:
            if missing:
                generate(suite.generate, missing, load_catalog(), root, progress=progress)
        except DatasetError:
            if not all(path.is_dir() for path in paths):
                raise
            # another run of this suite made them meanwhile: the same bytes (config and seed)
    return paths  # given ones were checked by run_suite; each cell reads its dataset's splits


def run_cell(
    dataset: Path,
    model: str,
    seed: int,
    suite: Suite,
    checkpoint: Path | None = None,
    device: str = "cpu",
) -> dict:
    """Train one model on one dataset with one seed and measure it (docs/benchmark.md); with
    ``checkpoint``, save the kept weights there (a figure can be re-measured later).
    ``device``: where it trains (``--device``); it is measured on the CPU."""
    recipe = load_recipe(model)
    budget = suite.budget_for(model)
    recipe["training"].update(budget)  # the suite's budget over the recipe's values
    splits = dataset_splits(dataset)
    attrs = splits["test"].attrs
    timing = {}
    start = time.perf_counter()
    result = train(recipe, dataset, seed=seed, progress=False, device=resolve_device(device))
    timing["train"] = time.perf_counter() - start
    result.model.cpu()
    if checkpoint is not None:
        save_checkpoint(result, checkpoint)
    record = {
        "dataset": dataset.name,
        "source": attrs.get("source", GENERATOR),
        "noise": float(attrs["noise"]),
        "model": recipe["name"],
        "seed": seed,
        "kind": "spiking" if result.spec.spiking else "conventional",
        "spec": result.spec.table(),
        "device": result.device,
        "family": recipe["model"],
        "classes": len(attrs["class_names"]),
        "train_size": splits["train"].size,
        "test_size": splits["test"].size,
        "epochs": result.epochs,
        **result.selection(),
        "stopped_by_time": result.stopped == "time",
        "train_seconds": round(result.seconds, 2),
        "budget": recorded_rules(budget),
    }
    record.update(
        measure(result.model, recipe, dataset, suite, result.test_predictions, timing, result.spec)
    )
    return record


METRICS = "neurobench-2.3.0-definitions/v1"  # what measure() computes; a cell records it


def measure(
    model: torch.nn.Module,
    recipe: dict,
    dataset: Path,
    suite: Suite,
    predicted: np.ndarray,
    timing: dict,
    spec: ModelSpec | None = None,
) -> dict:
    """Everything a cell measures on its trained model (on the CPU) besides training:
    accuracy, confusion, footprint, latency, NeuroBench's workload metrics, early decisions;
    ``timing`` gets the seconds of each part, and is recorded. ``spec``: what the model
    declares (default: :func:`~simlidar.models.protocol.spec_of` the model, the recipe's
    ``[spec]`` over it)."""
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
    if spec.output == STEPPED_SPIKES:
        silent_from = spike_threshold(attrs)
        stepped = stepped_decisions(model, x, y, spec, silent_from, per_sample=True)
        record["per_sample"] = stepped.pop("per_sample")
        record["stepped"] = stepped
        timing["stepped_decisions"] = time.perf_counter() - start
        start = time.perf_counter()
        figures = metrics.stepped_figures(model, x, lambda b: encode(b, spec, silent_from))
    elif spec.spiking:
        early = None
        if getattr(model, "event_driven", False):
            early = early_decisions(model, dataset, per_sample=True)
            record["per_sample"] = early.pop("per_sample")
            record["early"] = early
        timing["early_decisions"] = time.perf_counter() - start
        start = time.perf_counter()
        figures = metrics.spiking_figures(model, x, early)
    else:
        figures = metrics.conventional_figures(model, x, suite.board_power_w)
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
    from simlidar.bench.train import load_checkpoint

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
        record = _read_cell(path)
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
        record.update(measure(model, data["recipe"], dataset, suite, predicted, timing, spec))
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


def check_validation(suite: Suite, models: list[str], dataset: Path | None) -> None:
    """Every model's validation fraction leaves every class of every dataset of the run a
    training and a validation sample; a ConfigError naming the suite or recipe key otherwise
    (before anything is written). Checked on the per-class counts: generated datasets label
    sample i as i mod classes, so theirs come from the suite's sizes, never from an array of
    ``train_size`` labels."""
    if dataset is None and suite.generate is not None:
        from simlidar.generator.simulate import class_plan
        from simlidar.scene.recipe import load_catalog

        plan = class_plan(load_catalog(), suite.generate.classes)
        size, classes = suite.generate.train_size, plan.classes
        counted = [([size // classes + (k < size % classes) for k in range(classes)], plan.names)]
    else:
        counted = []
        for path in [dataset] if dataset is not None else suite.datasets:
            info = dataset_splits(path)["train"]
            names = [str(n) for n in info.attrs["class_names"]]
            labels = info.read(("labels",))["labels"]
            counted.append((np.bincount(labels, minlength=len(names)).tolist(), names))
    for model in models:
        fraction = training_rules(model, suite.budget_for(model))["validation"]
        where = (
            f"suite {suite.path}: key 'budget.validation'"
            if "validation" in suite.budget_for(model)
            else f"recipe {model}: key 'training.validation'"
        )
        for counts, names in counted if fraction else ():
            try:
                for count, name in zip(counts, names):
                    if count:
                        validation_count(count, fraction, name)
            except ConfigError as exc:
                raise ConfigError(f"{where}: {exc}") from None


def check_fits(suite: Suite, out: Path, dataset: Path | None) -> None:
    """A suite's generated datasets fit on the disk of ``out`` (those not generated yet) and a
    cell's splits fit in memory (a cell loads its dataset's delays and labels); a
    ResourceError before anything is written. Given datasets are checked as they are read."""
    config = suite.generate
    if dataset is not None or config is None:
        return
    from simlidar.generator.generate import check_disk_space, generated_name

    samples = config.train_size + config.test_size
    row_bytes = config.sensor.beams * config.width * np.dtype(np.float32).itemsize + 8
    check_memory(
        samples * row_bytes,
        f"suite {suite.path}: [generate] train_size={config.train_size}, "
        f"test_size={config.test_size}: a cell's delays and labels",
    )
    root = out / "datasets"
    todo = [n for n in suite.noise if not (root / generated_name(config.with_noise(n))).is_dir()]
    if todo:
        check_disk_space(config, len(todo), root)


def run_suite(
    suite: Suite,
    out: Path,
    models: list[str] | None = None,
    dataset: Path | None = None,
    progress: bool = True,
    scheduler: str | None = None,
    workers: int = 2,
    device: str = "cpu",
    thread_count: int = DEFAULT_THREADS,
) -> dict:
    """Run every unfinished cell of the suite into ``out``; write results.json and the report.

    scheduler : a Dask scheduler's address (or ``local``: a LocalCluster of ``workers``
        processes): each cell is then one task on the cluster, writing its own file into
        ``out`` (a path every worker must see; :mod:`simlidar.cluster`)
    device : where cells train (``auto``, ``cpu``, ``cuda``; :mod:`simlidar.bench.hardware`)
    thread_count : torch (and numba) threads of a cell, in place or on a worker: the same
        count gives the same cells
    returns : the results (what results.json holds)
    """
    check_threads(thread_count)
    resolve_device(device)  # a device this machine lacks is refused before anything is written
    from tqdm import tqdm

    from simlidar.bench.report import write_report

    models = list(models or suite.models)
    for model in models:
        load_recipe(model)  # unknown recipes fail before anything is written
    for path in [dataset] if dataset is not None else suite.datasets:
        check_trainable(path)  # every given dataset is sound, before anything is written
    check_validation(suite, models, dataset)
    check_fits(suite, out, dataset)
    claim(out, suite)
    datasets = resolve_datasets(suite, out, dataset, progress)
    cells = [(d, m, s) for d in datasets for m in models for s in suite.seeds]
    todo = [c for c in cells if not finished(out, *c, suite.budget_for(c[1]))]
    bar = tqdm(
        total=len(todo),
        desc=f"bench {suite.name}",
        unit="cell",
        disable=not progress,
        dynamic_ncols=True,
    )
    try:
        if scheduler is not None:
            from simlidar.cluster import LOCAL, connect, run_tasks
            from simlidar.processes import capped_workers

            if scheduler == LOCAL:  # one task a cell: no more processes than cells and cores
                workers = capped_workers(workers, len(todo), "cells")
            with connect(scheduler, workers) as client:
                tasks = [(d, m, s, suite, out, device, thread_count) for d, m, s in todo]
                names = [f"cell {cell_id(d, m, s)}" for d, m, s in todo]
                run_tasks(client, _cluster_cell, tasks, names, lambda index, _: bar.update())
        for d, m, s in todo if scheduler is None else ():
            bar.set_postfix_str(cell_id(d, m, s))
            run_and_write(d, m, s, suite, out, device, thread_count)
            bar.update()
    finally:
        bar.close()  # an error then gets a line of its own, not the end of the bar's
    results = collect(out, suite)
    write_report(results, out)
    return results


def run_and_write(
    dataset: Path,
    model: str,
    seed: int,
    suite: Suite,
    out: Path,
    device: str = "cpu",
    thread_count: int = DEFAULT_THREADS,
) -> str:
    """Run one cell on ``thread_count`` threads and write it (``out/cells/<cell>.json``, its
    checkpoint beside); its id."""
    name = cell_id(dataset, model, seed)
    start = time.perf_counter()
    with threads(thread_count):
        record = run_cell(dataset, model, seed, suite, out / "checkpoints" / f"{name}.pt", device)
        record["threads"] = thread_count
    record["seconds"] = round(time.perf_counter() - start, 2)
    record.update(
        inputs=cell_inputs(dataset, model, suite.budget_for(model)),
        machine=machine(),
        simlidar_version=__version__,
    )
    write_json(out / "cells" / f"{name}.json", record, indent=None)
    return name


def _cluster_cell(
    dataset: Path, model: str, seed: int, suite: Suite, out: Path, device: str, thread_count: int
) -> str:
    """A cluster task: one cell on the run's thread count, as in place (a worker runs as many
    cells at once as it has threads); the cell records the machine it ran on."""
    for folder in (dataset, out):
        if not Path(folder).is_dir():
            raise DatasetError(
                f"{folder}: not found on worker {socket.gethostname()}; expected it on a file "
                "system that every worker shares"
            )
    return run_and_write(dataset, model, seed, suite, out, device, thread_count)


def _read_cell(path: Path) -> dict:
    """A cell's record, the rules of a cell written before null stood for no time cap (a bare
    ``Infinity``) in today's form (:func:`recorded_rules`)."""
    record = json.loads(path.read_text())
    if isinstance(record.get("budget"), dict):
        record["budget"] = recorded_rules(record["budget"])
    inputs = record.get("inputs")
    if isinstance(inputs, dict) and isinstance(inputs.get("rules"), dict):
        inputs["rules"] = recorded_rules(inputs["rules"])
    return record


def collect(out: Path, suite: Suite) -> dict:
    """results.json from every finished cell in ``out`` (per-sample arrays stay in cells/)."""
    records = []
    for path in sorted((out / "cells").glob("*.json")):
        record = _read_cell(path)
        record.pop("per_sample", None)
        records.append(record)
    results = {
        "suite": {"name": suite.name, "sha256": suite.sha256, "description": suite.description},
        "simlidar_version": __version__,  # of the run that wrote this file; cells record theirs
        "machine": machine(),  # that wrote this file; each cell records the one it ran on
        "seconds": round(sum(r["seconds"] for r in records), 1),
        "cells": records,
    }
    write_json(out / "results.json", results)
    return results
