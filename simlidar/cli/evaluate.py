"""``simlidar evaluate``: a saved model scored on a dataset, measured as a benchmark cell is."""

import contextlib
import json
import sys
from pathlib import Path

import click

from simlidar.cli.options import IntegerRange, need_torch
from simlidar.errors import DatasetError, TrainingError


def _threads(command):
    """``--threads``, as train's: fixed and recorded, as a cell's figures depend on it."""
    from simlidar.bench.hardware import DEFAULT_THREADS, MAX_THREADS, check_threads

    return click.option(
        "--threads",
        type=IntegerRange(1, MAX_THREADS),
        default=DEFAULT_THREADS,
        callback=lambda _ctx, _param, count: check_threads(count),
        show_default=True,
        help="Torch (and spiking-kernel) threads; the latency depends on it, so it is recorded.",
    )(command)


@click.command()
@click.argument("checkpoint", type=click.Path(path_type=Path))
@click.option(
    "--dataset",
    type=click.Path(path_type=Path),
    required=True,
    help="Dataset directory in the simlidar schema; its test split is scored.",
)
@click.option(
    "--model",
    default=None,
    help="Only for a checkpoint of an outside model: its builder (package.module:function, "
    "path/to/file.py:function) or the recipe that names it, which evaluate then runs; a "
    "checkpoint alone never makes evaluate import outside code.",
)
@_threads
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object on stdout.")
@click.option(
    "--out",
    type=click.Path(dir_okay=False, path_type=Path),
    default=None,
    help="Also write the JSON object to this file (a new one: nothing is replaced).",
)
def evaluate(checkpoint, dataset, model, threads, as_json, out):
    """Score a checkpoint (simlidar train's, or a bench cell's checkpoints/<cell>.pt) on the
    test split of a dataset: accuracy, how early a spiking network decides, NeuroBench's
    metrics, latency, as a benchmark cell records them. The dataset must fit the model: the
    input shape and classes it was trained for, the same coding of no return (profile)."""
    need_torch("evaluate")
    from simlidar.bench.checkpoints import check_writable
    from simlidar.bench.evaluate import evaluate as run_evaluate
    from simlidar.bench.evaluate import summary
    from simlidar.bench.hardware import threads as using_threads
    from simlidar.bench.outdir import write_json

    if out is not None:  # before any work: evaluate replaces nothing
        if out.exists() or out.is_symlink():
            raise DatasetError(f"--out {out}: already exists; expected a new file")
        check_writable(out.parent)
    # with --json, what a model's code prints goes to stderr: stdout holds the one object
    kept = contextlib.redirect_stdout(sys.stderr) if as_json else contextlib.nullcontext()
    with kept, using_threads(threads):
        record = run_evaluate(checkpoint, dataset, model, threads)
    for line in record["evaluated"]["warnings"]:
        click.echo(f"warning: {line}", err=True)
    if out is not None:
        write_json(out, record)
    if not as_json:
        for line in summary(record):
            click.echo(line)
        if out is not None:
            click.echo(f"wrote {out}")
        return
    try:
        click.echo(json.dumps(record, allow_nan=False))
    except ValueError as exc:
        raise TrainingError(f"the figures: {exc}; expected finite numbers") from None
