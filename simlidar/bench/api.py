"""Put any model through the benchmark from Python (a notebook, a script): the same cells,
results.json and report that ``simlidar bench`` writes, so a user's results merge with a
suite's (``simlidar report``).

    from simlidar.bench.api import bench_model

    cells = bench_model(my_builder, "data/simlidar-32c-noise0.1-paper-v2.0.0",
                        budget={"epochs": 20}, out="bench/mine")

The model follows the builder protocol (:mod:`simlidar.models.registry`) and declares itself
(:mod:`simlidar.models.protocol`).
"""

import copy
import hashlib
import inspect
import json
from dataclasses import replace
from pathlib import Path

from simlidar.bench.hardware import DEFAULT_THREADS
from simlidar.bench.run import run_suite
from simlidar.bench.suite import BUDGET_KEYS, Suite, load_suite
from simlidar.errors import ConfigError
from simlidar.models.registry import register
from simlidar.models.training_config import TrainingConfig


def bench_model(
    model,
    dataset: str | Path | None = None,
    *,
    suite: str | Path | None = None,
    out: str | Path = "bench/api",
    seeds: tuple[int, ...] = (0,),
    budget: dict | None = None,
    name: str | None = None,
    device: str = "cpu",
    threads: int = DEFAULT_THREADS,
    progress: bool = False,
) -> list[dict]:
    """Train and score ``model`` on ``dataset`` (or on every dataset of ``suite``), one cell
    per (dataset, seed), written to ``out`` as ``simlidar bench`` writes them; returns the
    cells of the run (what results.json lists, the model's and any others in ``out``).

    model : a recipe name or path, ``"package.module:function"``, a builder function
        ``f(input_shape, classes, generator, **architecture) -> nn.Module``, or a module
        (copied for each cell; its initial weights are then not the seed's)
    dataset : a dataset directory; or ``suite``: a suite name or file (its datasets, its
        budget for the model's name, its data: ``out`` may be that suite's folder)
    seeds : one cell per seed (initial weights, batch order, validation rows)
    budget : epochs, max_seconds, validation, patience (over the recipe's [training])
    name : what the cells call a function or module (default: its ``__name__`` / class name)
    device, threads : as ``--device`` and ``--threads``
    progress : a progress bar on stderr
    """
    if (dataset is None) == (suite is None):
        raise ConfigError("bench_model: expected a dataset or a suite, exactly one")
    key = _model_key(model, name)
    budget = dict(budget or {})
    unknown = sorted(set(budget) - set(BUDGET_KEYS))
    if unknown:
        raise ConfigError(f"budget key {unknown[0]!r}: expected one of {list(BUDGET_KEYS)}")
    TrainingConfig.check_table(budget, "bench_model", prefix="budget.")
    if suite is not None:
        chosen = load_suite(suite)
        chosen = replace(chosen, models=(key,), seeds=tuple(seeds))
        chosen = chosen.with_budget(**budget) if budget else chosen
    else:
        chosen = _dataset_suite(Path(dataset), key, tuple(seeds), budget)
    results = run_suite(chosen, Path(out), progress=progress, device=device, thread_count=threads)
    return results["cells"]


def _model_key(model, name: str | None) -> str:
    """What the registry calls ``model``: a recipe or builder name as given, or the key of a
    function or module registered in this process."""
    import torch

    if isinstance(model, str | Path):
        return str(model)
    if isinstance(model, torch.nn.Module):
        module = model

        def function(input_shape, classes, generator=None, **architecture):
            return copy.deepcopy(module)

        fingerprint = hashlib.sha256(repr(module).encode())
        for value in module.state_dict().values():
            fingerprint.update(value.detach().cpu().numpy().tobytes())
        return register(function, name or type(module).__name__, fingerprint.hexdigest())
    if callable(model):
        try:
            source = hashlib.sha256(inspect.getsource(model).encode()).hexdigest()
        except (OSError, TypeError):
            source = None
        return register(model, name or getattr(model, "__name__", "builder"), source)
    raise ConfigError(
        f"bench_model: model {type(model).__name__}: expected a recipe, a builder or a module"
    )


def _dataset_suite(dataset: Path, key: str, seeds: tuple[int, ...], budget: dict) -> Suite:
    """A suite of one dataset: its data digest is a suite file's listing the same path."""
    if not dataset.is_dir():
        raise ConfigError(f"bench_model: dataset {dataset}: expected a dataset directory")
    listed = [str(dataset)]
    text = json.dumps({"datasets": listed, "models": [key], "seeds": list(seeds)}, sort_keys=True)
    return Suite(
        name="api",
        path=Path("simlidar.bench.api"),
        sha256=hashlib.sha256(text.encode()).hexdigest(),
        data_sha256=hashlib.sha256(json.dumps(listed, sort_keys=True).encode()).hexdigest(),
        description=f"simlidar.bench.api.bench_model on {dataset.name}",
        models=(key,),
        seeds=seeds,
        generate=None,
        noise=(),
        datasets=(dataset,),
        budget={"*": budget},
    )
