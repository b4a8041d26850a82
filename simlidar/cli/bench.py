"""``simlidar train`` and ``bench``: models trained and scored on datasets."""

import contextlib
import json
import sys
from pathlib import Path

import click

from simlidar.bench.suite import load_suite, suite_names
from simlidar.cli.options import (
    IntegerRange,
    Workers,
    need_torch,
    scheduler_option,
    setting_option,
)
from simlidar.errors import ConfigError, DatasetError, SimlidarError
from simlidar.models.training_config import TrainingConfig
from simlidar.settings import help_of


def _override(name: str, **options):
    """An option that overrides the recipe's (or suite's) TrainingConfig value ``name``."""
    what = help_of(TrainingConfig, name)
    return setting_option(
        TrainingConfig, name, default=None, help=f"Override: {what[0].lower()}{what[1:]}", **options
    )


_selection_options = [
    _override("validation"),
    _override("patience"),
]


def _selection(command):
    for option in reversed(_selection_options):
        command = option(command)
    return command


def _hardware(command):
    """``--device`` and ``--threads``: where a model trains, on how many threads (recorded)."""
    from simlidar.bench.hardware import DEFAULT_THREADS, DEVICES, MAX_THREADS, check_threads

    command = click.option(
        "--threads",
        type=IntegerRange(1, MAX_THREADS),
        default=DEFAULT_THREADS,
        callback=lambda _ctx, _param, count: check_threads(count),  # before anything is written
        show_default=True,
        help="Torch (and spiking-kernel) threads of a run; a cell's figures depend on it, so it "
        "is fixed and recorded (1: measured fastest here, docs/benchmark.md).",
    )(command)
    return click.option(
        "--device",
        default="cpu",
        show_default=True,
        metavar="|".join(DEVICES),
        help="Where models train: auto (CUDA where there is a GPU), cpu, cuda or cuda:N; "
        "measured on the CPU.",
    )(command)


def _device(value: str):
    """The torch device of ``--device``, or a usage error naming it."""
    from simlidar.bench.hardware import resolve_device

    try:
        return resolve_device(value)
    except ConfigError as exc:
        raise click.BadParameter(str(exc), param_hint="'--device'") from None


def _chosen(result) -> str:
    """Which epoch a ``simlidar train`` run kept, and why it stopped, in words."""
    from simlidar.bench.selection import ANNEALED

    if result.stopped == "own-fit":
        return (
            f"trained by its own simlidar_fit (validation accuracy of {result.validation_size} "
            "held-out samples recorded)"
        )
    why = {
        "plateau": "stopped on a validation plateau",
        "epochs": "ran every epoch",
        "time": "stopped by the time cap",
    }[result.stopped]
    kept = f"epoch {result.best_epoch + 1} of {result.epochs} kept"
    if not result.validation_size:
        return f"{result.epochs} epochs, no validation, the last kept, {why}"
    if result.rule == ANNEALED:
        return (
            f"{kept} (the last of its cosine schedule; validation accuracy of "
            f"{result.validation_size} held-out samples recorded, not used to choose), {why}"
        )
    return f"{kept} (best validation accuracy of {result.validation_size} held-out samples), {why}"


@click.command()
@click.option(
    "--model",
    "model",
    required=True,
    help="Model recipe: a name in baselines/ (snn_simlidar, ...), a .toml file, or an outside "
    "builder package.module:function or path/to/file.py:function (docs/benchmark.md, 'Your own "
    "model').",
)
@click.option(
    "--dataset",
    type=click.Path(path_type=Path),
    required=True,
    help="Dataset directory in the simlidar schema.",
)
@click.option(
    "--out",
    type=click.Path(file_okay=False, path_type=Path),
    default=Path("runs"),
    show_default=True,
    help="Folder for the checkpoint.",
)
@click.option("--seed", type=IntegerRange(0, 2**63 - 1), default=0, show_default=True)
@_override("epochs")
@_override("max_seconds")
@_selection
@_hardware
@click.option(
    "--force", is_flag=True, help="Replace a checkpoint of the same model, dataset and seed."
)
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object on stdout.")
def train(
    model,
    dataset,
    out,
    seed,
    epochs,
    max_seconds,
    validation,
    patience,
    device,
    threads,
    force,
    as_json,
):
    """Train a model on a dataset's train split, keep the epoch with the best accuracy on a
    held-out validation part of it (the last epoch of a cosine schedule), score that once on
    the test split, save a checkpoint named by model, dataset and seed
    (<out>/<model>-<dataset>-seed<seed>.pt; an existing one is replaced only with --force)."""
    need_torch("train")
    from simlidar.bench.checkpoints import check_writable, checkpoint_path, save_checkpoint
    from simlidar.bench.hardware import threads as using_threads
    from simlidar.bench.selection import ANNEALED
    from simlidar.bench.train import train as train_model
    from simlidar.models.registry import load_recipe
    from simlidar.release.verify import check_trainable

    device = _device(device)
    with _stdout_kept_for(as_json):
        recipe = load_recipe(model)
        given = {"validation": validation, "patience": patience}
        recipe["training"].update({k: v for k, v in given.items() if v is not None})
        check_trainable(dataset)  # a sound dataset, or a one-line error
        check_writable(out)  # before training, not after
        path = checkpoint_path(out, recipe["name"], dataset, seed)
        if path.exists() and not force:
            raise DatasetError(f"{path} already exists: pass --force to replace it")
        with using_threads(threads):
            result = train_model(
                recipe, dataset, seed=seed, epochs=epochs, max_seconds=max_seconds, device=device
            )
    result.model.cpu()
    if result.rule == ANNEALED and result.stopped == "time":
        click.echo(
            f"warning: the time cap stopped the cosine schedule after epoch {result.epochs} of "
            f"{result.epoch_cap}, before it annealed (learning rate {result.history[-1]['lr']:.3g} "
            "in that epoch): the kept weights are not the schedule's end; raise --max-seconds "
            "or lower --epochs",
            err=True,
        )
    record = {
        "model": recipe["name"],
        "dataset": str(dataset),
        "seed": seed,
        "test_accuracy": round(result.test_accuracy, 4),
        "epochs": result.epochs,
        **result.selection(),
        "seconds": round(result.seconds, 1),
        "checkpoint": None,  # set once written
        "spec": result.spec.table(),
        "device": result.device,
        "threads": threads,
    }
    with _stdout_kept_for(as_json):  # the decisions run the model again
        import torch

        from simlidar.bench.measure import decision_record
        from simlidar.dataset.loaders import load_split

        x, y = load_split(dataset, "test")
        x = torch.from_numpy(x)[:, None]
        record |= decision_record(result.model, dataset, result.spec, result.silent_from, x, y)
    if not as_json:  # the result first: a checkpoint that cannot be written loses nothing else
        click.echo(
            f"{recipe['name']}: test accuracy {result.test_accuracy:.4f}, {_chosen(result)}, "
            f"{result.seconds:.0f} s"
        )
        if "early" in record:
            from simlidar.bench.early import format_early

            click.echo(format_early(record["early"]))
        if "stepped" in record:
            from simlidar.bench.stepped import format_stepped

            click.echo(format_stepped(record["stepped"]))
    try:
        save_checkpoint(result, path, dataset)
    except SimlidarError:
        if as_json:  # the result all the same, with no checkpoint
            click.echo(json.dumps(record))
        raise
    record["checkpoint"] = str(path)
    click.echo(json.dumps(record) if as_json else f"wrote {path}")


def _stream_suite(suite, models, dataset, out, epochs, threads, as_json):
    """``simlidar bench`` of a stream suite (:mod:`simlidar.bench.stream_suite`)."""
    import shlex

    import torch

    from simlidar.bench.stream_suite import load_stream_suite, run_stream_suite

    try:
        chosen = load_stream_suite(suite)
    except ConfigError as exc:
        raise click.BadParameter(str(exc), param_hint="'--suite'") from None
    names = None if models is None else [m.strip() for m in models.split(",") if m.strip()]
    given = [
        ("--suite", suite),
        ("--models", models),
        ("--dataset", dataset),
        ("--out", out),
        ("--epochs", epochs),
        ("--threads", threads),
    ]
    default = chosen.name if dataset is None else f"{chosen.name}-{dataset.name}"
    out = out if out is not None else (Path("bench") / default).absolute()
    command = "simlidar bench" + "".join(
        f" {name} {shlex.quote(str(value))}" for name, value in given if value is not None
    )
    torch.set_num_threads(threads)
    with _stdout_kept_for(as_json):
        table = run_stream_suite(
            chosen,
            out,
            command,
            dataset=dataset,
            models=names,
            epochs=epochs,
            progress=not as_json,
            note=lambda line: click.echo(line, err=as_json),
        )
    if as_json:
        click.echo(json.dumps({"suite": chosen.name, "out": str(out), "models": table}))
        return
    click.echo(f"{len(table)} models in {out}: cells.jsonl, report.md, accuracy-latency.png")


def _absolute(_ctx, _param, path: Path | None) -> Path | None:
    """A path option made absolute as it is parsed: a model's code, run later in this process,
    may change the working directory (``os.chdir``), which must not move ``--out``."""
    return None if path is None else path.absolute()


def _stdout_kept_for(as_json: bool):
    """With ``--json``, what a model's code prints goes to stderr while it runs: stdout holds
    the one JSON object (a builder printing megabytes broke it)."""
    return contextlib.redirect_stdout(sys.stderr) if as_json else contextlib.nullcontext()


@click.command()
@click.option(
    "--suite",
    default="quick",
    show_default=True,
    help=f"Suite: a name in benchmark/ ({', '.join(suite_names())}) or a .toml file.",
)
@click.option(
    "--models",
    default=None,
    help="Comma-separated model recipes to run instead of the suite's (e.g. snn_simlidar,cnn): "
    "a name in baselines/, a .toml recipe file (its [spec] table: what the model outputs and "
    "wants), or an outside builder package.module:function or path/to/file.py:function "
    "(docs/benchmark.md, 'Your own model'). The suite's [budget] sets every model's epochs "
    "and time cap over its recipe's (quick: 10 epochs for a model it does not name); "
    "--epochs and --max-seconds over both; the run prints each value it replaced.",
)
# --dataset and --out look like train's, but are optional here, with their own help
@click.option(
    "--dataset",
    type=click.Path(path_type=Path),
    default=None,
    callback=_absolute,
    help="Run the suite's models on this dataset directory instead of the suite's datasets.",
)
@click.option(
    "--out",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    callback=_absolute,
    help="Output directory (default: bench/<suite name>; with --dataset, bench/<suite "
    "name>-<dataset directory name>, apart from the suite's own cells).",
)
@_override("epochs")
@_override("max_seconds")
@_selection
@click.option(
    "--remeasure",
    is_flag=True,
    help="Measure the finished cells of --out again from their checkpoints (no training).",
)
@scheduler_option("every unfinished cell as one task")
@click.option(
    "--workers",
    type=Workers(),
    default=None,
    help="With --scheduler local: the LocalCluster's processes (default: auto, every core).",
)
@_hardware
@click.option("--json", "as_json", is_flag=True, help="Print results.json's content on stdout.")
def bench(
    suite,
    models,
    dataset,
    out,
    epochs,
    max_seconds,
    validation,
    patience,
    remeasure,
    scheduler,
    workers,
    device,
    threads,
    as_json,
):
    """Train and score the suite's models on its datasets: accuracy, how early spiking networks
    decide, energy, latency, size. Writes results.json, report.md and pictures; a rerun into
    the same directory skips the cells already finished."""
    need_torch("bench")
    from simlidar.bench.run import anchored, anchored_model, run_suite
    from simlidar.bench.stream_suite import is_stream_suite

    if is_stream_suite(suite):
        refused = {
            "--max-seconds": max_seconds,
            "--validation": validation,
            "--patience": patience,
            "--remeasure": remeasure or None,
            "--scheduler": scheduler,
            "--workers": workers,
            "--device": None if device == "cpu" else device,
        }
        given = [name for name, value in refused.items() if value is not None]
        if given:
            raise click.UsageError(
                f"{given[0]}: not an option of a stream suite ({suite}); expected --models, "
                "--dataset, --out, --epochs, --threads or --json"
            )
        _stream_suite(suite, models, dataset, out, epochs, threads, as_json)
        return
    try:
        chosen = anchored(load_suite(suite))
    except ConfigError as exc:
        raise click.BadParameter(str(exc), param_hint="'--suite'") from None
    # every path absolute before a model's code runs (importing a builder runs it)
    default = chosen.name if dataset is None else f"{chosen.name}-{dataset.name}"
    out = out if out is not None else (Path("bench") / default).absolute()
    names = None
    if models is not None:
        from simlidar.models.registry import load_recipe

        names = [anchored_model(m.strip()) for m in models.split(",") if m.strip()]
        try:
            for name in names or [models]:
                load_recipe(name)
        except ConfigError as exc:
            raise click.BadParameter(str(exc), param_hint="'--models'") from None
    chosen = chosen.with_budget(
        epochs=epochs, max_seconds=max_seconds, validation=validation, patience=patience
    )
    if remeasure:
        given = {
            "--models": models,
            "--dataset": dataset,
            "--epochs": epochs,
            "--max-seconds": max_seconds,
            "--validation": validation,
            "--patience": patience,
        }
        given["--scheduler"] = scheduler
        extra = [name for name, value in given.items() if value is not None]
        if extra:
            raise click.UsageError(
                f"--remeasure re-measures the finished cells of --out as they "
                f"were trained; expected no {extra[0]}"
            )
        from simlidar.bench.measure import remeasure as run_remeasure

        results = run_remeasure(out, chosen, progress=not as_json)
    else:
        if workers is not None and scheduler != "local":
            raise click.UsageError(
                f"--workers {workers} sizes a LocalCluster; expected --scheduler local with it"
            )
        with _stdout_kept_for(as_json):
            results = run_suite(
                chosen,
                out,
                models=names,
                dataset=dataset,
                progress=not as_json,
                scheduler=scheduler,
                workers=workers or Workers().convert("auto", None, None),
                device=str(_device(device)),
                thread_count=threads,
                note=lambda line: click.echo(f"note: {line}", err=True),
            )
    if as_json:
        click.echo(json.dumps(results))
        return
    click.echo(f"{len(results['cells'])} cells in {out}: results.json, report.md")
    width = max((len(cell["model"]) for cell in results["cells"]), default=0)
    for cell in results["cells"]:
        click.echo(
            f"  {cell['dataset']}  {cell['model']:<{width}}  seed {cell['seed']}  accuracy "
            f"{cell['accuracy']:.4f}  latency {cell['latency_ms']:.2f} ms"
        )
