"""Run a suite: train and score every (dataset, model, seed) cell, write results and report.

Output directory layout::

    <out>/suite.json          which suite (name, sha256 of its file) owns the directory
    <out>/datasets/...        datasets generated on the fly by the suite
    <out>/cells/<id>.json     one finished cell (written atomically): a rerun skips it
    <out>/checkpoints/<id>.pt its kept weights (save_checkpoint; not published: re-measuring)
    <out>/results.json        every finished cell plus suite, versions, machine, time taken
    <out>/report.md, *.png    tables beside the paper's numbers, and pictures
"""

import math
import socket
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

from simlidar import __version__
from simlidar.bench.cells import (
    cell_id,
    cell_inputs,
    finished,
    recorded_rules,
    training_rules,
)
from simlidar.bench.checkpoints import save_checkpoint
from simlidar.bench.checks import probe_model
from simlidar.bench.hardware import DEFAULT_THREADS, check_threads, resolve_device, threads
from simlidar.bench.measure import measure
from simlidar.bench.outdir import claim, collect, machine, write_json
from simlidar.bench.selection import validation_count
from simlidar.bench.suite import BUDGET_KEYS, Suite
from simlidar.bench.train import train
from simlidar.content import shipped_or_path
from simlidar.dataset.reader import dataset_splits
from simlidar.dataset.version import GENERATOR
from simlidar.errors import ConfigError, DatasetError
from simlidar.models.registry import check_distinct, is_outside, load_recipe, model_name
from simlidar.release.verify import check_trainable
from simlidar.resources import check_memory


def anchored_model(model: str) -> str:
    """``model`` with a relative recipe path made absolute; a recipe's name, a builder and an
    absolute path as given. A model's code may change the working directory (``os.chdir``),
    which must then change no path of the run. Cells record a recipe by its file's stem and
    content, never its path (:func:`~simlidar.bench.cells.cell_inputs`): the same cells. A
    builder's file named alone keeps its name, which a cell's fingerprint holds: the registry
    keeps the module it imported first (:func:`~simlidar.models.registry.builder`)."""
    if is_outside(model) and not model.endswith(".toml"):
        return model
    try:
        path = shipped_or_path(model, "baselines", "model recipe")
    except ConfigError:  # an unknown name: refused where recipes are loaded
        return model
    return model if path.is_absolute() else str(path.absolute())


def anchored(suite: Suite) -> Suite:
    """``suite`` with its dataset directories and recipe paths absolute (its budget's keys with
    them: :func:`anchored_model`), read before any model's code runs; the suite's file, name
    and digests as they were."""
    return replace(
        suite,
        models=tuple(anchored_model(m) for m in suite.models),
        datasets=tuple(path.absolute() for path in suite.datasets),
        budget={k if k == "*" else anchored_model(k): v for k, v in suite.budget.items()},
    )


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
    ``device``: where it trains (``--device``); it is measured on the CPU. ``suite``: the
    suite whose budget (epochs, time, validation, patience) and selection the cell follows."""
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
        save_checkpoint(result, checkpoint, dataset)
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
        measure(
            result.model,
            recipe,
            dataset,
            suite.board_power_w,
            result.test_predictions,
            timing,
            result.spec,
        )
    )
    return record


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


def sample_shapes(suite: Suite, dataset: Path | None) -> set[tuple[int, int, int]]:
    """(H, W, classes) of the run's datasets: a given dataset's own, or what the suite's
    [generate] table will make."""
    if dataset is None and suite.generate is not None:
        from simlidar.generator.simulate import class_plan
        from simlidar.scene.recipe import load_catalog

        config = suite.generate
        classes = class_plan(load_catalog(), config.classes).classes
        return {(config.sensor.beams, config.width, classes)}
    shapes = set()
    for path in [dataset] if dataset is not None else suite.datasets:
        info = dataset_splits(path)["train"]
        shapes.add((info.height, info.width, len(info.attrs["class_names"])))
    return shapes


def check_models(suite: Suite, models: list[str], dataset: Path | None) -> None:
    """Build every model for the run's sample shapes and check its output on two samples
    (:func:`~simlidar.bench.checks.probe_model`), before anything is written: a model refused
    once its cell has started would leave ``suite.json`` and ``cells/`` behind."""
    for model in models:
        recipe = load_recipe(model)
        cap = training_rules(model, suite.budget_for(model))["max_seconds"]  # None: no cap
        for height, width, classes in sorted(sample_shapes(suite, dataset)):
            probe_model(recipe, (height, width), classes, math.inf if cap is None else cap)


def budget_notes(suite: Suite, models: list[str]) -> list[str]:
    """One line for each model whose recipe's [training] the suite's budget overrides (the
    rule: the suite's ``[budget.<model>]``, else its ``[budget]``, over the recipe;
    ``bench --epochs`` and the like over both), saying what it trains by and what its recipe
    said: a recipe's epochs are never replaced silently."""
    lines = []
    for model in models:
        recipe = load_recipe(model)["training"]
        budget = suite.budget_for(model)
        changed = [
            f"{key} {budget[key]:g} (its recipe: {recipe[key]:g})"
            for key in BUDGET_KEYS
            if key in budget and key in recipe and budget[key] != recipe[key]
        ]
        if changed:
            lines.append(
                f"{model_name(model)}: {', '.join(changed)}, by suite {suite.name}'s budget"
            )
    return lines


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
    note: Callable[[str], None] | None = None,
) -> dict:
    """Run every unfinished cell of the suite into ``out``; write results.json and the report.

    models : the recipes to run (None: the suite's)
    dataset : one dataset directory to run them on instead of the suite's datasets
    progress : a progress bar on stderr
    scheduler : a Dask scheduler's address (or ``local``: a LocalCluster of ``workers``
        processes): each cell is then one task on the cluster, writing its own file into
        ``out`` (a path every worker must see; :mod:`simlidar.cluster`)
    device : where cells train (``auto``, ``cpu``, ``cuda``; :mod:`simlidar.bench.hardware`)
    thread_count : torch (and numba) threads of a cell, in place or on a worker: the same
        count gives the same cells
    note : told, once every check has passed, each recipe value the suite's budget replaces
        (:func:`budget_notes`)
    returns : the results (what results.json holds)
    """
    # every path absolute before a model's code runs: it may change the working directory
    suite, out = anchored(suite), Path(out).absolute()
    dataset = None if dataset is None else Path(dataset).absolute()
    models = [anchored_model(str(m)) for m in models or suite.models]
    check_threads(thread_count)
    resolve_device(device)  # a device this machine lacks is refused before anything is written
    from tqdm import tqdm

    from simlidar.bench.report import write_report

    for model in models:
        load_recipe(model)  # unknown recipes fail before anything is written
    check_distinct(models)
    for path in [dataset] if dataset is not None else suite.datasets:
        check_trainable(path)  # every given dataset is sound, before anything is written
    check_validation(suite, models, dataset)
    check_fits(suite, out, dataset)
    check_models(suite, models, dataset)
    claim(out, suite)
    datasets = resolve_datasets(suite, out, dataset, progress)
    for line in budget_notes(suite, models) if note is not None else ():
        note(line)
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
    checkpoint beside); its id.

    dataset, model, seed : the cell: a dataset directory, a recipe name or path (or an outside
        builder named alone) and the training seed
    suite : the suite whose budget and selection the cell follows (:func:`run_cell`)
    out : the run's output directory
    device : where the cell trains (``cpu``, ``cuda``, ``auto``: :mod:`simlidar.bench.hardware`);
        it is measured on the CPU
    """
    name = cell_id(dataset, model, seed)
    start = time.perf_counter()
    with threads(thread_count):
        record = run_cell(dataset, model, seed, suite, out / "checkpoints" / f"{name}.pt", device)
        record["threads"] = thread_count
        where = machine()  # inside: its torch_threads is the count the cell ran on
    record["seconds"] = round(time.perf_counter() - start, 2)
    record.update(
        inputs=cell_inputs(dataset, model, suite.budget_for(model)),
        machine=where,
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
